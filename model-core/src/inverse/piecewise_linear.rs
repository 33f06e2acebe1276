//! Piecewise-linear tier: straight lines between the calibration points. The points are the
//! calibration's; the tier keeps only each line's slope.

use super::{clamp_pressure, interval_index, InverseCurve};
use crate::calibration::{CalibrationCurve, MAX_CURVE_POINTS};

/// The slope of each line, kPa per unit dC/C0 (computed in f64).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LineSlopes {
    kpa_per_relative_change: [f32; MAX_CURVE_POINTS - 1],
}

impl LineSlopes {
    /// The slopes of the lines through the curve's points.
    pub(crate) fn new(curve: &CalibrationCurve) -> Self {
        let mut kpa_per_relative_change = [0.0; MAX_CURVE_POINTS - 1];
        for (pair, slope) in curve
            .points()
            .windows(2)
            .zip(kpa_per_relative_change.iter_mut())
        {
            if let [low, high] = pair {
                *slope = ((high.pressure_kpa - low.pressure_kpa) as f64
                    / (high.relative_change - low.relative_change) as f64)
                    as f32;
            }
        }
        Self {
            kpa_per_relative_change,
        }
    }

    /// Pressure for a relative change on `curve` (the one the slopes were built from).
    #[inline]
    pub(crate) fn pressure_kpa(&self, curve: &CalibrationCurve, relative_change: f32) -> f32 {
        let points = curve.points();
        let index = interval_index(points, relative_change);
        let (Some(start), Some(end), Some(slope)) = (
            points.get(index),
            points.get(index + 1),
            self.kpa_per_relative_change.get(index),
        ) else {
            return 0.0;
        };
        // The line ends at the interval's end point, which is the top on the last interval.
        clamp_pressure(
            start.pressure_kpa + (relative_change - start.relative_change) * slope,
            end.pressure_kpa,
        )
    }
}

/// Linear interpolation of pressure in relative change between neighbouring points, owning its
/// curve (host tools, tier selection; the pad keeps only the slopes).
#[derive(Debug, Clone, PartialEq)]
pub struct PiecewiseLinearInverse {
    curve: CalibrationCurve,
    slopes: LineSlopes,
}

impl PiecewiseLinearInverse {
    /// Lines through the curve's points.
    pub fn new(curve: &CalibrationCurve) -> Self {
        Self {
            curve: curve.clone(),
            slopes: LineSlopes::new(curve),
        }
    }

    /// The compact part the pad keeps.
    pub(crate) fn slopes(&self) -> &LineSlopes {
        &self.slopes
    }
}

impl InverseCurve for PiecewiseLinearInverse {
    #[inline]
    fn pressure_kpa(&self, relative_change: f32) -> f32 {
        self.slopes.pressure_kpa(&self.curve, relative_change)
    }
}
