//! Linear tier: one sensitivity, the secant from the origin to the top calibration point.

use super::{clamp_pressure, InverseCurve};
use crate::calibration::CalibrationCurve;

/// Pressure = relative change / sensitivity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearInverse {
    kpa_per_relative_change: f32,
    top_pressure_kpa: f32,
}

impl LinearInverse {
    /// The secant through the origin and the top point.
    pub fn new(curve: &CalibrationCurve) -> Self {
        let top = curve.top();
        Self {
            kpa_per_relative_change: top.pressure_kpa / top.relative_change,
            top_pressure_kpa: top.pressure_kpa,
        }
    }

    /// Sensitivity in 1/kPa.
    pub fn sensitivity_per_kpa(&self) -> f32 {
        1.0 / self.kpa_per_relative_change
    }
}

impl InverseCurve for LinearInverse {
    #[inline]
    fn pressure_kpa(&self, relative_change: f32) -> f32 {
        clamp_pressure(
            relative_change * self.kpa_per_relative_change,
            self.top_pressure_kpa,
        )
    }
}
