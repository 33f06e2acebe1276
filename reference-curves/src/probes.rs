//! Which readings to ask an inverse about on a curve, and the rule its answers are held to: the
//! same for model-core's host property tests and the on-target test.

use crate::ForwardCubic;

/// Error allowed beyond rounding, kPa.
pub const PRESSURE_TOLERANCE_KPA: f64 = 0.01;

/// f32 ulps of dC/C0 that rounding in an f32 evaluation of the cubic explains.
pub const ROUNDING_ULPS: f64 = 8.0;

/// The spacing of f32 values at `value`.
pub fn ulp(value: f32) -> f64 {
    let value = value.abs();
    f64::from(f32::from_bits(value.to_bits() + 1) - value)
}

/// Readings worth asking about on a curve, in `0 < y <= top`: `per_interval` spread evenly in
/// pressure over every interval, the midpoint in dC/C0 of every interval, and each point's dC/C0
/// and 1 and 3 ulps either side.
pub fn probes(reference: &ForwardCubic, points: &[(f32, f32)], per_interval: usize) -> Vec<f32> {
    let mut probes = Vec::new();
    for pair in points.windows(2) {
        let (low_kpa, high_kpa) = (f64::from(pair[0].0), f64::from(pair[1].0));
        for step in 0..per_interval {
            let fraction = (step as f64 + 0.5) / per_interval as f64;
            probes.push(
                reference.relative_change_at(low_kpa + fraction * (high_kpa - low_kpa)) as f32,
            );
        }
        probes.push(((f64::from(pair[0].1) + f64::from(pair[1].1)) / 2.0) as f32);
    }
    for (_, relative_change) in points.iter().skip(1) {
        let bits = relative_change.to_bits();
        for offset in [-3i32, -1, 0, 1, 3] {
            probes.push(f32::from_bits(bits.wrapping_add_signed(offset)));
        }
    }
    let (_, top_relative) = reference.top();
    probes.retain(|y| *y > 0.0 && f64::from(*y) <= top_relative);
    probes
}

/// Whether `pressure_kpa` is an acceptable inverse of `relative_change`: within
/// [`PRESSURE_TOLERANCE_KPA`] of a pressure whose reference dC/C0 is within [`ROUNDING_ULPS`]
/// ulps of it.
pub fn acceptable(reference: &ForwardCubic, relative_change: f32, pressure_kpa: f64) -> bool {
    reference.accepts(
        f64::from(relative_change),
        pressure_kpa,
        PRESSURE_TOLERANCE_KPA,
        ROUNDING_ULPS * ulp(relative_change),
    )
}
