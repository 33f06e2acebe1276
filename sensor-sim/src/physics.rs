//! The pad's physics: the simulator's own ground truth, written without the pressure model
//! (model-core is used only to hand a calibration to callers, see
//! [`PadPhysics::matching_calibration`]).
//!
//! # Capacitance
//!
//! `C = Cp + C0 r (1 + dC/C0) k(T)`
//!
//! - `C0` is the taxel's unloaded sensor capacitance at 25 °C ([`TaxelPhysics::unloaded_pf`];
//!   by default 4.46–4.55 pF, the spread of four hand-made taxels around the article's 4.57 pF).
//! - `Cp` is the parasitic capacitance of the shielded lead and the converter input
//!   ([`TaxelPhysics::parasitic_pf`], 1.2 pF by default). It is not part of the dielectric, so
//!   it neither follows the load nor the permittivity.
//! - `r` is the fraction of C0 the pad retains after load cycles (1 unless
//!   [`PadEffects::baseline_loss_per_cycle`] is set, see below).
//! - `k(T)` is the dielectric's permittivity relative to 25 °C.
//!
//! # Pressure: a parallel plate over a densifying elastomer
//!
//! The article's Eq. 4 for a parallel plate whose gap closes by `δ` from `d0`:
//! `dC/C0 = δ / (d0 − δ) = ε / (1 − ε)` with the compressive strain `ε = δ / d0`. The dielectric
//! (Cu/CB/PDMS, a filled elastomer) is modelled as a foam that stiffens as it densifies:
//!
//! `P(ε) = E0 ε / (1 − ε/εd)^m`
//!
//! with `E0` the initial compressive modulus ([`TaxelPhysics::modulus_kpa`], 110.4–112.6 kPa by
//! default: a ±1 % spread between taxels), `εd` the densification strain the gap can never
//! close beyond ([`Dielectric::densification_strain`], 0.2464) and `m` the densification
//! exponent ([`Dielectric::densification_exponent`], 0.444). The strain at a pressure is the
//! root of `P(ε) = P` on `[0, εd)` (unique: `P(ε)` increases from 0 to infinity), found by
//! safeguarded Newton iteration in f64. The resulting curve is none of the model's families: not
//! a polynomial or spline in P, not piecewise linear, not `A (1 − e^(−P/B))`.
//!
//! The three parameters were fitted to the article's Table 1 (minimax over 10..50 kPa). The
//! nominal curve (`E0` = 111.5 kPa, the mean of the four taxels) against Table 1:
//!
//! | P (kPa) | 10 | 20 | 30 | 40 | 50 |
//! |---|---|---|---|---|---|
//! | Table 1 dC/C0 | 0.0829 | 0.1475 | 0.1981 | 0.2317 | 0.2563 |
//! | this curve | 0.08239 | 0.14816 | 0.19726 | 0.23234 | 0.25692 |
//!
//! within 0.0009 of Table 1 at every point, and so is the mean of the four default taxels; each
//! default taxel is within 0.0021 of it (the tests in `tests/physics.rs` allow 0.001 and
//! 0.0025). The slope at 0 is `1/E0`, 0.0090 per kPa (Table 1's 0–10 kPa secant: 0.0083).
//! Above 50 kPa the same law continues: the curve keeps rising more and more slowly
//! towards `εd / (1 − εd)` = 0.327 (0.274 at 60 kPa, 0.306 at 100 kPa). Pressures are clamped
//! to [0, [`MAX_PRESSURE_KPA`]]; a negative or non-finite pressure is an unloaded taxel.
//!
//! # Temperature
//!
//! The sensor's own capacitance scales with the permittivity; the article (Fig. 13) measured
//! eps_r = 5.56 at 25 °C and 5.38 at 55 °C and says the drop starts above 25 °C. Assumed here:
//! `k(T) = 1` at and below 25 °C, `k(T) = 1 − 0.0324 (T − 25)/30` above, continued linearly past
//! 55 °C (nothing was measured there; the device's model flags it) up to
//! [`MAX_TEMPERATURE_C`], where it stops. The mechanics do not depend on temperature (the
//! article gives no data). A non-finite temperature is taken as 25 °C.
//!
//! # Optional effects (off by default)
//!
//! [`PadEffects`] adds what the article reports qualitatively or for another protocol; each is
//! evaluated at the simulated instant a conversion samples the scene, so it needs state, kept per
//! taxel:
//! - **Hysteresis.** After a peak pressure `Pp`, and until the taxel is fully unloaded (0 kPa),
//!   the strain below the peak is `ε(P) + h ε(Pp) 4x(1 − x)`, `x = P/Pp`: the pad recovers late
//!   on unloading, by at most `h` of the peak strain at half the peak (and never beyond the
//!   peak's strain). Reloading below the peak follows the same branch (no inner loops); above it
//!   the loading curve again. Continuous everywhere.
//! - **Baseline loss with cycling.** Each load cycle (above
//!   [`PadEffects::cycle_threshold_kpa`], then below half of it) removes
//!   [`PadEffects::baseline_loss_per_cycle`] of C0 (the article: 4.57 → 4.31 pF after 5000
//!   cycles at 5 kPa, [`ARTICLE_BASELINE_LOSS_PER_CYCLE`]), down to [`MIN_RETENTION`] of it.

use model_core::{Calibration, CalibrationError, CalibrationSpec, CurvePoint};

/// Taxels on the pad.
const TAXELS: usize = 4;

/// Default unloaded capacitance C0 per taxel at 25 °C, pF: about 4.5 pF (the article's taxels),
/// with the small spread four hand-made taxels have.
pub const DEFAULT_UNLOADED_PF: [f32; TAXELS] = [4.52, 4.47, 4.55, 4.46];

/// Default parasitic capacitance per taxel (shielded lead and converter input), pF.
pub const DEFAULT_PARASITIC_PF: f32 = 1.2;

/// Default initial compressive modulus E0 of the dielectric under each taxel, kPa (mean
/// 111.5 kPa, ±1 %).
pub const DEFAULT_MODULUS_KPA: [f32; TAXELS] = [112.6, 110.4, 112.0, 111.0];

/// Default densification strain εd.
pub const DEFAULT_DENSIFICATION_STRAIN: f32 = 0.2464;

/// Default densification exponent m.
pub const DEFAULT_DENSIFICATION_EXPONENT: f32 = 0.444;

/// The temperature at which C0 is given and the permittivity ratio is 1, °C.
pub const REFERENCE_TEMPERATURE_C: f32 = 25.0;

/// Relative permittivity drop per °C above 25 °C: 3.24 % over 30 °C (5.56 → 5.38).
const PERMITTIVITY_DROP_PER_C: f64 = 0.0324 / 30.0;

/// Above this temperature the permittivity stops changing, °C (the top of the converter's and
/// the temperature sensor's operating range).
pub const MAX_TEMPERATURE_C: f32 = 125.0;

/// Pressures are clamped to this, kPa (10 MPa: far beyond anything the pad survives; keeps the
/// strain root well inside f64).
pub const MAX_PRESSURE_KPA: f32 = 10_000.0;

/// The article's loss of C0 per load cycle: 1 − 4.31/4.57 over 5000 cycles.
pub const ARTICLE_BASELINE_LOSS_PER_CYCLE: f32 = (1.0 - 4.31 / 4.57) / 5000.0;

/// The baseline loss stops at this fraction of C0.
pub const MIN_RETENTION: f64 = 0.5;

/// Pressures of the factory calibration, kPa: 0, 5, …, 50.
pub const FACTORY_CALIBRATION_KPA: [f32; 11] = [
    0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0,
];

/// Newton steps are stopped at this change of the normalised strain.
const STRAIN_TOLERANCE: f64 = 1e-14;
/// At most this many root-finding steps (each halves the bracket at worst).
const MAX_ROOT_STEPS: usize = 200;

/// One taxel's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaxelPhysics {
    /// Unloaded sensor capacitance C0 at 25 °C, pF (finite, > 0).
    pub unloaded_pf: f32,
    /// Parasitic capacitance Cp, pF (finite, >= 0).
    pub parasitic_pf: f32,
    /// Initial compressive modulus E0 of the dielectric under the taxel, kPa (finite, > 0).
    pub modulus_kpa: f32,
}

/// The dielectric's densification, shared by the taxels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dielectric {
    /// Strain εd the gap closes towards but never reaches (0 < εd <= 0.9).
    pub densification_strain: f32,
    /// Exponent m of the stiffening (0 < m <= 10).
    pub densification_exponent: f32,
}

impl Default for Dielectric {
    fn default() -> Self {
        Self {
            densification_strain: DEFAULT_DENSIFICATION_STRAIN,
            densification_exponent: DEFAULT_DENSIFICATION_EXPONENT,
        }
    }
}

/// Effects of the pad's history, all off by default (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PadEffects {
    /// Extra strain on the unloading branch at half the peak, as a fraction of the peak's strain
    /// (0 ..= 0.5; 0 = no hysteresis).
    pub hysteresis: f32,
    /// Fraction of C0 lost per load cycle (0 ..= 0.01; 0 = no loss;
    /// [`ARTICLE_BASELINE_LOSS_PER_CYCLE`] is the article's).
    pub baseline_loss_per_cycle: f32,
    /// A cycle is a rise above this pressure and a fall below half of it, kPa (finite, > 0).
    pub cycle_threshold_kpa: f32,
}

impl Default for PadEffects {
    fn default() -> Self {
        Self {
            hysteresis: 0.0,
            baseline_loss_per_cycle: 0.0,
            cycle_threshold_kpa: 1.0,
        }
    }
}

impl PadEffects {
    /// Whether every value is in its documented range.
    pub fn is_valid(&self) -> bool {
        (0.0..=0.5).contains(&self.hysteresis)
            && (0.0..=0.01).contains(&self.baseline_loss_per_cycle)
            && self.cycle_threshold_kpa.is_finite()
            && self.cycle_threshold_kpa > 0.0
    }
}

/// The simulated pad.
#[derive(Debug, Clone, PartialEq)]
pub struct PadPhysics {
    /// Taxels C11, C12, C21, C22, wired to CIN1..CIN4.
    pub taxels: [TaxelPhysics; TAXELS],
    /// The dielectric's densification.
    pub dielectric: Dielectric,
    /// History effects (off by default).
    pub effects: PadEffects,
}

impl Default for PadPhysics {
    /// [`DEFAULT_UNLOADED_PF`], [`DEFAULT_PARASITIC_PF`] and [`DEFAULT_MODULUS_KPA`] per taxel,
    /// the default dielectric, no history effects.
    fn default() -> Self {
        Self {
            taxels: core::array::from_fn(|taxel| TaxelPhysics {
                unloaded_pf: DEFAULT_UNLOADED_PF[taxel],
                parasitic_pf: DEFAULT_PARASITIC_PF,
                modulus_kpa: DEFAULT_MODULUS_KPA[taxel],
            }),
            dielectric: Dielectric::default(),
            effects: PadEffects::default(),
        }
    }
}

/// A pressure as the physics takes it: negative or non-finite is unloaded, the rest clamped.
fn sanitized_pressure_kpa(pressure_kpa: f32) -> f64 {
    if pressure_kpa.is_finite() {
        f64::from(pressure_kpa.clamp(0.0, MAX_PRESSURE_KPA))
    } else {
        0.0
    }
}

/// The strain at which `E0 ε / (1 − ε/εd)^m` equals the pressure, on the loading curve.
///
/// With `u = ε/εd` and `a = P / (E0 εd)` the equation is `g(u) = ln u − m ln(1 − u) − ln a = 0`,
/// increasing on (0, 1) from −∞ to +∞: Newton steps from `a / (1 + a)` (the root for m = 1),
/// bisection whenever a step would leave the bracket.
fn loading_strain(modulus_kpa: f64, dielectric: &Dielectric, pressure_kpa: f64) -> f64 {
    let densification = f64::from(dielectric.densification_strain);
    let exponent = f64::from(dielectric.densification_exponent);
    if !(pressure_kpa > 0.0) {
        return 0.0;
    }
    let normalised = pressure_kpa / (modulus_kpa * densification);
    let log_target = normalised.ln();
    let (mut low, mut high) = (0.0f64, 1.0f64);
    let mut u = normalised / (1.0 + normalised);
    for _ in 0..MAX_ROOT_STEPS {
        let residual = u.ln() - exponent * (1.0 - u).ln() - log_target;
        if residual < 0.0 {
            low = u;
        } else {
            high = u;
        }
        let slope = 1.0 / u + exponent / (1.0 - u);
        let newton = u - residual / slope;
        let next = if newton > low && newton < high {
            newton
        } else {
            0.5 * (low + high)
        };
        let step = (next - u).abs();
        u = next;
        if step < STRAIN_TOLERANCE || high - low < STRAIN_TOLERANCE {
            break;
        }
    }
    u * densification
}

/// The relative permittivity eps_r(T) / eps_r(25 °C) of the dielectric.
pub fn permittivity_ratio(temperature_c: f32) -> f64 {
    let temperature_c = if temperature_c.is_finite() {
        f64::from(temperature_c.min(MAX_TEMPERATURE_C))
    } else {
        f64::from(REFERENCE_TEMPERATURE_C)
    };
    let above_c = (temperature_c - f64::from(REFERENCE_TEMPERATURE_C)).max(0.0);
    1.0 - PERMITTIVITY_DROP_PER_C * above_c
}

/// Eq. 4: the relative change of a parallel plate whose gap is compressed by `strain`.
fn relative_change_of_strain(strain: f64) -> f64 {
    strain / (1.0 - strain)
}

impl PadPhysics {
    /// The compressive strain of a taxel's dielectric at a pressure on the loading curve (the
    /// fresh pad, no history).
    pub fn strain(&self, taxel: usize, pressure_kpa: f32) -> f64 {
        self.taxels.get(taxel).map_or(0.0, |parameters| {
            loading_strain(
                f64::from(parameters.modulus_kpa),
                &self.dielectric,
                sanitized_pressure_kpa(pressure_kpa),
            )
        })
    }

    /// The true dC/C0 of a taxel at a pressure on the loading curve (the fresh pad, at any
    /// temperature: the permittivity scales C and C0 alike).
    pub fn relative_change(&self, taxel: usize, pressure_kpa: f32) -> f64 {
        relative_change_of_strain(self.strain(taxel, pressure_kpa))
    }

    /// The true capacitance of a taxel's input, pF, for the fresh pad on the loading curve (no
    /// hysteresis, no baseline loss); 0 for a taxel outside 0..4.
    pub fn capacitance_pf(&self, taxel: usize, pressure_kpa: f32, temperature_c: f32) -> f64 {
        self.taxels.get(taxel).map_or(0.0, |parameters| {
            f64::from(parameters.parasitic_pf)
                + f64::from(parameters.unloaded_pf)
                    * (1.0 + self.relative_change(taxel, pressure_kpa))
                    * permittivity_ratio(temperature_c)
        })
    }

    /// The pad's factory calibration: what a careful calibration of this pad produces, taken
    /// from the truth rather than from a pressure model. Per taxel, the true loading curve
    /// sampled at [`FACTORY_CALIBRATION_KPA`] (0, 5, …, 50 kPa, noise-free, rounded to f32) and
    /// the taxel's parasitic capacitance; model-core's default temperature law, thresholds and
    /// id 0. Between its points a model interpolates, so converting with it is close to the
    /// truth, not equal to it (model-core's monotone cubic through these points was measured up
    /// to 0.065 kPa off the true curve, near 48 kPa).
    pub fn matching_calibration(&self) -> Result<Calibration, CalibrationError> {
        let mut spec = CalibrationSpec::default();
        for (index, (taxel_spec, taxel)) in spec.taxels.iter_mut().zip(&self.taxels).enumerate() {
            taxel_spec.points.clear();
            for &pressure_kpa in &FACTORY_CALIBRATION_KPA {
                let point = CurvePoint::new(
                    pressure_kpa,
                    self.relative_change(index, pressure_kpa) as f32,
                );
                if taxel_spec.points.push(point).is_err() {
                    return Err(CalibrationError::TooFewPoints { taxel: index as u8 });
                }
            }
            taxel_spec.parasitic_pf = taxel.parasitic_pf;
        }
        Calibration::new(&spec)
    }

    /// Index of the first taxel whose parameters are not finite or out of range.
    pub(crate) fn first_invalid_taxel(&self) -> Option<usize> {
        self.taxels.iter().position(|taxel| {
            let unloaded_ok = taxel.unloaded_pf.is_finite() && taxel.unloaded_pf > 0.0;
            let parasitic_ok = taxel.parasitic_pf.is_finite() && taxel.parasitic_pf >= 0.0;
            let modulus_ok = taxel.modulus_kpa.is_finite() && taxel.modulus_kpa > 0.0;
            !(unloaded_ok && parasitic_ok && modulus_ok)
        })
    }

    /// Whether the dielectric and the effects are in their documented ranges.
    pub(crate) fn pad_is_valid(&self) -> bool {
        let dielectric = &self.dielectric;
        let densification_ok =
            dielectric.densification_strain > 0.0 && dielectric.densification_strain <= 0.9;
        let exponent_ok =
            dielectric.densification_exponent > 0.0 && dielectric.densification_exponent <= 10.0;
        densification_ok && exponent_ok && self.effects.is_valid()
    }
}

/// A taxel's history.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct TaxelState {
    /// Highest pressure since the taxel was last fully unloaded, kPa.
    peak_kpa: f64,
    /// Above the cycle threshold, waiting for the release.
    loaded: bool,
    /// Load cycles completed.
    cycles: u64,
}

/// The physics ready to evaluate, with the pad's history.
#[derive(Debug, Clone)]
pub(crate) struct PhysicsModel {
    physics: PadPhysics,
    states: [TaxelState; TAXELS],
}

impl PhysicsModel {
    pub(crate) fn new(physics: PadPhysics) -> Self {
        Self {
            physics,
            states: [TaxelState::default(); TAXELS],
        }
    }

    pub(crate) fn physics(&self) -> &PadPhysics {
        &self.physics
    }

    /// Replaces the history effects; the history itself (peaks, cycles) is kept.
    pub(crate) fn set_effects(&mut self, effects: PadEffects) {
        self.physics.effects = effects;
    }

    /// Load cycles counted per taxel.
    pub(crate) fn cycles(&self) -> [u64; TAXELS] {
        core::array::from_fn(|taxel| self.states[taxel].cycles)
    }

    /// The state after the taxel felt `pressure_kpa` (sanitised), and the strain it then has.
    fn evolve(&self, taxel: usize, pressure_kpa: f64) -> (TaxelState, f64) {
        let Some((parameters, state)) = self.physics.taxels.get(taxel).zip(self.states.get(taxel))
        else {
            return (TaxelState::default(), 0.0);
        };
        let modulus_kpa = f64::from(parameters.modulus_kpa);
        let dielectric = &self.physics.dielectric;
        let effects = &self.physics.effects;
        let mut next = *state;
        let loading = loading_strain(modulus_kpa, dielectric, pressure_kpa);
        let hysteresis = f64::from(effects.hysteresis);
        let strain = if pressure_kpa <= 0.0 {
            next.peak_kpa = 0.0;
            0.0
        } else if pressure_kpa >= state.peak_kpa {
            next.peak_kpa = pressure_kpa;
            loading
        } else {
            let fraction = pressure_kpa / state.peak_kpa;
            let peak_strain = loading_strain(modulus_kpa, dielectric, state.peak_kpa);
            // Unloading never leaves more strain than the peak had.
            (loading + hysteresis * peak_strain * 4.0 * fraction * (1.0 - fraction))
                .min(peak_strain)
        };
        let threshold_kpa = f64::from(effects.cycle_threshold_kpa);
        if pressure_kpa > threshold_kpa {
            next.loaded = true;
        } else if state.loaded && pressure_kpa < 0.5 * threshold_kpa {
            next.loaded = false;
            next.cycles = next.cycles.saturating_add(1);
        }
        (next, strain)
    }

    /// The input's capacitance from a state and a strain, pF.
    fn capacitance_from(
        &self,
        taxel: usize,
        state: &TaxelState,
        strain: f64,
        temperature_c: f32,
    ) -> f64 {
        let Some(parameters) = self.physics.taxels.get(taxel) else {
            return 0.0;
        };
        let loss = f64::from(self.physics.effects.baseline_loss_per_cycle) * state.cycles as f64;
        let retention = (1.0 - loss).max(MIN_RETENTION);
        f64::from(parameters.parasitic_pf)
            + f64::from(parameters.unloaded_pf)
                * retention
                * (1.0 + relative_change_of_strain(strain))
                * permittivity_ratio(temperature_c)
    }

    /// The capacitance a conversion sees, pF; the taxel's history moves on.
    pub(crate) fn convert(&mut self, taxel: usize, pressure_kpa: f32, temperature_c: f32) -> f64 {
        let (next, strain) = self.evolve(taxel, sanitized_pressure_kpa(pressure_kpa));
        let capacitance_pf = self.capacitance_from(taxel, &next, strain, temperature_c);
        if let Some(state) = self.states.get_mut(taxel) {
            *state = next;
        }
        capacitance_pf
    }

    /// The capacitance a conversion would see now, pF, without moving the history on.
    pub(crate) fn peek(&self, taxel: usize, pressure_kpa: f32, temperature_c: f32) -> f64 {
        let (next, strain) = self.evolve(taxel, sanitized_pressure_kpa(pressure_kpa));
        self.capacitance_from(taxel, &next, strain, temperature_c)
    }
}
