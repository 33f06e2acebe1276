//! Shared test helpers: a deterministic proptest configuration, calibration specs (distinct,
//! worst-case, and a strategy over valid ones), the test flash geometries and store shortcuts.
// Every test file uses a different subset of these helpers.
#![allow(dead_code)]
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test helpers: a failure is a test failure"
)]

use core::future::Future;
use core::ops::Range;

use calibration_store::{CalibrationStore, LoadOutcome, RamFlash, RamFlashError};
use embedded_storage_async::nor_flash::NorFlash;
use heapless::Vec;
use model_core::calibration::{
    CalibrationSpec, CurvePoint, FaultThresholds, PermittivityPoint, TaxelCalibrationSpec,
    MAX_CURVE_POINTS, MAX_TEMPERATURE_POINTS,
};
use model_core::reading::MAX_MEASURABLE_PF;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed};

/// A fixed seed and no regression files, so every run draws the same cases.
pub fn config(cases: u32) -> Config {
    Config {
        cases,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(0xCA1B_2026),
        failure_persistence: None,
        ..Config::default()
    }
}

/// Small pages: three 2 KiB pages, the store on the last two so that page 0 checks that nothing
/// is written outside the range.
pub const SMALL_PAGE: usize = 2048;
/// The flash of the small-page tests.
pub type SmallFlash = RamFlash<{ 3 * SMALL_PAGE }, SMALL_PAGE>;
/// The store's range in [`SmallFlash`].
pub const SMALL_RANGE: Range<u32> = SMALL_PAGE as u32..3 * SMALL_PAGE as u32;
/// The untouched first page of [`SmallFlash`].
pub const OUTSIDE_RANGE: Range<usize> = 0..SMALL_PAGE;

/// The STM32F411CE's flash as far as the store sees it: 512 KiB in 128 KiB pages (the 16 and
/// 64 KiB sectors at the start are never touched, so uniform pages model it).
pub type F411Flash = RamFlash<{ 512 * 1024 }, { 128 * 1024 }>;

/// Runs a future to completion.
pub fn block_on<T>(future: impl Future<Output = T>) -> T {
    embassy_futures::block_on(future)
}

/// A fresh blank small flash, boxed (tests move it around a lot).
pub fn small_flash() -> Box<SmallFlash> {
    Box::new(SmallFlash::new())
}

/// A store over the small range of `flash`.
pub fn small_store(flash: &mut SmallFlash) -> CalibrationStore<&mut SmallFlash> {
    CalibrationStore::new(flash, SMALL_RANGE).unwrap()
}

/// "Reboot": power on, a new store on the same bytes, load.
pub fn reboot_and_load(flash: &mut SmallFlash) -> LoadOutcome<RamFlashError> {
    flash.power_cycle();
    block_on(small_store(flash).load(0))
}

/// Saves through a fresh store and panics on failure.
pub fn save<F: NorFlash>(flash: F, range: Range<u32>, spec: &CalibrationSpec)
where
    F::Error: core::fmt::Debug,
{
    let mut store = CalibrationStore::new(flash, range).unwrap();
    block_on(store.save(spec)).unwrap();
}

/// A valid spec that differs from every other `spec(id)`: the id, and a parasitic capacitance.
pub fn spec(id: u32) -> CalibrationSpec {
    let mut spec = CalibrationSpec {
        id,
        ..CalibrationSpec::default()
    };
    spec.taxels[(id % 4) as usize].parasitic_pf = (id % 1000) as f32 * 0.01;
    spec
}

/// The longest record's spec: a 5-byte id, 16 points and a calibrated C0 on every taxel, 8
/// temperature points.
pub fn worst_case_spec(id: u32) -> CalibrationSpec {
    let taxel = |taxel: usize| TaxelCalibrationSpec {
        points: (0..MAX_CURVE_POINTS)
            .map(|index| {
                let step = index as f32;
                CurvePoint::new(step * 3.5, step * (0.017 + 0.001 * taxel as f32))
            })
            .collect(),
        parasitic_pf: 1.5 + taxel as f32,
        unloaded_sensor_pf: Some(4.25 + 0.125 * taxel as f32),
    };
    CalibrationSpec {
        id,
        taxels: [taxel(0), taxel(1), taxel(2), taxel(3)],
        temperature_points: (0..MAX_TEMPERATURE_POINTS)
            .map(|index| PermittivityPoint {
                temperature_c: -20.0 + 10.0 * index as f32,
                permittivity_ratio: 1.0 - 0.004 * index as f32,
            })
            .collect(),
        characterised_min_c: -20.0,
        characterised_max_c: 60.0,
        thresholds: FaultThresholds::default(),
    }
}

/// `spec` with no calibrated C0 on any taxel: what a version-2 record can hold.
pub fn without_c0(mut spec: CalibrationSpec) -> CalibrationSpec {
    for taxel in &mut spec.taxels {
        taxel.unloaded_sensor_pf = None;
    }
    spec
}

/// The small-page flash as the previous firmware's store (record format version 2) left it after
/// saving `spec(5)` and then `without_c0(worst_case_spec(7))`: produced by that store's code.
pub fn version_2_flash() -> Box<SmallFlash> {
    let image: &[u8; 3 * SMALL_PAGE] = include_bytes!("../data/v2-flash-small-pages.bin");
    Box::new(SmallFlash::from_bytes(*image))
}

/// The newest calibration in [`version_2_flash`], saved with save counter 1.
pub fn version_2_flash_newest() -> CalibrationSpec {
    without_c0(worst_case_spec(7))
}

/// `spec(id)` for even ids and `worst_case_spec(id)` for odd ones: records of both lengths.
pub fn mixed_spec(id: u32) -> CalibrationSpec {
    if id.is_multiple_of(2) {
        spec(id)
    } else {
        worst_case_spec(id)
    }
}

fn curve() -> impl Strategy<Value = Vec<CurvePoint, MAX_CURVE_POINTS>> {
    proptest::collection::vec((0.01f32..10.0, 0.0001f32..0.1), 1..MAX_CURVE_POINTS).prop_map(
        |steps| {
            let mut points = Vec::new();
            let mut point = CurvePoint::new(0.0, 0.0);
            points.push(point).unwrap();
            for (pressure_step_kpa, change_step) in steps {
                point.pressure_kpa += pressure_step_kpa;
                point.relative_change += change_step;
                points.push(point).unwrap();
            }
            points
        },
    )
}

/// No calibrated C0 (the default, and every version-2 record), or one anywhere in the valid
/// range (0, MAX_MEASURABLE_PF].
fn unloaded_sensor_pf() -> impl Strategy<Value = Option<f32>> {
    prop_oneof![
        Just(None),
        (f32::MIN_POSITIVE..=MAX_MEASURABLE_PF).prop_map(Some),
        Just(Some(MAX_MEASURABLE_PF)),
    ]
}

fn taxel() -> impl Strategy<Value = TaxelCalibrationSpec> {
    (curve(), 0.0f32..=100.0, unloaded_sensor_pf()).prop_map(
        |(points, parasitic_pf, unloaded_sensor_pf)| TaxelCalibrationSpec {
            points,
            parasitic_pf,
            unloaded_sensor_pf,
        },
    )
}

/// Any calibration that validates, up to the maximum sizes.
pub fn valid_spec() -> impl Strategy<Value = CalibrationSpec> {
    let law = (
        -60.0f32..0.0,
        proptest::collection::vec((0.1f32..20.0, 0.5f32..=2.0), 1..=MAX_TEMPERATURE_POINTS),
        0.1f32..100.0,
    );
    let thresholds = (0.0f32..=50.0, 0.0f32..0.1, 0.001f32..0.9);
    (
        any::<u32>(),
        proptest::array::uniform4(taxel()),
        law,
        thresholds,
    )
        .prop_map(|(id, taxels, law, thresholds)| {
            let (first_c, steps, span_c) = law;
            let mut temperature_c = first_c;
            let temperature_points = steps
                .into_iter()
                .map(|(step_c, permittivity_ratio)| {
                    temperature_c += step_c;
                    PermittivityPoint {
                        temperature_c,
                        permittivity_ratio,
                    }
                })
                .collect();
            let (open_below_pf, dead_band_relative, shorted_margin) = thresholds;
            CalibrationSpec {
                id,
                taxels,
                temperature_points,
                characterised_min_c: first_c,
                characterised_max_c: first_c + span_c,
                thresholds: FaultThresholds {
                    open_below_pf,
                    shorted_below_relative: dead_band_relative + shorted_margin,
                    dead_band_relative,
                },
            }
        })
}

/// The outcome as the spec it carries, or a label for the other outcomes.
pub fn describe(outcome: &LoadOutcome<RamFlashError>) -> String {
    match outcome {
        LoadOutcome::Stored(spec) => format!("Stored(id {})", spec.id),
        LoadOutcome::Absent => "Absent".into(),
        LoadOutcome::Corrupt(reason) => format!("Corrupt({reason:?})"),
    }
}
