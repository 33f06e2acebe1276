//! Piecewise-linear tier: straight lines between the calibration points.

use super::{clamp_pressure, InverseCurve};
use crate::calibration::{CalibrationCurve, MAX_CURVE_POINTS};

/// Linear interpolation of pressure in relative change between neighbouring points.
#[derive(Debug, Clone, PartialEq)]
pub struct PiecewiseLinearInverse {
    relative_change_starts: [f32; MAX_CURVE_POINTS],
    pressure_starts_kpa: [f32; MAX_CURVE_POINTS],
    kpa_per_relative_change: [f32; MAX_CURVE_POINTS],
    segment_count: usize,
    top_pressure_kpa: f32,
}

impl PiecewiseLinearInverse {
    /// Lines through the curve's points.
    pub fn new(curve: &CalibrationCurve) -> Self {
        let points = curve.points();
        let mut inverse = Self {
            relative_change_starts: [0.0; MAX_CURVE_POINTS],
            pressure_starts_kpa: [0.0; MAX_CURVE_POINTS],
            kpa_per_relative_change: [0.0; MAX_CURVE_POINTS],
            segment_count: points.len().saturating_sub(1),
            top_pressure_kpa: curve.top().pressure_kpa,
        };
        for (index, pair) in points.windows(2).enumerate() {
            let (low, high) = (pair[0], pair[1]);
            inverse.relative_change_starts[index] = low.relative_change;
            inverse.pressure_starts_kpa[index] = low.pressure_kpa;
            inverse.kpa_per_relative_change[index] = ((high.pressure_kpa - low.pressure_kpa) as f64
                / (high.relative_change - low.relative_change) as f64)
                as f32;
        }
        inverse
    }
}

impl InverseCurve for PiecewiseLinearInverse {
    #[inline]
    fn pressure_kpa(&self, relative_change: f32) -> f32 {
        let mut index = 0;
        while index + 1 < self.segment_count
            && relative_change >= self.relative_change_starts[index + 1]
        {
            index += 1;
        }
        clamp_pressure(
            self.pressure_starts_kpa[index]
                + (relative_change - self.relative_change_starts[index])
                    * self.kpa_per_relative_change[index],
            self.top_pressure_kpa,
        )
    }
}
