//! The default tier inverts its own monotone cubic on every valid calibration, not only the
//! article's: thousands of generated hard calibrations (2 to 16 points, unequal spacing, nearly
//! equal neighbours, a nearly flat top, a steep start) against an f64 bisection of the
//! Fritsch–Carlson cubic written independently of model-core (crate `taxel-reference-curves`).
//!
//! The acceptance rule: the answer is within 0.01 kPa of a pressure whose reference dC/C0 is
//! within a few f32 ulps of the reading, i.e. the error is 0.01 kPa beyond what the f32
//! rounding of dC/C0 itself explains (a few ulps times the local slope of the inverse).

use model_core::inverse::InverseCurve;
use model_core::{CalibrationCurve, CurvePoint, TaxelInverses};
use proptest::prelude::*;
use reference_curves::{hard_calibration, ForwardCubic};

/// Error allowed beyond rounding, kPa (the bound).
const PRESSURE_TOLERANCE_KPA: f64 = 0.01;
/// f32 ulps of dC/C0 that rounding in the cubic's f32 evaluation explains.
const ROUNDING_ULPS: f64 = 8.0;
/// Probes per interval, spread evenly in pressure.
const PROBES_PER_INTERVAL: usize = 24;

fn ulp(value: f32) -> f64 {
    let value = value.abs();
    f64::from(f32::from_bits(value.to_bits() + 1) - value)
}

/// Readings worth asking about on a curve: evenly spread in pressure over every interval, each
/// point and a few ulps either side of it, and the midpoint in dC/C0 of every interval.
fn probes(reference: &ForwardCubic, points: &[(f32, f32)]) -> Vec<f32> {
    let mut probes = Vec::new();
    for pair in points.windows(2) {
        let (low_kpa, high_kpa) = (f64::from(pair[0].0), f64::from(pair[1].0));
        for step in 0..PROBES_PER_INTERVAL {
            let fraction = (step as f64 + 0.5) / PROBES_PER_INTERVAL as f64;
            let pressure_kpa = low_kpa + fraction * (high_kpa - low_kpa);
            probes.push(reference.relative_change_at(pressure_kpa) as f32);
        }
        probes.push(((f64::from(pair[0].1) + f64::from(pair[1].1)) / 2.0) as f32);
    }
    for (_, relative_change) in points.iter().skip(1) {
        let bits = relative_change.to_bits();
        for offset in [-3i32, -1, 0, 1, 3] {
            probes.push(f32::from_bits(bits.wrapping_add_signed(offset)));
        }
    }
    probes
}

fn check(seed: u64) -> Result<(), TestCaseError> {
    let (points, shape) = hard_calibration(seed);
    let curve_points: Vec<CurvePoint> = points
        .iter()
        .map(|(pressure_kpa, relative_change)| CurvePoint::new(*pressure_kpa, *relative_change))
        .collect();
    let curve = CalibrationCurve::new(&curve_points, 0)
        .map_err(|error| TestCaseError::fail(format!("seed {seed}: refused {error:?}")))?;
    let pressures_kpa: Vec<f64> = points.iter().map(|p| f64::from(p.0)).collect();
    let relative_changes: Vec<f64> = points.iter().map(|p| f64::from(p.1)).collect();
    let reference = ForwardCubic::new(&pressures_kpa, &relative_changes)
        .ok_or_else(|| TestCaseError::fail(format!("seed {seed}: reference refused")))?;
    let inverses = TaxelInverses::new(&curve);
    let cubic = inverses.monotone_cubic();
    let (top_kpa, top_relative) = reference.top();
    for relative_change in probes(&reference, &points) {
        if !(relative_change > 0.0 && f64::from(relative_change) <= top_relative) {
            continue;
        }
        let got_kpa = f64::from(cubic.pressure_kpa(relative_change));
        prop_assert!(
            got_kpa.is_finite() && (0.0..=top_kpa).contains(&got_kpa),
            "seed {seed} ({shape:?}): {got_kpa} outside 0..={top_kpa}"
        );
        prop_assert!(
            reference.accepts(
                f64::from(relative_change),
                got_kpa,
                PRESSURE_TOLERANCE_KPA,
                ROUNDING_ULPS * ulp(relative_change),
            ),
            "seed {seed} ({shape:?}, {} points): dC/C0 {relative_change:e} gave {got_kpa} kPa, \
             reference {} kPa",
            points.len(),
            reference.pressure_kpa(f64::from(relative_change)),
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    #[test]
    fn the_default_tier_inverts_its_cubic_on_hard_calibrations(seed in any::<u64>()) {
        check(seed)?;
    }
}

/// The seeds the on-target test runs (`m4-bench`), checked here too so a host failure points at
/// the same case.
#[test]
fn the_first_thousand_seeds_pass() {
    for seed in 0..1000 {
        if let Err(error) = check(seed) {
            panic!("{error}");
        }
    }
}
