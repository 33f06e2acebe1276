//! Monotone cubic tier: the inverse of the Fritsch–Carlson cubic dC/C0 = f(P) through the
//! calibration points, which is the model's reference curve, for every valid calibration.
//!
//! # Method
//!
//! On the interval holding the reading, the forward cubic `f(s)` (local coordinate `s` in
//! `0 ..= w`) is non-decreasing (Fritsch–Carlson). The root of `f(s) = y` is found in two stages.
//!
//! 1. **Fast path: inverse-Hermite start, one Newton step, a proven error bound.** The start
//!    `s0` is the cubic Hermite interpolant of the inverse through the interval's ends, with the
//!    inverse's end slopes `1 / f'` limited to three times its secant (so a flat end cannot throw
//!    it far), clamped into `0 ..= w`. One Newton step `s1 = s0 - r / f'(s0)` (with
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

use super::{clamp_pressure, InverseCurve};
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

/// Per interval: the inverse-Hermite start and the fast path's error bound factor.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct InverseSegment {
    /// `s0(t) = t (g1 + t (g2 + t g3))`, `t = y - y_k`.
    start: [f32; 3],
    /// `B = max|f''| max(f')^2 / (2 min(f')^3)`, per kPa; infinite when `f'` reaches 0.
    error_bound_per_kpa: f32,
}

/// Inverse of the monotone cubic through the calibration points.
#[derive(Debug, Clone, PartialEq)]
pub struct MonotoneCubicInverse {
    forward: MonotoneCubic,
    relative_change_starts: [f32; MAX_CURVE_POINTS],
    inverse_segments: [InverseSegment; MAX_CURVE_POINTS - 1],
    top_pressure_kpa: f32,
}

impl MonotoneCubicInverse {
    /// Builds the forward cubic and, per interval, the inverse-Hermite start and error bound.
    pub fn new(curve: &CalibrationCurve) -> Self {
        let forward = MonotoneCubic::new(&curve.pressures_kpa(), &curve.relative_changes());
        let mut relative_change_starts = [0.0; MAX_CURVE_POINTS];
        let mut inverse_segments = [InverseSegment::default(); MAX_CURVE_POINTS - 1];
        for (index, point) in curve.points().iter().enumerate().take(MAX_CURVE_POINTS) {
            relative_change_starts[index] = point.relative_change;
        }
        for (slot, segment) in inverse_segments.iter_mut().zip(forward.segments()) {
            *slot = InverseSegment::new(segment);
        }
        Self {
            forward,
            relative_change_starts,
            inverse_segments,
            top_pressure_kpa: curve.top().pressure_kpa,
        }
    }

    /// The forward curve (pressure to relative change).
    pub fn forward(&self) -> &MonotoneCubic {
        &self.forward
    }
}

impl InverseSegment {
    /// From the interval's forward cubic. The start only has to be near the root, so it is
    /// formed in f32; the error bound carries the guarantee, so it is formed in f64.
    fn new(segment: &CubicSegment) -> Self {
        let width_kpa = segment.width;
        let rise = segment.value_at(width_kpa) - segment.coefficients[0];
        if !(width_kpa > 0.0 && rise > 0.0) {
            return Self {
                start: [0.0; 3],
                error_bound_per_kpa: f32::INFINITY,
            };
        }
        let secant = width_kpa / rise;
        let limit = 3.0 * secant;
        let inverse_slope = |tangent: f32| {
            if tangent * limit > 1.0 {
                1.0 / tangent
            } else {
                limit
            }
        };
        let g0 = inverse_slope(segment.coefficients[1]);
        let g1 = inverse_slope(segment.slope_at(width_kpa));
        let start = [
            g0,
            (3.0 * secant - 2.0 * g0 - g1) / rise,
            (g0 + g1 - 2.0 * secant) / (rise * rise),
        ];
        let (slope_min, slope_max) = segment.slope_range(0.0, f64::from(width_kpa));
        let bound = segment.curvature_max() * slope_max * slope_max
            / (2.0 * slope_min * slope_min * slope_min);
        let error_bound_per_kpa = if slope_min > 0.0 && bound.is_finite() && bound < 1.0e30 {
            bound as f32
        } else {
            f32::INFINITY
        };
        Self {
            start,
            error_bound_per_kpa,
        }
    }

    #[inline(always)]
    fn start(&self, rise: f32) -> f32 {
        let [g1, g2, g3] = self.start;
        rise * (g1 + rise * (g2 + rise * g3))
    }
}

/// Stage 2 of the module doc: the bracketed, safeguarded Newton iteration from `s`.
#[inline(never)]
fn solve_bracketed(segment: &CubicSegment, error_bound_per_kpa: f32, y: f32, mut s: f32) -> f32 {
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
            if error_bound_per_kpa * step * step <= ACCEPTED_ERROR_KPA {
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
        let segments = self.forward.segments();
        let mut index = 0;
        while index + 1 < segments.len()
            && relative_change >= self.relative_change_starts[index + 1]
        {
            index += 1;
        }
        let (Some(segment), Some(inverse)) =
            (segments.get(index), self.inverse_segments.get(index))
        else {
            return 0.0;
        };
        let start = clamp_f32(
            inverse.start(relative_change - segment.coefficients[0]),
            0.0,
            segment.width,
        );
        let step = (segment.value_at(start) - relative_change) / segment.slope_at(start);
        let s = if inverse.error_bound_per_kpa * step * step <= ACCEPTED_ERROR_KPA {
            clamp_f32(start - step, 0.0, segment.width)
        } else {
            solve_bracketed(segment, inverse.error_bound_per_kpa, relative_change, start)
        };
        clamp_pressure(segment.x_start + s, self.top_pressure_kpa)
    }
}
