//! Monotone cubic tier: the inverse of the Fritsch–Carlson cubic dC/C0 = f(P) through the
//! calibration points, which is the model's reference curve, for every valid calibration.
//!
//! # Storage
//!
//! Besides the calibration's own points the tier keeps, per point, the Fritsch–Carlson tangent
//! (computed in f64, stored in f32) and, per interval, the error bound of stage 1 below: 124
//! bytes for a 16-point curve. Each interval's cubic is formed from them when a reading falls in
//! it (Hermite form, no division).
//!
//! # Method
//!
//! The reading's interval `[P_k, P_k+1]` is found by binary search over the points' dC/C0. On it
//! the cubic is written in the unit coordinate `t = (P - P_k) / w` (`w = P_k+1 - P_k`): with
//! `d = dC/C0_k+1 - dC/C0_k` and the tangents scaled to the interval, `a = w m_k`,
//! `b = w m_k+1`, `f(t) = dC/C0_k + t (a + t ((3 d - 2 a - b) + t (a + b - 2 d)))`, the same
//! Hermite cubic as [`crate::monotone_cubic::MonotoneCubic`]'s (whose coefficients, in the local
//! pressure, are rounded from f64: the two agree to f32 rounding). It is non-decreasing on
//! `0 ..= 1` (Fritsch–Carlson). The root of `f(t) = y` is found in two stages.
//!
//! 1. **Fast path: a chord start, at most [`FAST_NEWTON_STEPS`] Newton steps, a proven error
//!    bound.** The start `t0 = (y - dC/C0_k) / d` is where the chord of the interval reaches the
//!    reading. A Newton step `t1 = t0 - r / f'(t0)` (with `r = f(t0) - y`) follows. With
//!    `m = min f'`, `M = max f'` and `K = max |f''|` over the interval (computed once, in f64,
//!    from the f32 coefficients, when the tier is built), Taylor's theorem gives
//!    `|t1 - t*| <= K / (2 m) * (t0 - t*)^2` and the mean-value theorem
//!    `|t0 - t*| <= |r / f'(t0)| * M / m`; so the pressure `P_k + w t1` is within
//!    `B * step^2` of the root, `B = w K M^2 / (2 m^3)` (kPa). The step is accepted when
//!    `B * step^2 <= ACCEPTED_ERROR_KPA`, a bound that holds in exact arithmetic for a Newton
//!    step from any point of the interval; so when the first step is not accepted, the second
//!    starts from `t1` (clamped into the interval) under the same rule. On ordinary calibrations
//!    (the article's, anything with neighbouring secants of similar size) this is the path
//!    taken.
//! 2. **Safeguarded Newton in a bracket.** Otherwise (a nearly flat spot makes `m` tiny or zero,
//!    or the start was poor) the root is kept in a bracket `[low, high]` (`f(low) <= y <=
//!    f(high)`, initially the whole interval) that every evaluation narrows, starting from the
//!    fast path's last iterate. A Newton step is taken only when it lands strictly inside the
//!    bracket and the previous Newton step halved the bracket; otherwise the bracket is bisected.
//!    So the bracket at least halves every two iterations: after `2 n` iterations it is at most
//!    `2^-n` of the interval wide, and the loop stops when it is `2^-20` of it (or at f32
//!    resolution), within [`MAX_BRACKETED_ITERATIONS`] iterations whatever the calibration. A
//!    Newton step that meets the bound of stage 1 ends it earlier.
//!
//! A host converting many readings at once (a recording) calls the batch form,
//! [`super::ActiveInverse::pressures_kpa`]: the same arithmetic on eight values at a time, step
//! by step, which gives the same bits (tested) and lets a superscalar core with vector
//! instructions overlap the values' division chains.
//!
//! The result is the root of the f32 cubic to within the bound above, plus what the f32
//! evaluation of `f` near the root cannot resolve: a few ulps of `y` times the local slope of the
//! inverse `1 / f'`. Where `f'` is tiny (nearly equal neighbouring calibration points) that is
//! large, and it is a property of the calibration, not of the method: see
//! [`crate::conditioning`].

use super::{clamp_pressure, interval_index, InverseCurve};
use crate::bounds::clamp_f32;
use crate::calibration::{CalibrationCurve, CurvePoint, MAX_CURVE_POINTS};
use crate::monotone_cubic::{tangents, CubicSegment, MonotoneCubic};

/// Largest error (kPa, exact arithmetic) accepted from a Newton step of the fast path. The chord
/// start is coarse (tenths of a kPa on the article's curve), so at this level the first step
/// rarely qualifies and the second does: the result is then as close to the cubic's root as a
/// single step from the former 64-node start table made it (worst 8.9e-6 kPa against an f64
/// reference over the article's curve, 1.0e-5 before).
pub const ACCEPTED_ERROR_KPA: f32 = 1.0e-5;

/// Most Newton steps of the fast path before the bracketed stage takes over.
pub const FAST_NEWTON_STEPS: usize = 2;

/// The bracket stops narrowing at this fraction of the interval (2^-20).
const BRACKET_RELATIVE_WIDTH: f32 = 1.0 / 1_048_576.0;

/// Most iterations of the bracketed stage: the bracket halves at least every two iterations, so
/// 2 x 20 reach [`BRACKET_RELATIVE_WIDTH`]; two spare.
pub const MAX_BRACKETED_ITERATIONS: usize = 42;

/// What the monotone cubic tier keeps besides the curve's points.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CubicKnots {
    /// Fritsch–Carlson tangent d(dC/C0)/dP at each point, per kPa.
    tangents: [f32; MAX_CURVE_POINTS],
    /// Per interval, `B = w max|f''| max(f')^2 / (2 min(f')^3)` in kPa (derivatives in the unit
    /// coordinate); infinite where `f'` reaches 0.
    error_bounds_kpa: [f32; MAX_CURVE_POINTS - 1],
}

/// One interval's cubic in the unit coordinate, with what turns its root into a pressure.
#[derive(Clone, Copy)]
struct UnitInterval {
    /// `f(t)`, `t` in `0 ..= 1`.
    cubic: CubicSegment,
    /// dC/C0 across the interval.
    rise: f32,
    /// Pressure at the interval's start, kPa.
    start_kpa: f32,
    /// Interval width, kPa.
    width_kpa: f32,
}

impl UnitInterval {
    /// The pressure at unit coordinate `t`, clamped to the curve.
    #[inline(always)]
    fn pressure_kpa(&self, t: f32, top_pressure_kpa: f32) -> f32 {
        clamp_pressure(self.start_kpa + t * self.width_kpa, top_pressure_kpa)
    }
}

impl CubicKnots {
    /// The tangents of the curve's Fritsch–Carlson cubic and each interval's error bound.
    pub(crate) fn new(curve: &CalibrationCurve) -> Self {
        let tangents_f64 = tangents(&curve.pressures_kpa(), &curve.relative_changes());
        let mut knots = Self {
            tangents: tangents_f64.map(|tangent| tangent as f32),
            error_bounds_kpa: [f32::INFINITY; MAX_CURVE_POINTS - 1],
        };
        let points = curve.points();
        let mut error_bounds_kpa = [f32::INFINITY; MAX_CURVE_POINTS - 1];
        for (index, slot) in error_bounds_kpa.iter_mut().enumerate() {
            if let Some(interval) = knots.interval(points, index) {
                *slot = error_bound_kpa(&interval);
            }
        }
        knots.error_bounds_kpa = error_bounds_kpa;
        knots
    }

    /// Interval `index`'s cubic, from its points and tangents (`None` past the last interval).
    #[inline(always)]
    fn interval(&self, points: &[CurvePoint], index: usize) -> Option<UnitInterval> {
        let (Some(low), Some(high), Some(start_tangent), Some(end_tangent)) = (
            points.get(index),
            points.get(index + 1),
            self.tangents.get(index),
            self.tangents.get(index + 1),
        ) else {
            return None;
        };
        let width_kpa = high.pressure_kpa - low.pressure_kpa;
        let rise = high.relative_change - low.relative_change;
        let start_slope = width_kpa * start_tangent;
        let end_slope = width_kpa * end_tangent;
        Some(UnitInterval {
            cubic: CubicSegment {
                x_start: 0.0,
                width: 1.0,
                coefficients: [
                    low.relative_change,
                    start_slope,
                    3.0 * rise - 2.0 * start_slope - end_slope,
                    start_slope + end_slope - 2.0 * rise,
                ],
            },
            rise,
            start_kpa: low.pressure_kpa,
            width_kpa,
        })
    }

    /// Pressure for a relative change (module doc: both stages). `curve` must be the one the
    /// knots were built from.
    #[inline]
    pub(crate) fn pressure_kpa(&self, curve: &CalibrationCurve, relative_change: f32) -> f32 {
        let points = curve.points();
        let index = interval_index(points, relative_change);
        let (Some(interval), Some(&bound)) = (
            self.interval(points, index),
            self.error_bounds_kpa.get(index),
        ) else {
            return 0.0;
        };
        let top_pressure_kpa = curve.top().pressure_kpa;
        let cubic = &interval.cubic;
        let [start_relative_change, ..] = cubic.coefficients;
        let mut t = clamp_f32(
            (relative_change - start_relative_change) / interval.rise,
            0.0,
            1.0,
        );
        for _ in 0..FAST_NEWTON_STEPS {
            let step = (cubic.value_at(t) - relative_change) / cubic.slope_at(t);
            let next = clamp_f32(t - step, 0.0, 1.0);
            if bound * step * step <= ACCEPTED_ERROR_KPA {
                return interval.pressure_kpa(next, top_pressure_kpa);
            }
            t = next;
        }
        let t = solve_bracketed(cubic, bound, ACCEPTED_ERROR_KPA, relative_change, t);
        interval.pressure_kpa(t, top_pressure_kpa)
    }

    /// Pressures for many relative changes, in place: bit for bit what
    /// [`CubicKnots::pressure_kpa`] gives for each, arranged for a host converting a recording.
    /// A value's work is one long chain of dependent divisions; here the intervals' cubics are
    /// formed once (by the same arithmetic) and [`BATCH_LANES`] values go through each step
    /// together, so that a superscalar core overlaps their chains. The interval is counted
    /// without a branch and both fast-path steps are always taken, the result chosen afterwards
    /// by the same test; the rare value neither step settles goes through
    /// [`CubicKnots::pressure_kpa`] itself.
    pub(crate) fn pressures_kpa(&self, curve: &CalibrationCurve, values: &mut [f32]) {
        let Some(formed) = FormedIntervals::new(self, curve) else {
            values.fill(0.0);
            return;
        };
        let mut lanes = values.chunks_exact_mut(BATCH_LANES);
        for lane_values in &mut lanes {
            if let Ok(lane_values) = <&mut [f32; BATCH_LANES]>::try_from(lane_values) {
                formed.lanes_pressure_kpa(self, curve, lane_values);
            }
        }
        for value in lanes.into_remainder() {
            *value = self.pressure_kpa(curve, *value);
        }
    }

    /// Pressure for a relative change solved to the bracket's resolution, without the fast
    /// path's early acceptance (for the table tier's nodes).
    pub(crate) fn solved_pressure_kpa(
        &self,
        curve: &CalibrationCurve,
        relative_change: f32,
    ) -> f32 {
        let points = curve.points();
        let index = interval_index(points, relative_change);
        match (
            self.interval(points, index),
            self.error_bounds_kpa.get(index),
        ) {
            (Some(interval), Some(bound)) => {
                let t = solve_bracketed(&interval.cubic, *bound, 0.0, relative_change, 0.5);
                interval.pressure_kpa(t, curve.top().pressure_kpa)
            }
            _ => 0.0,
        }
    }
}

/// Values converted together by [`CubicKnots::pressures_kpa`].
const BATCH_LANES: usize = 8;

/// Every interval's cubic and error bound of a curve, formed once for
/// [`CubicKnots::pressures_kpa`].
struct FormedIntervals {
    /// The inner points' dC/C0 (every point but the first and the last), then +inf.
    inner_starts: [f32; MAX_CURVE_POINTS],
    /// The last interval's index.
    last_index: usize,
    /// Per interval, as [`CubicKnots::interval`] forms it.
    intervals: [UnitInterval; MAX_CURVE_POINTS - 1],
    /// Per interval, the fast path's error bound.
    bounds_kpa: [f32; MAX_CURVE_POINTS - 1],
    /// The top of the curve, kPa.
    top_pressure_kpa: f32,
}

impl FormedIntervals {
    /// `None` for a curve without an interval (a valid curve has one).
    fn new(knots: &CubicKnots, curve: &CalibrationCurve) -> Option<Self> {
        let points = curve.points();
        let last_index = points.len().checked_sub(2)?;
        let first = knots.interval(points, 0)?;
        let mut formed = Self {
            inner_starts: [f32::INFINITY; MAX_CURVE_POINTS],
            last_index,
            intervals: [first; MAX_CURVE_POINTS - 1],
            bounds_kpa: knots.error_bounds_kpa,
            top_pressure_kpa: curve.top().pressure_kpa,
        };
        for (start, point) in formed
            .inner_starts
            .iter_mut()
            .zip(points.get(1..=last_index).unwrap_or(&[]))
        {
            *start = point.relative_change;
        }
        for (index, slot) in formed.intervals.iter_mut().enumerate() {
            if let Some(interval) = knots.interval(points, index) {
                *slot = interval;
            }
        }
        Some(formed)
    }

    /// [`CubicKnots::pressures_kpa`] of one group of lanes, step by step across the lanes.
    #[inline(always)]
    fn lanes_pressure_kpa(
        &self,
        knots: &CubicKnots,
        curve: &CalibrationCurve,
        values: &mut [f32; BATCH_LANES],
    ) {
        const _: () = assert!(FAST_NEWTON_STEPS == 2, "the lanes take exactly two steps");
        const _: () = assert!(MAX_CURVE_POINTS == 16, "the search halves 16 starts");
        let mut indices = [0usize; BATCH_LANES];
        for (index, value) in indices.iter_mut().zip(&*values) {
            // For strictly increasing points the count of inner points at or below a value is
            // the index the scan of `interval_index` stops at (NaN counts none, as it scans
            // none); the padding counts only for +inf, which the scan puts in the last
            // interval. The starts are sorted, so the count is found by halving (15 at most,
            // more than the 14 inner points of the longest curve).
            let mut count = 0;
            for step in [8, 4, 2, 1] {
                if self
                    .inner_starts
                    .get(count + step - 1)
                    .is_some_and(|start| *value >= *start)
                {
                    count += step;
                }
            }
            *index = count.min(self.last_index);
        }
        let mut lanes = Lanes::default();
        for (lane, index) in indices.iter().enumerate() {
            if let Some(interval) = self.intervals.get(*index) {
                lanes.set(lane, interval);
            }
        }
        let t0 = lanes.chord_starts(values);
        let first_steps = lanes.newton_steps(values, &t0);
        let t1 = clamped_steps(&t0, &first_steps);
        let second_steps = lanes.newton_steps(values, &t1);
        for ((((value, index), first), second), t1) in values
            .iter_mut()
            .zip(&indices)
            .zip(&first_steps)
            .zip(&second_steps)
            .zip(&t1)
        {
            let (Some(interval), Some(&bound)) =
                (self.intervals.get(*index), self.bounds_kpa.get(*index))
            else {
                *value = 0.0;
                continue;
            };
            *value = if bound * first * first <= ACCEPTED_ERROR_KPA {
                interval.pressure_kpa(*t1, self.top_pressure_kpa)
            } else if bound * second * second <= ACCEPTED_ERROR_KPA {
                interval.pressure_kpa(clamp_f32(t1 - second, 0.0, 1.0), self.top_pressure_kpa)
            } else {
                knots.pressure_kpa(curve, *value)
            };
        }
    }
}

/// The lanes' cubics coefficient by coefficient, so that each step is one loop over plain
/// arrays (which the compiler can turn into vector instructions: the same IEEE operations per
/// lane). A lane without an interval keeps zeros and a rise of 1.
struct Lanes {
    c0: [f32; BATCH_LANES],
    c1: [f32; BATCH_LANES],
    c2: [f32; BATCH_LANES],
    c3: [f32; BATCH_LANES],
    rise: [f32; BATCH_LANES],
}

impl Default for Lanes {
    fn default() -> Self {
        Self {
            c0: [0.0; BATCH_LANES],
            c1: [0.0; BATCH_LANES],
            c2: [0.0; BATCH_LANES],
            c3: [0.0; BATCH_LANES],
            rise: [1.0; BATCH_LANES],
        }
    }
}

impl Lanes {
    /// Lane `lane` takes the interval's cubic.
    #[inline(always)]
    fn set(&mut self, lane: usize, interval: &UnitInterval) {
        if let (Some(c0), Some(c1), Some(c2), Some(c3), Some(rise)) = (
            self.c0.get_mut(lane),
            self.c1.get_mut(lane),
            self.c2.get_mut(lane),
            self.c3.get_mut(lane),
            self.rise.get_mut(lane),
        ) {
            [*c0, *c1, *c2, *c3] = interval.cubic.coefficients;
            *rise = interval.rise;
        }
    }

    /// Where each lane's chord reaches its value, clamped to `0 ..= 1`.
    #[inline(always)]
    fn chord_starts(&self, values: &[f32; BATCH_LANES]) -> [f32; BATCH_LANES] {
        let mut starts = [0.0f32; BATCH_LANES];
        for (((start, value), c0), rise) in
            starts.iter_mut().zip(values).zip(&self.c0).zip(&self.rise)
        {
            *start = clamp_f32((value - c0) / rise, 0.0, 1.0);
        }
        starts
    }

    /// One Newton step per lane toward `f(t) = value`, as [`CubicSegment`] evaluates it.
    #[inline(always)]
    fn newton_steps(
        &self,
        values: &[f32; BATCH_LANES],
        t: &[f32; BATCH_LANES],
    ) -> [f32; BATCH_LANES] {
        let mut steps = [0.0f32; BATCH_LANES];
        for ((((((step, value), t), c0), c1), c2), c3) in steps
            .iter_mut()
            .zip(values)
            .zip(t)
            .zip(&self.c0)
            .zip(&self.c1)
            .zip(&self.c2)
            .zip(&self.c3)
        {
            let cubic = CubicSegment {
                x_start: 0.0,
                width: 1.0,
                coefficients: [*c0, *c1, *c2, *c3],
            };
            *step = (cubic.value_at(*t) - value) / cubic.slope_at(*t);
        }
        steps
    }
}

/// `t - step` per lane, clamped to `0 ..= 1`.
#[inline(always)]
fn clamped_steps(t: &[f32; BATCH_LANES], steps: &[f32; BATCH_LANES]) -> [f32; BATCH_LANES] {
    let mut next = [0.0f32; BATCH_LANES];
    for ((next, t), step) in next.iter_mut().zip(t).zip(steps) {
        *next = clamp_f32(t - step, 0.0, 1.0);
    }
    next
}

/// The fast path's error bound of an interval (module doc), from its f32 coefficients in f64;
/// infinite where the slope reaches 0.
fn error_bound_kpa(interval: &UnitInterval) -> f32 {
    let cubic = &interval.cubic;
    let (slope_min, slope_max) = cubic.slope_range(0.0, 1.0);
    let bound = f64::from(interval.width_kpa) * cubic.curvature_max() * slope_max * slope_max
        / (2.0 * slope_min * slope_min * slope_min);
    if slope_min > 0.0 && bound.is_finite() && bound < 1.0e30 {
        bound as f32
    } else {
        f32::INFINITY
    }
}

/// Stage 2 of the module doc: the bracketed, safeguarded Newton iteration from `s`, in the
/// segment's local coordinate.
#[inline(never)]
fn solve_bracketed(
    segment: &CubicSegment,
    error_bound_kpa: f32,
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
            if error_bound_kpa * step * step <= accepted_error_kpa {
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

/// Inverse of the monotone cubic through a curve's points, owning its curve, with the forward
/// cubic for references (host tools, tier selection). The pad keeps only the compact part.
#[derive(Debug, Clone, PartialEq)]
pub struct MonotoneCubicInverse {
    curve: CalibrationCurve,
    knots: CubicKnots,
    forward: MonotoneCubic,
}

impl MonotoneCubicInverse {
    /// Builds the tangents, each interval's error bound and the forward cubic.
    pub fn new(curve: &CalibrationCurve) -> Self {
        Self {
            curve: curve.clone(),
            knots: CubicKnots::new(curve),
            forward: MonotoneCubic::new(&curve.pressures_kpa(), &curve.relative_changes()),
        }
    }

    /// The forward curve (pressure to relative change).
    pub fn forward(&self) -> &MonotoneCubic {
        &self.forward
    }

    /// The compact part the pad keeps.
    pub(crate) fn knots(&self) -> &CubicKnots {
        &self.knots
    }
}

impl InverseCurve for MonotoneCubicInverse {
    #[inline]
    fn pressure_kpa(&self, relative_change: f32) -> f32 {
        self.knots.pressure_kpa(&self.curve, relative_change)
    }
}
