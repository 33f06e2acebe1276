//! The pad's physics: a taxel's capacitance from its pressure and the pad temperature,
//!
//! `C = Cp + C0 (1 + f(P)) eps(T) / eps(25 °C)`,
//!
//! where `f` is model-core's reference forward curve of the taxel's calibration (the monotone
//! cubic through the calibration points), `eps(T) / eps(25 °C)` is the calibration's permittivity
//! law, `C0` the taxel's unloaded capacitance and `Cp` its parasitic (cable and input)
//! capacitance, which does not follow the permittivity.
//!
//! Outside the calibrated pressures nothing was measured, so the simulation assumes: below
//! 0 kPa (and for a non-finite pressure) the taxel is unloaded; above the top calibration point
//! (50 kPa in the article) the curve continues as a straight line with the slope it has at the
//! top point. The permittivity law is model-core's, which is flat outside its points. A
//! non-finite temperature is taken as 25 °C.

use model_core::{
    Calibration, CalibrationError, TaxelModel, TemperatureLaw, REFERENCE_TEMPERATURE_C, TAXEL_COUNT,
};

/// Default unloaded capacitance C0 per taxel, pF: about 4.5 pF (the article's taxels), with the
/// small spread four hand-made taxels have.
pub const DEFAULT_UNLOADED_PF: [f32; TAXEL_COUNT] = [4.52, 4.47, 4.55, 4.46];

/// Default parasitic capacitance per taxel (shielded lead and converter input), pF.
pub const DEFAULT_PARASITIC_PF: f32 = 1.2;

/// Pressure step used to measure the curve's slope at its top point, kPa.
const TOP_SLOPE_STEP_KPA: f32 = 0.05;

/// One taxel's electrical parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaxelPhysics {
    /// Unloaded sensor capacitance C0 at 25 °C, pF (finite, > 0).
    pub unloaded_pf: f32,
    /// Parasitic capacitance Cp, pF (finite, >= 0).
    pub parasitic_pf: f32,
}

/// The simulated pad: four taxels and the calibration whose curve and temperature law they
/// follow.
#[derive(Debug, Clone, PartialEq)]
pub struct PadPhysics {
    /// Taxels C11, C12, C21, C22, wired to CIN1..CIN4.
    pub taxels: [TaxelPhysics; TAXEL_COUNT],
    /// Source of the forward curve `f(P)` per taxel and of the permittivity law. Its
    /// `parasitic_pf` values are not used here (the taxels' own are):
    /// [`PadPhysics::matching_calibration`] gives the calibration a pad model should use.
    pub calibration: Calibration,
}

impl Default for PadPhysics {
    /// [`DEFAULT_UNLOADED_PF`], [`DEFAULT_PARASITIC_PF`] on every taxel, the article's curve and
    /// temperature law (`Calibration::default()`).
    fn default() -> Self {
        Self {
            taxels: core::array::from_fn(|taxel| TaxelPhysics {
                unloaded_pf: DEFAULT_UNLOADED_PF[taxel],
                parasitic_pf: DEFAULT_PARASITIC_PF,
            }),
            calibration: Calibration::default(),
        }
    }
}

impl PadPhysics {
    /// The calibration with each taxel's parasitic capacitance set to this pad's: what a pad
    /// model converting this simulation's readings should be given.
    pub fn matching_calibration(&self) -> Result<Calibration, CalibrationError> {
        let mut spec = self.calibration.to_spec();
        for (taxel_spec, taxel) in spec.taxels.iter_mut().zip(&self.taxels) {
            taxel_spec.parasitic_pf = taxel.parasitic_pf;
        }
        Calibration::new(&spec)
    }

    /// Index of the first taxel whose parameters are not finite or out of range.
    pub(crate) fn first_invalid_taxel(&self) -> Option<usize> {
        self.taxels.iter().position(|taxel| {
            let unloaded_ok = taxel.unloaded_pf.is_finite() && taxel.unloaded_pf > 0.0;
            let parasitic_ok = taxel.parasitic_pf.is_finite() && taxel.parasitic_pf >= 0.0;
            !(unloaded_ok && parasitic_ok)
        })
    }
}

/// The physics ready to evaluate.
#[derive(Debug, Clone)]
pub(crate) struct PhysicsModel {
    physics: PadPhysics,
    curves: [TaxelModel; TAXEL_COUNT],
    top_slope_per_kpa: [f32; TAXEL_COUNT],
    law: TemperatureLaw,
}

impl PhysicsModel {
    pub(crate) fn new(physics: PadPhysics) -> Self {
        let curves =
            core::array::from_fn(|taxel| TaxelModel::new(&physics.calibration.taxels()[taxel]));
        let top_slope_per_kpa = core::array::from_fn(|taxel| {
            let model: &TaxelModel = &curves[taxel];
            let top_kpa = physics.calibration.taxels()[taxel].curve.top().pressure_kpa;
            let below_kpa = (top_kpa - TOP_SLOPE_STEP_KPA).max(0.0);
            let span_kpa = top_kpa - below_kpa;
            if span_kpa > 0.0 {
                (model.inverses().relative_change_at(top_kpa)
                    - model.inverses().relative_change_at(below_kpa))
                    / span_kpa
            } else {
                0.0
            }
        });
        let law = physics.calibration.temperature_law().clone();
        Self {
            physics,
            curves,
            top_slope_per_kpa,
            law,
        }
    }

    pub(crate) fn physics(&self) -> &PadPhysics {
        &self.physics
    }

    /// dC/C0 at a pressure, extended past the top point with the top slope.
    pub(crate) fn relative_change(&self, taxel: usize, pressure_kpa: f32) -> f64 {
        let pressure_kpa = if pressure_kpa.is_finite() {
            pressure_kpa.max(0.0)
        } else {
            0.0
        };
        let top_kpa = self.physics.calibration.taxels()[taxel]
            .curve
            .top()
            .pressure_kpa;
        let inverses = self.curves[taxel].inverses();
        if pressure_kpa <= top_kpa {
            inverses.relative_change_at(pressure_kpa) as f64
        } else {
            inverses.relative_change_at(top_kpa) as f64
                + self.top_slope_per_kpa[taxel] as f64 * (pressure_kpa - top_kpa) as f64
        }
    }

    /// The taxel's capacitance, pF.
    pub(crate) fn capacitance_pf(
        &self,
        taxel: usize,
        pressure_kpa: f32,
        temperature_c: f32,
    ) -> f64 {
        let temperature_c = if temperature_c.is_finite() {
            temperature_c
        } else {
            REFERENCE_TEMPERATURE_C
        };
        let parameters = self.physics.taxels[taxel];
        let permittivity_ratio = self.law.permittivity_ratio(temperature_c) as f64
            / self.law.permittivity_ratio(REFERENCE_TEMPERATURE_C) as f64;
        parameters.parasitic_pf as f64
            + parameters.unloaded_pf as f64
                * (1.0 + self.relative_change(taxel, pressure_kpa))
                * permittivity_ratio
    }
}
