//! Building the monotone cubic tier's grid (module doc of `cubic`, stage 1), once per
//! calibration or tier change: each interval's cubic and bound, the warp, and per cell its seed
//! and the largest first step its bound accepts. The reading's path is in `cubic.rs`.

use super::{
    interval_index, solve_bracketed, CubicKnots, CubicSegment, IntervalData, MonotoneCubic,
    SeedCell, ACCEPTED_ERROR_KPA, INTERVAL_SLOTS, SEED_CELLS,
};
use crate::bounds::clamp_f32;
use crate::calibration::{CalibrationCurve, CurvePoint};
use crate::monotone_cubic::derivative_range;

/// The longest first step a cell accepts, kPa, whatever its bound (which is 0 on a straight
/// interval): the f32 rounding of a step's arithmetic grows with the step (about 2^-24 of it,
/// through the cubic's terms at its start), and is far below [`ACCEPTED_ERROR_KPA`] up to this.
const MAX_ACCEPTED_STEP_KPA: f32 = 4.0;

/// A cell's reach past its ends, and past its knot, in cells: far more than the rounding of a
/// reading's position (a few ulps of it).
const CELL_MARGIN: f64 = 0.01;

/// The roots' margin in a reach, as a fraction of the interval: they are solved to 2^-20 of it.
const ROOT_MARGIN: f64 = 1.0e-4;

/// The seed's margin in a reach, relative to the sum of its coefficients' magnitudes and the
/// top pressure: the f32 evaluation of a cubic, and of `s0`, errs by a few ulps of those.
const SEED_MARGIN: f64 = 1.0e-6;

/// The Chebyshev points of `0 ..= 1` for a cubic, `(1 - cos((2 k + 1) pi / 8)) / 2`.
const CHEBYSHEV_POINTS: [f64; 4] = [
    0.038_060_233_744_356_62,
    0.308_658_283_817_455_1,
    0.691_341_716_182_544_9,
    0.961_939_766_255_643_4,
];

impl CubicKnots {
    /// Each interval's cubic and error bound, and the seed grid.
    pub(crate) fn new(curve: &CalibrationCurve) -> Self {
        let top = curve.top();
        // No reading is above the top slot's +inf: a reading of the last interval's cells,
        // the top included, is below their knot.
        let top_slot = IntervalData {
            coefficients: [f32::INFINITY, 0.0, 0.0, 0.0],
            start_kpa: top.pressure_kpa,
            error_bound_kpa: f32::INFINITY,
        };
        let mut knots = Self {
            intervals: [top_slot; INTERVAL_SLOTS],
            warp: [0.0; 2],
            top_kpa: top.pressure_kpa,
            cells: [SeedCell::EMPTY; SEED_CELLS],
            #[cfg(all(feature = "batch", target_arch = "x86_64"))]
            lane_columns: super::LaneColumns::EMPTY,
        };
        let forward = MonotoneCubic::new(&curve.pressures_kpa(), &curve.relative_changes());
        for ((slot, segment), point) in knots
            .intervals
            .iter_mut()
            .zip(forward.segments())
            .zip(curve.points())
        {
            *slot = IntervalData {
                coefficients: segment.coefficients,
                start_kpa: point.pressure_kpa,
                error_bound_kpa: f32::INFINITY,
            };
        }
        for index in 0..INTERVAL_SLOTS {
            let bound = knots
                .segment(index)
                .map_or(f32::INFINITY, |(segment, _)| error_bound_kpa(&segment));
            if let Some(slot) = knots.intervals.get_mut(index) {
                slot.error_bound_kpa = bound;
            }
        }
        if top.relative_change > 0.0 {
            knots.warp = knots.warp(f64::from(top.relative_change));
            let points = curve.points();
            let cells: [SeedCell; SEED_CELLS] =
                core::array::from_fn(|cell| knots.seed_cell(points, cell));
            knots.cells = cells;
        }
        #[cfg(all(feature = "batch", target_arch = "x86_64"))]
        {
            knots.lane_columns = knots.gather_lane_columns();
        }
        knots
    }

    /// The grid's warp (module doc, stage 1), `a y / (1 - b y)` as `[1 / a, b / a]`: `b` such
    /// that the inverse's slope at the top over its slope at 0 is the warp's (within
    /// `1 / 16 ..= 16`), `a` such that the top is a little inside the last cell rather than past
    /// the grid.
    fn warp(&self, top: f64) -> [f32; 2] {
        let slope = |index: usize, local: f32| {
            self.segment(index)
                .map_or(0.0, |(segment, _)| f64::from(segment.slope_at(local)))
        };
        let last = self
            .intervals
            .iter()
            .filter(|data| data.coefficients[0].is_finite())
            .count();
        let end = self
            .segment(last.saturating_sub(1))
            .map_or(0.0, |(segment, _)| segment.width);
        // NaN (no slope at all) gives 1/16, a warp like any other.
        let ratio = clamp_f32(
            (slope(0, 0.0) / slope(last.saturating_sub(1), end)) as f32,
            1.0 / 16.0,
            16.0,
        );
        let b = (1.0 - 1.0 / f64::from(libm::sqrtf(ratio))) / top;
        let a = SEED_CELLS as f64 * (1.0 - 1.0 / 262_144.0) * (1.0 - b * top) / top;
        [(1.0 / a) as f32, (b / a) as f32]
    }

    /// The reading at position `position` of the grid (the warp's inverse), in f64.
    pub(super) fn unwarped(&self, position: f64) -> f64 {
        let [alpha, beta] = self.warp.map(f64::from);
        position * alpha / (1.0 + beta * position)
    }

    /// Cell `cell` of the seed grid (module doc, stage 1).
    fn seed_cell(&self, points: &[CurvePoint], cell: usize) -> SeedCell {
        let top = points
            .last()
            .map_or(0.0, |point| f64::from(point.relative_change));
        let [alpha, beta] = self.warp.map(f64::from);
        let at = |position: f64| self.unwarped(position).max(0.0).min(top);
        let root = |position: f64| {
            let relative_change = at(position) as f32;
            let index = interval_index(points, relative_change);
            self.root(index, relative_change)
                .map_or(f64::from(self.top_kpa), |(local, data)| {
                    f64::from(data.start_kpa) + local
                })
        };
        // Through the roots at the four Chebyshev points of the cell (Newton's divided
        // differences, expanded).
        let [u0, u1, u2, u3] = CHEBYSHEV_POINTS;
        let [p0, p1, p2, p3] = CHEBYSHEV_POINTS.map(|u| root(cell as f64 + u));
        let (d01, d12, d23) = (
            (p1 - p0) / (u1 - u0),
            (p2 - p1) / (u2 - u1),
            (p3 - p2) / (u3 - u2),
        );
        let (d012, d123) = ((d12 - d01) / (u2 - u0), (d23 - d12) / (u3 - u1));
        let d0123 = (d123 - d012) / (u3 - u0);
        let seed = [
            (p0 - u0 * d01 + u0 * u1 * d012 - u0 * u1 * u2 * d0123) as f32,
            (d01 - (u0 + u1) * d012 + (u0 * u1 + u0 * u2 + u1 * u2) * d0123) as f32,
            (d012 - (u0 + u1 + u2) * d0123) as f32,
            d0123 as f32,
        ];
        // The sides: the readings of the cell lie in `low ..= high`, below the knot in the
        // interval holding `low`, at or above it in the next.
        let (low, high) = (
            at(cell as f64 - CELL_MARGIN),
            at(cell as f64 + 1.0 + CELL_MARGIN),
        );
        let index = interval_index(points, low as f32);
        let last_inner = points.len().saturating_sub(2);
        let knot = points
            .get(index + 1)
            .map_or(top, |point| f64::from(point.relative_change));
        let inner_knots = points
            .iter()
            .enumerate()
            .filter(|(k, point)| {
                *k > index && *k <= last_inner && f64::from(point.relative_change) <= high
            })
            .count();
        let knot_position = knot / (alpha - beta * knot) - cell as f64;
        let below = (knot_position + CELL_MARGIN).clamp(0.0, 1.0);
        let above = (knot_position - CELL_MARGIN).clamp(0.0, 1.0);
        let below_limit = self.max_step_squared(index, (low, high.min(knot)), &seed, (0.0, below));
        let max_step_squared = match inner_knots {
            // No reading of the cell is at or above the knot (the top's slot is +inf).
            0 => below_limit,
            1 => {
                below_limit.min(self.max_step_squared(index + 1, (knot, high), &seed, (above, 1.0)))
            }
            // Past a second knot the readings belong to a later interval than the next.
            _ => f32::NEG_INFINITY,
        };
        SeedCell {
            seed,
            max_step_squared,
            interval: u8::try_from(index).unwrap_or(0),
        }
    }

    /// The root of `relative_change` in interval `index` (local pressure, to the bracket's
    /// resolution) and the interval's data.
    fn root(&self, index: usize, relative_change: f32) -> Option<(f64, &IntervalData)> {
        let (segment, data) = self.segment(index)?;
        let local = solve_bracketed(
            &segment,
            f32::INFINITY,
            0.0,
            relative_change,
            0.5 * segment.width,
        );
        Some((f64::from(local), data))
    }

    /// `ACCEPTED_ERROR_KPA / B` rounded down, `B` over the reach in interval `index` of a cell's
    /// readings in `low ..= high` and of the cell's seeds at positions `first ..= last` (module
    /// doc, stage 1); `-inf` where the reach's checks fail.
    fn max_step_squared(
        &self,
        index: usize,
        (low, high): (f64, f64),
        seed: &[f32; 4],
        (first, last): (f64, f64),
    ) -> f32 {
        let Some((segment, data)) = self.segment(index) else {
            return f32::NEG_INFINITY;
        };
        let (Some((low_root, _)), Some((high_root, _))) =
            (self.root(index, low as f32), self.root(index, high as f32))
        else {
            return f32::NEG_INFINITY;
        };
        let start_kpa = f64::from(data.start_kpa);
        let seed = seed.map(f64::from);
        let (seed_low, seed_high) = cubic_range(seed, first, last);
        let seed_margin = SEED_MARGIN
            * (seed.iter().map(|c| c.abs()).sum::<f64>() + f64::from(self.top_kpa).abs());
        let root_margin = ROOT_MARGIN * f64::from(segment.width);
        let reach_low = (low_root - root_margin).min(seed_low - start_kpa - seed_margin);
        let reach_high = (high_root + root_margin).max(seed_high - start_kpa + seed_margin);
        let cubic = segment.coefficients.map(f64::from);
        let [c0, c1, c2, c3] = cubic;
        let value = |s: f64| c0 + s * (c1 + s * (c2 + s * c3));
        // The reach holds the root of every reading of the side.
        if !(value(reach_low) <= low && value(reach_high) >= high) {
            return f32::NEG_INFINITY;
        }
        let (slope_min, slope_max) = derivative_range(cubic, reach_low, reach_high);
        let curvature = |s: f64| (2.0 * c2 + 6.0 * c3 * s).abs();
        let bound = bound_kpa(
            curvature(reach_low).max(curvature(reach_high)),
            slope_min,
            slope_max,
        );
        if bound.is_finite() {
            // Rounded down: the f32 product `step^2` and this limit's rounding stay on the
            // safe side of `B step^2 <= ACCEPTED_ERROR_KPA`.
            let limit = f64::from(ACCEPTED_ERROR_KPA) / f64::from(bound) * (1.0 - 1.0e-6);
            (limit as f32).min(MAX_ACCEPTED_STEP_KPA * MAX_ACCEPTED_STEP_KPA)
        } else {
            f32::NEG_INFINITY
        }
    }
}

/// Bounds of the cubic `coefficients` over `low ..= high`: its ends where it is monotone there,
/// else the ends widened by the largest slope times the width.
fn cubic_range(coefficients: [f64; 4], low: f64, high: f64) -> (f64, f64) {
    let [c0, c1, c2, c3] = coefficients;
    let value = |u: f64| c0 + u * (c1 + u * (c2 + u * c3));
    let (at_low, at_high) = (value(low), value(high));
    let (slope_min, slope_max) = derivative_range(coefficients, low, high);
    if slope_min >= 0.0 {
        (at_low, at_high)
    } else {
        let spread = (high - low) * slope_max.max(-slope_min);
        (at_low.min(at_high) - spread, at_low.max(at_high) + spread)
    }
}

/// The fast path's error bound of an interval (module doc), from its f32 coefficients in f64;
/// infinite where the slope reaches 0.
fn error_bound_kpa(segment: &CubicSegment) -> f32 {
    let (slope_min, slope_max) = segment.slope_range(0.0, f64::from(segment.width));
    bound_kpa(segment.curvature_max(), slope_min, slope_max)
}

/// `B = K M^2 / (2 m^3)` (module doc, stage 1) in f32; infinite where `m` is not positive or
/// `B` is too large to be of use.
fn bound_kpa(curvature_max: f64, slope_min: f64, slope_max: f64) -> f32 {
    let bound = curvature_max * slope_max * slope_max / (2.0 * slope_min * slope_min * slope_min);
    if slope_min > 0.0 && bound.is_finite() && bound < 1.0e30 {
        bound as f32
    } else {
        f32::INFINITY
    }
}
