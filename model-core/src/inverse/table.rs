//! Table tier, built for speed: the monotone cubic's inverse sampled on a uniform grid of
//! relative change, linearly interpolated. One multiply, one conversion, two small loads, one
//! multiply-add, one scale; no search, no division.
//!
//! Each node's pressure is kept as a 24-bit fraction of the top pressure (units of
//! `top * 2^-24`), which is what lets a pad hold the table in 200 bytes per taxel: a node is
//! within `top * 2^-25` of the sampled inverse (1.5e-6 kPa on a 50 kPa curve, less than half an
//! f32 ulp of the top pressure), so the table's error against the cubic, its interpolation
//! error, is what it was with f32 nodes. The first node is 0 and the last the top pressure,
//! exactly.

use super::{clamp_pressure, InverseCurve};
use crate::bounds::clamp_f32;

/// Grid intervals over `0 ..= top relative change`.
pub const TABLE_INTERVALS: usize = 64;

/// The code of the top pressure: the last node, which is not stored.
const FULL_SCALE_CODE: u32 = 1 << 24;

/// Uniform table of the inverse.
#[derive(Debug, Clone, PartialEq)]
pub struct TableInverse {
    /// Nodes `0 .. TABLE_INTERVALS` in units of `kpa_per_code`, 24-bit little-endian; the last
    /// node is [`FULL_SCALE_CODE`].
    codes: [[u8; 3]; TABLE_INTERVALS],
    /// The top pressure times 2^-24 (exact).
    kpa_per_code: f32,
    intervals_per_relative_change: f32,
}

impl TableInverse {
    /// Samples an inverse at the grid's relative changes; the first node is the origin and the
    /// last the top point.
    pub(crate) fn sampled(
        inverse: impl Fn(f32) -> f32,
        top_relative_change: f32,
        top_pressure_kpa: f32,
    ) -> Self {
        let codes_per_kpa = f64::from(FULL_SCALE_CODE) / f64::from(top_pressure_kpa);
        let mut codes = [[0u8; 3]; TABLE_INTERVALS];
        // The curve's start is known exactly: node 0 stays (0, 0).
        for (index, slot) in codes.iter_mut().enumerate().skip(1) {
            let pressure_kpa = inverse(Self::node_relative_change(index, top_relative_change));
            let code = libm::round(f64::from(pressure_kpa) * codes_per_kpa)
                .clamp(0.0, f64::from(FULL_SCALE_CODE - 1)) as u32;
            let [low, middle, high, _] = code.to_le_bytes();
            *slot = [low, middle, high];
        }
        Self {
            codes,
            kpa_per_code: top_pressure_kpa / FULL_SCALE_CODE as f32,
            intervals_per_relative_change: TABLE_INTERVALS as f32 / top_relative_change,
        }
    }

    /// The relative change of grid node `index`.
    pub(crate) fn node_relative_change(index: usize, top_relative_change: f32) -> f32 {
        (top_relative_change as f64 * index as f64 / TABLE_INTERVALS as f64) as f32
    }

    /// The grid cell of a relative change and the fraction into it (NaN goes to cell 0).
    #[inline(always)]
    fn cell(&self, relative_change: f32) -> (usize, f32) {
        let position = clamp_f32(
            relative_change * self.intervals_per_relative_change,
            0.0,
            TABLE_INTERVALS as f32,
        );
        // Within 0 ..= TABLE_INTERVALS, so is the index (a saturating conversion).
        let index = position as usize;
        (index, position - index as f32)
    }

    /// Node `index`'s code as f32 (exact: at most 2^24).
    #[inline(always)]
    fn code(&self, index: usize) -> f32 {
        match self.codes.get(index) {
            Some(&[low, middle, high]) => u32::from_le_bytes([low, middle, high, 0]) as f32,
            None => FULL_SCALE_CODE as f32,
        }
    }
}

impl InverseCurve for TableInverse {
    #[inline]
    fn pressure_kpa(&self, relative_change: f32) -> f32 {
        let (index, fraction) = self.cell(relative_change);
        let (low, high) = (self.code(index), self.code(index + 1));
        clamp_pressure(
            (low + fraction * (high - low)) * self.kpa_per_code,
            FULL_SCALE_CODE as f32 * self.kpa_per_code,
        )
    }
}
