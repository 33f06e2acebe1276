//! Monotone cubic tier: the inverse of the Fritsch–Carlson cubic dC/C0 = f(P) through the
//! calibration points, which is the model's reference curve, for every valid calibration.
//!
//! # Method
//!
//! On the interval holding the reading, the forward cubic `f(s)` (local coordinate `s` in
//! `0 ..= w`) is non-decreasing (Fritsch–Carlson). The root of `f(s) = y` is found in two stages.
//!
//! 1. **Fast path: a table start, one Newton step, a proven error bound.** The start `s0` is
//!    the inverse sampled on a uniform grid of dC/C0 (the table tier's grid, whose nodes are
//!    solved by stage 2 when the calibration is loaded), linearly interpolated and clamped into
//!    the interval that holds the reading; each grid cell also stores the first interval it
//!    touches, so finding the interval is a step or two, not a search from the start. One
//!    Newton step `s1 = s0 - r / f'(s0)` (with
//!    `r = f(s0) - y`) follows. With `m = min f'`, `M = max f'` and `K = max |f''|` over the
//!    interval (computed once, in f64, when the calibration is loaded), Taylor's theorem gives
//!    `|s1 - s*| <= K / (2 m) * (s0 - s*)^2` and the mean-value theorem
//!    `|s0 - s*| <= |r / f'(s0)| * M / m`; so `|s1 - s*| <= B * step^2` with
//!    `B = K M^2 / (2 m^3)`. The step is accepted when `B * step^2 <= ACCEPTED_ERROR_KPA`, a
//!    bound that holds in exact arithmetic whatever the start. On ordinary calibrations (the
//!    article's, anything with neighbouring secants of similar size) this is the path taken.
//! 2. **Safeguarded Newton in a bracket.** Otherwise (a nearly flat spot makes `m` tiny or zero,
//!    or the start was poor) the root is kept in a bracket `[low, high]` (`f(low) <= y <=
//!    f(high)`, initially the whole interval) that every evaluation narrows. A Newton step is
//!    taken only when it lands strictly inside the bracket and the previous Newton step halved
//!    the bracket; otherwise the bracket is bisected. So the bracket at least halves every two
//!    iterations: after `2 n` iterations it is at most `w / 2^n` wide, and the loop stops when it
//!    is `w / 2^20` wide (or at f32 resolution), within [`MAX_BRACKETED_ITERATIONS`] iterations
//!    whatever the calibration. A Newton step that meets the bound of stage 1 ends it earlier.
//!
//! The result is the root of the f32 cubic to within the bound above, plus what the f32
//! evaluation of `f` near the root cannot resolve: a few ulps of `y` times the local slope of the
//! inverse `1 / f'`. Where `f'` is tiny (nearly equal neighbouring calibration points) that is
//! large, and it is a property of the calibration, not of the method: see
//! [`crate::conditioning`].

use super::{clamp_pressure, InverseCurve, TableInverse, TABLE_INTERVALS};
use crate::bounds::clamp_f32;
use crate::calibration::{CalibrationCurve, MAX_CURVE_POINTS};
use crate::monotone_cubic::{CubicSegment, MonotoneCubic};

/// Largest error (kPa, exact arithmetic) accepted from the fast path's Newton step.
pub const ACCEPTED_ERROR_KPA: f32 = 1.0e-3;

/// The bracket stops narrowing at this fraction of the interval width (2^-20).
const BRACKET_RELATIVE_WIDTH: f32 = 1.0 / 1_048_576.0;

/// Most iterations of the bracketed stage: the bracket halves at least every two iterations, so
/// 2 x 20 reach [`BRACKET_RELATIVE_WIDTH`]; two spare.
pub const MAX_BRACKETED_ITERATIONS: usize = 42;

/// Inverse of the monotone cubic through the calibration points.
#[derive(Debug, Clone, PartialEq)]
pub struct MonotoneCubicInverse {
    forward: MonotoneCubic,
    relative_change_starts: [f32; MAX_CURVE_POINTS],
    /// Per interval, `B = max|f''| max(f')^2 / (2 min(f')^3)` per kPa; infinite where `f'`
    /// reaches 0.
    error_bounds_per_kpa: [f32; MAX_CURVE_POINTS - 1],
    /// The start: the inverse on a uniform grid (also the table tier).
    table: TableInverse,
    /// Per grid node, the interval holding its dC/C0.
    first_segments: [u8; TABLE_INTERVALS + 1],
    top_pressure_kpa: f32,
}

impl MonotoneCubicInverse {
    /// Builds the forward cubic, each interval's error bound, and the start grid (solved with
    /// the bracketed stage, so it is as good as the inverse itself).
    pub fn new(curve: &CalibrationCurve) -> Self {
        let forward = MonotoneCubic::new(&curve.pressures_kpa(), &curve.relative_changes());
        let top = curve.top();
        let mut relative_change_starts = [0.0; MAX_CURVE_POINTS];
        for (slot, point) in relative_change_starts.iter_mut().zip(curve.points()) {
            *slot = point.relative_change;
        }
        let mut error_bounds_per_kpa = [f32::INFINITY; MAX_CURVE_POINTS - 1];
        for (slot, segment) in error_bounds_per_kpa.iter_mut().zip(forward.segments()) {
            *slot = error_bound_per_kpa(segment);
        }
        let mut inverse = Self {
            forward,
            relative_change_starts,
            error_bounds_per_kpa,
            table: TableInverse::sampled(|_| 0.0, top.relative_change, top.pressure_kpa),
            first_segments: [0; TABLE_INTERVALS + 1],
            top_pressure_kpa: top.pressure_kpa,
        };
        let mut first_segments = [0u8; TABLE_INTERVALS + 1];
        for (node, slot) in first_segments.iter_mut().enumerate() {
            let relative_change = TableInverse::node_relative_change(node, top.relative_change);
            *slot = inverse.segment_from(0, relative_change) as u8;
        }
        inverse.first_segments = first_segments;
        inverse.table = TableInverse::sampled(
            |relative_change| {
                let index = inverse.segment_from(0, relative_change);
                match (
                    inverse.forward.segments().get(index),
                    inverse.error_bounds_per_kpa.get(index),
                ) {
                    (Some(segment), Some(bound)) => {
                        // No early acceptance: the grid is solved to the bracket's resolution.
                        let s = solve_bracketed(
                            segment,
                            *bound,
                            0.0,
                            relative_change,
                            0.5 * segment.width,
                        );
                        clamp_pressure(segment.x_start + s, inverse.top_pressure_kpa)
                    }
                    _ => 0.0,
                }
            },
            top.relative_change,
            top.pressure_kpa,
        );
        inverse
    }

    /// The forward curve (pressure to relative change).
    pub fn forward(&self) -> &MonotoneCubic {
        &self.forward
    }

    /// The start grid, which is also the table tier.
    pub fn table(&self) -> &TableInverse {
        &self.table
    }

    /// The interval holding `relative_change`, searching forward from interval `first`.
    #[inline(always)]
    fn segment_from(&self, first: usize, relative_change: f32) -> usize {
        let count = self.forward.segments().len();
        let mut index = first;
        while index + 1 < count
            && self
                .relative_change_starts
                .get(index + 1)
                .is_some_and(|start| relative_change >= *start)
        {
            index += 1;
        }
        index
    }
}

/// The fast path's error bound factor of an interval (module doc), from its f32 coefficients in
/// f64; infinite where the slope reaches 0.
fn error_bound_per_kpa(segment: &CubicSegment) -> f32 {
    let (slope_min, slope_max) = segment.slope_range(0.0, f64::from(segment.width));
    let bound =
        segment.curvature_max() * slope_max * slope_max / (2.0 * slope_min * slope_min * slope_min);
    if slope_min > 0.0 && bound.is_finite() && bound < 1.0e30 {
        bound as f32
    } else {
        f32::INFINITY
    }
}

/// Stage 2 of the module doc: the bracketed, safeguarded Newton iteration from `s`.
#[inline(never)]
fn solve_bracketed(
    segment: &CubicSegment,
    error_bound_per_kpa: f32,
    accepted_error_kpa: f32,
    y: f32,
    mut s: f32,
) -> f32 {
    let tolerance = segment.width * BRACKET_RELATIVE_WIDTH;
    let (mut low, mut high) = (0.0f32, segment.width);
    // Bracket width when the last Newton step was taken (infinite after a bisection).
    let mut width_at_newton = f32::INFINITY;
    for _ in 0..MAX_BRACKETED_ITERATIONS {
        let residual = segment.value_at(s) - y;
        if residual > 0.0 {
            high = s;
        } else if residual < 0.0 {
            low = s;
        } else {
            return s;
        }
        let width = high - low;
        if !(width > tolerance) {
            break;
        }
        let step = residual / segment.slope_at(s);
        let newton = s - step;
        if width <= 0.5 * width_at_newton && newton > low && newton < high {
            if error_bound_per_kpa * step * step <= accepted_error_kpa {
                return newton;
            }
            width_at_newton = width;
            s = newton;
        } else {
            width_at_newton = f32::INFINITY;
            s = 0.5 * (low + high);
            if !(s > low && s < high) {
                break;
            }
        }
    }
    0.5 * (low + high)
}

impl InverseCurve for MonotoneCubicInverse {
    #[inline]
    fn pressure_kpa(&self, relative_change: f32) -> f32 {
        let cell = self.table.cell(relative_change);
        let start_kpa = self.table.interpolate(cell);
        let first = self.first_segments.get(cell.0).copied().unwrap_or(0);
        let index = self.segment_from(usize::from(first), relative_change);
        let (Some(segment), Some(bound)) = (
            self.forward.segments().get(index),
            self.error_bounds_per_kpa.get(index),
        ) else {
            return 0.0;
        };
        let start = clamp_f32(start_kpa - segment.x_start, 0.0, segment.width);
        let step = (segment.value_at(start) - relative_change) / segment.slope_at(start);
        let s = if bound * step * step <= ACCEPTED_ERROR_KPA {
            clamp_f32(start - step, 0.0, segment.width)
        } else {
            solve_bracketed(segment, *bound, ACCEPTED_ERROR_KPA, relative_change, start)
        };
        clamp_pressure(segment.x_start + s, self.top_pressure_kpa)
    }
}
