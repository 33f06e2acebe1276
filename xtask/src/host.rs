//! Host-side figures: criterion's time per conversion, and what model-core says about its own
//! tiers on the article's curve (leave-one-out model-form error, converter-noise propagation,
//! use-case selection).

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use model_core::use_case::{evaluate_tier, CONVERTER_NOISE_PF, NOMINAL_SENSOR_PF};
use model_core::{
    select_tier, CalibrationCurve, CurvePoint, SelectionError, TaxelInverses, Tier, TierChoice,
    UseCase, ARTICLE_TABLE_1,
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

/// Runs `cargo bench -p model-core --bench tiers` with its results under `criterion_home`.
pub fn run_benches(root: &Path, criterion_home: &Path) -> Result<()> {
    m4::run_checked(
        m4::cargo()
            .current_dir(root)
            .env("CRITERION_HOME", criterion_home)
            .args(["bench", "-p", "model-core", "--bench", "tiers"]),
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
    let mut errors = Vec::new();
    for left_out in 1..points.len() - 1 {
        let reduced: Vec<CurvePoint> = points
            .iter()
            .enumerate()
            .filter(|(index, _)| *index != left_out)
            .map(|(_, point)| *point)
            .collect();
        let curve = CalibrationCurve::new(&reduced, 0).ok()?;
        let inverses = TaxelInverses::new(&curve);
        if !inverses.supports(tier) {
            return None;
        }
        let point = points[left_out];
        let predicted = inverses.pressure_kpa(tier, point.relative_change);
        errors.push((
            point.pressure_kpa,
            f64::from((predicted - point.pressure_kpa).abs()),
        ));
    }
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
    /// What `select_tier` returned.
    pub selected: std::result::Result<TierChoice, SelectionError>,
    /// Every supported tier evaluated over the use case's range.
    pub evaluated: Vec<TierChoice>,
}

/// `select_tier` for the three use cases on the article's curve.
pub fn use_case_selections() -> Vec<UseCaseSelection> {
    let inverses = article_inverses();
    let law = model_core::TemperatureLaw::article_default();
    let top_kpa = CalibrationCurve::article_default().top().pressure_kpa;
    [
        ("light touch", UseCase::LIGHT_TOUCH),
        ("gripper", UseCase::GRIPPER),
        ("glove", UseCase::GLOVE),
    ]
    .into_iter()
    .map(|(name, use_case)| UseCaseSelection {
        name,
        use_case,
        selected: select_tier(
            &inverses,
            top_kpa,
            law.characterised_min_c(),
            law.characterised_max_c(),
            &use_case,
        ),
        evaluated: Tier::ALL
            .into_iter()
            .filter(|tier| inverses.supports(*tier))
            .map(|tier| evaluate_tier(&inverses, tier, use_case.pressure_max_kpa))
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
    fn every_use_case_gets_an_answer() {
        let selections = use_case_selections();
        assert_eq!(selections.len(), 3);
        for selection in selections {
            assert!(!selection.evaluated.is_empty());
        }
    }
}
