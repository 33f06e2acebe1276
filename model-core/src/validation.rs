//! Leave-one-out cross-validation of a tier on calibration points: how well a tier predicts a
//! point it was not built from, the honest measure of a curve form's error between the points.

use heapless::Vec;

use crate::calibration::{CalibrationCurve, CurvePoint, MAX_CURVE_POINTS};
use crate::inverse::{TaxelInverses, Tier};

/// Per interior point (index 1 ..= n - 2, in order), the tier's predicted pressure minus the
/// applied one when the curve is rebuilt without that point, kPa; `None` where the reduced curve
/// is invalid or cannot provide the tier.
pub fn leave_one_out_errors_kpa(
    points: &[CurvePoint],
    tier: Tier,
) -> Vec<Option<f32>, MAX_CURVE_POINTS> {
    let mut errors = Vec::new();
    for left_out in 1..points.len().saturating_sub(1) {
        let reduced: Vec<CurvePoint, MAX_CURVE_POINTS> = points
            .iter()
            .enumerate()
            .filter(|(index, _)| *index != left_out)
            .map(|(_, point)| *point)
            .collect();
        let error = CalibrationCurve::new(&reduced, 0)
            .ok()
            .map(|curve| TaxelInverses::new(&curve))
            .filter(|inverses| inverses.supports(tier))
            .map(|inverses| {
                let point = points[left_out];
                inverses.pressure_kpa(tier, point.relative_change) - point.pressure_kpa
            });
        // Interior points are fewer than MAX_CURVE_POINTS, so this always fits.
        let _ = errors.push(error);
    }
    errors
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::ARTICLE_TABLE_1;

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
    fn too_few_points_give_no_folds() {
        assert!(leave_one_out_errors_kpa(&ARTICLE_TABLE_1[..2], Tier::MonotoneCubic).is_empty());
    }
}
