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
use reference_curves::{acceptable, hard_calibration, probes, ForwardCubic};

/// Probes per interval, spread evenly in pressure.
const PROBES_PER_INTERVAL: usize = 24;

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
    let (top_kpa, _) = reference.top();
    for relative_change in probes(&reference, &points, PROBES_PER_INTERVAL) {
        let got_kpa = f64::from(cubic.pressure_kpa(relative_change));
        prop_assert!(
            got_kpa.is_finite() && (0.0..=top_kpa).contains(&got_kpa),
            "seed {seed} ({shape:?}): {got_kpa} outside 0..={top_kpa}"
        );
        prop_assert!(
            acceptable(&reference, relative_change, got_kpa),
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
