//! "Model only what a use case needs": pick the cheapest tier whose error fits a use case's
//! pressure range, temperature range and error budget, or say why none does.
//!
//! Error is measured, not assumed: for each tier it is the largest deviation from the reference
//! curve (the monotone cubic through the calibration points) over a fine grid of the use case's
//! pressure range, computed from the calibration in hand, plus the pressure noise that the
//! converter's 0.5 fF rms noise causes at the top of the range, where the curve is flattest.
//! Cost is the instruction count per taxel conversion measured on a Cortex-M4F under QEMU
//! (`cargo xtask m4-test`, which fails when a build drifts from these figures).

use crate::inverse::{TaxelInverses, Tier};

/// Instructions per taxel conversion (temperature correction included) on the Cortex-M4F,
/// measured by the on-target benchmark (`TaxelModel::convert`, opt-level 3, mean over a
/// 0–50 kPa x 5–55 °C grid; see docs/PERFORMANCE.md); the on-target test fails if a build
/// drifts from them by more than 15 %.
pub const MEASURED_INSTRUCTIONS: [(Tier, u32); 7] = [
    (Tier::Linear, 88),
    (Tier::PiecewiseLinear, 119),
    (Tier::MonotoneCubic, 178),
    (Tier::Saturating, 146),
    (Tier::SaturatingMicromath, 132),
    (Tier::Table, 108),
    (Tier::Polynomial, 102),
];

/// rms converter noise at 100 S/s, pF (FDC1004: about 16 effective bits, 0.5 fF).
pub const CONVERTER_NOISE_PF: f32 = 0.0005;

/// A typical unloaded taxel capacitance, pF, used to turn converter noise into kPa.
pub const NOMINAL_SENSOR_PF: f32 = 4.5;

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
    pub model_error_kpa: f32,
    /// rms pressure noise from converter noise at the top of the range, kPa.
    pub noise_kpa: f32,
    /// Measured instructions per taxel conversion on the Cortex-M4F.
    pub instructions: u32,
}

impl TierChoice {
    /// The error compared with the budget: model error plus noise.
    pub fn total_error_kpa(&self) -> f32 {
        self.model_error_kpa + self.noise_kpa
    }
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

/// Error and cost of a tier over `0 ..= pressure_max_kpa`.
pub fn evaluate_tier(inverses: &TaxelInverses, tier: Tier, pressure_max_kpa: f32) -> TierChoice {
    let mut model_error_kpa = 0.0f32;
    for step in 0..ERROR_GRID_POINTS {
        let pressure_kpa = pressure_max_kpa * step as f32 / (ERROR_GRID_POINTS - 1) as f32;
        let relative_change = inverses.relative_change_at(pressure_kpa);
        let error = (inverses.pressure_kpa(tier, relative_change) - pressure_kpa).abs();
        model_error_kpa = model_error_kpa.max(error);
    }
    // Slope of the reference curve just below the top of the range, where it is smallest.
    let delta_kpa = (0.01 * pressure_max_kpa).max(1e-3);
    let slope_per_kpa = (inverses.relative_change_at(pressure_max_kpa)
        - inverses.relative_change_at(pressure_max_kpa - delta_kpa))
        / delta_kpa;
    let noise_kpa = if slope_per_kpa > 0.0 {
        CONVERTER_NOISE_PF / NOMINAL_SENSOR_PF / slope_per_kpa
    } else {
        f32::MAX
    };
    TierChoice {
        tier,
        model_error_kpa,
        noise_kpa,
        instructions: measured_instructions(tier),
    }
}

/// The cheapest tier (fewest measured instructions) that fits the use case on this taxel.
pub fn select_tier(
    inverses: &TaxelInverses,
    top_pressure_kpa: f32,
    characterised_min_c: f32,
    characterised_max_c: f32,
    use_case: &UseCase,
) -> Result<TierChoice, SelectionError> {
    select_tier_for_taxels(
        &[inverses],
        top_pressure_kpa,
        characterised_min_c,
        characterised_max_c,
        use_case,
    )
}

/// The cheapest tier that fits the use case on every one of these taxels; a tier's error is
/// that of its worst taxel.
pub fn select_tier_for_taxels(
    taxels: &[&TaxelInverses],
    top_pressure_kpa: f32,
    characterised_min_c: f32,
    characterised_max_c: f32,
    use_case: &UseCase,
) -> Result<TierChoice, SelectionError> {
    let valid = !taxels.is_empty()
        && use_case.pressure_max_kpa > 0.0
        && use_case.pressure_max_kpa.is_finite()
        && use_case.temperature_min_c <= use_case.temperature_max_c
        && use_case.error_budget_kpa > 0.0
        && use_case.error_budget_kpa.is_finite();
    if !valid {
        return Err(SelectionError::InvalidUseCase);
    }
    if use_case.pressure_max_kpa > top_pressure_kpa {
        return Err(SelectionError::PressureAboveCalibration {
            top_kpa: top_pressure_kpa,
        });
    }
    if !(use_case.temperature_min_c >= characterised_min_c
        && use_case.temperature_max_c <= characterised_max_c)
    {
        return Err(SelectionError::TemperatureOutsideCharacterised {
            min_c: characterised_min_c,
            max_c: characterised_max_c,
        });
    }
    let mut cheapest_fit: Option<TierChoice> = None;
    let mut most_accurate: Option<TierChoice> = None;
    for tier in Tier::ALL {
        if !taxels.iter().all(|inverses| inverses.supports(tier)) {
            continue;
        }
        let Some(choice) = taxels
            .iter()
            .map(|inverses| evaluate_tier(inverses, tier, use_case.pressure_max_kpa))
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
    use crate::calibration::{CalibrationCurve, TemperatureLaw};

    #[test]
    fn every_tier_has_a_measured_instruction_count() {
        for tier in Tier::ALL {
            let instructions = measured_instructions(tier);
            assert!(instructions > 0 && instructions < u32::MAX, "{tier:?}");
        }
    }

    #[test]
    fn each_use_case_gets_the_cheapest_tier_that_fits_its_budget() {
        let curve = CalibrationCurve::article_default();
        let inverses = TaxelInverses::new(&curve);
        let law = TemperatureLaw::article_default();
        for use_case in [UseCase::LIGHT_TOUCH, UseCase::GRIPPER, UseCase::GLOVE] {
            let choice = select_tier(
                &inverses,
                curve.top().pressure_kpa,
                law.characterised_min_c(),
                law.characterised_max_c(),
                &use_case,
            )
            .unwrap_or_else(|error| panic!("{use_case:?}: {error:?}"));
            assert!(
                choice.total_error_kpa() <= use_case.error_budget_kpa,
                "{use_case:?}: {choice:?}"
            );
            assert_eq!(choice.instructions, measured_instructions(choice.tier));
            for tier in Tier::ALL
                .into_iter()
                .filter(|tier| inverses.supports(*tier))
            {
                let other = evaluate_tier(&inverses, tier, use_case.pressure_max_kpa);
                if other.instructions < choice.instructions {
                    assert!(
                        other.total_error_kpa() > use_case.error_budget_kpa,
                        "{use_case:?}: {tier:?} is cheaper than {:?} and fits: {other:?}",
                        choice.tier
                    );
                }
            }
        }
    }
}
