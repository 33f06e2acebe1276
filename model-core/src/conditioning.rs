//! How well a calibration determines pressure: the pressure noise that converter noise causes,
//! per calibration interval. Where neighbouring calibration points are nearly equal in dC/C0 the
//! curve is nearly flat, so a tiny change in capacitance spans a wide range of pressure there:
//! that is a property of the calibration (information for whoever made it), not an error of the
//! inverse, and `Calibration::new` still accepts the curve.
//!
//! Noise in dC/C0 is `noise_pf / C0`; in pressure it is that over the slope of the reference
//! curve, `d(dC/C0)/dP`, and the worst case over a range is where the slope is smallest.

use heapless::Vec;

use crate::calibration::MAX_CURVE_POINTS;
use crate::monotone_cubic::MonotoneCubic;

/// rms converter noise at 100 S/s, pF (FDC1004: about 16 effective bits, 0.5 fF).
pub const CONVERTER_NOISE_PF: f32 = 0.0005;

/// A typical unloaded taxel capacitance, pF (the article's 4.5 pF), used when a calibration
/// carries no measured C0.
pub const NOMINAL_SENSOR_PF: f32 = 4.5;

/// The pressure noise over one calibration interval.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct IntervalNoise {
    /// Interval start, kPa.
    pub pressure_low_kpa: f32,
    /// Interval end, kPa.
    pub pressure_high_kpa: f32,
    /// Largest rms pressure noise in the interval, kPa (infinite where the curve is flat).
    pub noise_kpa: f32,
}

/// rms pressure noise, kPa, that `noise_pf` of capacitance noise causes on a taxel of unloaded
/// sensor capacitance `sensor_pf` where the curve's slope is `slope_per_kpa` (dC/C0 per kPa).
pub fn pressure_noise_kpa(noise_pf: f32, sensor_pf: f32, slope_per_kpa: f64) -> f32 {
    let noise_relative = f64::from(noise_pf) / f64::from(sensor_pf);
    if slope_per_kpa > 0.0 && noise_relative.is_finite() {
        (noise_relative / slope_per_kpa) as f32
    } else {
        f32::INFINITY
    }
}

/// Per interval of the curve, the worst pressure noise in it.
pub fn interval_noise(
    forward: &MonotoneCubic,
    sensor_pf: f32,
    noise_pf: f32,
) -> Vec<IntervalNoise, { MAX_CURVE_POINTS - 1 }> {
    let mut intervals = Vec::new();
    for segment in forward.segments() {
        let (slope_min, _) = segment.slope_range(0.0, f64::from(segment.width));
        // At most MAX_CURVE_POINTS - 1 segments, the capacity: a push cannot fail.
        let _ = intervals.push(IntervalNoise {
            pressure_low_kpa: segment.x_start,
            pressure_high_kpa: segment.x_start + segment.width,
            noise_kpa: pressure_noise_kpa(noise_pf, sensor_pf, slope_min),
        });
    }
    intervals
}

/// The worst pressure noise over `0 ..= pressure_max_kpa`, kPa.
pub fn worst_noise_kpa(
    forward: &MonotoneCubic,
    pressure_max_kpa: f32,
    sensor_pf: f32,
    noise_pf: f32,
) -> f32 {
    let mut slope_min = f64::INFINITY;
    for segment in forward.segments() {
        if segment.x_start >= pressure_max_kpa && segment.x_start > 0.0 {
            break;
        }
        let end = f64::from(pressure_max_kpa) - f64::from(segment.x_start);
        slope_min = slope_min.min(segment.slope_range(0.0, end).0);
    }
    pressure_noise_kpa(noise_pf, sensor_pf, slope_min)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::CalibrationCurve;
    use crate::inverse::TaxelInverses;

    #[test]
    fn article_noise_grows_towards_the_flat_top() {
        let inverses = TaxelInverses::new(&CalibrationCurve::article_default());
        let forward = inverses.monotone_cubic().forward();
        let intervals = interval_noise(forward, NOMINAL_SENSOR_PF, CONVERTER_NOISE_PF);
        assert_eq!(intervals.len(), 5);
        // By hand: 0.5 fF / 4.5 pF = 1.11e-4 of dC/C0; the article's sensitivity is
        // 0.0083 /kPa at the start and about 0.0025 /kPa (or less, at the end tangent) at the top.
        let first = intervals[0].noise_kpa;
        let last = intervals[4].noise_kpa;
        assert!(first > 0.010 && first < 0.02, "{first}");
        assert!(last > 0.04 && last < 0.08, "{last}");
        let worst = worst_noise_kpa(forward, 50.0, NOMINAL_SENSOR_PF, CONVERTER_NOISE_PF);
        assert_eq!(
            worst,
            intervals.iter().map(|i| i.noise_kpa).fold(0.0, f32::max)
        );
        let light = worst_noise_kpa(forward, 10.0, NOMINAL_SENSOR_PF, CONVERTER_NOISE_PF);
        assert_eq!(light, first);
    }

    #[test]
    fn a_flat_interval_is_reported_not_hidden() {
        let points = [
            crate::CurvePoint::new(0.0, 0.0),
            crate::CurvePoint::new(10.0, 0.1),
            crate::CurvePoint::new(20.0, 0.10001),
            crate::CurvePoint::new(30.0, 0.15),
        ];
        let curve = CalibrationCurve::new(&points, 0).unwrap_or_else(|_| unreachable!());
        let inverses = TaxelInverses::new(&curve);
        let intervals = interval_noise(
            inverses.monotone_cubic().forward(),
            NOMINAL_SENSOR_PF,
            CONVERTER_NOISE_PF,
        );
        // The secant of the middle interval is 1e-6 /kPa: 1.1e-4 / 1e-6 = 111 kPa of noise, at
        // least (the cubic is flatter still inside it).
        assert!(intervals[1].noise_kpa > 100.0, "{:?}", intervals[1]);
        // Fritsch–Carlson flattens the neighbours' ends at the flat interval too.
        assert!(intervals[0].noise_kpa > intervals[1].noise_kpa / 10.0);
    }
}
