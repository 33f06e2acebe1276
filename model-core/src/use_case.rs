//! "Model only what a use case needs": pick the cheapest tier whose error fits a use case's
//! pressure range, temperature range and error budget, or say why none does.
//!
//! Error is measured, not assumed, from the calibration in hand, as the sum of four parts:
//! - numerical: the tier's largest deviation from the reference curve (the monotone cubic
//!   through the calibration points) over a fine grid of the use case's pressure range;
//! - model form: for the interpolating forms, how well the form predicts a calibration point it
//!   was not built from (leave-one-out over the interior points in the range), scaled from the
//!   doubled spacing a fold has to the calibration's own spacing by the form's order of accuracy
//!   (2^-3 for the cubic, which the table and the polynomial carry too, 2^-2 for straight lines
//!   between points); for the fitted forms (linear, saturating), their error at the calibration
//!   points;
//! - noise: the pressure noise the converter's 0.5 fF rms causes where the curve is flattest in
//!   the range, on the taxel's C0 shrunk by the permittivity at the range's warmest temperature;
//! - temperature: the pad sensor's uncertainty (TMP117, 0.1 °C) times the steepest slope of the
//!   permittivity law inside the use case's temperature range, in pressure at the flattest point.
//!
//! Cost is the instruction count per taxel conversion measured on a Cortex-M4F under QEMU
//! (`cargo xtask m4-test`, which fails when a build drifts from these figures).
//!
//! Selection chooses only among the tiers on the Pareto front of cost against error, the
//! device's tiers ([`Tier::ON_DEVICE`]: linear, table, monotone-cubic; see [`crate::inverse`]),
//! in every build: the research tiers (feature `research-tiers`) are chosen by name, never by a
//! use case, so a host and a device select alike.

use heapless::Vec;

use crate::calibration::{CalibrationCurve, TemperatureLaw, MAX_CURVE_POINTS};
use crate::conditioning::{worst_noise_kpa, CONVERTER_NOISE_PF};
use crate::inverse::{TaxelInverses, Tier};
use crate::validation::leave_one_out_errors_kpa;

/// Instructions per taxel conversion on the Cortex-M4F, per tier: generated from a measurement
/// (see the module it comes from).
pub use crate::measured_instructions::MEASURED_INSTRUCTIONS;

/// Uncertainty of the pad's temperature sensor, °C (TMP117: +-0.1 °C from -20 to 50 °C).
pub const TEMPERATURE_UNCERTAINTY_C: f32 = 0.1;

/// Points of the pressure grid the error is measured on.
const ERROR_GRID_POINTS: usize = 501;

/// What a use case needs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UseCase {
    /// Highest pressure of interest, kPa (the range starts at 0).
    pub pressure_max_kpa: f32,
    /// Lowest pad temperature expected, °C.
    pub temperature_min_c: f32,
    /// Highest pad temperature expected, °C.
    pub temperature_max_c: f32,
    /// Largest acceptable error, kPa.
    pub error_budget_kpa: f32,
}

impl UseCase {
    /// Whether the use case can be served: a finite positive pressure range and error budget,
    /// and finite temperatures with the lowest below the highest. The one rule for the device's
    /// argument check and the tier selection.
    pub fn is_valid(&self) -> bool {
        self.pressure_max_kpa.is_finite()
            && self.pressure_max_kpa > 0.0
            && self.temperature_min_c.is_finite()
            && self.temperature_max_c.is_finite()
            && self.temperature_min_c < self.temperature_max_c
            && self.error_budget_kpa.is_finite()
            && self.error_budget_kpa > 0.0
    }

    /// Light touch: 0-10 kPa at room temperature, 0.1 kPa.
    pub const LIGHT_TOUCH: UseCase = UseCase {
        pressure_max_kpa: 10.0,
        temperature_min_c: 20.0,
        temperature_max_c: 30.0,
        error_budget_kpa: 0.1,
    };
    /// Robot gripper: 0-50 kPa at 15-35 °C, 0.5 kPa.
    pub const GRIPPER: UseCase = UseCase {
        pressure_max_kpa: 50.0,
        temperature_min_c: 15.0,
        temperature_max_c: 35.0,
        error_budget_kpa: 0.5,
    };
    /// Glove: 0-50 kPa at 25-40 °C (skin-warmed), 1 kPa.
    pub const GLOVE: UseCase = UseCase {
        pressure_max_kpa: 50.0,
        temperature_min_c: 25.0,
        temperature_max_c: 40.0,
        error_budget_kpa: 1.0,
    };
}

/// A tier with its measured error and cost for a use case.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TierChoice {
    /// The tier.
    pub tier: Tier,
    /// Largest deviation from the reference curve over the use case's range, kPa.
    pub numerical_error_kpa: f32,
    /// Estimated error of the tier's curve form between the calibration points (leave-one-out,
    /// scaled to the calibration's spacing), kPa.
    pub model_form_error_kpa: f32,
    /// rms pressure noise from converter noise where the curve is flattest in the range, kPa.
    pub noise_kpa: f32,
    /// Pressure error from the temperature sensor's uncertainty over the range, kPa.
    pub temperature_error_kpa: f32,
    /// Measured instructions per taxel conversion on the Cortex-M4F.
    pub instructions: u32,
}

impl TierChoice {
    /// The error compared with the budget: the sum of the four parts.
    pub fn total_error_kpa(&self) -> f32 {
        self.numerical_error_kpa
            + self.model_form_error_kpa
            + self.noise_kpa
            + self.temperature_error_kpa
    }
}

/// What selection needs to know about one taxel.
#[derive(Debug, Clone, Copy)]
pub struct TaxelEvidence<'a> {
    /// The taxel's tiers.
    pub inverses: &'a TaxelInverses,
    /// Its calibration curve (for leave-one-out).
    pub curve: &'a CalibrationCurve,
    /// Its unloaded sensor capacitance C0 at 25 °C, pF (the calibrated one, else nominal).
    pub sensor_pf: f32,
}

/// Why no tier was chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SelectionError {
    /// A limit is not finite, the range is empty, or the budget is not positive.
    InvalidUseCase,
    /// The pressure range reaches above the calibrated top.
    PressureAboveCalibration {
        /// Top of the calibration, kPa.
        top_kpa: f32,
    },
    /// The temperature range leaves the characterised range, where no error can be promised.
    TemperatureOutsideCharacterised {
        /// Lowest characterised temperature, °C.
        min_c: f32,
        /// Highest characterised temperature, °C.
        max_c: f32,
    },
    /// Even the most accurate tier misses the budget; here is the best one.
    NoTierWithinBudget {
        /// The most accurate tier and its error.
        best: TierChoice,
    },
}

/// Measured instructions for a tier.
pub fn measured_instructions(tier: Tier) -> u32 {
    MEASURED_INSTRUCTIONS
        .iter()
        .find(|(measured, _)| *measured == tier)
        .map_or(u32::MAX, |(_, instructions)| *instructions)
}

/// Order of accuracy by which a leave-one-out error (at twice the spacing) is scaled down to the
/// calibration's own spacing: 2^-order.
const fn order_of_accuracy(tier: Tier) -> i32 {
    match tier {
        Tier::MonotoneCubic | Tier::Table | Tier::Polynomial => 3,
        Tier::PiecewiseLinear => 2,
        Tier::Linear | Tier::Saturating | Tier::SaturatingMicromath => 0,
    }
}

/// Largest |numerical deviation| of a tier from the reference curve over `0 ..= pressure_max_kpa`.
pub fn numerical_error_kpa(inverses: &TaxelInverses, tier: Tier, pressure_max_kpa: f32) -> f32 {
    let mut error_kpa = 0.0f32;
    for step in 0..ERROR_GRID_POINTS {
        let pressure_kpa = pressure_max_kpa * step as f32 / (ERROR_GRID_POINTS - 1) as f32;
        let relative_change = inverses.relative_change_at(pressure_kpa);
        let error = (inverses.pressure_kpa(tier, relative_change) - pressure_kpa).abs();
        if !(error <= error_kpa) {
            error_kpa = if error.is_nan() { f32::INFINITY } else { error };
        }
    }
    error_kpa
}

/// The curve form whose model-form error a tier carries: the table and the polynomial
/// approximate the monotone cubic (their own distance from it is the numerical part).
const fn form_of(tier: Tier) -> Tier {
    match tier {
        Tier::Table | Tier::Polynomial => Tier::MonotoneCubic,
        other => other,
    }
}

/// Model-form error of a tier over the interior points up to the first one at or above
/// `pressure_max_kpa`; 0 when the curve has no interior point.
///
/// For the interpolating forms (the cubic, and straight lines between points) it is the
/// leave-one-out error scaled by the form's order. The fitted forms (linear, saturating) do not
/// pass through the points, so their error at the points, with the fit in hand, is already
/// their form error (refitting without each point would barely move it, and would cost the MCU
/// seconds of soft-float fitting).
pub fn model_form_error_kpa(taxel: &TaxelEvidence<'_>, tier: Tier, pressure_max_kpa: f32) -> f32 {
    let points = taxel.curve.points();
    let form = form_of(tier);
    let errors = match form {
        Tier::MonotoneCubic | Tier::PiecewiseLinear => leave_one_out_errors_kpa(points, form),
        _ => {
            let mut residuals: Vec<Option<f32>, MAX_CURVE_POINTS> = Vec::new();
            for point in points.iter().skip(1).take(points.len().saturating_sub(2)) {
                let predicted_kpa = taxel.inverses.pressure_kpa(tier, point.relative_change);
                if residuals
                    .push(Some(predicted_kpa - point.pressure_kpa))
                    .is_err()
                {
                    break;
                }
            }
            residuals
        }
    };
    let mut worst_kpa = 0.0f32;
    for (point, error) in points.iter().skip(1).zip(&errors) {
        let error_kpa = error.map_or(f32::INFINITY, f32::abs);
        if !(error_kpa <= worst_kpa) {
            worst_kpa = if error_kpa.is_nan() {
                f32::INFINITY
            } else {
                error_kpa
            };
        }
        if point.pressure_kpa >= pressure_max_kpa {
            break;
        }
    }
    worst_kpa / (1u32 << order_of_accuracy(form)) as f32
}

/// Error and cost of a tier for a use case on one taxel.
pub fn evaluate_tier(
    taxel: &TaxelEvidence<'_>,
    tier: Tier,
    law: &TemperatureLaw,
    use_case: &UseCase,
) -> TierChoice {
    let pressure_max_kpa = use_case.pressure_max_kpa;
    let forward = taxel.inverses.monotone_cubic().forward();
    let (min_c, max_c) = (use_case.temperature_min_c, use_case.temperature_max_c);
    // The warmest temperature shrinks C0 most (the permittivity falls above 25 °C).
    let ratio_min = law
        .permittivity_ratio(min_c)
        .min(law.permittivity_ratio(max_c));
    let noise_kpa = worst_noise_kpa(
        forward,
        pressure_max_kpa,
        taxel.sensor_pf * ratio_min,
        CONVERTER_NOISE_PF,
    );
    // A temperature error dT moves dC/C0 by (1 + y) (dk/dT) dT / k; as capacitance that is
    // (1 + y) C0 |dk/dT| dT, turned into pressure like converter noise.
    let top_relative = f64::from(taxel.inverses.relative_change_at(pressure_max_kpa));
    let slope_per_c = law.steepest_slope_per_c(min_c, max_c);
    let temperature_pf =
        (1.0 + top_relative) as f32 * taxel.sensor_pf * slope_per_c * TEMPERATURE_UNCERTAINTY_C;
    let temperature_error_kpa = if temperature_pf > 0.0 {
        worst_noise_kpa(
            forward,
            pressure_max_kpa,
            taxel.sensor_pf * ratio_min,
            temperature_pf,
        )
    } else {
        0.0
    };
    TierChoice {
        tier,
        numerical_error_kpa: numerical_error_kpa(taxel.inverses, tier, pressure_max_kpa),
        model_form_error_kpa: model_form_error_kpa(taxel, tier, pressure_max_kpa),
        noise_kpa,
        temperature_error_kpa,
        instructions: measured_instructions(tier),
    }
}

/// The cheapest tier (fewest measured instructions) that fits the use case on every one of these
/// taxels; a tier's error is that of its worst taxel. The candidates are the device's tiers
/// ([`Tier::ON_DEVICE`]) in every build: a research tier is never chosen.
pub fn select_tier_for_taxels(
    taxels: &[TaxelEvidence<'_>],
    law: &TemperatureLaw,
    use_case: &UseCase,
) -> Result<TierChoice, SelectionError> {
    if taxels.is_empty() || !use_case.is_valid() {
        return Err(SelectionError::InvalidUseCase);
    }
    let top_kpa = taxels
        .iter()
        .map(|taxel| taxel.curve.top().pressure_kpa)
        .fold(f32::INFINITY, f32::min);
    if use_case.pressure_max_kpa > top_kpa {
        return Err(SelectionError::PressureAboveCalibration { top_kpa });
    }
    let (min_c, max_c) = (law.characterised_min_c(), law.characterised_max_c());
    if !(use_case.temperature_min_c >= min_c && use_case.temperature_max_c <= max_c) {
        return Err(SelectionError::TemperatureOutsideCharacterised { min_c, max_c });
    }
    let mut cheapest_fit: Option<TierChoice> = None;
    let mut most_accurate: Option<TierChoice> = None;
    for tier in Tier::ON_DEVICE {
        if !taxels.iter().all(|taxel| taxel.inverses.supports(tier)) {
            continue;
        }
        let Some(choice) = taxels
            .iter()
            .map(|taxel| evaluate_tier(taxel, tier, law, use_case))
            .reduce(|worst, next| {
                if next.total_error_kpa() > worst.total_error_kpa() {
                    next
                } else {
                    worst
                }
            })
        else {
            continue;
        };
        if most_accurate.is_none_or(|best| choice.total_error_kpa() < best.total_error_kpa()) {
            most_accurate = Some(choice);
        }
        if choice.total_error_kpa() <= use_case.error_budget_kpa
            && cheapest_fit.is_none_or(|best| choice.instructions < best.instructions)
        {
            cheapest_fit = Some(choice);
        }
    }
    match (cheapest_fit, most_accurate) {
        (Some(choice), _) => Ok(choice),
        (None, Some(best)) => Err(SelectionError::NoTierWithinBudget { best }),
        (None, None) => Err(SelectionError::InvalidUseCase),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conditioning::NOMINAL_SENSOR_PF;

    #[test]
    fn every_tier_has_a_measured_instruction_count() {
        for tier in Tier::ALL {
            let instructions = measured_instructions(tier);
            assert!(instructions > 0 && instructions < u32::MAX, "{tier:?}");
        }
    }

    /// `check` of one taxel of the article's curve as selection's evidence, and its law.
    fn with_article_evidence(check: impl FnOnce(&[TaxelEvidence<'_>], &TemperatureLaw)) {
        let curve = CalibrationCurve::article_default();
        let inverses = TaxelInverses::new(&curve);
        let evidence = [TaxelEvidence {
            inverses: &inverses,
            curve: &curve,
            sensor_pf: NOMINAL_SENSOR_PF,
        }];
        check(&evidence, &TemperatureLaw::article_default());
    }

    #[test]
    fn each_use_case_gets_the_cheapest_tier_that_fits_its_budget_or_says_why() {
        with_article_evidence(|evidence, law| {
            for use_case in [UseCase::LIGHT_TOUCH, UseCase::GRIPPER, UseCase::GLOVE] {
                match select_tier_for_taxels(evidence, law, &use_case) {
                    Ok(choice) => {
                        assert!(choice.total_error_kpa() <= use_case.error_budget_kpa);
                        for taxel in evidence {
                            for tier in Tier::ON_DEVICE
                                .into_iter()
                                .filter(|tier| taxel.inverses.supports(*tier))
                            {
                                let other = evaluate_tier(taxel, tier, law, &use_case);
                                if other.instructions < choice.instructions {
                                    assert!(
                                        other.total_error_kpa() > use_case.error_budget_kpa,
                                        "{use_case:?}: {tier:?} is cheaper than {:?} and fits",
                                        choice.tier
                                    );
                                }
                            }
                        }
                    }
                    Err(SelectionError::NoTierWithinBudget { best }) => {
                        assert!(best.total_error_kpa() > use_case.error_budget_kpa);
                    }
                    Err(other) => panic!("{use_case:?}: {other:?}"),
                }
            }
        });
    }

    #[test]
    fn the_temperature_range_counts() {
        let curve = CalibrationCurve::article_default();
        let inverses = TaxelInverses::new(&curve);
        let law = TemperatureLaw::article_default();
        let taxel = TaxelEvidence {
            inverses: &inverses,
            curve: &curve,
            sensor_pf: NOMINAL_SENSOR_PF,
        };
        let cold = UseCase {
            temperature_min_c: 5.0,
            temperature_max_c: 25.0,
            ..UseCase::GRIPPER
        };
        let warm = UseCase {
            temperature_min_c: 30.0,
            temperature_max_c: 55.0,
            ..UseCase::GRIPPER
        };
        let cold = evaluate_tier(&taxel, Tier::MonotoneCubic, &law, &cold);
        let warm = evaluate_tier(&taxel, Tier::MonotoneCubic, &law, &warm);
        // The article's law is flat at or below 25 °C: no temperature error there.
        assert_eq!(cold.temperature_error_kpa, 0.0);
        // Above: 0.1 °C x 0.108 %/°C x (1 + 0.2563) = 1.36e-4 of dC/C0, over the flattest
        // slope (about 0.0024 /kPa at 50 kPa): about 0.06 kPa.
        assert!(
            (0.04..0.08).contains(&warm.temperature_error_kpa),
            "{}",
            warm.temperature_error_kpa
        );
        assert!(warm.noise_kpa > cold.noise_kpa);
    }

    #[test]
    fn model_form_error_is_the_scaled_leave_one_out_or_the_fit_error() {
        let curve = CalibrationCurve::article_default();
        let inverses = TaxelInverses::new(&curve);
        let taxel = TaxelEvidence {
            inverses: &inverses,
            curve: &curve,
            sensor_pf: NOMINAL_SENSOR_PF,
        };
        // Piecewise linear (a research tier) without the 30 kPa point misses it by 2.02 kPa
        // (validation's test computes such a fold by hand); scaled by 2^-2 for straight lines.
        #[cfg(feature = "research-tiers")]
        {
            let linear_pieces = model_form_error_kpa(&taxel, Tier::PiecewiseLinear, 50.0);
            assert!(
                (linear_pieces - 2.019 / 4.0).abs() < 0.01,
                "{linear_pieces}"
            );
            // Up to 10 kPa only the 10 kPa fold counts.
            let light = model_form_error_kpa(&taxel, Tier::PiecewiseLinear, 10.0);
            assert!((light - 1.2407 / 4.0).abs() < 0.01, "{light}");
        }
        // The table and the polynomial carry the cubic's form error.
        let cubic = model_form_error_kpa(&taxel, Tier::MonotoneCubic, 50.0);
        assert_eq!(model_form_error_kpa(&taxel, Tier::Table, 50.0), cubic);
        #[cfg(feature = "research-tiers")]
        assert_eq!(model_form_error_kpa(&taxel, Tier::Polynomial, 50.0), cubic);
        // The linear tier's form error is its miss at the points: at 20 kPa by hand, the secant
        // 50/0.2563 kPa per unit gives 28.78 kPa for 0.1475, 8.78 kPa off (the worst point).
        let linear = model_form_error_kpa(&taxel, Tier::Linear, 50.0);
        assert!((linear - 8.775).abs() < 0.01, "{linear}");
    }

    /// With or without the research tiers, selection picks from the Pareto front (the device's
    /// tiers), so a host with the research tiers selects as the device does.
    #[test]
    fn selection_picks_from_the_front_with_or_without_research_tiers() {
        with_article_evidence(|evidence, law| {
            let mut chosen = 0;
            for pressure_max_kpa in [5.0, 10.0, 20.0, 35.0, 50.0] {
                for error_budget_kpa in [0.02, 0.05, 0.1, 0.2, 0.5, 0.7, 1.0, 2.0, 5.0, 20.0] {
                    let use_case = UseCase {
                        pressure_max_kpa,
                        error_budget_kpa,
                        ..UseCase::GRIPPER
                    };
                    let Ok(choice) = select_tier_for_taxels(evidence, law, &use_case) else {
                        continue;
                    };
                    chosen += 1;
                    assert!(
                        Tier::ON_DEVICE.contains(&choice.tier),
                        "{use_case:?}: {:?} is off the front",
                        choice.tier
                    );
                }
            }
            assert!(chosen > 0);
        });
    }
}
