//! Independent f64 implementations of every tier's model, for the golden vectors: none of
//! model-core's f32 code is used, only the calibration points it holds (widened from f32, since
//! those are the numbers the firmware has).
//!
//! - reference curve: the Fritsch–Carlson monotone cubic, forward dC/C0 = f(P), in Hermite form,
//!   inverted by bisection: `reference_curves::ForwardCubic`, the one definition shared with
//!   model-core's host tests and the fuzz target;
//! - linear: the secant from the origin to the top point;
//! - piecewise linear: secants between the points;
//! - saturating: dC/C0 = A (1 - exp(-P / B)) fitted by least squares (A exact for each B, B by
//!   golden-section search on ln B), inverted in closed form P = B ln(A / (A - y));
//! - table: 64 uniform intervals of the reference inverse sampled in f64, interpolated in f64.

use model_core::Tier;
pub use reference_curves::ForwardCubic;

/// Intervals of the table tier (model-core's `TABLE_INTERVALS`).
pub const TABLE_INTERVALS: usize = 64;

/// Least-squares fit of dC/C0 = A (1 - exp(-P / B)): (A, B in kPa).
fn saturating_fit(pressures_kpa: &[f64], relative_changes: &[f64]) -> (f64, f64) {
    let asymptote_and_error = |scale_kpa: f64| {
        let shapes: Vec<f64> = pressures_kpa
            .iter()
            .map(|pressure| 1.0 - (-pressure / scale_kpa).exp())
            .collect();
        let numerator: f64 = shapes
            .iter()
            .zip(relative_changes)
            .map(|(shape, y)| shape * y)
            .sum();
        let denominator: f64 = shapes.iter().map(|shape| shape * shape).sum();
        let asymptote = numerator / denominator;
        let squared: f64 = shapes
            .iter()
            .zip(relative_changes)
            .map(|(shape, y)| (asymptote * shape - y).powi(2))
            .sum();
        (asymptote, squared)
    };
    let (mut low, mut high) = (0.1f64.ln(), 1.0e5f64.ln());
    let ratio = (5.0f64.sqrt() - 1.0) / 2.0;
    for _ in 0..300 {
        let left = high - ratio * (high - low);
        let right = low + ratio * (high - low);
        if asymptote_and_error(left.exp()).1 < asymptote_and_error(right.exp()).1 {
            high = right;
        } else {
            low = left;
        }
    }
    let scale_kpa = (0.5 * (low + high)).exp();
    (asymptote_and_error(scale_kpa).0, scale_kpa)
}

/// Every tier's model in f64.
pub struct References {
    forward: ForwardCubic,
    pressures_kpa: Vec<f64>,
    relative_changes: Vec<f64>,
    asymptote: f64,
    scale_kpa: f64,
    table_kpa: Vec<f64>,
    polynomial: Vec<f64>,
}

/// Degree of the polynomial tier (model-core's `POLYNOMIAL_DEGREE`).
const POLYNOMIAL_DEGREE: usize = 7;

/// Least-squares c1 ..= cD of P = sum c_k u^k, u = dC/C0 / top, no constant term, over 257
/// points of the f64 reference inverse: the polynomial tier's model, fitted independently in f64
/// (normal equations, Gaussian elimination with partial pivoting).
// Row operations read one row of the matrix while writing another: indices say it plainest.
#[allow(clippy::needless_range_loop)]
fn polynomial_fit(forward: &ForwardCubic, top_relative: f64) -> Vec<f64> {
    const POINTS: usize = 257;
    let degree = POLYNOMIAL_DEGREE;
    let mut matrix = vec![vec![0.0f64; degree + 1]; degree];
    for point in 0..POINTS {
        let u = point as f64 / (POINTS - 1) as f64;
        let pressure = forward.pressure_kpa(u * top_relative);
        let powers: Vec<f64> = (1..=degree).map(|power| u.powi(power as i32)).collect();
        for row in 0..degree {
            for column in 0..degree {
                matrix[row][column] += powers[row] * powers[column];
            }
            matrix[row][degree] += powers[row] * pressure;
        }
    }
    for column in 0..degree {
        let pivot = (column..degree)
            .max_by(|a, b| {
                matrix[*a][column]
                    .abs()
                    .total_cmp(&matrix[*b][column].abs())
            })
            .unwrap_or(column);
        matrix.swap(column, pivot);
        for row in column + 1..degree {
            let factor = matrix[row][column] / matrix[column][column];
            for inner in column..=degree {
                matrix[row][inner] -= factor * matrix[column][inner];
            }
        }
    }
    let mut coefficients = vec![0.0f64; degree];
    for row in (0..degree).rev() {
        let sum: f64 = (row + 1..degree)
            .map(|inner| matrix[row][inner] * coefficients[inner])
            .sum();
        coefficients[row] = (matrix[row][degree] - sum) / matrix[row][row];
    }
    coefficients
}

impl References {
    /// Builds every model from calibration points starting at (0, 0); `None` when the points
    /// are not a curve (fewer than two, or not strictly increasing).
    pub fn new(pressures_kpa: &[f64], relative_changes: &[f64]) -> Option<Self> {
        let forward = ForwardCubic::new(pressures_kpa, relative_changes)?;
        let (asymptote, scale_kpa) = saturating_fit(pressures_kpa, relative_changes);
        let top_relative = relative_changes[relative_changes.len() - 1];
        let mut table_kpa: Vec<f64> = (0..=TABLE_INTERVALS)
            .map(|index| forward.pressure_kpa(top_relative * index as f64 / TABLE_INTERVALS as f64))
            .collect();
        table_kpa[TABLE_INTERVALS] = pressures_kpa[pressures_kpa.len() - 1];
        let polynomial = polynomial_fit(&forward, top_relative);
        Some(Self {
            forward,
            pressures_kpa: pressures_kpa.to_vec(),
            relative_changes: relative_changes.to_vec(),
            asymptote,
            scale_kpa,
            table_kpa,
            polynomial,
        })
    }

    /// The reference curve (forward cubic).
    pub fn forward(&self) -> &ForwardCubic {
        &self.forward
    }

    /// Top calibration point (pressure kPa, dC/C0).
    pub fn top(&self) -> (f64, f64) {
        self.forward.top()
    }

    /// A tier's pressure for `0 < relative_change <= top`, clamped to `0 ..= top pressure`
    /// like every tier of the model.
    pub fn pressure_kpa(&self, tier: Tier, relative_change: f64) -> f64 {
        let (top_kpa, top_relative) = self.top();
        let raw = match tier {
            Tier::Linear => relative_change * top_kpa / top_relative,
            Tier::PiecewiseLinear => {
                let last = self.pressures_kpa.len() - 1;
                let k = (0..last)
                    .rev()
                    .find(|&k| relative_change >= self.relative_changes[k])
                    .unwrap_or(0);
                self.pressures_kpa[k]
                    + (relative_change - self.relative_changes[k])
                        * (self.pressures_kpa[k + 1] - self.pressures_kpa[k])
                        / (self.relative_changes[k + 1] - self.relative_changes[k])
            }
            Tier::MonotoneCubic => self.forward.pressure_kpa(relative_change),
            Tier::Saturating | Tier::SaturatingMicromath => {
                if relative_change >= self.asymptote {
                    top_kpa
                } else {
                    self.scale_kpa * (self.asymptote / (self.asymptote - relative_change)).ln()
                }
            }
            Tier::Table => {
                let position = (relative_change / top_relative * TABLE_INTERVALS as f64)
                    .clamp(0.0, TABLE_INTERVALS as f64);
                let index = (position.floor() as usize).min(TABLE_INTERVALS);
                let next = (index + 1).min(TABLE_INTERVALS);
                self.table_kpa[index]
                    + (position - index as f64) * (self.table_kpa[next] - self.table_kpa[index])
            }
            Tier::Polynomial => {
                let u = relative_change / top_relative;
                self.polynomial
                    .iter()
                    .rev()
                    .fold(0.0, |sum, coefficient| sum * u + coefficient)
                    * u
            }
        };
        if raw > 0.0 {
            raw.min(top_kpa)
        } else {
            0.0
        }
    }
}
