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
use reference_curves::{hard_calibration, ForwardCubic};

/// Seeds of the hard calibrations in the file: 0 .. this.
pub const SEEDS: u64 = 64;
/// Error allowed beyond rounding, kPa (model-core's host test).
pub const PRESSURE_TOLERANCE_KPA: f64 = 0.01;
/// f32 ulps of dC/C0 that rounding in the cubic's f32 evaluation explains (the host test's).
pub const ROUNDING_ULPS: f64 = 8.0;
/// Probes per interval spread evenly in pressure (the host test uses 24; the target gets a few
/// dozen per curve in all).
const PROBES_PER_INTERVAL: usize = 3;
/// Offsets in f32 ulps around each calibration point's dC/C0.
const POINT_OFFSETS_ULPS: [i32; 5] = [-3, -1, 0, 1, 3];

fn ulp(value: f32) -> f64 {
    let value = value.abs();
    f64::from(f32::from_bits(value.to_bits() + 1) - value)
}

/// The probes of a curve, as the host test chooses them but fewer: evenly spread in pressure
/// over every interval, the midpoint in dC/C0 of every interval, and each point's dC/C0 and a
/// few ulps either side; only those in `0 < y <= top` (the inverse's domain).
fn probe_values(reference: &ForwardCubic, points: &[(f32, f32)]) -> Vec<f32> {
    let mut probes = Vec::new();
    for pair in points.windows(2) {
        let (low_kpa, high_kpa) = (f64::from(pair[0].0), f64::from(pair[1].0));
        for step in 0..PROBES_PER_INTERVAL {
            let fraction = (step as f64 + 0.5) / PROBES_PER_INTERVAL as f64;
            probes.push(
                reference.relative_change_at(low_kpa + fraction * (high_kpa - low_kpa)) as f32,
            );
        }
        probes.push(((f64::from(pair[0].1) + f64::from(pair[1].1)) / 2.0) as f32);
    }
    for (_, relative_change) in points.iter().skip(1) {
        let bits = relative_change.to_bits();
        for offset in POINT_OFFSETS_ULPS {
            probes.push(f32::from_bits(bits.wrapping_add_signed(offset)));
        }
    }
    let (_, top_relative) = reference.top();
    probes.retain(|y| *y > 0.0 && f64::from(*y) <= top_relative);
    probes
}

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
        let values = probe_values(&reference, &points);
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
