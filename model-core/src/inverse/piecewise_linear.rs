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
        for (((pair, relative_start), pressure_start), slope) in points
            .windows(2)
            .zip(inverse.relative_change_starts.iter_mut())
            .zip(inverse.pressure_starts_kpa.iter_mut())
            .zip(inverse.kpa_per_relative_change.iter_mut())
        {
            if let [low, high] = pair {
                *relative_start = low.relative_change;
                *pressure_start = low.pressure_kpa;
                *slope = ((high.pressure_kpa - low.pressure_kpa) as f64
                    / (high.relative_change - low.relative_change) as f64)
                    as f32;
            }
        }
        inverse
    }
}

impl InverseCurve for PiecewiseLinearInverse {
    #[inline]
    fn pressure_kpa(&self, relative_change: f32) -> f32 {
        let mut index = 0;
        while index + 1 < self.segment_count
            && self
                .relative_change_starts
                .get(index + 1)
                .is_some_and(|start| relative_change >= *start)
        {
            index += 1;
        }
        let (Some(pressure_start), Some(relative_start), Some(slope)) = (
            self.pressure_starts_kpa.get(index),
            self.relative_change_starts.get(index),
            self.kpa_per_relative_change.get(index),
        ) else {
            return 0.0;
        };
        clamp_pressure(
            pressure_start + (relative_change - relative_start) * slope,
            self.top_pressure_kpa,
        )
    }
}
