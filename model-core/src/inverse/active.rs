//! The one tier a taxel model keeps: only what that tier needs beyond the calibration's points,
//! so that a pad's model stays small (eight pads share the device's static RAM). Another
//! tier is built again from the calibration when it is chosen. Without the feature
//! `research-tiers` only the device's tiers can be held (see [`super`]).

use super::cubic::CubicKnots;
#[cfg(feature = "research-tiers")]
use super::piecewise_linear::LineSlopes;
use super::{InverseCurve, LinearInverse, TableInverse, Tier};
#[cfg(feature = "research-tiers")]
use super::{
    Libm, Micromath, MonotoneCubicInverse, PolynomialInverse, SaturatingFit, SaturatingInverse,
};
use crate::calibration::CalibrationCurve;

/// One tier's inverse of one curve, evaluated together with that curve (the piecewise-linear
/// and monotone cubic tiers read its points).
#[derive(Debug, Clone, PartialEq)]
pub struct ActiveInverse(Active);

// The default tier is the largest by design (its seed grid: `cubic.rs`), and the one a pad
// usually holds; without an allocator there is nothing to box it into. `pad.rs` asserts the size.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
enum Active {
    Linear(LinearInverse),
    MonotoneCubic(CubicKnots),
    Table(TableInverse),
    #[cfg(feature = "research-tiers")]
    PiecewiseLinear(LineSlopes),
    #[cfg(feature = "research-tiers")]
    Saturating(SaturatingInverse<Libm>),
    #[cfg(feature = "research-tiers")]
    SaturatingMicromath(SaturatingInverse<Micromath>),
    #[cfg(feature = "research-tiers")]
    Polynomial(PolynomialInverse),
}

impl ActiveInverse {
    /// The default tier (monotone cubic), which every valid curve supports.
    pub fn default_tier(curve: &CalibrationCurve) -> Self {
        Self(Active::MonotoneCubic(CubicKnots::new(curve)))
    }

    /// A tier for a curve, building only what it needs; `None` when the curve does not support
    /// it (see [`super::TaxelInverses::supports`]) or this build does not have it (a research
    /// tier without the feature `research-tiers`: [`Tier::is_built`]).
    pub fn new(curve: &CalibrationCurve, tier: Tier) -> Option<Self> {
        let active = match tier {
            Tier::Linear => Active::Linear(LinearInverse::new(curve)),
            Tier::MonotoneCubic => return Some(Self::default_tier(curve)),
            Tier::Table => Active::Table(table(curve, &CubicKnots::new(curve))),
            #[cfg(feature = "research-tiers")]
            Tier::PiecewiseLinear => Active::PiecewiseLinear(LineSlopes::new(curve)),
            #[cfg(feature = "research-tiers")]
            Tier::Saturating => Active::Saturating(SaturatingInverse::new(
                &SaturatingFit::new(curve)?,
                curve.top().pressure_kpa,
            )),
            #[cfg(feature = "research-tiers")]
            Tier::SaturatingMicromath => Active::SaturatingMicromath(SaturatingInverse::new(
                &SaturatingFit::new(curve)?,
                curve.top().pressure_kpa,
            )),
            #[cfg(feature = "research-tiers")]
            Tier::Polynomial => Active::Polynomial(PolynomialInverse::new(
                &MonotoneCubicInverse::new(curve),
                curve,
            )?),
            #[cfg(not(feature = "research-tiers"))]
            _ => return None,
        };
        Some(Self(active))
    }

    /// Wraps a tier's part built elsewhere (by [`super::TaxelInverses`]).
    pub(super) fn from_linear(inverse: LinearInverse) -> Self {
        Self(Active::Linear(inverse))
    }

    /// See [`ActiveInverse::from_linear`].
    #[cfg(feature = "research-tiers")]
    pub(super) fn from_piecewise_linear(slopes: LineSlopes) -> Self {
        Self(Active::PiecewiseLinear(slopes))
    }

    /// See [`ActiveInverse::from_linear`].
    pub(super) fn from_monotone_cubic(knots: CubicKnots) -> Self {
        Self(Active::MonotoneCubic(knots))
    }

    /// See [`ActiveInverse::from_linear`].
    #[cfg(feature = "research-tiers")]
    pub(super) fn from_saturating(fit: &SaturatingFit, top_pressure_kpa: f32) -> Self {
        Self(Active::Saturating(SaturatingInverse::new(
            fit,
            top_pressure_kpa,
        )))
    }

    /// See [`ActiveInverse::from_linear`].
    #[cfg(feature = "research-tiers")]
    pub(super) fn from_saturating_micromath(fit: &SaturatingFit, top_pressure_kpa: f32) -> Self {
        Self(Active::SaturatingMicromath(SaturatingInverse::new(
            fit,
            top_pressure_kpa,
        )))
    }

    /// See [`ActiveInverse::from_linear`].
    pub(super) fn from_table(table: TableInverse) -> Self {
        Self(Active::Table(table))
    }

    /// See [`ActiveInverse::from_linear`].
    #[cfg(feature = "research-tiers")]
    pub(super) fn from_polynomial(polynomial: PolynomialInverse) -> Self {
        Self(Active::Polynomial(polynomial))
    }

    /// The tier.
    pub fn tier(&self) -> Tier {
        match &self.0 {
            Active::Linear(_) => Tier::Linear,
            Active::MonotoneCubic(_) => Tier::MonotoneCubic,
            Active::Table(_) => Tier::Table,
            #[cfg(feature = "research-tiers")]
            Active::PiecewiseLinear(_) => Tier::PiecewiseLinear,
            #[cfg(feature = "research-tiers")]
            Active::Saturating(_) => Tier::Saturating,
            #[cfg(feature = "research-tiers")]
            Active::SaturatingMicromath(_) => Tier::SaturatingMicromath,
            #[cfg(feature = "research-tiers")]
            Active::Polynomial(_) => Tier::Polynomial,
        }
    }

    /// Pressure in kPa for a relative change in `0 ..= top`, always finite and within
    /// `0 ..= top pressure`. `curve` must be the one the inverse was built from.
    #[inline]
    pub fn pressure_kpa(&self, curve: &CalibrationCurve, relative_change: f32) -> f32 {
        match &self.0 {
            Active::Linear(inverse) => inverse.pressure_kpa(relative_change),
            Active::MonotoneCubic(knots) => knots.pressure_kpa(curve, relative_change),
            Active::Table(table) => table.pressure_kpa(relative_change),
            #[cfg(feature = "research-tiers")]
            Active::PiecewiseLinear(slopes) => slopes.pressure_kpa(curve, relative_change),
            #[cfg(feature = "research-tiers")]
            Active::Saturating(inverse) => inverse.pressure_kpa(relative_change),
            #[cfg(feature = "research-tiers")]
            Active::SaturatingMicromath(inverse) => inverse.pressure_kpa(relative_change),
            #[cfg(feature = "research-tiers")]
            Active::Polynomial(polynomial) => polynomial.pressure_kpa(relative_change),
        }
    }

    /// [`ActiveInverse::pressure_kpa`] of every value, in place, with the tier chosen once: bit
    /// for bit the same pressures (tested), faster where many readings are converted at once (a
    /// recording on the host); the monotone cubic tier then overlaps the values' work.
    pub fn pressures_kpa(&self, curve: &CalibrationCurve, values: &mut [f32]) {
        fn each(values: &mut [f32], inverse: impl Fn(f32) -> f32) {
            for value in values.iter_mut() {
                *value = inverse(*value);
            }
        }
        match &self.0 {
            Active::Linear(inverse) => each(values, |value| inverse.pressure_kpa(value)),
            Active::MonotoneCubic(knots) => knots.pressures_kpa(curve, values),
            Active::Table(table) => each(values, |value| table.pressure_kpa(value)),
            #[cfg(feature = "research-tiers")]
            Active::PiecewiseLinear(slopes) => {
                each(values, |value| slopes.pressure_kpa(curve, value))
            }
            #[cfg(feature = "research-tiers")]
            Active::Saturating(inverse) => each(values, |value| inverse.pressure_kpa(value)),
            #[cfg(feature = "research-tiers")]
            Active::SaturatingMicromath(inverse) => {
                each(values, |value| inverse.pressure_kpa(value))
            }
            #[cfg(feature = "research-tiers")]
            Active::Polynomial(polynomial) => each(values, |value| polynomial.pressure_kpa(value)),
        }
    }
}

/// The table tier of a curve: its cubic's inverse solved at every grid node.
pub(super) fn table(curve: &CalibrationCurve, knots: &CubicKnots) -> TableInverse {
    let top = curve.top();
    TableInverse::sampled(
        |relative_change| knots.solved_pressure_kpa(curve, relative_change),
        top.relative_change,
        top.pressure_kpa,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::CurvePoint;
    use crate::inverse::TaxelInverses;

    #[test]
    fn each_tier_built_alone_is_the_one_built_with_all_the_others() {
        let convex = [
            CurvePoint::new(0.0, 0.0),
            CurvePoint::new(10.0, 0.01),
            CurvePoint::new(20.0, 0.05),
        ];
        let curves = [
            CalibrationCurve::article_default(),
            CalibrationCurve::new(&convex, 0).unwrap_or_else(|_| unreachable!()),
        ];
        for curve in &curves {
            let inverses = TaxelInverses::new(curve);
            for tier in Tier::ALL {
                let alone = ActiveInverse::new(curve, tier);
                assert_eq!(alone, inverses.active(tier), "{tier:?}");
                assert_eq!(alone.is_some(), inverses.supports(tier), "{tier:?}");
                let Some(alone) = alone else {
                    continue;
                };
                assert_eq!(alone.tier(), tier);
                let top = curve.top().relative_change;
                for step in 0..=1000 {
                    let relative_change = top * step as f32 / 1000.0;
                    assert_eq!(
                        alone.pressure_kpa(curve, relative_change).to_bits(),
                        inverses.pressure_kpa(tier, relative_change).to_bits(),
                        "{tier:?} at {relative_change}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_tier_is_held_exactly_when_this_build_has_it() {
        let curve = CalibrationCurve::article_default();
        let inverses = TaxelInverses::new(&curve);
        for tier in Tier::ALL {
            assert_eq!(
                tier.is_built(),
                !tier.is_research() || cfg!(feature = "research-tiers")
            );
            assert_eq!(
                tier.is_research(),
                !Tier::ON_DEVICE.contains(&tier),
                "{tier:?}"
            );
            // The article's curve supports every tier a build has.
            assert_eq!(ActiveInverse::new(&curve, tier).is_some(), tier.is_built());
            assert_eq!(inverses.active(tier).is_some(), tier.is_built());
            assert_eq!(inverses.supports(tier), tier.is_built());
        }
    }

    /// The device's build: every research tier refused, and asking for one anyway gives the
    /// default tier's pressure rather than a panic or an invented number.
    #[cfg(not(feature = "research-tiers"))]
    #[test]
    fn without_the_feature_the_research_tiers_are_refused() {
        let curve = CalibrationCurve::article_default();
        let inverses = TaxelInverses::new(&curve);
        for tier in [
            Tier::PiecewiseLinear,
            Tier::Saturating,
            Tier::SaturatingMicromath,
            Tier::Polynomial,
        ] {
            assert!(!tier.is_built() && tier.is_research());
            assert_eq!(ActiveInverse::new(&curve, tier), None);
            assert_eq!(inverses.active(tier), None);
            assert!(!inverses.supports(tier));
            // The protocol and recordings still name it.
            assert_eq!(Tier::from_id(tier as u8), Some(tier));
            assert_eq!(Tier::from_name(tier.name()), Some(tier));
            let relative_change = 0.1;
            assert_eq!(
                inverses.pressure_kpa(tier, relative_change),
                inverses.pressure_kpa(Tier::MonotoneCubic, relative_change)
            );
        }
    }

    #[test]
    fn table_nodes_are_the_solved_cubic_within_two_24_bit_steps() {
        let curve = CalibrationCurve::article_default();
        let knots = CubicKnots::new(&curve);
        let table = table(&curve, &knots);
        let top = curve.top();
        let step_kpa = top.pressure_kpa / (1u32 << 24) as f32;
        for node in 0..=crate::inverse::TABLE_INTERVALS {
            let relative_change = TableInverse::node_relative_change(node, top.relative_change);
            let solved = knots.solved_pressure_kpa(&curve, relative_change);
            let stored = table.pressure_kpa(relative_change);
            // Half a step of rounding to the code, and the f32 rounding of the grid position
            // and of the interpolation (an ulp of the pressure, at most half a step here).
            assert!(
                (stored - solved).abs() <= 2.0 * step_kpa,
                "node {node}: {stored} vs {solved}"
            );
        }
        assert_eq!(table.pressure_kpa(0.0), 0.0);
        assert_eq!(table.pressure_kpa(top.relative_change), top.pressure_kpa);
    }
}
