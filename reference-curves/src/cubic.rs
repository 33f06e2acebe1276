//! The Fritsch–Carlson monotone cubic, forward dC/C0 = f(P), in f64 Hermite form, inverted by
//! bisection (no Newton, no shared code with the implementation it checks).

/// The monotone cubic through the points, evaluated in f64.
#[derive(Debug, Clone, PartialEq)]
pub struct ForwardCubic {
    pressures_kpa: Vec<f64>,
    relative_changes: Vec<f64>,
    tangents: Vec<f64>,
}

impl ForwardCubic {
    /// Fritsch–Carlson: three-point mean tangents (zero at a change of sign), secant tangents at
    /// the ends, then each interval's (alpha, beta) pulled into the circle of radius 3. `None`
    /// unless there are at least two points, as many of each, strictly increasing.
    pub fn new(pressures_kpa: &[f64], relative_changes: &[f64]) -> Option<Self> {
        let count = pressures_kpa.len();
        let increasing = |values: &[f64]| values.windows(2).all(|pair| pair[0] < pair[1]);
        if count < 2
            || relative_changes.len() != count
            || !increasing(pressures_kpa)
            || !increasing(relative_changes)
        {
            return None;
        }
        let secants: Vec<f64> = pressures_kpa
            .windows(2)
            .zip(relative_changes.windows(2))
            .map(|(x, y)| (y[1] - y[0]) / (x[1] - x[0]))
            .collect();
        let mut tangents = vec![0.0; count];
        tangents[0] = secants[0];
        tangents[count - 1] = secants[count - 2];
        for k in 1..count - 1 {
            let (left, right) = (secants[k - 1], secants[k]);
            tangents[k] = if left * right <= 0.0 {
                0.0
            } else {
                (left + right) / 2.0
            };
        }
        for (k, secant) in secants.iter().enumerate() {
            let alpha = tangents[k] / secant;
            let beta = tangents[k + 1] / secant;
            let radius = alpha.hypot(beta);
            if radius > 3.0 {
                tangents[k] = 3.0 / radius * alpha * secant;
                tangents[k + 1] = 3.0 / radius * beta * secant;
            }
        }
        Some(Self {
            pressures_kpa: pressures_kpa.to_vec(),
            relative_changes: relative_changes.to_vec(),
            tangents,
        })
    }

    /// The top point (pressure kPa, dC/C0).
    pub fn top(&self) -> (f64, f64) {
        let last = self.pressures_kpa.len() - 1;
        (self.pressures_kpa[last], self.relative_changes[last])
    }

    /// dC/C0 at a pressure within the points' range (clamped to it).
    pub fn relative_change_at(&self, pressure_kpa: f64) -> f64 {
        let last = self.pressures_kpa.len() - 1;
        let pressure_kpa = pressure_kpa.clamp(0.0, self.pressures_kpa[last]);
        let k = (0..last)
            .rev()
            .find(|&k| pressure_kpa >= self.pressures_kpa[k])
            .unwrap_or(0);
        let width = self.pressures_kpa[k + 1] - self.pressures_kpa[k];
        let t = (pressure_kpa - self.pressures_kpa[k]) / width;
        let (t2, t3) = (t * t, t * t * t);
        (2.0 * t3 - 3.0 * t2 + 1.0) * self.relative_changes[k]
            + (t3 - 2.0 * t2 + t) * width * self.tangents[k]
            + (-2.0 * t3 + 3.0 * t2) * self.relative_changes[k + 1]
            + (t3 - t2) * width * self.tangents[k + 1]
    }

    /// Pressure at which the cubic reaches `relative_change` (bisection to f64 precision);
    /// 0 at or below 0, the top pressure at or above the top.
    pub fn pressure_kpa(&self, relative_change: f64) -> f64 {
        let (top_kpa, top_relative) = self.top();
        if !(relative_change > 0.0) {
            return 0.0;
        }
        if relative_change >= top_relative {
            return top_kpa;
        }
        let (mut low, mut high) = (0.0, top_kpa);
        for _ in 0..2000 {
            let middle = 0.5 * (low + high);
            if middle <= low || middle >= high {
                break;
            }
            if self.relative_change_at(middle) < relative_change {
                low = middle;
            } else {
                high = middle;
            }
        }
        0.5 * (low + high)
    }

    /// Whether `pressure_kpa` inverts `relative_change` to within `pressure_tolerance_kpa`,
    /// beyond `relative_tolerance` of dC/C0 (the rounding the caller's arithmetic explains): some
    /// pressure within `pressure_tolerance_kpa` of the answer has a dC/C0 within
    /// `relative_tolerance` of the reading. By monotonicity that is two evaluations.
    pub fn accepts(
        &self,
        relative_change: f64,
        pressure_kpa: f64,
        pressure_tolerance_kpa: f64,
        relative_tolerance: f64,
    ) -> bool {
        let below = self.relative_change_at(pressure_kpa - pressure_tolerance_kpa);
        let above = self.relative_change_at(pressure_kpa + pressure_tolerance_kpa);
        below <= relative_change + relative_tolerance
            && above >= relative_change - relative_tolerance
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_through_the_points_and_inverts_them() {
        let pressures = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0];
        let changes = [0.0, 0.0829, 0.1475, 0.1981, 0.2317, 0.2563];
        let cubic = ForwardCubic::new(&pressures, &changes).unwrap();
        for (p, y) in pressures.iter().zip(changes) {
            assert!((cubic.relative_change_at(*p) - y).abs() < 1e-15);
            assert!((cubic.pressure_kpa(y) - p).abs() < 1e-9 || y == 0.0);
        }
    }

    #[test]
    fn refuses_points_that_are_not_a_curve() {
        assert!(ForwardCubic::new(&[0.0], &[0.0]).is_none());
        assert!(ForwardCubic::new(&[0.0, 1.0], &[0.0, 0.0]).is_none());
        assert!(ForwardCubic::new(&[0.0, 1.0], &[0.0]).is_none());
    }
}
