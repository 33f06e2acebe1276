//! Hard calibrations for the golden file: valid but ill-conditioned curves from
//! `reference_curves::hard_calibration`, each with probes of its inverse and the pressures the
//! f64 reference (`reference_curves::ForwardCubic`) accepts for them.
//!
//! The acceptance rule is model-core's host test's (model-core/tests/hard_calibrations.rs):
//! `ForwardCubic::accepts(y, p, 0.01 kPa, 8 ulp(y))`, i.e. p is within 0.01 kPa of a pressure
//! whose reference dC/C0 is within 8 f32 ulps of y. The reference curve is strictly increasing,
//! so for p in 0 ..= top that is the interval
//! `P(y - 8 ulp) - 0.01 ..= P(y + 8 ulp) + 0.01` with P the reference inverse (clamped to
//! 0 ..= top): two numbers the target compares with, written here and checked here against
//! `accepts` itself.

use crate::format::{
    HardCalibration, Probe, CALIBRATION_POINTS_MAX, CALIBRATION_PROBES_MAX, SHAPE_BYTES,
};
use reference_curves::{
    hard_calibration, probes, ulp, ForwardCubic, PRESSURE_TOLERANCE_KPA, ROUNDING_ULPS,
};

/// Seeds of the hard calibrations in the file: 0 .. this.
pub const SEEDS: u64 = 64;
/// Probes per interval spread evenly in pressure (the host test uses 24; the target gets a few
/// dozen per curve in all).
const PROBES_PER_INTERVAL: usize = 3;

/// One probe with its accepted interval, checked against `ForwardCubic::accepts`.
fn probe(reference: &ForwardCubic, seed: u64, relative_change: f32) -> Result<Probe, String> {
    let y = f64::from(relative_change);
    let allowance = ROUNDING_ULPS * ulp(relative_change);
    let lower_kpa = reference.pressure_kpa(y - allowance) - PRESSURE_TOLERANCE_KPA;
    let upper_kpa = reference.pressure_kpa(y + allowance) + PRESSURE_TOLERANCE_KPA;
    let (top_kpa, _) = reference.top();
    // Both ends (pulled into 0 ..= top, where the target's answer must lie) are accepted by the
    // rule itself, a hair inside them.
    let inside = 1e-9;
    for end in [
        (lower_kpa + inside).max(0.0),
        (upper_kpa - inside).min(top_kpa),
    ] {
        if !reference.accepts(y, end, PRESSURE_TOLERANCE_KPA, allowance) {
            return Err(format!(
                "hard calibration seed {seed}: dC/C0 {relative_change:e}: the bound {end} kPa \
                 is not accepted by ForwardCubic::accepts"
            ));
        }
    }
    Ok(Probe {
        relative_change,
        reference_kpa: reference.pressure_kpa(y),
        lower_kpa,
        upper_kpa,
    })
}

/// The hard calibrations of seeds `0 .. SEEDS`.
pub fn hard_calibrations() -> Result<Vec<HardCalibration>, String> {
    let mut calibrations = Vec::new();
    for seed in 0..SEEDS {
        let (points, shape) = hard_calibration(seed);
        if points.len() > CALIBRATION_POINTS_MAX {
            return Err(format!(
                "hard calibration seed {seed}: {} points",
                points.len()
            ));
        }
        let pressures_kpa: Vec<f64> = points.iter().map(|point| f64::from(point.0)).collect();
        let relative_changes: Vec<f64> = points.iter().map(|point| f64::from(point.1)).collect();
        let reference = ForwardCubic::new(&pressures_kpa, &relative_changes)
            .ok_or_else(|| format!("hard calibration seed {seed}: the reference refused it"))?;
        let values = probes(&reference, &points, PROBES_PER_INTERVAL);
        if values.len() > CALIBRATION_PROBES_MAX {
            return Err(format!(
                "hard calibration seed {seed}: {} probes",
                values.len()
            ));
        }
        let mut probes = [Probe::default(); CALIBRATION_PROBES_MAX];
        for (slot, value) in probes.iter_mut().zip(&values) {
            *slot = probe(&reference, seed, *value)?;
        }
        let mut padded = [(0.0, 0.0); CALIBRATION_POINTS_MAX];
        padded[..points.len()].copy_from_slice(&points);
        let shape_name = format!("{shape:?}");
        let mut shape_bytes = [0u8; SHAPE_BYTES];
        if shape_name.len() > SHAPE_BYTES || !shape_name.is_ascii() {
            return Err(format!("shape name {shape_name:?} does not fit"));
        }
        shape_bytes[..shape_name.len()].copy_from_slice(shape_name.as_bytes());
        calibrations.push(HardCalibration {
            seed,
            shape: shape_bytes,
            point_count: points.len() as u32,
            points: padded,
            probe_count: values.len() as u32,
            probes,
        });
    }
    Ok(calibrations)
}
