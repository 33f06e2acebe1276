//! Monotone cubic tier: the inverse of the Fritsch–Carlson cubic dC/C0 = f(P) through the
//! calibration points, which is the model's reference curve, for every valid calibration.
//!
//! # Storage
//!
//! Besides the calibration's own points the tier keeps, per interval, its cubic's coefficients
//! (from the Fritsch–Carlson tangents, computed in f64, in f32 arithmetic), the error bound of
//! stage 1 below and where its seed cells are; [`HINT_CELLS`] interval hints; and a seed table
//! of [`SEED_CELLS`] cells: 716 bytes a taxel, all computed when the calibration or the tier is
//! installed, so that a reading costs a lookup, three multiply-adds, one Newton step and one
//! division (the firmware's RAM holds it for eight pads: the pad model's size is asserted in
//! `pad.rs`).
//!
//! # Method
//!
//! On the interval `[P_k, P_k+1]` of the reading the cubic is written in the unit coordinate
//! `t = (P - P_k) / w` (`w = P_k+1 - P_k`): with `d = dC/C0_k+1 - dC/C0_k` and the tangents
//! scaled to the interval, `a = w m_k`, `b = w m_k+1`, `f(t) = dC/C0_k + t (a + t ((3 d - 2 a -
//! b) + t (a + b - 2 d)))`, the same Hermite cubic as
//! [`crate::monotone_cubic::MonotoneCubic`]'s (whose coefficients, in the local pressure, are
//! rounded from f64: the two agree to f32 rounding). It is non-decreasing on `0 ..= 1`
//! (Fritsch–Carlson). The root of `f(t) = y` is found in two stages.
//!
//! 1. **Fast path: a seed from the table, at most [`FAST_NEWTON_STEPS`] Newton steps, a proven
//!    error bound.** The reading's interval is found by a forward scan over the points' dC/C0
//!    from a hint (equal cells of `0 ..= top`; the scan rarely moves). Each interval has its
//!    own cells of the seed table, equal in dC/C0 (at least one each, the rest shared where a
//!    cell spans the most kPa); a cell holds the inverse over it as a cubic in the interval's
//!    unit coordinate (Hermite, through the roots and their slopes at the cell's ends, slopes
//!    capped at three times the cell's secant so that the seed is monotone), and the seed
//!    `t0` is that cubic at the reading. A Newton step `t1 = t0 - r / f'(t0)` (with
//!    `r = f(t0) - y`) follows. With `m = min f'`, `M = max f'` and `K = max |f''|` over a part
//!    of the interval holding `t0` and the root, Taylor's theorem gives
//!    `|t1 - t*| <= K / (2 m) * (t0 - t*)^2` and the mean-value theorem
//!    `|t0 - t*| <= |r / f'(t0)| * M / m`; so the pressure `P_k + w t1` is within
//!    `B * step^2` of the root, `B = w K M^2 / (2 m^3)` (kPa). For the first step that part is
//!    the cell's reach (its readings' roots and its seeds, with a margin for rounding), whose
//!    bound each cell keeps; for later steps the whole interval, whose bound each interval
//!    keeps (both computed once, in f64, from the f32 coefficients). A step is accepted when
//!    `B * step^2 <= ACCEPTED_ERROR_KPA`, which holds in exact arithmetic whatever the seed;
//!    when the first is not accepted, the second starts from `t1` (clamped into the interval)
//!    under the interval's bound. The seed only decides how often the first step is enough:
//!    for every reading of the article's curve, for at least 95 % of readings of ordinary
//!    concave calibrations (tested).
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
//! The result is the root of the f32 cubic to within the bound above, plus what the f32
//! evaluation of `f` near the root cannot resolve: a few ulps of `y` times the local slope of the
//! inverse `1 / f'`. Where `f'` is tiny (nearly equal neighbouring calibration points) that is
//! large, and it is a property of the calibration, not of the method: see
//! [`crate::conditioning`].

use super::{clamp_pressure, interval_index, interval_index_from, InverseCurve};
use crate::bounds::clamp_f32;
use crate::calibration::{CalibrationCurve, CurvePoint, MAX_CURVE_POINTS};
use crate::monotone_cubic::{tangents, CubicSegment, MonotoneCubic};

/// Largest error (kPa, exact arithmetic) accepted from a Newton step of the fast path.
pub const ACCEPTED_ERROR_KPA: f32 = 1.0e-5;

/// Cells of the seed table (module doc, stage 1): enough that one Newton step from the seed
/// meets [`ACCEPTED_ERROR_KPA`] on ordinary calibrations, few enough for eight pads in the
/// firmware's RAM (20 bytes a cell, per taxel).
pub const SEED_CELLS: usize = 16;

/// Cells of the interval hints: twice the most intervals, so that the scan from a hint rarely
/// moves.
const HINT_CELLS: usize = 32;

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
    /// Per interval, its cubic's higher coefficients, error bound and seed cells.
    intervals: [IntervalData; MAX_CURVE_POINTS - 1],
    /// Hint cells per unit of dC/C0 (`HINT_CELLS / top`).
    hints_per_relative_change: f32,
    /// Per hint cell (equal cells of `0 ..= top` in dC/C0), the interval of its lowest dC/C0:
    /// the scan for a reading's interval starts there.
    interval_hints: [u8; HINT_CELLS],
    /// The seed table, interval after interval.
    seed_cells: [SeedCell; SEED_CELLS],
}

/// What the tier keeps per interval.
#[derive(Debug, Clone, Copy, PartialEq)]
struct IntervalData {
    /// `f(t)`'s coefficients of `t`, `t^2` and `t^3` (the constant is the start point's dC/C0),
    /// from the Fritsch–Carlson tangents (computed in f64, rounded to f32) in f32 arithmetic.
    higher_coefficients: [f32; 3],
    /// `B = w max|f''| max(f')^2 / (2 min(f')^3)` in kPa (derivatives in the unit coordinate);
    /// infinite where `f'` reaches 0.
    error_bound_kpa: f32,
    /// Seed cells per unit of dC/C0 (the interval's cell count over its rise).
    cells_per_relative_change: f32,
    /// The first seed cell's index in the table.
    first_cell: u8,
    /// The last seed cell's index in the table.
    last_cell: u8,
    /// The interval's own index.
    index: u8,
}

impl IntervalData {
    const EMPTY: Self = Self {
        higher_coefficients: [0.0; 3],
        error_bound_kpa: f32::INFINITY,
        cells_per_relative_change: 0.0,
        first_cell: 0,
        last_cell: 0,
        index: 0,
    };
}

/// One cell of the seed table.
#[derive(Debug, Clone, Copy, PartialEq)]
struct SeedCell {
    /// The seed `t = c0 + u (c1 + u (c2 + u c3))` in the interval's unit coordinate at position
    /// `u` in the cell (`0 ..= 1`).
    unit_seed: [f32; 4],
    /// The fast path's error bound `B` of a first Newton step from the seed (module doc, stage
    /// 1), over the part of the interval the cell's readings and seeds can reach; infinite where
    /// the slope reaches 0.
    bound_kpa: f32,
}

impl SeedCell {
    const EMPTY: Self = Self {
        unit_seed: [0.0; 4],
        bound_kpa: f32::INFINITY,
    };

    /// The seed at position `u` in the cell.
    #[inline(always)]
    fn seed(&self, u: f32) -> f32 {
        let [c0, c1, c2, c3] = self.unit_seed;
        c0 + u * (c1 + u * (c2 + u * c3))
    }
}

/// Where a reading falls: its interval's points and data, its seed cell and its position in that
/// cell.
#[derive(Clone, Copy)]
struct Lookup<'a> {
    low: &'a CurvePoint,
    high: &'a CurvePoint,
    data: &'a IntervalData,
    cell: &'a SeedCell,
    u: f32,
}

impl Lookup<'_> {
    /// One Newton step from the cell's seed: the pressure when the cell's bound accepts the
    /// step, else the step's unit coordinate for the rest of the search. The scalar path and the
    /// host's batch both take it, so they agree bit for bit.
    #[inline(always)]
    fn first_step(&self, relative_change: f32) -> Result<f32, f32> {
        // Not clamped: for a reading of the interval the seed lies between the cell's end roots
        // (a monotone cubic, up to rounding far inside the cell's reach); for any other the
        // clamps below decide the result.
        let t = self.cell.seed(self.u);
        let [c1, c2, c3] = self.data.higher_coefficients;
        let cubic = CubicSegment {
            x_start: 0.0,
            width: 1.0,
            coefficients: [self.low.relative_change, c1, c2, c3],
        };
        let step = (cubic.value_at(t) - relative_change) / cubic.slope_at(t);
        let next = clamp_f32(t - step, 0.0, 1.0);
        // The step started from the seed, within the cell's reach: the cell's bound holds.
        if self.cell.bound_kpa * step * step <= ACCEPTED_ERROR_KPA {
            let (start_kpa, end_kpa) = (self.low.pressure_kpa, self.high.pressure_kpa);
            // With `next` in `0 ..= 1` the pressure is at least the start (both non-negative);
            // only rounding can take it past the interval's end, and so past the top.
            Ok(end_clamped(
                start_kpa + next * (end_kpa - start_kpa),
                end_kpa,
            ))
        } else {
            Err(next)
        }
    }
}

/// One interval's cubic in the unit coordinate, with what turns its root into a pressure.
#[derive(Clone, Copy)]
struct UnitInterval {
    /// `f(t)`, `t` in `0 ..= 1`.
    cubic: CubicSegment,
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
    /// Each interval's cubic and error bound, the interval hints and the seed table.
    pub(crate) fn new(curve: &CalibrationCurve) -> Self {
        let points = curve.points();
        let tangents = tangents(&curve.pressures_kpa(), &curve.relative_changes())
            .map(|tangent| tangent as f32);
        let mut knots = Self {
            intervals: [IntervalData::EMPTY; MAX_CURVE_POINTS - 1],
            hints_per_relative_change: 0.0,
            interval_hints: [0; HINT_CELLS],
            seed_cells: [SeedCell::EMPTY; SEED_CELLS],
        };
        for (index, data) in knots.intervals.iter_mut().enumerate() {
            let (Some(low), Some(high), Some(start_tangent), Some(end_tangent)) = (
                points.get(index),
                points.get(index + 1),
                tangents.get(index),
                tangents.get(index + 1),
            ) else {
                break;
            };
            let width_kpa = high.pressure_kpa - low.pressure_kpa;
            let rise = high.relative_change - low.relative_change;
            let start_slope = width_kpa * start_tangent;
            let end_slope = width_kpa * end_tangent;
            data.index = index as u8;
            data.higher_coefficients = [
                start_slope,
                3.0 * rise - 2.0 * start_slope - end_slope,
                start_slope + end_slope - 2.0 * rise,
            ];
        }
        for index in 0..MAX_CURVE_POINTS - 1 {
            if let (Some(interval), Some(data)) = (
                knots.interval(points, index),
                knots.intervals.get(index).copied(),
            ) {
                if let Some(slot) = knots.intervals.get_mut(index) {
                    *slot = IntervalData {
                        error_bound_kpa: error_bound_kpa(&interval),
                        ..data
                    };
                }
            }
        }
        let top = curve.top().relative_change;
        if top > 0.0 {
            knots.hints_per_relative_change = HINT_CELLS as f32 / top;
            let hint_width = f64::from(top) / HINT_CELLS as f64;
            knots.interval_hints = core::array::from_fn(|hint| {
                // A reading of this cell is at least its start less the rounding of its
                // position (far below a hundredth of a cell).
                let lowest = ((hint as f64 - 0.01) * hint_width).max(0.0) as f32;
                u8::try_from(interval_index(points, lowest)).unwrap_or(0)
            });
        }
        knots.fill_seed_table(curve);
        knots
    }

    /// Shares the seed table's cells among the intervals (at least one each, the rest where a
    /// cell spans the most kPa) and fills each cell (module doc, stage 1).
    fn fill_seed_table(&mut self, curve: &CalibrationCurve) {
        let points = curve.points();
        let intervals = points.len().saturating_sub(1).min(SEED_CELLS);
        let mut counts = [0usize; MAX_CURVE_POINTS - 1];
        for count in counts.iter_mut().take(intervals) {
            *count = 1;
        }
        let width_kpa = |index: usize| match (points.get(index), points.get(index + 1)) {
            (Some(low), Some(high)) => high.pressure_kpa - low.pressure_kpa,
            _ => 0.0,
        };
        for _ in intervals..SEED_CELLS {
            let widest = (0..intervals).max_by(|a, b| {
                let per_cell = |index: usize| {
                    width_kpa(index) / counts.get(index).copied().unwrap_or(1).max(1) as f32
                };
                per_cell(*a).total_cmp(&per_cell(*b))
            });
            if let Some(count) = widest.and_then(|index| counts.get_mut(index)) {
                *count += 1;
            }
        }
        let mut next_cell = 0usize;
        for index in 0..intervals {
            let (Some(interval), Some(low), Some(&count)) = (
                self.interval(points, index),
                points.get(index),
                counts.get(index),
            ) else {
                continue;
            };
            let rise = interval.cubic.value_at(1.0) - low.relative_change;
            if let Some(data) = self.intervals.get_mut(index) {
                data.cells_per_relative_change = if rise > 0.0 { count as f32 / rise } else { 0.0 };
                data.first_cell = next_cell as u8;
                data.last_cell = (next_cell + count - 1) as u8;
            }
            for cell in 0..count {
                let filled = seed_cell(&interval, low.relative_change, rise, cell, count);
                if let Some(slot) = self.seed_cells.get_mut(next_cell + cell) {
                    *slot = filled;
                }
            }
            next_cell += count;
        }
    }

    /// Interval `index`'s end points and data (`None` past the last interval).
    #[inline(always)]
    fn parts<'a>(
        &'a self,
        points: &'a [CurvePoint],
        index: usize,
    ) -> Option<(&'a CurvePoint, &'a CurvePoint, &'a IntervalData)> {
        Some((
            points.get(index)?,
            points.get(index + 1)?,
            self.intervals.get(index)?,
        ))
    }

    /// Interval `index`'s cubic (`None` past the last interval).
    #[inline(always)]
    fn interval(&self, points: &[CurvePoint], index: usize) -> Option<UnitInterval> {
        let (low, high, data) = self.parts(points, index)?;
        let [c1, c2, c3] = data.higher_coefficients;
        Some(UnitInterval {
            cubic: CubicSegment {
                x_start: 0.0,
                width: 1.0,
                coefficients: [low.relative_change, c1, c2, c3],
            },
            start_kpa: low.pressure_kpa,
            width_kpa: high.pressure_kpa - low.pressure_kpa,
        })
    }

    /// Pressure for a relative change (module doc: both stages). `curve` must be the one the
    /// knots were built from.
    #[inline]
    pub(crate) fn pressure_kpa(&self, curve: &CalibrationCurve, relative_change: f32) -> f32 {
        self.solve(curve, relative_change).0
    }

    /// A reading's interval (its points and data), seed cell and position in that cell.
    #[inline(always)]
    fn lookup<'a>(&'a self, points: &'a [CurvePoint], relative_change: f32) -> Option<Lookup<'a>> {
        // The scan from the hint's interval (a saturating conversion: NaN and negative readings
        // start at the first interval, those past the top at the last hint).
        let hint = (relative_change * self.hints_per_relative_change) as usize;
        let start = self
            .interval_hints
            .get(hint.min(HINT_CELLS - 1))
            .copied()
            .unwrap_or(0);
        let index = interval_index_from(points, relative_change, usize::from(start));
        self.cell_of(points, index, relative_change)
    }

    /// [`CubicKnots::lookup`] once the reading's interval is known.
    #[inline(always)]
    fn cell_of<'a>(
        &'a self,
        points: &'a [CurvePoint],
        index: usize,
        relative_change: f32,
    ) -> Option<Lookup<'a>> {
        let (low, high, data) = self.parts(points, index)?;
        let position = (relative_change - low.relative_change) * data.cells_per_relative_change;
        // Saturating again: NaN and negative positions are the first cell, those past the
        // interval's end the last (the seed is then clamped into the interval).
        let local =
            (position as usize).min(usize::from(data.last_cell.saturating_sub(data.first_cell)));
        let cell = self.seed_cells.get(usize::from(data.first_cell) + local)?;
        Some(Lookup {
            low,
            high,
            data,
            cell,
            u: position - local as f32,
        })
    }

    /// [`CubicKnots::pressure_kpa`] with the number of Newton steps taken outside the bracketed
    /// stage (one more than [`FAST_NEWTON_STEPS`]: the bracketed stage ran).
    #[inline(always)]
    fn solve(&self, curve: &CalibrationCurve, relative_change: f32) -> (f32, usize) {
        let Some(lookup) = self.lookup(curve.points(), relative_change) else {
            return (0.0, 0);
        };
        match lookup.first_step(relative_change) {
            Ok(pressure_kpa) => (pressure_kpa, 1),
            Err(next) => {
                self.solve_further(curve, usize::from(lookup.data.index), relative_change, next)
            }
        }
    }

    /// The rest of the search when the first step from the seed was not accepted: at most
    /// [`FAST_NEWTON_STEPS`] `- 1` more steps judged by the interval's bound, then the
    /// bracketed stage, from `t` in interval `index`. Apart from the hot path, which then keeps
    /// few values live.
    #[cold]
    #[inline(never)]
    fn solve_further(
        &self,
        curve: &CalibrationCurve,
        index: usize,
        relative_change: f32,
        mut t: f32,
    ) -> (f32, usize) {
        let (Some(interval), Some(data)) = (
            self.interval(curve.points(), index),
            self.intervals.get(index),
        ) else {
            return (0.0, 0);
        };
        let bound = data.error_bound_kpa;
        let top_pressure_kpa = curve.top().pressure_kpa;
        let cubic = &interval.cubic;
        for steps in 2..=FAST_NEWTON_STEPS {
            let step = (cubic.value_at(t) - relative_change) / cubic.slope_at(t);
            let next = clamp_f32(t - step, 0.0, 1.0);
            if bound * step * step <= ACCEPTED_ERROR_KPA {
                return (interval.pressure_kpa(next, top_pressure_kpa), steps);
            }
            t = next;
        }
        let t = solve_bracketed(cubic, bound, ACCEPTED_ERROR_KPA, relative_change, t);
        (
            interval.pressure_kpa(t, top_pressure_kpa),
            FAST_NEWTON_STEPS + 1,
        )
    }

    /// Pressures for many relative changes, in place: bit for bit what
    /// [`CubicKnots::pressure_kpa`] gives for each (tested), arranged for a host converting a
    /// recording: the interval found by a branchless search (a random reading would mispredict
    /// the scan's branches), then the same first step as the scalar path, each value straight
    /// after its lookup (gathering the lookups into per-lane columns first, for vector
    /// arithmetic, cost more in stalled loads than the vectors saved). A value whose first step
    /// is not accepted goes through [`CubicKnots::pressure_kpa`] itself.
    pub(crate) fn pressures_kpa(&self, curve: &CalibrationCurve, values: &mut [f32]) {
        let points = curve.points();
        // The inner points' dC/C0 (every point but the first and the last), then +inf: the
        // branchless search below counts those at or below a reading.
        let mut inner_starts = [f32::INFINITY; MAX_CURVE_POINTS];
        let last_index = points.len().saturating_sub(2);
        for (start, point) in inner_starts
            .iter_mut()
            .zip(points.get(1..=last_index).unwrap_or(&[]))
        {
            *start = point.relative_change;
        }
        let points = curve.points();
        // For strictly increasing points the count of inner points at or below a value is the
        // interval the scan of `lookup` stops at (NaN counts none, as the scan moves past none;
        // the padding counts only for +inf, which the scan puts in the last interval). Counted
        // over all sixteen at once (vector compares): no branch for a random reading to
        // mispredict, and no chain of dependent loads.
        let interval_of = |value: f32| {
            inner_starts
                .iter()
                .map(|start| usize::from(value >= *start))
                .sum::<usize>()
                .min(last_index)
        };
        // Four values at a time, stage by stage: each value's lookup, seed, step and test are
        // one long chain of dependent operations, which the core overlaps only when the chains
        // of several values are next to each other in the program.
        let mut groups = values.chunks_exact_mut(BATCH_GROUP);
        for group in &mut groups {
            let Ok(group) = <&mut [f32; BATCH_GROUP]>::try_from(group) else {
                continue;
            };
            let lookups = group.map(|value| self.cell_of(points, interval_of(value), value));
            let mut steps = [Err(0.0); BATCH_GROUP];
            for ((step, lookup), value) in steps.iter_mut().zip(&lookups).zip(group.iter()) {
                if let Some(lookup) = lookup {
                    *step = lookup.first_step(*value);
                }
            }
            for (value, step) in group.iter_mut().zip(steps) {
                *value = match step {
                    Ok(pressure_kpa) => pressure_kpa,
                    Err(_) => self.pressure_kpa(curve, *value),
                };
            }
        }
        for value in groups.into_remainder() {
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
        match (self.interval(points, index), self.intervals.get(index)) {
            (Some(interval), Some(data)) => {
                let t = solve_bracketed(
                    &interval.cubic,
                    data.error_bound_kpa,
                    0.0,
                    relative_change,
                    0.5,
                );
                interval.pressure_kpa(t, curve.top().pressure_kpa)
            }
            _ => 0.0,
        }
    }
}

/// Values [`CubicKnots::pressures_kpa`] takes together.
const BATCH_GROUP: usize = 4;

/// `pressure_kpa`, or `end_kpa` where rounding took it past (module doc, stage 1).
#[inline(always)]
fn end_clamped(pressure_kpa: f32, end_kpa: f32) -> f32 {
    if pressure_kpa > end_kpa {
        end_kpa
    } else {
        pressure_kpa
    }
}

/// Cell `cell` of `count` equal cells in dC/C0 of an interval starting at `start`, rising by
/// `rise`: the Hermite cubic of the inverse through its ends (each solved to the bracket's
/// resolution) with their slopes, capped at three times the cell's secant so that the seed is
/// monotone; and the error bound over the cell's reach (its readings and its seeds, with a
/// margin for rounding).
fn seed_cell(
    interval: &UnitInterval,
    start: f32,
    rise: f32,
    cell: usize,
    count: usize,
) -> SeedCell {
    let cubic = &interval.cubic;
    let cell_rise = f64::from(rise) / count as f64;
    let root = |fraction: f64| {
        let relative_change = (f64::from(start) + cell_rise * fraction) as f32;
        let t = solve_bracketed(cubic, f32::INFINITY, 0.0, relative_change, 0.5);
        // dt/d(dC/C0), scaled to the cell; infinite at a flat spot of the curve.
        (f64::from(t), cell_rise / f64::from(cubic.slope_at(t)))
    };
    let (t_start, slope_start) = root(cell as f64);
    let (t_end, slope_end) = root(cell as f64 + 1.0);
    let secant = t_end - t_start;
    let capped = |slope: f64| {
        if slope.is_finite() && slope >= 0.0 {
            slope.min(3.0 * secant)
        } else {
            secant
        }
    };
    let (a, b) = (capped(slope_start), capped(slope_end));
    // A reading of this cell lies within a hundredth of a cell of it (rounding of its
    // position), its root and the seed (monotone between the ends up to rounding) within the
    // margin of the roots there.
    const MARGIN: f64 = 1.0e-4;
    let reach_low = (root(cell as f64 - 0.01).0 - MARGIN).max(0.0);
    let reach_high = (root(cell as f64 + 1.01).0 + MARGIN).min(1.0);
    let (slope_min, slope_max) = cubic.slope_range(reach_low, reach_high);
    let [_, _, c2, c3] = cubic.coefficients.map(f64::from);
    let curvature = |t: f64| (2.0 * c2 + 6.0 * c3 * t).abs();
    SeedCell {
        unit_seed: [
            t_start as f32,
            a as f32,
            (3.0 * secant - 2.0 * a - b) as f32,
            (a + b - 2.0 * secant) as f32,
        ],
        bound_kpa: bound_kpa(
            interval.width_kpa,
            curvature(reach_low).max(curvature(reach_high)),
            slope_min,
            slope_max,
        ),
    }
}

/// The fast path's error bound of an interval (module doc), from its f32 coefficients in f64;
/// infinite where the slope reaches 0.
fn error_bound_kpa(interval: &UnitInterval) -> f32 {
    let cubic = &interval.cubic;
    let (slope_min, slope_max) = cubic.slope_range(0.0, 1.0);
    bound_kpa(
        interval.width_kpa,
        cubic.curvature_max(),
        slope_min,
        slope_max,
    )
}

/// `B = w K M^2 / (2 m^3)` (module doc, stage 1) in f32; infinite where `m` is not positive or
/// `B` is too large to be of use.
fn bound_kpa(width_kpa: f32, curvature_max: f64, slope_min: f64, slope_max: f64) -> f32 {
    let bound = f64::from(width_kpa) * curvature_max * slope_max * slope_max
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::CurvePoint;

    /// Steps taken over `readings` evenly spread in `0 ..= top`: how many needed one Newton step,
    /// two, and the bracketed stage.
    fn steps_taken(curve: &CalibrationCurve, readings: usize) -> [usize; FAST_NEWTON_STEPS + 1] {
        let knots = CubicKnots::new(curve);
        let top = curve.top().relative_change;
        let mut counts = [0; FAST_NEWTON_STEPS + 1];
        for reading in 1..=readings {
            let relative_change = top * reading as f32 / readings as f32;
            let (_, steps) = knots.solve(curve, relative_change);
            if let Some(count) = counts.get_mut(steps.saturating_sub(1)) {
                *count += 1;
            }
        }
        counts
    }

    #[test]
    fn one_newton_step_from_the_seed_is_enough_on_the_articles_curve() {
        let counts = steps_taken(&CalibrationCurve::article_default(), 10_000);
        assert_eq!(counts, [10_000, 0, 0], "readings per number of steps");
    }

    #[test]
    fn one_newton_step_is_enough_on_ordinary_curves() {
        // Concave, saturating curves of 4 to 16 unequally spaced points, as a pad's calibration
        // gives them: at least 95 % of readings take one step, at most 0.1 % the bracketed stage
        // (a second step is judged by the interval's bound, which is loose on long intervals).
        let mut counts = [0usize; FAST_NEWTON_STEPS + 1];
        for points in 4..=16usize {
            for skew in [0.5f32, 1.0, 2.0] {
                let mut curve_points = [CurvePoint::new(0.0, 0.0); MAX_CURVE_POINTS];
                for (point, slot) in curve_points.iter_mut().enumerate().take(points) {
                    let share = libm::powf(point as f32 / (points - 1) as f32, skew);
                    let pressure_kpa = 50.0 * share;
                    *slot = CurvePoint::new(
                        pressure_kpa,
                        0.4 * (1.0 - libm::expf(-pressure_kpa / 15.0)),
                    );
                }
                let Ok(curve) = CalibrationCurve::new(&curve_points[..points], 0) else {
                    panic!("{points} points, skew {skew}: refused");
                };
                for (total, count) in counts.iter_mut().zip(steps_taken(&curve, 2_000)) {
                    *total += count;
                }
            }
        }
        let readings: usize = counts.iter().sum();
        assert!(
            counts[0] * 100 >= readings * 95 && counts[2] * 1_000 <= readings,
            "readings per number of steps (one, two, bracketed): {counts:?}"
        );
    }

    #[test]
    fn every_interval_has_cells_and_each_seed_runs_from_0_to_1_upward() {
        let curve = CalibrationCurve::article_default();
        let knots = CubicKnots::new(&curve);
        let intervals = curve.points().len() - 1;
        let mut next_first = 0;
        for data in &knots.intervals[..intervals] {
            assert_eq!(usize::from(data.first_cell), next_first);
            assert!(data.last_cell >= data.first_cell);
            next_first = usize::from(data.last_cell) + 1;
            let mut previous = -1.0e-6;
            for cell in
                &knots.seed_cells[usize::from(data.first_cell)..=usize::from(data.last_cell)]
            {
                for step in 0..=8 {
                    let seed = cell.seed(step as f32 / 8.0);
                    assert!(seed >= previous - 1.0e-6, "{seed} after {previous}");
                    previous = seed;
                }
            }
            assert!(
                (previous - 1.0).abs() < 1.0e-5,
                "the interval's seeds end at {previous}"
            );
        }
        assert_eq!(next_first, SEED_CELLS);
    }
}
