//! Independent references for model-core's tests, written without model-core:
//!
//! - [`ForwardCubic`]: the Fritsch–Carlson monotone cubic through calibration points, in f64
//!   Hermite form, and its inverse by bisection;
//! - [`hard_calibration`]: a deterministic generator of valid but ill-conditioned calibration
//!   curves (2 to 16 points, unequal spacing, nearly equal neighbours, a nearly flat top, a steep
//!   start), as f32 points the way a calibration file or flash record holds them;
//! - [`probes`] and [`acceptable`]: the readings to ask an inverse about on such a curve and the
//!   rule its answers are held to (0.01 kPa beyond 8 f32 ulps of dC/C0).
//!
//! Used by model-core's property tests, by the on-target test's golden vectors and by the fuzz
//! target, so all three check the same things against the same reference.

mod cubic;
mod hard;
mod probes;

pub use cubic::ForwardCubic;
pub use hard::{hard_calibration, CurveShape, HARD_CALIBRATION_POINTS_MAX};
pub use probes::{acceptable, probes, ulp, PRESSURE_TOLERANCE_KPA, ROUNDING_ULPS};
