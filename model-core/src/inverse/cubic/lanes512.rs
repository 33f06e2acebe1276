//! The default inverse's first step for sixteen readings at once with AVX-512: `lanes.rs`'s
//! step (the same operations in the same order as [`CubicKnots::first_step`], so the same bits;
//! tested) on registers twice as wide, where one permute looks an entry up among 32 (every cell
//! of the grid, every interval slot) instead of three permutes and two blends among 24.

use core::arch::x86_64::{
    __m512, __m512i, __mmask16, _mm512_add_epi32, _mm512_add_ps, _mm512_and_si512,
    _mm512_castps_si512, _mm512_castsi512_ps, _mm512_cmp_ps_mask, _mm512_cvtepi32_ps,
    _mm512_cvttps_epi32, _mm512_div_ps, _mm512_mask_add_epi32, _mm512_mask_blend_ps,
    _mm512_max_epi32, _mm512_min_epi32, _mm512_mul_ps, _mm512_permutex2var_ps, _mm512_set1_epi32,
    _mm512_set1_ps, _mm512_setzero_si512, _mm512_sub_ps, _CMP_GE_OQ, _CMP_LE_OQ, _CMP_LT_OQ,
};

use super::{CubicKnots, LaneColumns, INTERVAL_MASK, INTERVAL_SLOTS, LANE_ENTRIES, SEED_CELLS};

/// Readings a step takes together: sixteen f32 fill an AVX-512 register.
pub(super) const LANES: usize = 16;

/// Entries of a [`Table`]: two registers of sixteen.
const ENTRIES: usize = 2 * LANES;

const _: () = assert!(ENTRIES == LANE_ENTRIES);

const _: () = assert!(SEED_CELLS <= ENTRIES && INTERVAL_SLOTS <= ENTRIES);

/// Up to [`ENTRIES`] values (one field of every cell, or of every interval) as two registers,
/// looked up for sixteen indices by one permute.
#[derive(Clone, Copy)]
struct Table([__m512; 2]);

impl Table {
    /// The table of a column's [`ENTRIES`] values.
    #[target_feature(enable = "avx512f")]
    fn new(values: &[f32; ENTRIES]) -> Self {
        let [low, high]: [[f32; LANES]; 2] = bytemuck::cast(*values);
        Self([bytemuck::cast(low), bytemuck::cast(high)])
    }

    /// Lane by lane, the entry at the lane's index (below [`ENTRIES`]).
    #[target_feature(enable = "avx512f")]
    fn at(&self, index: __m512i) -> __m512 {
        _mm512_permutex2var_ps(self.0[0], index, self.0[1])
    }
}

/// A [`CubicKnots`]' cells and intervals as tables, made once per batch of readings.
pub(super) struct LaneTables {
    alpha: __m512,
    beta: __m512,
    seed: [Table; 4],
    max_step_squared: Table,
    interval: Table,
    coefficients: [Table; 4],
    start_kpa: Table,
    top_bits: __m512i,
}

impl LaneTables {
    /// `knots`' tables.
    #[target_feature(enable = "avx512f")]
    pub(super) fn new(knots: &CubicKnots) -> Self {
        let LaneColumns {
            cells: [s0, s1, s2, s3, max_step_squared, interval],
            intervals: [c0, c1, c2, c3, start_kpa],
        } = &knots.lane_columns;
        let [alpha, beta] = knots.warp;
        Self {
            alpha: _mm512_set1_ps(alpha),
            beta: _mm512_set1_ps(beta),
            seed: [
                Table::new(s0),
                Table::new(s1),
                Table::new(s2),
                Table::new(s3),
            ],
            max_step_squared: Table::new(max_step_squared),
            interval: Table::new(interval),
            coefficients: [
                Table::new(c0),
                Table::new(c1),
                Table::new(c2),
                Table::new(c3),
            ],
            start_kpa: Table::new(start_kpa),
            top_bits: _mm512_set1_epi32(knots.top_kpa.to_bits() as i32),
        }
    }

    /// [`CubicKnots::first_step`] of sixteen readings: where the cell's bound accepts the step
    /// (exactly where `first_step` gives `Ok`) its pressure (the same bits), elsewhere the
    /// reading itself, for the rest of the search; and a bit per lane set where it accepts.
    #[target_feature(enable = "avx512f")]
    pub(super) fn first_steps(&self, readings: &[f32; LANES]) -> ([f32; LANES], __mmask16) {
        let y: __m512 = bytemuck::cast(*readings);
        let position = _mm512_div_ps(y, _mm512_sub_ps(self.alpha, _mm512_mul_ps(self.beta, y)));
        // On the grid: `0 <= position < SEED_CELLS` (NaN is not), where truncation gives the
        // same whole cells as `first_step`'s u32.
        let on_grid = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(position, _mm512_set1_ps(0.0))
            & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(position, _mm512_set1_ps(SEED_CELLS as f32));
        let zero = _mm512_setzero_si512();
        let cell = _mm512_min_epi32(
            _mm512_max_epi32(_mm512_cvttps_epi32(position), zero),
            _mm512_set1_epi32(SEED_CELLS as i32 - 1),
        );
        let u = _mm512_sub_ps(position, _mm512_cvtepi32_ps(cell));
        let [s0, s1, s2, s3] = self.seed.map(|table| table.at(cell));
        let seed_kpa = _mm512_add_ps(
            s0,
            _mm512_mul_ps(
                u,
                _mm512_add_ps(
                    s1,
                    _mm512_mul_ps(u, _mm512_add_ps(s2, _mm512_mul_ps(u, s3))),
                ),
            ),
        );
        let first = _mm512_and_si512(
            _mm512_castps_si512(self.interval.at(cell)),
            _mm512_set1_epi32(INTERVAL_MASK as i32),
        );
        let one = _mm512_set1_epi32(1);
        let next_start = self.coefficients[0].at(_mm512_add_epi32(first, one));
        // One interval further where the reading is at or past the knot.
        let above = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(y, next_start);
        let data = _mm512_mask_add_epi32(first, above, first, one);
        let [c0, c1, c2, c3] = self.coefficients.map(|table| table.at(data));
        let start_kpa = self.start_kpa.at(data);
        // `newton_step`.
        let local = _mm512_sub_ps(seed_kpa, start_kpa);
        let high = _mm512_add_ps(c2, _mm512_mul_ps(local, c3));
        let middle = _mm512_add_ps(c1, _mm512_mul_ps(local, high));
        let slope = _mm512_add_ps(
            middle,
            _mm512_mul_ps(local, _mm512_add_ps(high, _mm512_mul_ps(local, c3))),
        );
        let step = _mm512_div_ps(
            _mm512_sub_ps(_mm512_add_ps(c0, _mm512_mul_ps(local, middle)), y),
            slope,
        );
        let next_kpa = _mm512_add_ps(start_kpa, _mm512_sub_ps(local, step));
        let accepted = on_grid
            & _mm512_cmp_ps_mask::<_CMP_LE_OQ>(
                _mm512_mul_ps(step, step),
                self.max_step_squared.at(cell),
            );
        // `clamped_on_bits`.
        let bits = _mm512_min_epi32(
            _mm512_max_epi32(_mm512_castps_si512(next_kpa), zero),
            self.top_bits,
        );
        let answers = _mm512_mask_blend_ps(accepted, y, _mm512_castsi512_ps(bits));
        (bytemuck::cast(answers), accepted)
    }
}
