//! Monotone cubic tier: the exact inverse of the Fritsch–Carlson cubic dC/C0 = f(P) through the
//! calibration points, which is the model's reference curve.
//!
//! The forward cubic is the natural model (the calibration controls P and measures dC/C0); its
//! inverse is found per interval by Newton's method from the secant guess. Two steps bring the
//! f32 result to its rounding floor on the article's curve (see the tests).

use super::{clamp_pressure, InverseCurve};
use crate::bounds::clamp_f32;
use crate::calibration::{CalibrationCurve, MAX_CURVE_POINTS};
use crate::monotone_cubic::MonotoneCubic;

/// Newton steps per inversion.
pub const NEWTON_STEPS: usize = 2;

/// Inverse of the monotone cubic through the calibration points.
#[derive(Debug, Clone, PartialEq)]
pub struct MonotoneCubicInverse {
    forward: MonotoneCubic,
    relative_change_starts: [f32; MAX_CURVE_POINTS],
    kpa_per_relative_change: [f32; MAX_CURVE_POINTS],
    top_pressure_kpa: f32,
}

impl MonotoneCubicInverse {
    /// Builds the forward cubic and the per-interval secants used as Newton's first guess.
    pub fn new(curve: &CalibrationCurve) -> Self {
        let forward = MonotoneCubic::new(&curve.pressures_kpa(), &curve.relative_changes());
        let mut relative_change_starts = [0.0; MAX_CURVE_POINTS];
        let mut kpa_per_relative_change = [0.0; MAX_CURVE_POINTS];
        for (index, pair) in curve.points().windows(2).enumerate() {
            relative_change_starts[index] = pair[0].relative_change;
            kpa_per_relative_change[index] = ((pair[1].pressure_kpa - pair[0].pressure_kpa) as f64
                / (pair[1].relative_change - pair[0].relative_change) as f64)
                as f32;
        }
        Self {
            forward,
            relative_change_starts,
            kpa_per_relative_change,
            top_pressure_kpa: curve.top().pressure_kpa,
        }
    }

    /// The forward curve (pressure to relative change).
    pub fn forward(&self) -> &MonotoneCubic {
        &self.forward
    }
}

impl InverseCurve for MonotoneCubicInverse {
    #[inline]
    fn pressure_kpa(&self, relative_change: f32) -> f32 {
        let segments = self.forward.segments();
        let mut index = 0;
        while index + 1 < segments.len()
            && relative_change >= self.relative_change_starts[index + 1]
        {
            index += 1;
        }
        let Some(segment) = segments.get(index) else {
            return 0.0;
        };
        let target = relative_change - segment.coefficients[0];
        let mut s = target * self.kpa_per_relative_change[index];
        for _ in 0..NEWTON_STEPS {
            let residual = segment.value_at(s) - relative_change;
            let slope = segment.slope_at(s);
            // A flat spot (only possible at an interval end) ends the iteration rather than
            // dividing by zero.
            if !(slope > 0.0) {
                break;
            }
            s = clamp_f32(s - residual / slope, 0.0, segment.width);
        }
        clamp_pressure(segment.x_start + s, self.top_pressure_kpa)
    }
}
