//! The default inverse's first step for eight readings at once with AVX2, for the host's batch
//! path: [`CubicKnots::first_step`]'s operations in the same order on eight lanes, so the same
//! bits (tested), with the grid's and the intervals' lookups done by permuting their columns
//! held in registers instead of one load per reading (which the compiler's own vector form
//! does, and AVX2's gathers do no faster).

use core::arch::x86_64::{
    __m256, __m256i, _mm256_add_epi32, _mm256_add_ps, _mm256_and_ps, _mm256_and_si256,
    _mm256_blendv_ps, _mm256_castps256_ps128, _mm256_castps_si256, _mm256_castsi256_ps,
    _mm256_cmp_ps, _mm256_cmpgt_epi32, _mm256_cvtepi32_ps, _mm256_cvttps_epi32, _mm256_div_ps,
    _mm256_extractf128_ps, _mm256_max_epi32, _mm256_min_epi32, _mm256_movemask_ps, _mm256_mul_ps,
    _mm256_permutevar8x32_ps, _mm256_set1_epi32, _mm256_set1_ps, _mm256_setr_ps,
    _mm256_setzero_si256, _mm256_sub_epi32, _mm256_sub_ps, _mm_cvtss_f32, _mm_extract_ps,
    _CMP_GE_OQ, _CMP_LE_OQ, _CMP_LT_OQ,
};

use super::{CubicKnots, LaneColumns, INTERVAL_MASK, INTERVAL_SLOTS, LANE_ENTRIES, SEED_CELLS};

/// Readings a step takes together: eight f32 fill an AVX2 register.
pub(super) const LANES: usize = 8;

/// Entries of a [`Column`]: three registers of eight.
const ENTRIES: usize = 3 * LANES;

const _: () = assert!(SEED_CELLS <= ENTRIES && INTERVAL_SLOTS <= ENTRIES);

/// Up to [`ENTRIES`] values (one field of every cell, or of every interval) as three
/// registers, looked up for eight indices at once.
#[derive(Clone, Copy)]
struct Column([__m256; 3]);

/// The three registers' choice for eight indices: the second register's lanes (index 8 and
/// above) and the third's (16 and above), as blend masks.
#[derive(Clone, Copy)]
struct Parts {
    index: __m256i,
    second: __m256,
    third: __m256,
}

impl Parts {
    #[target_feature(enable = "avx2")]
    fn of(index: __m256i) -> Self {
        Self {
            index,
            second: _mm256_castsi256_ps(_mm256_cmpgt_epi32(index, _mm256_set1_epi32(7))),
            third: _mm256_castsi256_ps(_mm256_cmpgt_epi32(index, _mm256_set1_epi32(15))),
        }
    }
}

impl Column {
    /// The column of a table's first [`ENTRIES`] values.
    #[target_feature(enable = "avx2")]
    fn new(values: &[f32; LANE_ENTRIES]) -> Self {
        let [low, middle, high, _]: [[f32; LANES]; 4] = bytemuck::cast(*values);
        Self([
            bytemuck::cast(low),
            bytemuck::cast(middle),
            bytemuck::cast(high),
        ])
    }

    /// Lane by lane, the entry at the lane's index, which is below `8 * REGISTERS` (the
    /// entries past the first register are looked up only when `REGISTERS` says they can be).
    #[target_feature(enable = "avx2")]
    fn at<const REGISTERS: usize>(&self, parts: Parts) -> __m256 {
        let [low, middle, high] = self.0;
        let low = _mm256_permutevar8x32_ps(low, parts.index);
        if REGISTERS == 1 {
            return low;
        }
        let middle = _mm256_permutevar8x32_ps(middle, parts.index);
        let low = _mm256_blendv_ps(low, middle, parts.second);
        if REGISTERS == 2 {
            return low;
        }
        let high = _mm256_permutevar8x32_ps(high, parts.index);
        _mm256_blendv_ps(low, high, parts.third)
    }
}

/// A [`CubicKnots`]' cells and intervals as columns, made once per batch of readings.
pub(super) struct LaneTables {
    /// The warp's `alpha` and `beta`, in every lane.
    alpha: __m256,
    beta: __m256,
    /// The cells' seed coefficients, largest accepted step squared and interval (its bits).
    seed: [Column; 4],
    max_step_squared: Column,
    interval: Column,
    /// The intervals' coefficients and start pressures.
    coefficients: [Column; 4],
    start_kpa: Column,
    /// The top point's pressure, as i32 bits, in every lane.
    top_bits: __m256i,
    /// The interval slots a step can look up: up to the largest of the cells' intervals and
    /// the one after it.
    interval_slots: usize,
}

impl LaneTables {
    /// `knots`' tables.
    #[target_feature(enable = "avx2")]
    pub(super) fn new(knots: &CubicKnots) -> Self {
        let LaneColumns {
            cells: [s0, s1, s2, s3, max_step_squared, interval],
            intervals: [c0, c1, c2, c3, start_kpa],
        } = &knots.lane_columns;
        let [alpha, beta] = knots.warp;
        Self {
            alpha: _mm256_set1_ps(alpha),
            beta: _mm256_set1_ps(beta),
            seed: [
                Column::new(s0),
                Column::new(s1),
                Column::new(s2),
                Column::new(s3),
            ],
            max_step_squared: Column::new(max_step_squared),
            interval: Column::new(interval),
            coefficients: [
                Column::new(c0),
                Column::new(c1),
                Column::new(c2),
                Column::new(c3),
            ],
            start_kpa: Column::new(start_kpa),
            top_bits: _mm256_set1_epi32(knots.top_kpa.to_bits() as i32),
            interval_slots: knots
                .cells
                .iter()
                .map(|cell| (usize::from(cell.interval) & INTERVAL_MASK) + 2)
                .max()
                .unwrap_or(ENTRIES),
        }
    }

    /// Whether the intervals' slots that a step can look up fit one register: on curves of up
    /// to eight points, the usual ones, whose steps then take a third of the lookups' permutes ([`LaneTables::first_steps`] with
    /// `INTERVALS` 1; else 3).
    pub(super) fn intervals_in_one_register(&self) -> bool {
        self.interval_slots <= LANES
    }

    /// [`CubicKnots::first_step`] of eight readings: where the cell's bound accepts the step
    /// (exactly where `first_step` gives `Ok`) its pressure (the same bits), elsewhere the
    /// reading itself, for the rest of the search; and a bit per lane set where it accepts.
    /// `INTERVALS`: the registers the intervals' slots take (1 only when
    /// [`LaneTables::intervals_in_one_register`]).
    #[target_feature(enable = "avx2")]
    pub(super) fn first_steps<const INTERVALS: usize>(
        &self,
        readings: &[f32; LANES],
    ) -> ([f32; LANES], i32) {
        let [r0, r1, r2, r3, r4, r5, r6, r7] = *readings;
        let y = _mm256_setr_ps(r0, r1, r2, r3, r4, r5, r6, r7);
        let position = _mm256_div_ps(y, _mm256_sub_ps(self.alpha, _mm256_mul_ps(self.beta, y)));
        // On the grid: `0 <= position < SEED_CELLS` (NaN is not), where truncation gives the
        // same whole cells as `first_step`'s u32.
        let on_grid = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GE_OQ>(position, _mm256_set1_ps(0.0)),
            _mm256_cmp_ps::<_CMP_LT_OQ>(position, _mm256_set1_ps(SEED_CELLS as f32)),
        );
        let zero = _mm256_setzero_si256();
        let whole = _mm256_min_epi32(
            _mm256_max_epi32(_mm256_cvttps_epi32(position), zero),
            _mm256_set1_epi32(SEED_CELLS as i32 - 1),
        );
        let cell = Parts::of(whole);
        let u = _mm256_sub_ps(position, _mm256_cvtepi32_ps(whole));
        let [s0, s1, s2, s3] = self.seed.map(|column| column.at::<3>(cell));
        let seed_kpa = _mm256_add_ps(
            s0,
            _mm256_mul_ps(
                u,
                _mm256_add_ps(
                    s1,
                    _mm256_mul_ps(u, _mm256_add_ps(s2, _mm256_mul_ps(u, s3))),
                ),
            ),
        );
        let first = _mm256_and_si256(
            _mm256_castps_si256(self.interval.at::<3>(cell)),
            _mm256_set1_epi32(INTERVAL_MASK as i32),
        );
        let next_start = self.coefficients[0]
            .at::<INTERVALS>(Parts::of(_mm256_add_epi32(first, _mm256_set1_epi32(1))));
        // A lane's mask is -1 where the reading is at or past the knot: one interval further.
        let above = _mm256_cmp_ps::<_CMP_GE_OQ>(y, next_start);
        let data = Parts::of(_mm256_sub_epi32(first, _mm256_castps_si256(above)));
        let [c0, c1, c2, c3] = self.coefficients.map(|column| column.at::<INTERVALS>(data));
        let start_kpa = self.start_kpa.at::<INTERVALS>(data);
        // `newton_step`.
        let local = _mm256_sub_ps(seed_kpa, start_kpa);
        let high = _mm256_add_ps(c2, _mm256_mul_ps(local, c3));
        let middle = _mm256_add_ps(c1, _mm256_mul_ps(local, high));
        let slope = _mm256_add_ps(
            middle,
            _mm256_mul_ps(local, _mm256_add_ps(high, _mm256_mul_ps(local, c3))),
        );
        let step = _mm256_div_ps(
            _mm256_sub_ps(_mm256_add_ps(c0, _mm256_mul_ps(local, middle)), y),
            slope,
        );
        let next_kpa = _mm256_add_ps(start_kpa, _mm256_sub_ps(local, step));
        let accepted = _mm256_and_ps(
            on_grid,
            _mm256_cmp_ps::<_CMP_LE_OQ>(
                _mm256_mul_ps(step, step),
                self.max_step_squared.at::<3>(cell),
            ),
        );
        // `clamped_on_bits`.
        let bits = _mm256_min_epi32(
            _mm256_max_epi32(_mm256_castps_si256(next_kpa), zero),
            self.top_bits,
        );
        let answers = _mm256_blendv_ps(y, _mm256_castsi256_ps(bits), accepted);
        (lanes(answers), _mm256_movemask_ps(accepted))
    }
}

/// A register's eight values.
#[target_feature(enable = "avx2")]
fn lanes(values: __m256) -> [f32; LANES] {
    let low = _mm256_castps256_ps128(values);
    let high = _mm256_extractf128_ps::<1>(values);
    let bits = |value: i32| f32::from_bits(value as u32);
    [
        _mm_cvtss_f32(low),
        bits(_mm_extract_ps::<1>(low)),
        bits(_mm_extract_ps::<2>(low)),
        bits(_mm_extract_ps::<3>(low)),
        _mm_cvtss_f32(high),
        bits(_mm_extract_ps::<1>(high)),
        bits(_mm_extract_ps::<2>(high)),
        bits(_mm_extract_ps::<3>(high)),
    ]
}
