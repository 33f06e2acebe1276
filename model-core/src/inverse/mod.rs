//! Inversion tiers: relative capacitance change dC/C0 to pressure, behind one interface.
//!
//! Every tier is built from a validated [`CalibrationCurve`] and evaluated per reading. The
//! caller classifies the reading first, so a tier is only asked for `0 ..= top relative change`;
//! each still clamps its result to `0 ..= top pressure` so that no input can produce NaN or a
//! pressure outside the curve.
//!
//! A taxel model keeps one tier, as an [`ActiveInverse`]; [`TaxelInverses`] builds every tier
//! at once for tier selection, references and host tools.
//!
//! # The tiers the device keeps
//!
//! The device builds only the tiers on the Pareto front of cost against error in the shipped
//! build (M4 instructions per temperature-corrected inversion against the largest distance from
//! the default model over the grid; `cargo xtask report` draws it in docs/speed-vs-error.svg
//! and says there whether the measured front is still [`Tier::ON_DEVICE`]): `linear` (the
//! cheapest), `table` and `monotone-cubic` (the default, the reference curve). `table` is both
//! cheaper and more accurate than every other tier, so none of those can be what a use case
//! needs: `piecewise-linear`, `saturating`, `saturating-micromath` (a choice of logarithm, not
//! another model) and `polynomial` are research tiers. They are built only with the feature
//! `research-tiers` (host tools, the M4 benchmark, the reports). Without it [`Tier`] still names all seven (the wire
//! protocol and recordings carry their ids), but a research tier is refused:
//! [`ActiveInverse::new`] and [`TaxelInverses::active`] give `None`,
//! [`TaxelInverses::supports`] is false, and use-case selection never offers one (see
//! [`Tier::is_built`]).

mod active;
mod cubic;
mod linear;
#[cfg(feature = "research-tiers")]
mod piecewise_linear;
#[cfg(feature = "research-tiers")]
mod polynomial;
#[cfg(feature = "research-tiers")]
mod saturating;
mod table;

pub use active::ActiveInverse;
pub use cubic::{
    MonotoneCubicInverse, ACCEPTED_ERROR_KPA, FAST_NEWTON_STEPS, MAX_BRACKETED_ITERATIONS,
};
pub use linear::LinearInverse;
#[cfg(feature = "research-tiers")]
pub use piecewise_linear::PiecewiseLinearInverse;
#[cfg(feature = "research-tiers")]
pub use polynomial::{PolynomialInverse, POLYNOMIAL_DEGREE};
#[cfg(feature = "research-tiers")]
pub use saturating::{Libm, LnBackend, Micromath, SaturatingFit, SaturatingInverse};
pub use table::{TableInverse, TABLE_INTERVALS};

use crate::calibration::{CalibrationCurve, CurvePoint};

/// An inverse of a calibration curve: relative change to pressure.
pub trait InverseCurve {
    /// Pressure in kPa for a relative change in `0 ..= top`; always finite and within
    /// `0 ..= top pressure`.
    fn pressure_kpa(&self, relative_change: f32) -> f32;
}

/// The inversion tiers, cheapest-first is not implied: see [`Tier::ALL`] and the performance
/// report for measured cost and error. Every build names all of them (wire ids, recordings); the
/// research tiers are built only with the feature `research-tiers` ([`Tier::is_built`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum Tier {
    /// One sensitivity: the secant from the origin to the top calibration point.
    Linear = 0,
    /// Straight lines between the calibration points (research tier).
    PiecewiseLinear = 1,
    /// Exact inverse of the monotone (Fritsch–Carlson) cubic through the calibration points:
    /// the reference curve of the model.
    #[default]
    MonotoneCubic = 2,
    /// Fitted dC/C0 = A (1 - exp(-P / B)), inverted in closed form with libm's logf (research
    /// tier).
    Saturating = 3,
    /// The same fitted model, inverted with micromath's fast ln (research tier: a choice of
    /// logarithm, not another model).
    SaturatingMicromath = 4,
    /// A dense table of the monotone cubic's inverse with linear interpolation.
    Table = 5,
    /// A least-squares polynomial of the monotone cubic's inverse, by Horner's rule: built for
    /// speed (research tier).
    Polynomial = 6,
}

impl Tier {
    /// Every tier, in id order.
    pub const ALL: [Tier; 7] = [
        Tier::Linear,
        Tier::PiecewiseLinear,
        Tier::MonotoneCubic,
        Tier::Saturating,
        Tier::SaturatingMicromath,
        Tier::Table,
        Tier::Polynomial,
    ];

    /// The tiers the device builds, in id order: the Pareto front of M4 cost against distance
    /// from the default model in the shipped build, `linear` as the cheapest (module docs).
    pub const ON_DEVICE: [Tier; 3] = [Tier::Linear, Tier::MonotoneCubic, Tier::Table];

    /// Whether the tier is a research tier, off the Pareto front (not in
    /// [`Tier::ON_DEVICE`]): built only with the feature `research-tiers`, never on the device.
    pub fn is_research(self) -> bool {
        !Self::ON_DEVICE.contains(&self)
    }

    /// Whether this build of model-core has the tier: a device tier always, a research tier
    /// with the feature `research-tiers`. A tier that is not built is refused wherever one is
    /// built (`None`, or the caller's "tier unavailable").
    pub fn is_built(self) -> bool {
        !self.is_research() || cfg!(feature = "research-tiers")
    }

    /// Stable name used on the command line and in files.
    pub const fn name(self) -> &'static str {
        match self {
            Tier::Linear => "linear",
            Tier::PiecewiseLinear => "piecewise-linear",
            Tier::MonotoneCubic => "monotone-cubic",
            Tier::Saturating => "saturating",
            Tier::SaturatingMicromath => "saturating-micromath",
            Tier::Table => "table",
            Tier::Polynomial => "polynomial",
        }
    }

    /// The tier with this name.
    pub fn from_name(name: &str) -> Option<Tier> {
        Tier::ALL.into_iter().find(|tier| tier.name() == name)
    }

    /// The tier with this wire id.
    pub fn from_id(id: u8) -> Option<Tier> {
        Tier::ALL.into_iter().find(|tier| *tier as u8 == id)
    }

    /// Whether the tier passes exactly through the calibration points. The table does not: it
    /// samples the monotone cubic on a uniform grid, so it is within its interpolation error
    /// (measured in the performance report) of them.
    pub const fn interpolates_points(self) -> bool {
        matches!(self, Tier::PiecewiseLinear | Tier::MonotoneCubic)
    }
}

/// All tiers of one taxel that this build has, built at once from its curve (tier selection,
/// references, host tools); a taxel model keeps only the active one.
#[derive(Debug, Clone, PartialEq)]
pub struct TaxelInverses {
    linear: LinearInverse,
    monotone_cubic: MonotoneCubicInverse,
    table: TableInverse,
    #[cfg(feature = "research-tiers")]
    piecewise_linear: PiecewiseLinearInverse,
    #[cfg(feature = "research-tiers")]
    saturating: Option<SaturatingFit>,
    #[cfg(feature = "research-tiers")]
    polynomial: Option<PolynomialInverse>,
    #[cfg(feature = "research-tiers")]
    top_pressure_kpa: f32,
}

impl TaxelInverses {
    /// Builds every tier of this build for a curve.
    pub fn new(curve: &CalibrationCurve) -> Self {
        let monotone_cubic = MonotoneCubicInverse::new(curve);
        Self {
            linear: LinearInverse::new(curve),
            #[cfg(feature = "research-tiers")]
            piecewise_linear: PiecewiseLinearInverse::new(curve),
            #[cfg(feature = "research-tiers")]
            polynomial: PolynomialInverse::new(&monotone_cubic, curve),
            #[cfg(feature = "research-tiers")]
            saturating: SaturatingFit::new(curve),
            #[cfg(feature = "research-tiers")]
            top_pressure_kpa: curve.top().pressure_kpa,
            table: active::table(curve, monotone_cubic.knots()),
            monotone_cubic,
        }
    }

    /// Whether a tier can be used for this curve: false for a tier this build does not have
    /// ([`Tier::is_built`]); the saturating fit needs a concave curve, the polynomial a
    /// monotone fit.
    pub fn supports(&self, tier: Tier) -> bool {
        match tier {
            Tier::Linear | Tier::MonotoneCubic | Tier::Table => true,
            #[cfg(feature = "research-tiers")]
            Tier::PiecewiseLinear => true,
            #[cfg(feature = "research-tiers")]
            Tier::Saturating | Tier::SaturatingMicromath => self.saturating.is_some(),
            #[cfg(feature = "research-tiers")]
            Tier::Polynomial => self.polynomial.is_some(),
            #[cfg(not(feature = "research-tiers"))]
            _ => false,
        }
    }

    /// The tier as a taxel model keeps it (a copy of what was built here), or `None` when the
    /// curve does not support it or this build does not have it.
    pub fn active(&self, tier: Tier) -> Option<ActiveInverse> {
        Some(match tier {
            Tier::Linear => ActiveInverse::from_linear(self.linear),
            Tier::MonotoneCubic => {
                ActiveInverse::from_monotone_cubic(self.monotone_cubic.knots().clone())
            }
            Tier::Table => ActiveInverse::from_table(self.table.clone()),
            #[cfg(feature = "research-tiers")]
            Tier::PiecewiseLinear => {
                ActiveInverse::from_piecewise_linear(self.piecewise_linear.slopes().clone())
            }
            #[cfg(feature = "research-tiers")]
            Tier::Saturating => {
                ActiveInverse::from_saturating(self.saturating.as_ref()?, self.top_pressure_kpa)
            }
            #[cfg(feature = "research-tiers")]
            Tier::SaturatingMicromath => ActiveInverse::from_saturating_micromath(
                self.saturating.as_ref()?,
                self.top_pressure_kpa,
            ),
            #[cfg(feature = "research-tiers")]
            Tier::Polynomial => ActiveInverse::from_polynomial(self.polynomial.clone()?),
            #[cfg(not(feature = "research-tiers"))]
            _ => return None,
        })
    }

    /// Pressure for a relative change through the given tier. A tier the curve does not support,
    /// or this build does not have, falls back to the monotone cubic (callers check
    /// [`TaxelInverses::supports`] first).
    #[inline]
    pub fn pressure_kpa(&self, tier: Tier, relative_change: f32) -> f32 {
        match tier {
            Tier::Linear => self.linear.pressure_kpa(relative_change),
            Tier::Table => self.table.pressure_kpa(relative_change),
            #[cfg(feature = "research-tiers")]
            Tier::PiecewiseLinear => self.piecewise_linear.pressure_kpa(relative_change),
            #[cfg(feature = "research-tiers")]
            Tier::Polynomial => match &self.polynomial {
                Some(polynomial) => polynomial.pressure_kpa(relative_change),
                None => self.monotone_cubic.pressure_kpa(relative_change),
            },
            #[cfg(feature = "research-tiers")]
            Tier::Saturating => match &self.saturating {
                Some(fit) => SaturatingInverse::<Libm>::new(fit, self.top_pressure_kpa)
                    .pressure_kpa(relative_change),
                None => self.monotone_cubic.pressure_kpa(relative_change),
            },
            #[cfg(feature = "research-tiers")]
            Tier::SaturatingMicromath => match &self.saturating {
                Some(fit) => SaturatingInverse::<Micromath>::new(fit, self.top_pressure_kpa)
                    .pressure_kpa(relative_change),
                None => self.monotone_cubic.pressure_kpa(relative_change),
            },
            #[cfg(feature = "research-tiers")]
            Tier::MonotoneCubic => self.monotone_cubic.pressure_kpa(relative_change),
            #[cfg(not(feature = "research-tiers"))]
            _ => self.monotone_cubic.pressure_kpa(relative_change),
        }
    }

    /// The reference forward curve: relative change at a pressure (monotone cubic).
    pub fn relative_change_at(&self, pressure_kpa: f32) -> f32 {
        self.monotone_cubic.forward().value_at(pressure_kpa)
    }

    /// The saturating fit, if the curve allows one (research tier).
    #[cfg(feature = "research-tiers")]
    pub fn saturating_fit(&self) -> Option<&SaturatingFit> {
        self.saturating.as_ref()
    }

    /// The linear tier.
    pub fn linear(&self) -> &LinearInverse {
        &self.linear
    }

    /// The piecewise-linear tier (research tier).
    #[cfg(feature = "research-tiers")]
    pub fn piecewise_linear(&self) -> &PiecewiseLinearInverse {
        &self.piecewise_linear
    }

    /// The monotone cubic tier.
    pub fn monotone_cubic(&self) -> &MonotoneCubicInverse {
        &self.monotone_cubic
    }

    /// The table tier.
    pub fn table(&self) -> &TableInverse {
        &self.table
    }

    /// The polynomial tier, if the fit is monotone (research tier).
    #[cfg(feature = "research-tiers")]
    pub fn polynomial(&self) -> Option<&PolynomialInverse> {
        self.polynomial.as_ref()
    }
}

/// The interval `k` of a curve with `points[k] <= relative_change < points[k + 1]` (below the
/// first point or NaN gives 0, at or above the last point the last interval).
#[inline(always)]
pub(crate) fn interval_index(points: &[CurvePoint], relative_change: f32) -> usize {
    interval_index_from(points, relative_change, 0)
}

/// [`interval_index`] scanning from interval `start`, which must not be past the answer (a
/// hint: the monotone cubic tier's).
#[inline(always)]
pub(crate) fn interval_index_from(
    points: &[CurvePoint],
    relative_change: f32,
    start: usize,
) -> usize {
    // A forward scan: at most 15 steps, and on short curves fewer than a binary search's
    // bookkeeping costs.
    let mut index = start;
    while index + 2 < points.len()
        && points
            .get(index + 1)
            .is_some_and(|next| relative_change >= next.relative_change)
    {
        index += 1;
    }
    index
}

/// Clamps a tier's raw result into `0 ..= top`, mapping NaN to 0.
#[inline]
pub(crate) fn clamp_pressure(pressure_kpa: f32, top_pressure_kpa: f32) -> f32 {
    crate::bounds::clamp_f32(pressure_kpa, 0.0, top_pressure_kpa)
}
