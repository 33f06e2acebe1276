//! Monotone cubic tier: the inverse of the Fritsch–Carlson cubic dC/C0 = f(P) through the
//! calibration points, which is the model's reference curve, for every valid calibration.
//!
//! # Storage
//!
//! Per interval the tier keeps its cubic `f(s) = c0 + s (c1 + s (c2 + s c3))` in the local
//! pressure `s = P - P_k` (kPa), with [`crate::monotone_cubic::MonotoneCubic`]'s f32
//! coefficients (Fritsch–Carlson, computed in f64 and rounded; `c0` is the start point's
//! dC/C0), its start pressure `P_k` and the error bound of stage 1 over the whole interval; a
//! slot after the last interval holds the top pressure (the last interval's end) and `+inf` as
//! its dC/C0, and padding slots follow, so that the fast path's slot indexes need no bounds
//! check. A grid of [`SEED_CELLS`] cells over `0 ..= top` in dC/C0 keeps per cell a seed (the
//! pressure as a cubic of the position in the cell), the interval holding the cell's start and
//! the largest Newton step it accepts. That is 972 bytes a taxel, all computed when the
//! calibration or the tier is installed, so that a reading costs a division to find its cell,
//! one comparison for its interval, the seed, one Newton step with its division and one
//! comparison (the firmware's RAM holds it for eight pads: the pad model's size is asserted in
//! `pad.rs`).
//!
//! # Method
//!
//! On `0 ..= w` (`w = P_k+1 - P_k`) the cubic is non-decreasing (Fritsch–Carlson, up to the
//! rounding of its coefficients). The root of `f(s) = y` is found in two stages.
//!
//! 1. **Fast path: a seed from the grid, at most [`FAST_NEWTON_STEPS`] Newton steps, a proven
//!    error bound.** A reading `y` is at `p = y / (alpha - beta y)` cells of the grid, a warp
//!    that spends cells where the inverse is steep (`beta` gives it the ratio of the inverse's
//!    slopes at the top and at 0, within `1/16 ..= 16`; `alpha` puts the top a little inside
//!    the last cell). Its cell is `p` truncated (saturating: NaN is in the first; positions of
//!    -1 or less and past the grid are in none and take the rest of the search), `u` = `p` -
//!    cell (exact). The seed is the cell's cubic in `u`, the inverse's interpolant at the
//!    cell's four Chebyshev points. The interval is the cell's, or the next when `y` is at least
//!    the next slot's dC/C0: no search. A Newton step `s1 = s0 - r / f'(s0)` (`s0` = seed -
//!    `P_k`, not clamped; `r = f(s0) - y`) follows. With `m = min f'`, `M = max f'` and
//!    `K = max |f''|` over a range holding `s0` and the root `s*`, Taylor's theorem gives
//!    `|s1 - s*| <= K / (2 m) * (s0 - s*)^2` and the mean-value theorem
//!    `|s0 - s*| <= |r / f'(s0)| * M / m`; so `P_k + s1` is within `B * step^2` of the root,
//!    `B = K M^2 / (2 m^3)` (per kPa). For the first step the range is a side's reach (below
//!    the cell's knot in its interval, at or above it in the next), in f64 from the f32
//!    coefficients (the construction is in `grid.rs`, with the margins named here): the side's
//!    readings lie between those at the cell's ends widened by `CELL_MARGIN` (far more than
//!    the rounding of `p`), cut at the knot; their seeds within the seed cubic's bounds over
//!    the matching `u` (its ends where its derivative, a quadratic, is not negative) widened by
//!    `SEED_MARGIN` for the f32 evaluation of the seed and of `s0`; the reach is the hull of
//!    those and of the roots of the side's end readings widened by `ROOT_MARGIN`, past the
//!    interval's ends if need be (`f` is the same polynomial there). It is checked: `f` at its
//!    ends must straddle the side's readings and `m` must be positive, so that the root of
//!    every reading of the side is in it, unique. The cell keeps `ACCEPTED_ERROR_KPA / B` for
//!    the larger of its sides' `B`, rounded down so that the f32 test `step^2 <= limit`
//!    implies `B step^2 <= ACCEPTED_ERROR_KPA`, which holds in exact arithmetic whatever the
//!    seed; `-inf` (never met) where a check fails or a second knot is in the cell (past it
//!    the readings belong to a later interval). An accepted pressure, near a root in
//!    `0 ..= top`, is clamped there. Otherwise the interval is found
//!    by a scan from the cell's, and one more step, from the first step's result (or from the
//!    seed where the interval differs and the seed is closer) clamped into the interval, is
//!    judged by the interval's bound over `0 ..= w` (computed once, in f64). The seed only
//!    decides how often the first step is enough: for every reading of the article's curve, for
//!    at least 95 % of readings of ordinary concave calibrations (tested).
//! 2. **Safeguarded Newton in a bracket.** Otherwise (a nearly flat spot makes `m` tiny or zero,
//!    or the start was poor) the root is kept in a bracket `[low, high]` (`f(low) <= y <=
//!    f(high)`, initially the whole interval, whose ends are the answer when `y` is at or past
//!    them) that every evaluation narrows, starting from the fast path's last iterate. A Newton
//!    step is taken only when it lands strictly inside the bracket and the previous Newton step
//!    halved the bracket; otherwise the bracket is bisected. So the bracket at least halves
//!    every two iterations: after `2 n` iterations it is at most `2^-n` of the interval wide,
//!    and the loop stops when it is [`ACCEPTED_ERROR_KPA`] wide or `2^-20` of the interval,
//!    whichever is narrower (or at f32 resolution), within [`MAX_BRACKETED_ITERATIONS`]
//!    iterations whatever the calibration (which reach [`ACCEPTED_ERROR_KPA`] on intervals up
//!    to 160 kPa wide, `2^-24` of any wider one). Of the bracket's ends and middle, the one with
//!    the smallest residual is the answer. A Newton step that meets the interval's bound ends
//!    it earlier.
//!
//! The result is the root of the f32 cubic to within the bound above, plus what the f32
//! evaluation cannot resolve: a few ulps of `y`, and of the cubic's terms at the step's start,
//! times the local slope of the inverse `1 / f'`, and a few ulps of the pressure. (So that the
//! terms at the step's start stay near the root's, a first step longer than
//! `MAX_ACCEPTED_STEP_KPA` in `grid.rs` is never accepted.) Where `f'` is tiny (nearly equal
//! neighbouring calibration points) that is large, and it is a property of the calibration, not
//! of the method: see [`crate::conditioning`].

use super::{clamp_pressure, interval_index, interval_index_from, InverseCurve};
use crate::bounds::clamp_f32;
use crate::calibration::{CalibrationCurve, MAX_CURVE_POINTS};
use crate::monotone_cubic::{CubicSegment, MonotoneCubic};

mod grid;
#[cfg(all(feature = "batch", target_arch = "x86_64"))]
mod lanes;
#[cfg(all(feature = "batch", target_arch = "x86_64"))]
mod lanes512;

/// Largest error (kPa, exact arithmetic) accepted from a Newton step of the fast path.
pub const ACCEPTED_ERROR_KPA: f32 = 1.0e-5;

/// Cells of the seed grid (module doc, stage 1): enough that one Newton step from the seed
/// meets [`ACCEPTED_ERROR_KPA`] on ordinary calibrations, few enough for eight pads in the
/// firmware's RAM (24 bytes a cell, per taxel; 23 keep the tier under 1,000 bytes).
pub const SEED_CELLS: usize = 23;

/// Most Newton steps of the fast path before the bracketed stage takes over.
pub const FAST_NEWTON_STEPS: usize = 2;

/// The bracket stops narrowing at this fraction of the interval (2^-20), or at
/// [`ACCEPTED_ERROR_KPA`] where that is narrower.
const BRACKET_RELATIVE_WIDTH: f32 = 1.0 / 1_048_576.0;

/// Most iterations of the bracketed stage: the bracket halves at least every two iterations, so
/// 2 x 24 take an interval of up to 160 kPa to [`ACCEPTED_ERROR_KPA`] (any interval to 2^-24
/// of its width, past [`BRACKET_RELATIVE_WIDTH`]); two spare.
pub const MAX_BRACKETED_ITERATIONS: usize = 50;

/// Interval slots: every interval, the top point's, and padding, so that an interval index
/// masked with [`INTERVAL_MASK`], plus one, is always a slot (no bounds check on the fast path).
const INTERVAL_SLOTS: usize = MAX_CURVE_POINTS + 1;

/// See [`INTERVAL_SLOTS`].
const INTERVAL_MASK: usize = MAX_CURVE_POINTS - 1;

const _: () = assert!(MAX_CURVE_POINTS.is_power_of_two() && SEED_CELLS > 0);

/// What the monotone cubic tier keeps besides the curve's points.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CubicKnots {
    /// Per interval its cubic, start pressure and error bound; then the top point's slot.
    intervals: [IntervalData; INTERVAL_SLOTS],
    /// The grid's warp `[alpha, beta]`: a reading `y` is at `y / (alpha - beta y)` cells
    /// (module doc).
    warp: [f32; 2],
    /// The top point's pressure.
    top_kpa: f32,
    /// The seed grid over `0 ..= top` in dC/C0.
    cells: [SeedCell; SEED_CELLS],
    /// The cells and intervals as the host's vector forms look them up, made once with them.
    #[cfg(all(feature = "batch", target_arch = "x86_64"))]
    lane_columns: LaneColumns,
}

/// Entries of a vector lookup table: every cell of the grid, or every interval slot, padded
/// to what two AVX-512 registers (three AVX2 registers use the first 24) hold.
#[cfg(all(feature = "batch", target_arch = "x86_64"))]
const LANE_ENTRIES: usize = 32;

#[cfg(all(feature = "batch", target_arch = "x86_64"))]
const _: () = assert!(SEED_CELLS <= 24 && INTERVAL_SLOTS <= 24);

/// The cells' and the intervals' fields as columns, for the vector forms' lookup tables
/// (`lanes.rs`, `lanes512.rs`): per cell its seed's four coefficients, its largest accepted
/// step squared and its interval (the index's bits as an f32); per interval slot its cubic's
/// four coefficients and its start pressure. Entries past the cells' or slots' count are 0.
#[cfg(all(feature = "batch", target_arch = "x86_64"))]
#[derive(Debug, Clone, PartialEq)]
struct LaneColumns {
    cells: [[f32; LANE_ENTRIES]; 6],
    intervals: [[f32; LANE_ENTRIES]; 5],
}

#[cfg(all(feature = "batch", target_arch = "x86_64"))]
impl LaneColumns {
    const EMPTY: Self = Self {
        cells: [[0.0; LANE_ENTRIES]; 6],
        intervals: [[0.0; LANE_ENTRIES]; 5],
    };
}

/// What the tier keeps per interval (module doc, storage).
#[derive(Debug, Clone, Copy, PartialEq)]
struct IntervalData {
    /// `f(s)`'s coefficients in the local pressure `s` (kPa), constant (the start point's dC/C0)
    /// first: [`MonotoneCubic`]'s.
    coefficients: [f32; 4],
    /// Pressure at the interval's start, kPa.
    start_kpa: f32,
    /// `B = max|f''| max(f')^2 / (2 min(f')^3)` over the interval (per kPa, derivatives in the
    /// local pressure); infinite where `f'` reaches 0.
    error_bound_kpa: f32,
}

/// One cell of the seed grid.
#[derive(Debug, Clone, Copy, PartialEq)]
struct SeedCell {
    /// The seed pressure `c0 + u (c1 + u (c2 + u c3))` (kPa) at position `u` in the cell
    /// (`0 ..= 1`).
    seed: [f32; 4],
    /// The largest accepted `step^2` (kPa^2) of the first Newton step: `ACCEPTED_ERROR_KPA / B`
    /// over each side's reach (below the knot, at or above it), the smaller of the two, rounded
    /// down; `-inf` where no step is accepted.
    max_step_squared: f32,
    /// The interval holding the cell's start less its margin: that of its readings below the
    /// knot, which is the next interval's start.
    interval: u8,
}

impl SeedCell {
    const EMPTY: Self = Self {
        seed: [0.0; 4],
        max_step_squared: f32::NEG_INFINITY,
        interval: 0,
    };

    /// The seed at position `u` in the cell.
    #[inline(always)]
    fn seed(&self, u: f32) -> f32 {
        let [c0, c1, c2, c3] = self.seed;
        c0 + u * (c1 + u * (c2 + u * c3))
    }
}

/// One Newton step of `data`'s cubic from `seed_kpa` towards `relative_change`, not clamped
/// into the interval (the cell's bound holds over the reach of its seeds): the next pressure and
/// the step, kPa.
#[inline(always)]
fn newton_step(data: &IntervalData, seed_kpa: f32, relative_change: f32) -> (f32, f32) {
    let local = seed_kpa - data.start_kpa;
    // `f` and `f'` together by Horner's rule (the second column of the synthetic division).
    let [c0, c1, c2, c3] = data.coefficients;
    let high = c2 + local * c3;
    let middle = c1 + local * high;
    let slope = middle + local * (high + local * c3);
    let step = (c0 + local * middle - relative_change) / slope;
    (data.start_kpa + (local - step), step)
}

/// Why the first step gave no pressure, for the rest of the search: the reading's cell, the
/// first step's interval and that step's result (kPa).
type Miss = (usize, usize, f32);

/// [`Miss`] off the grid: no cell, no step.
const OFF_GRID: Miss = (SEED_CELLS, INTERVAL_SLOTS, 0.0);

impl CubicKnots {
    /// Interval `index`'s cubic as a segment and its data (`None` past the last interval).
    #[inline(always)]
    fn segment(&self, index: usize) -> Option<(CubicSegment, &IntervalData)> {
        let data = self.intervals.get(index)?;
        let next = self.intervals.get(index + 1)?;
        let width_kpa = next.start_kpa - data.start_kpa;
        // The top point's slot and the padding after it have zero width.
        let segment = CubicSegment {
            x_start: 0.0,
            width: width_kpa,
            coefficients: data.coefficients,
        };
        (width_kpa > 0.0).then_some((segment, data))
    }

    /// Pressure for a relative change (module doc: both stages). `curve` must be the one the
    /// knots were built from.
    #[inline]
    pub(crate) fn pressure_kpa(&self, curve: &CalibrationCurve, relative_change: f32) -> f32 {
        self.solve(curve, relative_change).0
    }

    /// [`CubicKnots::pressure_kpa`] for generic callers, compiled in their crate, which the
    /// firmware builds for size: outlining the fast path's short sequences into shared functions
    /// there costs the M4 more instructions (a call and a return each) than this one call.
    #[inline(never)]
    fn pressure_kpa_called(&self, curve: &CalibrationCurve, relative_change: f32) -> f32 {
        self.pressure_kpa(curve, relative_change)
    }

    /// A reading's position in the grid, in cells (module doc, stage 1).
    #[inline(always)]
    fn position(&self, relative_change: f32) -> f32 {
        let [alpha, beta] = self.warp;
        relative_change / (alpha - beta * relative_change)
    }

    /// The first Newton step from the reading's seed: the pressure when the cell's bound
    /// accepts it, else what the rest of the search needs. The scalar path and the host's batch
    /// both take it, so they agree bit for bit.
    #[inline(always)]
    fn first_step(&self, relative_change: f32) -> Result<f32, Miss> {
        let position = self.position(relative_change);
        // A negative position (a reading below 0, which truncation would put in the first cell
        // outside every cell's reach, or one past the warp's pole) and NaN are off the grid,
        // as positions past its end are.
        if !(position >= 0.0) {
            return Err(OFF_GRID);
        }
        // Through u32, which the M4 converts to and from in one instruction each and x86-64 in
        // a few (a u64, which usize is there, in many).
        let whole = position as u32;
        let cell_index = whole as usize;
        let Some(cell) = self.cells.get(cell_index) else {
            return Err(OFF_GRID);
        };
        let seed_kpa = cell.seed(position - whole as f32);
        // Masked, so that the slot and the next are in bounds without a check.
        let first = usize::from(cell.interval) & INTERVAL_MASK;
        let (Some(data), Some(next)) = (self.intervals.get(first), self.intervals.get(first + 1))
        else {
            return Err(OFF_GRID);
        };
        let above = relative_change >= next.coefficients[0];
        let data = if above { next } else { data };
        let (next_kpa, step) = newton_step(data, seed_kpa, relative_change);
        if step * step <= cell.max_step_squared {
            Ok(self.clamped_on_bits(next_kpa))
        } else {
            Err((cell_index, first + usize::from(above), next_kpa))
        }
    }

    /// An accepted step's pressure, within the bound of the root, which is in `0 ..= top`:
    /// clamped there on the bits, which takes fewer M4 instructions than comparing floats (an
    /// accepted step is not NaN; a non-negative f32 orders as its bits do, a negative one is
    /// negative as i32).
    #[inline(always)]
    fn clamped_on_bits(&self, pressure_kpa: f32) -> f32 {
        let bits = (pressure_kpa.to_bits() as i32).max(0);
        f32::from_bits(bits.min(self.top_kpa.to_bits() as i32) as u32)
    }

    /// [`CubicKnots::pressure_kpa`] with the number of Newton steps taken outside the bracketed
    /// stage (one more than [`FAST_NEWTON_STEPS`]: the bracketed stage ran).
    #[inline(always)]
    fn solve(&self, curve: &CalibrationCurve, relative_change: f32) -> (f32, usize) {
        match self.first_step(relative_change) {
            Ok(pressure_kpa) => (pressure_kpa, 1),
            Err((cell, interval, next_kpa)) => {
                self.solve_further(curve, relative_change, cell, interval, next_kpa)
            }
        }
    }

    /// The rest of the search when the first step was not accepted: the interval from a scan,
    /// at most [`FAST_NEWTON_STEPS`] `- 1` more steps judged by the interval's bound, then the
    /// bracketed stage. Apart from the hot path, which then keeps few values live.
    #[cold]
    #[inline(never)]
    fn solve_further(
        &self,
        curve: &CalibrationCurve,
        relative_change: f32,
        cell_index: usize,
        first_interval: usize,
        first_kpa: f32,
    ) -> (f32, usize) {
        let cell = self.cells.get(cell_index);
        let scan_from = cell.map_or(0, |cell| usize::from(cell.interval));
        let index = interval_index_from(curve.points(), relative_change, scan_from);
        let Some((segment, data)) = self.segment(index) else {
            return (0.0, 0);
        };
        let clamped = |kpa: f32| clamp_f32(kpa - data.start_kpa, 0.0, segment.width);
        let mut local = clamped(first_kpa);
        if index != first_interval {
            // The first step was in another interval's cubic: start from the seed instead where
            // that is closer.
            if let Some(cell) = cell {
                let position = self.position(relative_change);
                let seed = clamped(cell.seed(position - cell_index as f32));
                let residual = |local: f32| (segment.value_at(local) - relative_change).abs();
                if residual(seed) < residual(local) {
                    local = seed;
                }
            }
        }
        let bound = data.error_bound_kpa;
        for steps in 2..=FAST_NEWTON_STEPS {
            let step = (segment.value_at(local) - relative_change) / segment.slope_at(local);
            let next = clamp_f32(local - step, 0.0, segment.width);
            if bound * step * step <= ACCEPTED_ERROR_KPA {
                return (clamp_pressure(data.start_kpa + next, self.top_kpa), steps);
            }
            local = next;
        }
        let local = solve_bracketed(&segment, bound, ACCEPTED_ERROR_KPA, relative_change, local);
        (
            clamp_pressure(data.start_kpa + local, self.top_kpa),
            FAST_NEWTON_STEPS + 1,
        )
    }

    /// Pressures for many relative changes, in place: bit for bit what
    /// [`CubicKnots::pressure_kpa`] gives for each (tested), arranged for a host converting a
    /// recording. Where the CPU has AVX-512 (or AVX2), the first steps of sixteen (eight)
    /// readings at a time in vector instructions (`lanes512.rs`, `lanes.rs`; the batch inverse
    /// alone 1.50 ns a value with AVX-512, 2.50 with AVX2, about 7 as a plain loop), then
    /// [`CubicKnots::pressure_kpa`] itself for a reading whose first step is not accepted;
    /// elsewhere the first step of each in a plain loop, whose values' independent chains the
    /// core overlaps by itself.
    pub(crate) fn pressures_kpa(&self, curve: &CalibrationCurve, values: &mut [f32]) {
        // The crate's unsafe operations: calling a function compiled for an instruction set
        // extension, which Rust cannot prove the CPU has, after asking the CPU.
        #[cfg(all(feature = "batch", target_arch = "x86_64"))]
        if std::is_x86_feature_detected!("avx512f") {
            #[allow(unsafe_code)]
            // SAFETY: the CPU has AVX-512F (asked just above), the only feature the function
            // enables.
            unsafe {
                self.pressures_kpa_avx512(curve, values)
            };
            return;
        }
        #[cfg(all(feature = "batch", target_arch = "x86_64"))]
        if std::is_x86_feature_detected!("avx2") {
            #[allow(unsafe_code)]
            // SAFETY: the CPU has AVX2 (asked just above), the only feature the function enables.
            unsafe {
                self.pressures_kpa_avx2(curve, values)
            };
            return;
        }
        self.pressures_kpa_one_by_one(curve, values);
    }

    /// [`CubicKnots::pressures_kpa`] without vector instructions.
    fn pressures_kpa_one_by_one(&self, curve: &CalibrationCurve, values: &mut [f32]) {
        for value in values.iter_mut() {
            *value = match self.first_step(*value) {
                Ok(pressure_kpa) => pressure_kpa,
                Err(_) => self.pressure_kpa(curve, *value),
            };
        }
    }

    /// [`LaneColumns`] of these cells and intervals.
    #[cfg(all(feature = "batch", target_arch = "x86_64"))]
    fn gather_lane_columns(&self) -> LaneColumns {
        let mut columns = LaneColumns::EMPTY;
        for (index, cell) in self.cells.iter().enumerate() {
            let [s0, s1, s2, s3] = cell.seed;
            let values = [
                s0,
                s1,
                s2,
                s3,
                cell.max_step_squared,
                f32::from_bits(u32::from(cell.interval)),
            ];
            for (field, value) in columns.cells.iter_mut().zip(values) {
                if let Some(slot) = field.get_mut(index) {
                    *slot = value;
                }
            }
        }
        for (index, data) in self.intervals.iter().enumerate() {
            let [c0, c1, c2, c3] = data.coefficients;
            for (field, value) in columns
                .intervals
                .iter_mut()
                .zip([c0, c1, c2, c3, data.start_kpa])
            {
                if let Some(slot) = field.get_mut(index) {
                    *slot = value;
                }
            }
        }
        columns
    }

    /// [`CubicKnots::pressures_kpa`] with AVX2 (callable only where the CPU has it).
    #[cfg(all(feature = "batch", target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    fn pressures_kpa_avx2(&self, curve: &CalibrationCurve, values: &mut [f32]) {
        let tables = lanes::LaneTables::new(self);
        let one_register = tables.intervals_in_one_register();
        self.pressures_kpa_in_groups(curve, values, |readings| {
            let (answers, accepted) = if one_register {
                tables.first_steps::<1>(readings)
            } else {
                tables.first_steps::<3>(readings)
            };
            (answers, u64::from(accepted as u8))
        });
    }

    /// [`CubicKnots::pressures_kpa`] with AVX-512F (callable only where the CPU has it).
    #[cfg(all(feature = "batch", target_arch = "x86_64"))]
    #[target_feature(enable = "avx512f")]
    fn pressures_kpa_avx512(&self, curve: &CalibrationCurve, values: &mut [f32]) {
        let tables = lanes512::LaneTables::new(self);
        self.pressures_kpa_in_groups(curve, values, |readings| {
            let (answers, accepted) = tables.first_steps(readings);
            (answers, u64::from(accepted))
        });
    }

    /// The first steps of groups of up to 64 readings, `L` at a time by `first_steps` (which
    /// answers the readings whose step is accepted, keeps the others and gives a bit per
    /// accepted lane), with no branch between them, so that the core overlaps their long
    /// chains; then the rare readings whose step is not accepted, each through the rest of the
    /// search, and the readings past the last `L` one by one.
    #[cfg(all(feature = "batch", target_arch = "x86_64"))]
    #[inline(always)]
    fn pressures_kpa_in_groups<const L: usize>(
        &self,
        curve: &CalibrationCurve,
        values: &mut [f32],
        mut first_steps: impl FnMut(&[f32; L]) -> ([f32; L], u64),
    ) {
        let all_lanes = u64::MAX >> (u64::BITS as usize - L);
        for group in values.chunks_mut(u64::BITS as usize) {
            let mut rejected = 0u64;
            let mut chunks = group.chunks_exact_mut(L);
            for (index, chunk) in (&mut chunks).enumerate() {
                let mut readings = [0.0f32; L];
                for (reading, value) in readings.iter_mut().zip(chunk.iter()) {
                    *reading = *value;
                }
                let (answers, accepted) = first_steps(&readings);
                for (value, answer) in chunk.iter_mut().zip(answers) {
                    *value = answer;
                }
                rejected |= (!accepted & all_lanes) << (index * L);
            }
            self.pressures_kpa_one_by_one(curve, chunks.into_remainder());
            while rejected != 0 {
                if let Some(value) = group.get_mut(rejected.trailing_zeros() as usize) {
                    *value = self.pressure_kpa(curve, *value);
                }
                rejected &= rejected - 1;
            }
        }
    }

    /// Pressure for a relative change solved to the bracket's resolution, without the fast
    /// path's early acceptance (for the table tier's nodes).
    pub(crate) fn solved_pressure_kpa(
        &self,
        curve: &CalibrationCurve,
        relative_change: f32,
    ) -> f32 {
        let index = interval_index(curve.points(), relative_change);
        match self.segment(index) {
            Some((segment, data)) => {
                let local = solve_bracketed(
                    &segment,
                    data.error_bound_kpa,
                    0.0,
                    relative_change,
                    0.5 * segment.width,
                );
                clamp_pressure(data.start_kpa + local, self.top_kpa)
            }
            None => 0.0,
        }
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
    let (mut low, mut high) = (0.0f32, segment.width);
    // At or past an end of the interval the end is the answer (the cubic is non-decreasing on
    // it); NaN takes the start.
    let mut low_residual = segment.value_at(low) - y;
    if !(low_residual < 0.0) {
        return low;
    }
    let mut high_residual = segment.value_at(high) - y;
    if !(high_residual > 0.0) {
        return high;
    }
    let tolerance = (segment.width * BRACKET_RELATIVE_WIDTH).min(ACCEPTED_ERROR_KPA);
    // Bracket width when the last Newton step was taken (infinite after a bisection).
    let mut width_at_newton = f32::INFINITY;
    for _ in 0..MAX_BRACKETED_ITERATIONS {
        let residual = segment.value_at(s) - y;
        if residual > 0.0 {
            high = s;
            high_residual = residual;
        } else if residual < 0.0 {
            low = s;
            low_residual = residual;
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
    // Of the bracket's ends and its middle, the one whose residual is smallest: the bracket can
    // end just past a root the last iterate had all but met (an end at the root itself).
    let middle = 0.5 * (low + high);
    let middle_residual = (segment.value_at(middle) - y).abs();
    let (end, end_residual) = if -low_residual <= high_residual {
        (low, -low_residual)
    } else {
        (high, high_residual)
    };
    if middle_residual <= end_residual {
        middle
    } else {
        end
    }
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
        self.knots.pressure_kpa_called(&self.curve, relative_change)
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
    fn the_seeds_are_near_the_roots_and_each_cell_starts_in_its_interval() {
        let curve = CalibrationCurve::article_default();
        let knots = CubicKnots::new(&curve);
        let points = curve.points();
        for (index, cell) in knots.cells.iter().enumerate() {
            let start = points[usize::from(cell.interval)].relative_change;
            assert!(
                f64::from(start) <= knots.unwarped(index as f64),
                "cell {index}"
            );
            for step in 0..=64 {
                let u = step as f64 / 64.0;
                let relative_change = knots.unwarped(index as f64 + u) as f32;
                let solved = knots.solved_pressure_kpa(&curve, relative_change);
                let seed = cell.seed(u as f32);
                assert!(
                    (seed - solved).abs() < 0.02,
                    "cell {index} at {u}: {seed} vs {solved}"
                );
            }
            // The article's knots are more than a cell apart: every cell has a bound.
            assert!(cell.max_step_squared > 0.0, "cell {index}");
        }
        // The top is in the last cell, not past the grid.
        let top = curve.top();
        assert!(knots.position(top.relative_change) < SEED_CELLS as f32);
        assert!(knots.first_step(top.relative_change).is_ok());
        // The device's model; the host's batch keeps its vector lookup columns besides.
        #[cfg(all(feature = "batch", target_arch = "x86_64"))]
        let host_only = core::mem::size_of::<LaneColumns>();
        #[cfg(not(all(feature = "batch", target_arch = "x86_64")))]
        let host_only = 0;
        assert_eq!(core::mem::size_of::<CubicKnots>() - host_only, 972);
    }

    #[test]
    fn a_reading_below_zero_is_zero_pressure() {
        // The model classifies such readings before the inverse, but the inverse is public:
        // just below 0 a reading is in the first cell at a negative position (outside the
        // cells' proven reach), further below off the grid; either way it must give 0 kPa, as
        // the other tiers' clamp does.
        let curves = [
            CalibrationCurve::article_default(),
            CalibrationCurve::new(
                &[
                    CurvePoint::new(0.0, 0.0),
                    CurvePoint::new(1.0, 0.2),
                    CurvePoint::new(50.0, 0.25),
                ],
                0,
            )
            .unwrap_or_else(|_| panic!("refused")),
        ];
        for curve in &curves {
            let knots = CubicKnots::new(curve);
            for step in 1..=2_000 {
                let relative_change = -(step as f32) * 1.0e-5 * libm::powf(1.01, step as f32);
                let got = knots.pressure_kpa(curve, relative_change);
                assert!(got == 0.0, "{relative_change}: {got} kPa");
            }
            // At 0 itself the root is the curve's start: the step lands within rounding of it.
            for zero in [0.0f32, -0.0] {
                let got = knots.pressure_kpa(curve, zero);
                assert!(
                    (0.0..=ACCEPTED_ERROR_KPA).contains(&got),
                    "{zero}: {got} kPa"
                );
            }
            assert_eq!(knots.pressure_kpa(curve, f32::NEG_INFINITY), 0.0);
        }
    }

    /// A curve from its points' bit patterns (pressure, dC/C0).
    fn curve_of_bits(points: &[(u32, u32)]) -> CalibrationCurve {
        let points: heapless::Vec<CurvePoint, MAX_CURVE_POINTS> = points
            .iter()
            .map(|(pressure, change)| {
                CurvePoint::new(f32::from_bits(*pressure), f32::from_bits(*change))
            })
            .collect();
        CalibrationCurve::new(&points, 0).unwrap_or_else(|_| panic!("refused"))
    }

    #[cfg(all(feature = "batch", target_arch = "x86_64"))]
    #[test]
    fn the_vector_first_step_is_the_first_step() {
        // The host's AVX2 form accepts exactly the readings `first_step` accepts, with the
        // same bits, on the article's curve, the review's hard curves and concave curves of 4
        // to 16 points; over readings spread across the whole grid and beyond, every knot and
        // its neighbours, and NaN, infinities, zero, negatives and subnormals.
        let mut curves = std::vec![CalibrationCurve::article_default()];
        for points in [
            &[
                (0, 0),
                (0x3f06_829f, 0x3b87_2f4f),
                (0x42a5_4bfd, 0x3df4_ce74),
            ][..],
            &[
                (0, 0),
                (0x445b_c8fb, 0x3baf_dd7e),
                (0x446b_6f44, 0x3ddb_4972),
            ][..],
        ] {
            curves.push(curve_of_bits(points));
        }
        for points in 4..=16usize {
            let mut curve_points = [CurvePoint::new(0.0, 0.0); MAX_CURVE_POINTS];
            for (point, slot) in curve_points.iter_mut().enumerate().take(points) {
                let pressure_kpa = 50.0 * libm::powf(point as f32 / (points - 1) as f32, 1.5);
                *slot =
                    CurvePoint::new(pressure_kpa, 0.4 * (1.0 - libm::expf(-pressure_kpa / 15.0)));
            }
            if let Ok(curve) = CalibrationCurve::new(&curve_points[..points], 0) {
                curves.push(curve);
            }
        }
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut accepted = 0usize;
        let mut compared = 0usize;
        for curve in &curves {
            let knots = CubicKnots::new(curve);
            #[allow(unsafe_code)]
            // SAFETY: the CPU has AVX2 (asked above).
            let tables = unsafe { lanes::LaneTables::new(&knots) };
            #[allow(unsafe_code)]
            // SAFETY: made only where the CPU has AVX-512F (asked just here).
            let wide_tables = std::is_x86_feature_detected!("avx512f")
                .then(|| unsafe { lanes512::LaneTables::new(&knots) });
            let top = curve.top().relative_change;
            let mut readings = std::vec![
                f32::NAN,
                f32::INFINITY,
                f32::NEG_INFINITY,
                0.0,
                -0.0,
                -1.0e-6,
                -top,
                f32::MIN_POSITIVE,
                1.0e-40,
                top,
                2.0 * top,
                1.0e30,
                f32::MAX,
            ];
            for step in 0..=20_000u32 {
                readings.push(1.2 * top * step as f32 / 20_000.0);
            }
            for point in curve.points() {
                let bits = point.relative_change.to_bits();
                for offset in 0..4 {
                    readings.push(f32::from_bits(bits.wrapping_add(offset)));
                    readings.push(f32::from_bits(bits.wrapping_sub(offset)));
                }
            }
            // Each reading in every lane, among others.
            let mut lanes_of = std::vec::Vec::new();
            for (index, reading) in readings.iter().enumerate() {
                let mut lane_readings = [readings[(index * 7 + 3) % readings.len()]; lanes::LANES];
                lane_readings[index % lanes::LANES] = *reading;
                lanes_of.push((index % lanes::LANES, lane_readings));
            }
            for (lane, lane_readings) in lanes_of {
                let reading = lane_readings[lane];
                #[allow(unsafe_code)]
                // SAFETY: as above.
                let (pressures, accepted_bits) = if tables.intervals_in_one_register() {
                    let one = unsafe { tables.first_steps::<1>(&lane_readings) };
                    let three = unsafe { tables.first_steps::<3>(&lane_readings) };
                    assert_eq!(one.1, three.1, "{reading:e}");
                    for (one, three) in one.0.iter().zip(three.0) {
                        assert_eq!(one.to_bits(), three.to_bits(), "{reading:e}");
                    }
                    one
                } else {
                    unsafe { tables.first_steps::<3>(&lane_readings) }
                };
                let (lane_kpa, lane_accepted) = (pressures[lane], accepted_bits & (1 << lane) != 0);
                match knots.first_step(reading) {
                    Ok(kpa) => {
                        assert!(
                            lane_accepted,
                            "{reading:e}: the lane refused a step first_step took"
                        );
                        assert_eq!(lane_kpa.to_bits(), kpa.to_bits(), "{reading:e}");
                        accepted += 1;
                    }
                    Err(_) => {
                        assert!(!lane_accepted, "{reading:e}: the lane took a refused step");
                        assert_eq!(lane_kpa.to_bits(), reading.to_bits(), "kept: {reading:e}");
                    }
                }
                // AVX-512's sixteen lanes give what AVX2's eight give, the reading in two.
                if let Some(wide_tables) = &wide_tables {
                    let mut wide = [lane_readings[(lane + 1) % lanes::LANES]; lanes512::LANES];
                    wide[..lanes::LANES].copy_from_slice(&lane_readings);
                    wide[lanes::LANES + lane] = reading;
                    #[allow(unsafe_code)]
                    // SAFETY: the CPU has AVX-512F (asked above).
                    let (answers, accepted_bits) = unsafe { wide_tables.first_steps(&wide) };
                    for wide_lane in [lane, lanes::LANES + lane] {
                        let wide_accepted = accepted_bits & (1 << wide_lane) != 0;
                        assert_eq!(wide_accepted, lane_accepted, "{reading:e}");
                        assert_eq!(
                            answers[wide_lane].to_bits(),
                            lane_kpa.to_bits(),
                            "{reading:e}"
                        );
                    }
                }
                compared += 1;
            }
        }
        assert!(
            accepted * 10 >= compared * 8,
            "{accepted} of {compared} accepted"
        );
    }

    #[test]
    fn the_cases_an_independent_review_found_are_solved() {
        // Found against an f64 Fritsch-Carlson cubic and bisection, written apart from this
        // module; the references are that bisection's roots.
        // A reading just below 0 (at a negative position in the first cell) once took an
        // accepted first step to a false root of the cubic past its interval: 1.26 kPa.
        let curve = curve_of_bits(&[
            (0, 0),
            (0x3f06_829f, 0x3b87_2f4f),
            (0x42a5_4bfd, 0x3df4_ce74),
        ]);
        let knots = CubicKnots::new(&curve);
        assert_eq!(knots.pressure_kpa(&curve, f32::from_bits(0xbbcc_d927)), 0.0);
        // An 879 kPa first interval: the bracketed stage once gave its bracket's middle, 2^-21 of
        // the interval (4e-4 kPa) from the root at and just above 0.
        let curve = curve_of_bits(&[
            (0, 0),
            (0x445b_c8fb, 0x3baf_dd7e),
            (0x446b_6f44, 0x3ddb_4972),
        ]);
        let knots = CubicKnots::new(&curve);
        assert_eq!(knots.pressure_kpa(&curve, 0.0), 0.0);
        assert_eq!(knots.pressure_kpa(&curve, -1.0e-6), 0.0);
        let got = knots.pressure_kpa(&curve, f32::from_bits(0x3089_705f));
        assert!((got - 7.293_583_3e-3).abs() <= 1.0e-6, "{got}");
        // A straight interval has a bound of 0 and accepted any first step; pressures of 1e9
        // kPa made a step of 2,560 kPa whose rounding was 2.6e-4 kPa.
        let curve = curve_of_bits(&[
            (0, 0),
            (0x4ce6_ab0c, 0x3dbe_da18),
            (0x4d66_ab0c, 0x3e3e_da18),
            (0x4dad_0049, 0x3e8f_2392),
            (0x4de6_ab0c, 0x3ebe_da18),
            (0x4e10_2ae8, 0x3eee_909e),
            (0x4e2d_0049, 0x3f0f_2392),
            (0x4e49_d5ab, 0x3f26_fed5),
            (0x4e66_ab0c, 0x3f3e_da18),
            (0x4e81_c037, 0x3f56_b55b),
            (0x4e90_2ae8, 0x3f56_b5b8),
            (0x4e9e_9598, 0x3f56_b60a),
            (0x4ead_0049, 0x3f56_b6c6),
            (0x4ebb_6afa, 0x3f56_b760),
            (0x4ec9_d5ab, 0x3f56_b767),
            (0x4ed8_405b, 0x3f56_b775),
        ]);
        let knots = CubicKnots::new(&curve);
        let got = knots.pressure_kpa(&curve, f32::from_bits(0x2fdd_05ca));
        assert!((got - 0.521_744_44).abs() <= 2.0e-5, "{got}");
    }

    #[test]
    fn a_cell_with_several_knots_is_solved_by_the_rest_of_the_search() {
        // Points crowded into one cell: its readings past the first knot never take the first
        // step's result, and every reading still meets the bracket's answer.
        let points = [
            CurvePoint::new(0.0, 0.0),
            CurvePoint::new(20.0, 0.2),
            CurvePoint::new(20.5, 0.2010),
            CurvePoint::new(21.0, 0.2020),
            CurvePoint::new(50.0, 0.3),
        ];
        let Ok(curve) = CalibrationCurve::new(&points, 0) else {
            panic!("refused");
        };
        let knots = CubicKnots::new(&curve);
        assert!(knots.cells.iter().any(|cell| cell.max_step_squared < 0.0));
        // Held to the reference crate's f64 cubic, inverted by bisection (written apart from
        // this module).
        let Some(reference) = reference_curves::ForwardCubic::new(
            &points.map(|point| f64::from(point.pressure_kpa)),
            &points.map(|point| f64::from(point.relative_change)),
        ) else {
            panic!("the reference refused the curve");
        };
        for step in 0..=3_000 {
            let relative_change = 0.3 * step as f32 / 3_000.0;
            let got = knots.pressure_kpa(&curve, relative_change);
            let want = reference.pressure_kpa(f64::from(relative_change));
            assert!(
                (f64::from(got) - want).abs() <= 2.0e-4,
                "{relative_change}: {got} vs {want}"
            );
        }
    }
}
