//! Host-side figures: criterion's time per conversion, and what model-core says about its own
//! tiers on the article's curve (leave-one-out model-form error, converter-noise propagation,
//! use-case selection).

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use model_core::conditioning::{CONVERTER_NOISE_PF, NOMINAL_SENSOR_PF};
use model_core::inverse::{InverseCurve, PolynomialInverse, POLYNOMIAL_DEGREE};
use model_core::use_case::evaluate_tier;
use model_core::{
    leave_one_out_errors_kpa, select_tier_for_taxels, CalibrationCurve, SelectionError,
    TaxelInverses, Tier, TierChoice, UseCase, ARTICLE_TABLE_1,
};

use crate::m4;

/// Criterion's measurement of one benchmark.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HostTime {
    /// Mean time per conversion, ns.
    pub nanoseconds: f64,
    /// Lower end of criterion's 95 % confidence interval, ns.
    pub lower_nanoseconds: f64,
    /// Upper end, ns.
    pub upper_nanoseconds: f64,
}

impl HostTime {
    /// Conversions per second on one core.
    pub fn per_second(&self) -> f64 {
        1e9 / self.nanoseconds
    }
}

/// Runs `cargo bench -p model-core --bench tiers --features research-tiers` (every tier, the
/// research ones included) with its results under `criterion_home`.
pub fn run_benches(root: &Path, criterion_home: &Path) -> Result<()> {
    m4::run_checked(
        m4::cargo()
            .current_dir(root)
            .env("CRITERION_HOME", criterion_home)
            .args(["bench", "-p", "model-core", "--bench", "tiers"])
            .args(["--features", "research-tiers"]),
    )
}

/// Reads one benchmark's result: mean time per iteration over its throughput in elements.
pub fn read_bench(criterion_home: &Path, group: &str, tier: Tier) -> Result<HostTime> {
    let directory: PathBuf = criterion_home.join(group).join(tier.name()).join("new");
    let read = |name: &str| -> Result<serde_json::Value> {
        let path = directory.join(name);
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("reading {}", path.display()))?;
        serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))
    };
    let estimates = read("estimates.json")?;
    let benchmark = read("benchmark.json")?;
    let elements = benchmark["throughput"]["Elements"]
        .as_f64()
        .ok_or_else(|| anyhow!("{group}/{}: no Elements throughput", tier.name()))?;
    let value = |pointer: &str| {
        estimates
            .pointer(pointer)
            .and_then(serde_json::Value::as_f64)
            .map(|nanoseconds| nanoseconds / elements)
            .ok_or_else(|| anyhow!("{group}/{}: no {pointer} in estimates", tier.name()))
    };
    Ok(HostTime {
        nanoseconds: value("/mean/point_estimate")?,
        lower_nanoseconds: value("/mean/confidence_interval/lower_bound")?,
        upper_nanoseconds: value("/mean/confidence_interval/upper_bound")?,
    })
}

/// A tier's leave-one-out error on Table 1, kPa.
#[derive(Debug, Clone, PartialEq)]
pub struct LeaveOneOut {
    /// Largest error.
    pub max_kpa: f64,
    /// rms error.
    pub rms_kpa: f64,
    /// (left-out pressure, error) per interior point.
    pub per_point: Vec<(f32, f64)>,
}

/// Leave-one-out model-form error of a tier on Table 1: each interior point is left out, the
/// tier rebuilt from the others predicts its pressure. `None` when a reduced curve does not
/// support the tier.
pub fn leave_one_out(tier: Tier) -> Option<LeaveOneOut> {
    let points = ARTICLE_TABLE_1;
    let folds = leave_one_out_errors_kpa(&points, tier);
    let errors: Vec<(f32, f64)> = points[1..points.len() - 1]
        .iter()
        .zip(folds.iter())
        .map(|(point, error)| error.map(|error| (point.pressure_kpa, f64::from(error.abs()))))
        .collect::<Option<_>>()?;
    let max = errors.iter().map(|(_, error)| *error).fold(0.0, f64::max);
    let rms =
        (errors.iter().map(|(_, error)| error * error).sum::<f64>() / errors.len() as f64).sqrt();
    Some(LeaveOneOut {
        max_kpa: max,
        rms_kpa: rms,
        per_point: errors,
    })
}

/// rms pressure noise of a tier at a pressure from the converter's rms noise on C0: the noise in
/// dC/C0 times the tier's own dP/d(dC/C0) there (central difference over +-1 noise sigma).
pub fn pressure_noise_kpa(inverses: &TaxelInverses, tier: Tier, pressure_kpa: f32) -> f64 {
    let sigma = CONVERTER_NOISE_PF / NOMINAL_SENSOR_PF;
    let relative_change = inverses.relative_change_at(pressure_kpa);
    let up = inverses.pressure_kpa(tier, relative_change + sigma);
    let down = inverses.pressure_kpa(tier, relative_change - sigma);
    f64::from(up - down) / 2.0
}

/// Values of dC/C0, evenly spaced from 0 to the top point, at which the polynomial fits by degree
/// are compared with the monotone cubic.
pub const POLYNOMIAL_SWEEP_POINTS: usize = 2001;

/// Largest distance of a least-squares polynomial of the inverse with `coefficients` (u^1 up,
/// u = dC/C0 / top, evaluated as model-core's polynomial tier does, clamped to 0..top) from the
/// monotone cubic over 0 <= dC/C0 <= top, kPa.
fn polynomial_distance_kpa(
    inverses: &TaxelInverses,
    curve: &CalibrationCurve,
    coefficients: &[f32],
) -> f64 {
    let top = curve.top();
    let (top_relative_change, top_pressure_kpa) =
        (f64::from(top.relative_change), f64::from(top.pressure_kpa));
    (0..POLYNOMIAL_SWEEP_POINTS)
        .map(|index| {
            let relative_change =
                top_relative_change * index as f64 / (POLYNOMIAL_SWEEP_POINTS - 1) as f64;
            let u = relative_change / top_relative_change;
            let horner = coefficients
                .iter()
                .rev()
                .fold(0.0, |sum, coefficient| sum * u + f64::from(*coefficient));
            let pressure_kpa = (horner * u).clamp(0.0, top_pressure_kpa);
            let reference_kpa = f64::from(
                inverses
                    .monotone_cubic()
                    .pressure_kpa(relative_change as f32),
            );
            (pressure_kpa - reference_kpa).abs()
        })
        .fold(0.0, f64::max)
}

/// For each degree of model-core's polynomial fit of the inverse (1 up to one above the
/// polynomial tier's), on the article's curve: (degree, largest distance from the monotone cubic
/// in kPa, or None when the fit is refused as not monotone).
pub fn polynomial_degree_distances() -> Vec<(usize, Option<f64>)> {
    let curve = CalibrationCurve::article_default();
    let inverses = TaxelInverses::new(&curve);
    let reference = inverses.monotone_cubic();
    let distance = |coefficients: Option<&[f32]>| {
        coefficients.map(|coefficients| polynomial_distance_kpa(&inverses, &curve, coefficients))
    };
    macro_rules! degrees {
        ($($degree:literal),*) => {
            vec![$((
                $degree,
                distance(
                    PolynomialInverse::with_degree::<$degree>(reference, &curve)
                        .as_ref()
                        .map(|coefficients| &coefficients[..]),
                ),
            )),*]
        };
    }
    let mut distances = degrees!(1, 2, 3, 4, 5, 6, 7, 8, 9);
    distances.retain(|(degree, _)| *degree <= POLYNOMIAL_DEGREE + 1);
    distances
}

/// The article's curve, all tiers.
pub fn article_inverses() -> TaxelInverses {
    TaxelInverses::new(&CalibrationCurve::article_default())
}

/// A use case's selection and every tier's figures for it.
#[derive(Debug, Clone)]
pub struct UseCaseSelection {
    /// Name.
    pub name: &'static str,
    /// The use case.
    pub use_case: UseCase,
    /// What `select_tier_for_taxels` returned.
    pub selected: std::result::Result<TierChoice, SelectionError>,
    /// Every supported tier evaluated over the use case's range.
    pub evaluated: Vec<TierChoice>,
}

/// `select_tier_for_taxels` for the three use cases on the article's curve.
pub fn use_case_selections() -> Vec<UseCaseSelection> {
    let inverses = article_inverses();
    let curve = CalibrationCurve::article_default();
    let law = model_core::TemperatureLaw::article_default();
    let evidence = [model_core::TaxelEvidence {
        inverses: &inverses,
        curve: &curve,
        sensor_pf: NOMINAL_SENSOR_PF,
    }];
    [
        ("light touch", UseCase::LIGHT_TOUCH),
        ("gripper", UseCase::GRIPPER),
        ("glove", UseCase::GLOVE),
    ]
    .into_iter()
    .map(|(name, use_case)| UseCaseSelection {
        name,
        use_case,
        selected: select_tier_for_taxels(&evidence, &law, &use_case),
        evaluated: Tier::ALL
            .into_iter()
            .filter(|tier| inverses.supports(*tier))
            .map(|tier| evaluate_tier(&evidence[0], tier, &law, &use_case))
            .collect(),
    })
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolating_tiers_have_a_leave_one_out_error_and_linear_ignores_interior_points() {
        let LeaveOneOut {
            max_kpa: max,
            rms_kpa: rms,
            per_point: errors,
        } = leave_one_out(Tier::PiecewiseLinear).unwrap();
        assert_eq!(errors.len(), 4);
        assert!(max > 0.1 && rms <= max, "{max} {rms}");
        // The linear tier only uses the top point: leaving interior points out changes nothing,
        // its error is its distance to each point.
        let linear = leave_one_out(Tier::Linear).unwrap().per_point;
        let at_10 = linear
            .iter()
            .find(|(pressure, _)| *pressure == 10.0)
            .unwrap()
            .1;
        let expected = (0.0829f64 * 50.0 / 0.2563 - 10.0).abs();
        assert!((at_10 - expected).abs() < 1e-3, "{at_10} vs {expected}");
    }

    #[test]
    fn noise_grows_toward_the_top_as_the_curve_flattens() {
        let inverses = article_inverses();
        let low = pressure_noise_kpa(&inverses, Tier::MonotoneCubic, 5.0);
        let high = pressure_noise_kpa(&inverses, Tier::MonotoneCubic, 45.0);
        assert!(low > 0.005 && low < 0.05, "{low}");
        assert!(high > 2.0 * low, "{low} {high}");
        let linear_low = pressure_noise_kpa(&inverses, Tier::Linear, 5.0);
        let linear_high = pressure_noise_kpa(&inverses, Tier::Linear, 45.0);
        assert!((linear_low - linear_high).abs() < 1e-3 * linear_low.max(1e-9) + 1e-5);
    }

    #[test]
    fn the_polynomial_tier_degree_matches_its_own_inverse_and_higher_degrees_fit_closer() {
        let distances = polynomial_degree_distances();
        assert_eq!(distances.len(), POLYNOMIAL_DEGREE + 1);
        let at = |degree: usize| {
            distances
                .iter()
                .find(|(candidate, _)| *candidate == degree)
                .and_then(|(_, distance)| *distance)
        };
        // The polynomial tier itself, evaluated by model-core in f32, against the same reference.
        let inverses = article_inverses();
        let top = CalibrationCurve::article_default().top().relative_change;
        let tier_distance = (0..=2000)
            .map(|index| {
                let relative_change = top * index as f32 / 2000.0;
                f64::from(
                    (inverses.pressure_kpa(Tier::Polynomial, relative_change)
                        - inverses.monotone_cubic().pressure_kpa(relative_change))
                    .abs(),
                )
            })
            .fold(0.0, f64::max);
        let own = at(POLYNOMIAL_DEGREE).unwrap();
        assert!(
            (own - tier_distance).abs() < 1e-3,
            "{own} vs {tier_distance}"
        );
        assert!(at(1).unwrap() > at(3).unwrap(), "{distances:?}");
        assert!(at(1).unwrap() > 1.0, "{distances:?}");
    }

    #[test]
    fn every_use_case_gets_an_answer() {
        let selections = use_case_selections();
        assert_eq!(selections.len(), 3);
        for selection in selections {
            assert!(!selection.evaluated.is_empty());
        }
    }
}
