//! Fritsch–Carlson monotone cubic interpolation through strictly increasing points.
//!
//! Built once (in f64, so construction rounding never shows), evaluated in f32 as one cubic
//! polynomial per interval in the local coordinate `s = x - x_k`, which needs no division.

use crate::calibration::MAX_CURVE_POINTS;

/// One interval's cubic `y = c0 + s (c1 + s (c2 + s c3))`, `s = x - x_start`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CubicSegment {
    /// Interval start on the x axis.
    pub x_start: f32,
    /// Interval width on the x axis.
    pub width: f32,
    /// Polynomial coefficients, constant first.
    pub coefficients: [f32; 4],
}

impl CubicSegment {
    /// Value at local coordinate `s` (0 ..= width).
    #[inline]
    pub fn value_at(&self, s: f32) -> f32 {
        let [c0, c1, c2, c3] = self.coefficients;
        c0 + s * (c1 + s * (c2 + s * c3))
    }

    /// Derivative at local coordinate `s`.
    #[inline]
    pub fn slope_at(&self, s: f32) -> f32 {
        let [_, c1, c2, c3] = self.coefficients;
        c1 + s * (2.0 * c2 + s * (3.0 * c3))
    }

    /// Smallest and largest slope over local coordinates `s_low ..= s_high` (clamped to the
    /// interval), from the coefficients in f64: the derivative is a quadratic, so its extremes
    /// are at the ends or at its vertex.
    pub fn slope_range(&self, s_low: f64, s_high: f64) -> (f64, f64) {
        let width = f64::from(self.width);
        derivative_range(
            self.coefficients.map(f64::from),
            s_low.clamp(0.0, width),
            s_high.clamp(0.0, width),
        )
    }

    /// Largest |second derivative| over the interval (it is linear in `s`), in f64.
    pub fn curvature_max(&self) -> f64 {
        let [_, _, c2, c3] = self.coefficients.map(f64::from);
        let width = f64::from(self.width);
        (2.0 * c2).abs().max((2.0 * c2 + 6.0 * c3 * width).abs())
    }
}

/// Secant slopes of the intervals between strictly increasing points (the valid prefix of at
/// most [`MAX_CURVE_POINTS`] points).
fn secant_slopes(xs: &[f64], ys: &[f64]) -> [f64; MAX_CURVE_POINTS - 1] {
    let mut secant_slopes = [0.0f64; MAX_CURVE_POINTS - 1];
    for ((slot, x), y) in secant_slopes
        .iter_mut()
        .zip(xs.windows(2))
        .zip(ys.windows(2))
    {
        if let ([x0, x1], [y0, y1]) = (x, y) {
            *slot = (y1 - y0) / (x1 - x0);
        }
    }
    secant_slopes
}

/// Fritsch–Carlson tangents at the points: three-point means (zero at a change of sign), the
/// secants at the ends, then each interval's `(alpha, beta)` pulled into the circle of radius 3,
/// which is sufficient for the cubic on each interval to be monotone.
pub(crate) fn tangents(xs: &[f64], ys: &[f64]) -> [f64; MAX_CURVE_POINTS] {
    let count = xs.len().min(ys.len()).min(MAX_CURVE_POINTS);
    let secant_slopes = secant_slopes(xs, ys);
    let secants = secant_slopes
        .get(..count.saturating_sub(1))
        .unwrap_or_default();
    let mut tangents = [0.0f64; MAX_CURVE_POINTS];
    for (k, tangent) in tangents.iter_mut().enumerate().take(count) {
        let left = k.checked_sub(1).and_then(|index| secants.get(index));
        *tangent = match (left, secants.get(k)) {
            (Some(left), Some(right)) if left * right <= 0.0 => 0.0,
            (Some(left), Some(right)) => 0.5 * (left + right),
            (Some(end), None) | (None, Some(end)) => *end,
            (None, None) => 0.0,
        };
    }
    // In interval order: an interval's limiter may lower the tangent its right neighbour then
    // reads.
    for (k, secant) in secants.iter().enumerate() {
        let (Some(&start), Some(&end)) = (tangents.get(k), tangents.get(k + 1)) else {
            break;
        };
        let (start, end) = if *secant == 0.0 {
            (0.0, 0.0)
        } else {
            let alpha = start / secant;
            let beta = end / secant;
            let radius_squared = alpha * alpha + beta * beta;
            if radius_squared > 9.0 {
                // f32's square root is plenty for a scale factor (and the firmware links no
                // f64 one); an overflow gives 0, flat tangents, still monotone.
                let tau = 3.0 / f64::from(libm::sqrtf(radius_squared as f32));
                (tau * alpha * secant, tau * beta * secant)
            } else {
                (start, end)
            }
        };
        if let Some([first, second]) = tangents.get_mut(k..k + 2) {
            (*first, *second) = (start, end);
        }
    }
    tangents
}

/// A monotone piecewise cubic through up to [`MAX_CURVE_POINTS`] points.
#[derive(Debug, Clone, PartialEq)]
pub struct MonotoneCubic {
    segments: [CubicSegment; MAX_CURVE_POINTS - 1],
    segment_count: usize,
    x_end: f32,
    y_end: f32,
}

impl MonotoneCubic {
    /// Interpolant through `(xs[i], ys[i])`. Both must be strictly increasing, of equal length,
    /// 2 ..= [`MAX_CURVE_POINTS`] long; the caller (a validated curve) guarantees it, and anything
    /// else gives an interpolant over the valid prefix rather than a panic.
    pub fn new(xs: &[f64], ys: &[f64]) -> Self {
        let count = xs.len().min(ys.len()).min(MAX_CURVE_POINTS);
        let tangents = tangents(xs, ys);
        let secant_slopes = secant_slopes(xs, ys);
        let mut segments = [CubicSegment::default(); MAX_CURVE_POINTS - 1];
        for ((((segment, x), y), secant), tangent_pair) in segments
            .iter_mut()
            .zip(xs.windows(2))
            .zip(ys.windows(2))
            .zip(secant_slopes)
            .zip(tangents.windows(2))
            .take(count.saturating_sub(1))
        {
            let ([x0, x1], [y0, _], [start_tangent, end_tangent]) = (x, y, tangent_pair) else {
                break;
            };
            let width = x1 - x0;
            *segment = CubicSegment {
                x_start: *x0 as f32,
                width: width as f32,
                coefficients: [
                    *y0 as f32,
                    *start_tangent as f32,
                    ((3.0 * secant - 2.0 * start_tangent - end_tangent) / width) as f32,
                    ((start_tangent + end_tangent - 2.0 * secant) / (width * width)) as f32,
                ],
            };
        }
        let last = count.saturating_sub(1);
        Self {
            segments,
            segment_count: count.saturating_sub(1),
            x_end: xs.get(last).copied().unwrap_or(0.0) as f32,
            y_end: ys.get(last).copied().unwrap_or(0.0) as f32,
        }
    }

    /// The interval segments in x order.
    pub fn segments(&self) -> &[CubicSegment] {
        self.segments.get(..self.segment_count).unwrap_or_default()
    }

    /// Index of the segment holding `x` (x below the start gives 0, above the end the last).
    #[inline]
    pub fn segment_index(&self, x: f32) -> usize {
        let mut index = 0;
        while index + 1 < self.segment_count
            && self
                .segments
                .get(index + 1)
                .is_some_and(|next| x >= next.x_start)
        {
            index += 1;
        }
        index
    }

    /// Value at `x`, with `x` clamped to the interpolated range.
    #[inline]
    pub fn value_at(&self, x: f32) -> f32 {
        if !(x < self.x_end) {
            return self.y_end;
        }
        match self.segments.get(self.segment_index(x)) {
            Some(segment) => segment.value_at((x - segment.x_start).max(0.0)),
            None => self.y_end,
        }
    }
}

/// Smallest and largest derivative of the cubic `coefficients` (constant first, in the local
/// coordinate) over `low ..= high`, not clamped to an interval, in f64: the derivative is a
/// quadratic, so its extremes are at the ends or at its vertex.
pub(crate) fn derivative_range(coefficients: [f64; 4], low: f64, high: f64) -> (f64, f64) {
    let [_, c1, c2, c3] = coefficients;
    let slope = |s: f64| c1 + s * (2.0 * c2 + s * 3.0 * c3);
    let (at_low, at_high) = (slope(low), slope(high));
    let (mut min, mut max) = (at_low.min(at_high), at_low.max(at_high));
    if c3 != 0.0 {
        let vertex = -c2 / (3.0 * c3);
        if vertex > low && vertex < high {
            min = min.min(slope(vertex));
            max = max.max(slope(vertex));
        }
    }
    (min, max)
}

#[cfg(test)]
mod tests {
    use super::*;

    const PRESSURE_KPA: [f64; 6] = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0];
    const RELATIVE_CHANGE: [f64; 6] = [0.0, 0.0829, 0.1475, 0.1981, 0.2317, 0.2563];

    #[test]
    fn reproduces_the_points() {
        let cubic = MonotoneCubic::new(&PRESSURE_KPA, &RELATIVE_CHANGE);
        for (x, y) in PRESSURE_KPA.iter().zip(RELATIVE_CHANGE) {
            assert!(
                (cubic.value_at(*x as f32) - y as f32).abs() < 1e-6,
                "at {x}"
            );
        }
    }

    #[test]
    fn is_monotone_on_a_fine_grid() {
        let cubic = MonotoneCubic::new(&PRESSURE_KPA, &RELATIVE_CHANGE);
        let mut previous = f32::NEG_INFINITY;
        for step in 0..=5000 {
            let value = cubic.value_at(step as f32 * 0.01);
            assert!(value >= previous, "not monotone at step {step}");
            previous = value;
        }
    }

    #[test]
    fn stays_monotone_on_data_that_tempts_overshoot() {
        let xs = [0.0, 1.0, 2.0, 3.0, 4.0];
        let ys = [0.0, 0.001, 0.002, 10.0, 10.001];
        let cubic = MonotoneCubic::new(&xs, &ys);
        let mut previous = f32::NEG_INFINITY;
        for step in 0..=4000 {
            let value = cubic.value_at(step as f32 * 0.001);
            assert!(value >= previous - 1e-6);
            assert!((-1e-6..=10.001 + 1e-5).contains(&value));
            previous = value;
        }
    }
}
