//! Polynomial tier, built for speed: a least-squares polynomial of the monotone cubic's inverse,
//! P = u (c1 + u (c2 + ... u cD)) with u = (dC/C0) / top, evaluated by Horner's rule: one
//! multiply to scale, D multiply-adds, a clamp; no search, no table, no division.
//!
//! It has no constant term, so an unloaded taxel reads exactly 0 kPa. The fit is refused (the
//! tier is then unavailable) when the polynomial is not monotone over the curve.

use super::{clamp_pressure, InverseCurve, MonotoneCubicInverse};
use crate::calibration::CalibrationCurve;

/// Degree of the polynomial (see the tests for the measured error per degree).
pub const POLYNOMIAL_DEGREE: usize = 7;

/// Points of the reference inverse the polynomial is fitted to.
const FIT_POINTS: usize = 257;

/// Fitted inverse polynomial.
#[derive(Debug, Clone, PartialEq)]
pub struct PolynomialInverse {
    /// c1 ..= cD, lowest power first.
    coefficients: [f32; POLYNOMIAL_DEGREE],
    inverse_top_relative_change: f32,
    top_pressure_kpa: f32,
}

impl PolynomialInverse {
    /// Fits the polynomial of degree `POLYNOMIAL_DEGREE` to the reference inverse, or `None`
    /// when the result is not monotone or the system is singular.
    pub fn new(reference: &MonotoneCubicInverse, curve: &CalibrationCurve) -> Option<Self> {
        Self::with_degree::<POLYNOMIAL_DEGREE>(reference, curve).map(|coefficients| Self {
            coefficients,
            inverse_top_relative_change: 1.0 / curve.top().relative_change,
            top_pressure_kpa: curve.top().pressure_kpa,
        })
    }

    /// Least-squares coefficients c1 ..= cD of a degree-`D` fit (exposed for the degree study).
    pub fn with_degree<const D: usize>(
        reference: &MonotoneCubicInverse,
        curve: &CalibrationCurve,
    ) -> Option<[f32; D]> {
        let top_relative_change = curve.top().relative_change as f64;
        // Normal equations in f64 over the basis u^1 ..= u^D.
        let mut normal = [[0.0f64; D]; D];
        let mut right = [0.0f64; D];
        for point in 0..FIT_POINTS {
            let u = point as f64 / (FIT_POINTS - 1) as f64;
            let pressure_kpa = reference.pressure_kpa((u * top_relative_change) as f32) as f64;
            let mut powers = [0.0f64; D];
            let mut power = u;
            for slot in powers.iter_mut() {
                *slot = power;
                power *= u;
            }
            for ((normal_row, right_value), power_row) in
                normal.iter_mut().zip(right.iter_mut()).zip(powers.iter())
            {
                *right_value += power_row * pressure_kpa;
                for (value, power_column) in normal_row.iter_mut().zip(powers.iter()) {
                    *value += power_row * power_column;
                }
            }
        }
        let solution = solve(normal, right)?;
        // Monotone over the curve: the derivative must not go negative on a fine grid.
        for step in 0..=1000 {
            let u = step as f64 / 1000.0;
            let mut slope = 0.0;
            for (index, coefficient) in solution.iter().enumerate().rev() {
                slope = slope * u + (index + 1) as f64 * coefficient;
            }
            if slope < 0.0 {
                return None;
            }
        }
        let mut coefficients = [0.0f32; D];
        for (slot, value) in coefficients.iter_mut().zip(solution) {
            *slot = value as f32;
        }
        Some(coefficients)
    }
}

/// Gaussian elimination with partial pivoting; `None` for a singular system.
// Row operations read one row of the matrix while writing another: indices say it plainest.
// Every index here ranges over 0..D on arrays of length D (`column`, `row`, `inner` from `0..D`
// or `column + 1..D`, `pivot` from `(column..D)`), so none can be out of bounds.
#[allow(clippy::needless_range_loop, clippy::indexing_slicing)]
fn solve<const D: usize>(mut matrix: [[f64; D]; D], mut right: [f64; D]) -> Option<[f64; D]> {
    for column in 0..D {
        let pivot = (column..D).max_by(|a, b| {
            libm::fabs(matrix[*a][column]).total_cmp(&libm::fabs(matrix[*b][column]))
        })?;
        if !(libm::fabs(matrix[pivot][column]) > 1e-300) {
            return None;
        }
        matrix.swap(column, pivot);
        right.swap(column, pivot);
        for row in column + 1..D {
            let factor = matrix[row][column] / matrix[column][column];
            for inner in column..D {
                matrix[row][inner] -= factor * matrix[column][inner];
            }
            right[row] -= factor * right[column];
        }
    }
    let mut solution = [0.0f64; D];
    for row in (0..D).rev() {
        let mut sum = right[row];
        for inner in row + 1..D {
            sum -= matrix[row][inner] * solution[inner];
        }
        solution[row] = sum / matrix[row][row];
        if !solution[row].is_finite() {
            return None;
        }
    }
    Some(solution)
}

impl InverseCurve for PolynomialInverse {
    #[inline]
    fn pressure_kpa(&self, relative_change: f32) -> f32 {
        let u = relative_change * self.inverse_top_relative_change;
        let [lower @ .., highest] = self.coefficients;
        let mut pressure_kpa = highest;
        for coefficient in lower.iter().rev() {
            pressure_kpa = pressure_kpa * u + coefficient;
        }
        clamp_pressure(pressure_kpa * u, self.top_pressure_kpa)
    }
}
