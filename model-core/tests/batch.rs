//! The batch paths a host uses to convert recordings, `ActiveInverse::pressures_kpa` and
//! `PadModel::process_all` and `PadPipeline::process_all`, against the one-at-a-time paths the device runs: the same bits for
//! every tier, on generated hard calibrations, for fault, edge and arbitrary inputs. A batch that
//! differed in one ulp would make a re-processed recording disagree with what the device sent.

use model_core::baseline::BaselineTracking;
use model_core::inverse::ActiveInverse;
use model_core::{
    Calibration, CalibrationCurve, CalibrationSpec, ContactConfig, CurvePoint, ForceAndContact,
    PadGeometry, PadModel, PadOutput, PadPipeline, PadReport, PadRole, SampleInput, TaxelFlags,
    TaxelReading, Tier, BATCH_SAMPLE_SETS,
};
use proptest::prelude::*;
use reference_curves::{hard_calibration, probes, ForwardCubic};

/// A hard calibration's curve and its f64 reference (for the probes).
fn hard_curve(seed: u64) -> Option<(Vec<CurvePoint>, CalibrationCurve, ForwardCubic)> {
    let (points, _) = hard_calibration(seed);
    let curve_points: Vec<CurvePoint> = points
        .iter()
        .map(|(pressure_kpa, relative_change)| CurvePoint::new(*pressure_kpa, *relative_change))
        .collect();
    let curve = CalibrationCurve::new(&curve_points, 0).ok()?;
    let pressures_kpa: Vec<f64> = points.iter().map(|p| f64::from(p.0)).collect();
    let relative_changes: Vec<f64> = points.iter().map(|p| f64::from(p.1)).collect();
    let reference = ForwardCubic::new(&pressures_kpa, &relative_changes)?;
    Some((curve_points, curve, reference))
}

/// What the batch must agree on besides ordinary readings: every point and its neighbours, the
/// ends, NaN, infinities, zeros, subnormals and values far outside the curve.
fn edge_values(curve: &CalibrationCurve) -> Vec<f32> {
    let mut values = vec![
        f32::NAN,
        -f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        0.0,
        -0.0,
        f32::MIN_POSITIVE,
        f32::from_bits(1),
        -f32::from_bits(1),
        -1.0,
        f32::MAX,
        f32::MIN,
        1.0e30,
    ];
    for point in curve.points() {
        let bits = point.relative_change.to_bits();
        for offset in 0..=3u32 {
            values.push(f32::from_bits(bits.saturating_add(offset)));
            values.push(f32::from_bits(bits.saturating_sub(offset)));
        }
        values.push(point.relative_change * 2.0);
    }
    values
}

/// Every supported tier's batch against its one-at-a-time inverse on `values`, bit for bit,
/// over the whole slice and over every short slice (the lanes' remainder).
fn check_batch(curve: &CalibrationCurve, values: &[f32]) -> Result<(), TestCaseError> {
    for tier in Tier::ALL {
        let Some(inverse) = ActiveInverse::new(curve, tier) else {
            continue;
        };
        let one_by_one: Vec<u32> = values
            .iter()
            .map(|value| inverse.pressure_kpa(curve, *value).to_bits())
            .collect();
        let mut batch = values.to_vec();
        inverse.pressures_kpa(curve, &mut batch);
        for ((got, want), value) in batch.iter().zip(&one_by_one).zip(values) {
            prop_assert_eq!(
                got.to_bits(),
                *want,
                "{:?} at dC/C0 {:e}: batch {} one by one {}",
                tier,
                value,
                got,
                f32::from_bits(*want)
            );
        }
        for length in 1..=17.min(values.len()) {
            for (chunk, want) in values.chunks(length).zip(one_by_one.chunks(length)) {
                let mut batch = chunk.to_vec();
                inverse.pressures_kpa(curve, &mut batch);
                let got: Vec<u32> = batch.iter().map(|value| value.to_bits()).collect();
                prop_assert_eq!(&got, want, "{:?}, slices of {}", tier, length);
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1500))]

    /// Hard calibrations, probes spread over every interval and the edge values.
    #[test]
    fn every_tier_batch_is_its_inverse_bit_for_bit(seed in any::<u64>()) {
        let Some((points, curve, reference)) = hard_curve(seed) else {
            return Ok(());
        };
        let point_pairs: Vec<(f32, f32)> =
            points.iter().map(|point| (point.pressure_kpa, point.relative_change)).collect();
        let mut values = probes(&reference, &point_pairs, 24);
        values.extend(edge_values(&curve));
        check_batch(&curve, &values)?;
    }

    /// Arbitrary f32 bits as dC/C0.
    #[test]
    fn arbitrary_bits_give_the_same_pressures(
        seed in any::<u64>(),
        bits in proptest::collection::vec(any::<u32>(), 1..80),
    ) {
        let Some((_, curve, _)) = hard_curve(seed) else {
            return Ok(());
        };
        let values: Vec<f32> = bits.into_iter().map(f32::from_bits).collect();
        check_batch(&curve, &values)?;
    }
}

#[test]
fn the_article_curve_batch_is_its_inverse_bit_for_bit() {
    let curve = CalibrationCurve::article_default();
    let top = curve.top().relative_change;
    let mut values: Vec<f32> = (0..=20_000)
        .map(|step| top * step as f32 / 20_000.0)
        .collect();
    values.extend(edge_values(&curve));
    if let Err(error) = check_batch(&curve, &values) {
        panic!("{error}");
    }
}

/// One reading of a generated sequence.
#[derive(Debug, Clone, Copy)]
enum Reading {
    /// dC/C0 from the taxel's C0 (below 0, in the curve, beyond it).
    Relative(f32),
    /// Arbitrary bits as pF.
    Bits(u32),
    /// A raw converter code.
    Raw(i32, u8),
    /// No reading.
    Unavailable,
}

fn reading() -> impl Strategy<Value = Reading> {
    prop_oneof![
        8 => (-0.3f32..0.9).prop_map(Reading::Relative),
        2 => (-0.01f32..0.01).prop_map(Reading::Relative),
        1 => any::<u32>().prop_map(Reading::Bits),
        1 => (any::<i32>(), 0u8..40).prop_map(|(code, capdac)| Reading::Raw(code, capdac)),
        // Codes the converter gives (a negative total is a short), and its saturation codes.
        1 => (-0x80_0000i32..=0x7F_FFFF, 0u8..=31)
            .prop_map(|(code, capdac)| Reading::Raw(code, capdac)),
        1 => (prop_oneof![Just(0x7F_FFFF), Just(-0x80_0000)], 0u8..=31)
            .prop_map(|(code, capdac)| Reading::Raw(code, capdac)),
        // Exactly 0 pF: the edge of a short.
        1 => Just(Reading::Raw(0, 0)),
        1 => Just(Reading::Unavailable),
    ]
}

fn temperature() -> impl Strategy<Value = Option<f32>> {
    prop_oneof![
        6 => (24.0f32..26.0).prop_map(Some),
        1 => (-40.0f32..120.0).prop_map(Some),
        1 => any::<u32>().prop_map(|bits| Some(f32::from_bits(bits))),
        1 => Just(None),
    ]
}

/// One generated sample set: readings, acquisition flag bits, temperature, µs since the last.
type GeneratedSet = ([Reading; 4], [u16; 4], Option<f32>, Option<u32>);

/// A generated pad: every taxel on its own hard curve (or the default), a tier, tracking, a tare.
#[derive(Debug, Clone)]
struct Case {
    seeds: [u64; 4],
    tier: usize,
    tracking: bool,
    tare_sets: u16,
    sets: Vec<GeneratedSet>,
}

fn case() -> impl Strategy<Value = Case> {
    (
        any::<[u64; 4]>(),
        0..Tier::ALL.len(),
        any::<bool>(),
        0u16..6,
        proptest::collection::vec(
            (
                [reading(), reading(), reading(), reading()],
                any::<[u16; 4]>(),
                temperature(),
                proptest::option::of(0u32..20_000),
            ),
            1..(3 * BATCH_SAMPLE_SETS + 7),
        ),
    )
        .prop_map(|(seeds, tier, tracking, tare_sets, sets)| Case {
            seeds,
            tier,
            tracking,
            tare_sets,
            sets,
        })
}

const SENSOR_PF: f32 = 4.5;

fn pad_for(case: &Case) -> PadModel {
    let mut spec = CalibrationSpec::default();
    for (taxel, seed) in spec.taxels.iter_mut().zip(case.seeds) {
        // A quarter of the taxels keep the default curve.
        if seed % 4 == 0 {
            continue;
        }
        if let Some((points, _, _)) = hard_curve(seed) {
            taxel.points = points.iter().copied().collect();
        }
    }
    let calibration = Calibration::new(&spec).unwrap_or_default();
    let mut pad = PadModel::new(calibration);
    if let Some(tier) = Tier::ALL.get(case.tier) {
        // A tier this calibration does not support keeps the default.
        let _ = pad.set_tier(*tier);
    }
    if case.tracking {
        pad.set_baseline_tracking(BaselineTracking {
            enabled: true,
            ..BaselineTracking::default()
        });
    }
    if case.tare_sets > 0 {
        pad.start_tare(case.tare_sets);
    }
    pad
}

fn samples(case: &Case) -> Vec<SampleInput> {
    let mut time_us = 0u64;
    case.sets
        .iter()
        .map(|(readings, flags, temperature_c, step_us)| {
            let readings = readings.map(|reading| match reading {
                Reading::Relative(change) => {
                    TaxelReading::CapacitancePf(SENSOR_PF * (1.0 + change))
                }
                Reading::Bits(bits) => TaxelReading::CapacitancePf(f32::from_bits(bits)),
                Reading::Raw(code, capdac) => TaxelReading::Raw { code, capdac },
                Reading::Unavailable => TaxelReading::Unavailable,
            });
            let mut sample = SampleInput::new(readings, *temperature_c);
            // Acquisition flags on a few readings (most stay clean).
            sample.reading_flags = flags.map(|bits| {
                if bits % 16 == 0 {
                    TaxelFlags::from_bits_truncate(bits)
                } else {
                    TaxelFlags::empty()
                }
            });
            if let Some(step_us) = step_us {
                time_us += u64::from(*step_us);
                sample = sample.at_time_us(time_us);
            }
            sample
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// `process_all` over a sequence gives the outputs and the final state of `process` called
    /// set by set: tares that finish mid-batch, tracking, faults and arbitrary readings included.
    #[test]
    fn process_all_is_process_set_by_set(case in case()) {
        let samples = samples(&case);
        let mut one_by_one = pad_for(&case);
        let want: Vec<PadOutput> = samples.iter().map(|sample| one_by_one.process(sample)).collect();
        let mut batched = pad_for(&case);
        let mut got = Vec::new();
        batched.process_all(samples.iter().copied(), |position, output| {
            assert_eq!(position, got.len());
            got.push(*output);
        });
        prop_assert_eq!(got.len(), want.len());
        for (set, (got, want)) in got.iter().zip(&want).enumerate() {
            // Debug shows every float exactly (and -0.0, NaN), so equal text is equal bits.
            prop_assert_eq!(format!("{got:?}"), format!("{want:?}"), "set {}", set);
        }
        prop_assert_eq!(format!("{batched:?}"), format!("{one_by_one:?}"));
    }

    /// The whole pipeline's batch (model, force, centre of pressure, contact with its timing)
    /// gives the reports and final state of `PadPipeline::process` set by set.
    #[test]
    fn pipeline_process_all_is_process_set_by_set(case in case()) {
        let samples = samples(&case);
        let pipeline = || {
            PadPipeline::new(
                pad_for(&case),
                ForceAndContact::new(PadRole::Unspecified, PadGeometry::ARTICLE, ContactConfig::DEFAULT),
            )
        };
        let mut one_by_one = pipeline();
        let want: Vec<PadReport> = samples.iter().map(|sample| one_by_one.process(sample)).collect();
        let mut batched = pipeline();
        let mut got = Vec::new();
        batched.process_all(&samples, |position, report| {
            assert_eq!(position, got.len());
            got.push(*report);
        });
        prop_assert_eq!(got.len(), want.len());
        for (set, (got, want)) in got.iter().zip(&want).enumerate() {
            prop_assert_eq!(format!("{got:?}"), format!("{want:?}"), "set {}", set);
        }
        prop_assert_eq!(format!("{batched:?}"), format!("{one_by_one:?}"));
    }
}

#[test]
fn process_all_of_nothing_calls_nothing() {
    let mut pad = PadModel::new(Calibration::default());
    let before = pad.clone();
    let mut calls = 0;
    pad.process_all(core::iter::empty(), |_, _| calls += 1);
    assert_eq!(calls, 0);
    assert_eq!(pad, before);
}
