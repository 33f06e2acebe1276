//! Table tier, built for speed: the monotone cubic's inverse sampled on a uniform grid of
//! relative change, linearly interpolated. One multiply, one conversion, two loads, one
//! multiply-add; no search, no division.

use super::{clamp_pressure, InverseCurve, MonotoneCubicInverse};
use crate::bounds::clamp_f32;
use crate::calibration::CalibrationCurve;

/// Grid intervals over `0 ..= top relative change`.
pub const TABLE_INTERVALS: usize = 64;

/// Uniform table of the inverse with per-interval slopes.
#[derive(Debug, Clone, PartialEq)]
pub struct TableInverse {
    pressures_kpa: [f32; TABLE_INTERVALS + 1],
    steps_kpa: [f32; TABLE_INTERVALS + 1],
    intervals_per_relative_change: f32,
    top_pressure_kpa: f32,
}

impl TableInverse {
    /// Samples the monotone cubic inverse.
    pub fn new(reference: &MonotoneCubicInverse, curve: &CalibrationCurve) -> Self {
        let top = curve.top();
        let mut pressures_kpa = [0.0; TABLE_INTERVALS + 1];
        for (index, pressure) in pressures_kpa.iter_mut().enumerate() {
            let relative_change =
                (top.relative_change as f64 * index as f64 / TABLE_INTERVALS as f64) as f32;
            *pressure = reference.pressure_kpa(relative_change);
        }
        pressures_kpa[TABLE_INTERVALS] = top.pressure_kpa;
        let mut steps_kpa = [0.0; TABLE_INTERVALS + 1];
        for index in 0..TABLE_INTERVALS {
            steps_kpa[index] = pressures_kpa[index + 1] - pressures_kpa[index];
        }
        Self {
            pressures_kpa,
            steps_kpa,
            intervals_per_relative_change: TABLE_INTERVALS as f32 / top.relative_change,
            top_pressure_kpa: top.pressure_kpa,
        }
    }
}

impl InverseCurve for TableInverse {
    #[inline]
    fn pressure_kpa(&self, relative_change: f32) -> f32 {
        let position = clamp_f32(
            relative_change * self.intervals_per_relative_change,
            0.0,
            TABLE_INTERVALS as f32,
        );
        // The position is within 0 ..= TABLE_INTERVALS (NaN went to 0), so is the index.
        let index = position as usize;
        let fraction = position - index as f32;
        clamp_pressure(
            self.pressures_kpa[index] + fraction * self.steps_kpa[index],
            self.top_pressure_kpa,
        )
    }
}
