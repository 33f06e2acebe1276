//! Table tier, built for speed: the monotone cubic's inverse sampled on a uniform grid of
//! relative change, linearly interpolated. One multiply, one conversion, two loads, one
//! multiply-add; no search, no division. The same grid is the monotone-cubic tier's start.

use super::{clamp_pressure, InverseCurve};
use crate::bounds::clamp_f32;

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
    /// Samples an inverse at the grid's relative changes; the first node is the origin and the
    /// last the top point.
    pub(crate) fn sampled(
        inverse: impl Fn(f32) -> f32,
        top_relative_change: f32,
        top_pressure_kpa: f32,
    ) -> Self {
        let mut pressures_kpa = [0.0; TABLE_INTERVALS + 1];
        for (index, pressure) in pressures_kpa.iter_mut().enumerate() {
            *pressure = inverse(Self::node_relative_change(index, top_relative_change));
        }
        // The curve's ends are known exactly: (0, 0) and the top point.
        if let Some(first) = pressures_kpa.first_mut() {
            *first = 0.0;
        }
        if let Some(last) = pressures_kpa.last_mut() {
            *last = top_pressure_kpa;
        }
        let mut steps_kpa = [0.0; TABLE_INTERVALS + 1];
        for (step, pair) in steps_kpa.iter_mut().zip(pressures_kpa.windows(2)) {
            if let [low, high] = pair {
                *step = high - low;
            }
        }
        Self {
            pressures_kpa,
            steps_kpa,
            intervals_per_relative_change: TABLE_INTERVALS as f32 / top_relative_change,
            top_pressure_kpa,
        }
    }

    /// The relative change of grid node `index`.
    pub(crate) fn node_relative_change(index: usize, top_relative_change: f32) -> f32 {
        (top_relative_change as f64 * index as f64 / TABLE_INTERVALS as f64) as f32
    }

    /// The grid cell of a relative change and the fraction into it (NaN goes to cell 0).
    #[inline(always)]
    pub(crate) fn cell(&self, relative_change: f32) -> (usize, f32) {
        let position = clamp_f32(
            relative_change * self.intervals_per_relative_change,
            0.0,
            TABLE_INTERVALS as f32,
        );
        // Within 0 ..= TABLE_INTERVALS, so is the index (a saturating conversion).
        let index = position as usize;
        (index, position - index as f32)
    }

    /// The interpolated pressure in a cell, unclamped.
    #[inline(always)]
    pub(crate) fn interpolate(&self, (index, fraction): (usize, f32)) -> f32 {
        match (self.pressures_kpa.get(index), self.steps_kpa.get(index)) {
            (Some(pressure_kpa), Some(step_kpa)) => pressure_kpa + fraction * step_kpa,
            _ => self.top_pressure_kpa,
        }
    }
}

impl InverseCurve for TableInverse {
    #[inline]
    fn pressure_kpa(&self, relative_change: f32) -> f32 {
        clamp_pressure(
            self.interpolate(self.cell(relative_change)),
            self.top_pressure_kpa,
        )
    }
}
