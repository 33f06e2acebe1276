//! Saturating analytic tier: dC/C0 = A (1 - exp(-P / B)) fitted to the curve, inverted in closed
//! form as P = B ln(A / (A - dC/C0)).
//!
//! The logarithm's argument is written as a quotient >= 1 on purpose: micromath's `ln` is about
//! 12 % wrong below 1 (see the tests), and `-B ln(1 - y / A)` would feed it exactly that range.

use core::marker::PhantomData;

use super::{clamp_pressure, InverseCurve};
use crate::calibration::CalibrationCurve;

/// A natural logarithm implementation the MCU can run.
pub trait LnBackend {
    /// ln(x) for x >= 1.
    fn ln(x: f32) -> f32;
}

/// libm's `logf` (<= 0.8 ulp).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Libm;

impl LnBackend for Libm {
    #[inline]
    fn ln(x: f32) -> f32 {
        libm::logf(x)
    }
}

/// micromath's fast `ln` (about 1e-3 relative for x > 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Micromath;

impl LnBackend for Micromath {
    #[inline]
    fn ln(x: f32) -> f32 {
        micromath::F32Ext::ln(x)
    }
}

/// The fitted parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SaturatingFit {
    /// Asymptotic relative change A.
    pub asymptote: f32,
    /// Pressure scale B, kPa.
    pub scale_kpa: f32,
    /// Root-mean-square residual of the fit in relative change.
    pub rms_residual: f32,
}

impl SaturatingFit {
    /// Least-squares fit (A is solved exactly for each B; B by golden-section search in log
    /// space over 0.1 kPa .. 100 MPa). `None` when the curve is not concave: the search then
    /// runs to its upper bound (the model degenerates to a line), or the asymptote does not lie
    /// above the top point, where the closed-form inverse would be undefined.
    pub fn new(curve: &CalibrationCurve) -> Option<Self> {
        let pressures = curve.pressures_kpa();
        let relative_changes = curve.relative_changes();
        let residual_for = |scale_kpa: f64| -> (f64, f64) {
            let (mut numerator, mut denominator) = (0.0, 0.0);
            for (pressure, relative_change) in pressures.iter().zip(relative_changes.iter()) {
                let shape = 1.0 - libm::exp(-pressure / scale_kpa);
                numerator += relative_change * shape;
                denominator += shape * shape;
            }
            let asymptote = if denominator > 0.0 {
                numerator / denominator
            } else {
                0.0
            };
            let mut squared = 0.0;
            for (pressure, relative_change) in pressures.iter().zip(relative_changes.iter()) {
                let error = asymptote * (1.0 - libm::exp(-pressure / scale_kpa)) - relative_change;
                squared += error * error;
            }
            (squared, asymptote)
        };
        let (lowest, highest) = (libm::log(0.1f64), libm::log(1.0e5f64));
        let (mut low, mut high) = (lowest, highest);
        // The golden ratio's conjugate, (sqrt(5) - 1) / 2.
        let ratio = 0.618_033_988_749_894_9;
        for _ in 0..120 {
            let left = high - ratio * (high - low);
            let right = low + ratio * (high - low);
            if residual_for(libm::exp(left)).0 < residual_for(libm::exp(right)).0 {
                high = right;
            } else {
                low = left;
            }
        }
        let scale_kpa = libm::exp(0.5 * (low + high));
        let (squared, asymptote) = residual_for(scale_kpa);
        let top = curve.top().relative_change as f64;
        // The inverse's condition number grows as 1 / (A - y); require a margin above the top.
        let at_search_bound = 0.5 * (low + high) > highest - 0.01 * (highest - lowest);
        if !(asymptote > top * 1.01) || !scale_kpa.is_finite() || at_search_bound {
            return None;
        }
        Some(Self {
            asymptote: asymptote as f32,
            scale_kpa: scale_kpa as f32,
            rms_residual: libm::sqrtf((squared / pressures.len().max(1) as f64) as f32),
        })
    }

    /// The fitted forward model at a pressure (f64, for references and reports).
    pub fn relative_change_at(&self, pressure_kpa: f64) -> f64 {
        self.asymptote as f64 * (1.0 - libm::exp(-pressure_kpa / self.scale_kpa as f64))
    }
}

/// Closed-form inverse of a [`SaturatingFit`] with a chosen logarithm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SaturatingInverse<B> {
    asymptote: f32,
    scale_kpa: f32,
    top_pressure_kpa: f32,
    backend: PhantomData<B>,
}

impl<B: LnBackend> SaturatingInverse<B> {
    /// The inverse of a fit, clamped to the curve's top pressure.
    #[inline]
    pub fn new(fit: &SaturatingFit, top_pressure_kpa: f32) -> Self {
        Self {
            asymptote: fit.asymptote,
            scale_kpa: fit.scale_kpa,
            top_pressure_kpa,
            backend: PhantomData,
        }
    }
}

impl<B: LnBackend> InverseCurve for SaturatingInverse<B> {
    #[inline]
    fn pressure_kpa(&self, relative_change: f32) -> f32 {
        let distance_to_asymptote = self.asymptote - relative_change;
        if !(distance_to_asymptote > 0.0) {
            return self.top_pressure_kpa;
        }
        clamp_pressure(
            self.scale_kpa * B::ln(self.asymptote / distance_to_asymptote),
            self.top_pressure_kpa,
        )
    }
}
