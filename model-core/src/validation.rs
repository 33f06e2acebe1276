//! Leave-one-out cross-validation of a tier on calibration points: how well a tier predicts a
//! point it was not built from, the honest measure of a curve form's error between the points.

use heapless::Vec;

use crate::calibration::{CalibrationCurve, CurvePoint, MAX_CURVE_POINTS};
use crate::inverse::{ActiveInverse, Tier};

/// Per interior point (index 1 ..= n - 2, in order), the tier's predicted pressure minus the
/// applied one when the curve is rebuilt without that point, kPa; `None` where the reduced curve
/// is invalid or cannot provide the tier, and everywhere for a tier this build does not have
/// ([`Tier::is_built`]).
pub fn leave_one_out_errors_kpa(
    points: &[CurvePoint],
    tier: Tier,
) -> Vec<Option<f32>, MAX_CURVE_POINTS> {
    let mut errors = Vec::new();
    for (left_out, point) in points
        .iter()
        .enumerate()
        .skip(1)
        .take(points.len().saturating_sub(2))
    {
        let mut reduced: Vec<CurvePoint, MAX_CURVE_POINTS> = Vec::new();
        let mut fits = true;
        for (_, kept) in points
            .iter()
            .enumerate()
            .filter(|(index, _)| *index != left_out)
        {
            fits &= reduced.push(*kept).is_ok();
        }
        let error = CalibrationCurve::new(&reduced, 0)
            .ok()
            .filter(|_| fits)
            .and_then(|curve| pressure_through(&curve, tier, point.relative_change))
            .map(|pressure_kpa| pressure_kpa - point.pressure_kpa);
        if errors.push(error).is_err() {
            break;
        }
    }
    errors
}

/// One tier's pressure for a relative change on a curve, building only what the tier needs.
fn pressure_through(curve: &CalibrationCurve, tier: Tier, relative_change: f32) -> Option<f32> {
    ActiveInverse::new(curve, tier).map(|inverse| inverse.pressure_kpa(curve, relative_change))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::ARTICLE_TABLE_1;

    #[cfg(feature = "research-tiers")]
    #[test]
    fn piecewise_linear_on_table_1_matches_a_hand_computation() {
        let errors = leave_one_out_errors_kpa(&ARTICLE_TABLE_1, Tier::PiecewiseLinear);
        assert_eq!(errors.len(), 4);
        // Without the 10 kPa point, 0.0829 lies on the line from (0, 0) to (20, 0.1475).
        let expected = 0.0829 / 0.1475 * 20.0 - 10.0;
        let got = errors[0].unwrap_or(f32::NAN);
        assert!((got - expected).abs() < 1e-4, "{got} vs {expected}");
    }

    #[test]
    fn the_most_points_a_curve_holds_do_not_overflow() {
        let points: [CurvePoint; MAX_CURVE_POINTS] =
            core::array::from_fn(|index| CurvePoint::new(index as f32, index as f32 * 0.01));
        // Points on a line, which each of these tiers reproduces.
        for tier in [Tier::PiecewiseLinear, Tier::MonotoneCubic, Tier::Table]
            .into_iter()
            .filter(|tier| tier.is_built())
        {
            let errors = leave_one_out_errors_kpa(&points, tier);
            assert_eq!(errors.len(), MAX_CURVE_POINTS - 2);
            for error in errors {
                assert!(
                    error.unwrap_or(f32::NAN).abs() < 1e-4,
                    "{tier:?}: {error:?}"
                );
            }
        }
        // More points than a curve holds: no panic, the reduced curves simply do not fit.
        let too_many: [CurvePoint; MAX_CURVE_POINTS + 4] =
            core::array::from_fn(|index| CurvePoint::new(index as f32, index as f32 * 0.01));
        let errors = leave_one_out_errors_kpa(&too_many, Tier::MonotoneCubic);
        assert!(errors.len() <= MAX_CURVE_POINTS);
    }

    #[cfg(not(feature = "research-tiers"))]
    #[test]
    fn a_tier_this_build_does_not_have_gives_no_prediction() {
        let errors = leave_one_out_errors_kpa(&ARTICLE_TABLE_1, Tier::PiecewiseLinear);
        assert_eq!(errors.len(), 4);
        assert!(errors.iter().all(Option::is_none));
    }

    #[test]
    fn too_few_points_give_no_folds() {
        assert!(leave_one_out_errors_kpa(&ARTICLE_TABLE_1[..2], Tier::MonotoneCubic).is_empty());
    }
}
