//! The unloaded reference (C0) of each taxel: taken by averaging N sample sets (tare), optionally
//! followed slowly while the taxel is unloaded.

use crate::bounds::clamp_f32;
use crate::calibration::{FaultThresholds, TemperatureLaw, TAXEL_COUNT};
use crate::reading::SplitCapacitance;

/// One taxel's baseline.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Baseline {
    tared_capacitance: SplitCapacitance,
    // Accumulated apart from the tared capacitance so that steps far below its f32 resolution
    // add up; `reference` folds it in whenever it changes.
    tracked_drift_pf: f32,
    reference: SplitCapacitance,
    tared_sensor_pf: f32,
    permittivity_ratio: f32,
    permittivity_ratio_per_sensor_pf: f32,
    temperature_c: f32,
}

/// What a baseline is made from: the tared capacitance, the temperature at the tare and how far
/// tracking has moved it since (what is kept across an MCU reset; the rest is derived again from
/// the calibration).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BaselineRecord {
    /// The tared capacitance.
    pub capacitance: SplitCapacitance,
    /// Temperature at the tare, °C.
    pub temperature_c: f32,
    /// How far baseline tracking has moved the baseline from the tare, pF (0 without tracking;
    /// absent from files written before it existed).
    #[cfg_attr(feature = "serde", serde(default))]
    pub tracked_drift_pf: f32,
}

/// Why a baseline was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BaselineError {
    /// The capacitance or temperature is not finite.
    NotFinite,
    /// The sensor capacitance (baseline minus parasitic) is below the open-lead threshold, zero
    /// or negative: nothing to divide by.
    ImplausiblySmall,
    /// Too few valid sample sets were seen during the tare.
    TooFewSamples,
    /// The pad was not still during the tare (pressed, moving, or the lead disturbed): the
    /// readings spread by more than converter noise explains ([`TARE_STILL_SPREAD_PF`]).
    NotStill {
        /// Standard deviation of the taxel's readings during the tare, fF.
        spread_ff: u32,
    },
}

/// Largest standard deviation of a taxel's readings over a tare, pF: ten times the converter's
/// 0.5 fF rms noise. A press of 0.1 kPa on the article's curve moves 4.5 pF by about 4 fF, so a
/// tare taken while the pad is touched or moving spreads well beyond it.
pub const TARE_STILL_SPREAD_PF: f32 = 0.005;

impl Baseline {
    /// A baseline from an unloaded capacitance measured at `temperature_c`.
    pub fn new(
        capacitance: SplitCapacitance,
        parasitic_pf: f32,
        temperature_c: f32,
        law: &TemperatureLaw,
        thresholds: &FaultThresholds,
    ) -> Result<Self, BaselineError> {
        if !capacitance.offset_pf.is_finite()
            || !capacitance.fine_pf.is_finite()
            || !temperature_c.is_finite()
        {
            return Err(BaselineError::NotFinite);
        }
        let sensor_pf = (capacitance.offset_pf - parasitic_pf) + capacitance.fine_pf;
        if !(sensor_pf >= thresholds.open_below_pf) || !(sensor_pf > 0.0) {
            return Err(BaselineError::ImplausiblySmall);
        }
        let temperature_c =
            temperature_c.clamp(law.characterised_min_c(), law.characterised_max_c());
        let permittivity_ratio = law.permittivity_ratio(temperature_c);
        Ok(Self {
            tared_capacitance: capacitance,
            tracked_drift_pf: 0.0,
            reference: capacitance,
            tared_sensor_pf: sensor_pf,
            permittivity_ratio,
            permittivity_ratio_per_sensor_pf: permittivity_ratio / sensor_pf,
            temperature_c,
        })
    }

    /// A baseline from its record: [`Baseline::new`] on the tared capacitance, then moved by the
    /// record's tracked drift. A drift that is not finite, or that would leave no sensor
    /// capacitance above the open-lead threshold, refuses the record.
    pub fn from_record(
        record: &BaselineRecord,
        parasitic_pf: f32,
        law: &TemperatureLaw,
        thresholds: &FaultThresholds,
    ) -> Result<Self, BaselineError> {
        let mut baseline = Self::new(
            record.capacitance,
            parasitic_pf,
            record.temperature_c,
            law,
            thresholds,
        )?;
        if !record.tracked_drift_pf.is_finite() {
            return Err(BaselineError::NotFinite);
        }
        let sensor_pf = baseline.tared_sensor_pf + record.tracked_drift_pf;
        if !(sensor_pf >= thresholds.open_below_pf) || !(sensor_pf > 0.0) {
            return Err(BaselineError::ImplausiblySmall);
        }
        baseline.move_by_drift_pf(record.tracked_drift_pf);
        Ok(baseline)
    }

    /// The record this baseline is made from.
    pub fn record(&self) -> BaselineRecord {
        BaselineRecord {
            capacitance: self.tared_capacitance,
            temperature_c: self.temperature_c,
            tracked_drift_pf: self.tracked_drift_pf,
        }
    }

    /// The capacitance measured at the tare.
    pub fn tared_capacitance(&self) -> SplitCapacitance {
        self.tared_capacitance
    }

    /// How far tracking has moved the baseline from the tare, pF.
    pub fn tracked_drift_pf(&self) -> f32 {
        self.tracked_drift_pf
    }

    /// The sensor's own unloaded capacitance C0 (baseline minus parasitic), pF.
    pub fn sensor_pf(&self) -> f32 {
        self.tared_sensor_pf + self.tracked_drift_pf
    }

    /// Temperature at the tare, °C.
    pub fn temperature_c(&self) -> f32 {
        self.temperature_c
    }

    /// dC/C0 of a reading, both brought to the reference temperature.
    ///
    /// With k = eps(T) / eps(T0), the sensor part scales by k and the parasitic does not, so
    /// `dC/C0 = (C - Cp) / (k (C0 - Cp)) - 1`, formed as `dC * s / C0 + (s - 1)` with
    /// `s = 1 / k = eps(T0) / eps(T)`: the change `dC` is taken part by part (no cancellation),
    /// `eps(T0) / C0` is kept ready, and no division is left for the hot path.
    #[inline]
    pub fn relative_change(
        &self,
        reading: SplitCapacitance,
        inverse_permittivity_ratio: f32,
    ) -> f32 {
        let change_pf = reading.minus(self.reference);
        change_pf * (self.permittivity_ratio_per_sensor_pf * inverse_permittivity_ratio)
            + (self.permittivity_ratio * inverse_permittivity_ratio - 1.0)
    }

    /// Moves the baseline by `fraction` of the reading's offset from it (tracking), bounded to
    /// `max_drift_relative` of C0 away from the tared value. Returns whether the bound was hit.
    fn track(&mut self, relative_change: f32, tracking: &BaselineTracking) -> bool {
        let step_pf = relative_change * self.sensor_pf() * tracking.rate_per_sample;
        let limit_pf = tracking.max_drift_relative * self.tared_sensor_pf;
        let drift_pf = self.tracked_drift_pf + step_pf;
        let bounded_drift_pf = clamp_f32(drift_pf, -limit_pf, limit_pf);
        self.move_by_drift_pf(bounded_drift_pf);
        bounded_drift_pf != drift_pf
    }

    /// Sets the tracked drift and what depends on it.
    fn move_by_drift_pf(&mut self, drift_pf: f32) {
        self.tracked_drift_pf = drift_pf;
        self.reference.fine_pf = self.tared_capacitance.fine_pf + drift_pf;
        self.permittivity_ratio_per_sensor_pf = self.permittivity_ratio / self.sensor_pf();
    }
}

/// Slow baseline tracking while a taxel is unloaded; off by default.
///
/// It only moves while |dC/C0| stays below `contact_threshold_relative` (so a static contact
/// above the threshold freezes it, however long it lasts), by `rate_per_sample` of the offset per
/// sample, and never further than `max_drift_relative` of C0 from the tared value.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BaselineTracking {
    /// Whether tracking runs.
    pub enabled: bool,
    /// Above this |dC/C0| the taxel counts as touched and tracking stops (default 0.005, about
    /// 0.6 kPa on the article's curve).
    pub contact_threshold_relative: f32,
    /// Fraction of the offset applied per sample (default 1e-4: a time constant of 25 s at
    /// 400 sample sets per second).
    pub rate_per_sample: f32,
    /// Largest total drift from the tared value, as a fraction of C0 (default 0.02).
    pub max_drift_relative: f32,
}

impl Default for BaselineTracking {
    fn default() -> Self {
        Self {
            enabled: false,
            contact_threshold_relative: 0.005,
            rate_per_sample: 1.0e-4,
            max_drift_relative: 0.02,
        }
    }
}

impl BaselineTracking {
    /// Applies one tracking step; returns whether the drift bound was hit.
    pub(crate) fn update(&self, baseline: &mut Baseline, relative_change: f32) -> bool {
        if !self.enabled || !(relative_change.abs() < self.contact_threshold_relative) {
            return false;
        }
        baseline.track(relative_change, self)
    }
}

/// Averages unloaded sample sets into baselines.
#[derive(Debug, Clone, PartialEq)]
pub struct TareAccumulator {
    requested: u16,
    seen: u16,
    taxels: [TaxelSums; TAXEL_COUNT],
    temperature_sum_c: f64,
}

/// One taxel's sums over a tare.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct TaxelSums {
    offset_sum_pf: f64,
    fine_sum_pf: f64,
    // Deviations from the first reading (so the spread has no cancellation, and f32 holds them
    // exactly enough: fF-sized values, relative 1e-7).
    first_reading: Option<SplitCapacitance>,
    deviation_sum_pf: f32,
    deviation_square_sum_pf2: f32,
    count: u16,
}

impl TaxelSums {
    fn add(&mut self, capacitance: SplitCapacitance) {
        self.offset_sum_pf += capacitance.offset_pf as f64;
        self.fine_sum_pf += capacitance.fine_pf as f64;
        let first = *self.first_reading.get_or_insert(capacitance);
        let deviation_pf = capacitance.minus(first);
        self.deviation_sum_pf += deviation_pf;
        self.deviation_square_sum_pf2 += deviation_pf * deviation_pf;
        self.count = self.count.saturating_add(1);
    }

    /// The mean capacitance, or why there is none: too few readings, or not still.
    fn mean(&self, needed: u16) -> Result<SplitCapacitance, BaselineError> {
        let count = self.count;
        if count < needed || count == 0 {
            return Err(BaselineError::TooFewSamples);
        }
        let mean_deviation_pf = self.deviation_sum_pf / count as f32;
        let variance_pf2 =
            self.deviation_square_sum_pf2 / count as f32 - mean_deviation_pf * mean_deviation_pf;
        let spread_pf = libm::sqrtf(clamp_f32(variance_pf2, 0.0, f32::MAX));
        if !(spread_pf <= TARE_STILL_SPREAD_PF) {
            // Saturating conversion: NaN gives 0, beyond u32 gives u32::MAX.
            return Err(BaselineError::NotStill {
                spread_ff: (spread_pf * 1000.0) as u32,
            });
        }
        Ok(SplitCapacitance {
            offset_pf: (self.offset_sum_pf / count as f64) as f32,
            fine_pf: (self.fine_sum_pf / count as f64) as f32,
        })
    }
}

impl TareAccumulator {
    /// Starts a tare over `sample_sets` sets (at least 1).
    pub fn new(sample_sets: u16) -> Self {
        Self {
            requested: sample_sets.max(1),
            seen: 0,
            taxels: [TaxelSums::default(); TAXEL_COUNT],
            temperature_sum_c: 0.0,
        }
    }

    /// Sample sets still to come.
    pub fn remaining(&self) -> u16 {
        self.requested - self.seen
    }

    /// Adds one sample set: the usable capacitances (None for a faulted taxel) and the
    /// temperature used for it. Returns true when the tare has seen enough sets.
    pub fn add(
        &mut self,
        capacitances: &[Option<SplitCapacitance>; TAXEL_COUNT],
        temperature_c: f32,
    ) -> bool {
        for (sums, capacitance) in self.taxels.iter_mut().zip(capacitances) {
            if let Some(capacitance) = capacitance {
                sums.add(*capacitance);
            }
        }
        self.temperature_sum_c += temperature_c as f64;
        self.seen = self.seen.saturating_add(1).min(self.requested);
        self.seen >= self.requested
    }

    /// The baselines, per taxel; a taxel needs valid readings in at least half of the sets, and
    /// readings that stayed still (spread within [`TARE_STILL_SPREAD_PF`]).
    pub fn finish(
        &self,
        parasitic_pf: &[f32; TAXEL_COUNT],
        law: &TemperatureLaw,
        thresholds: &FaultThresholds,
    ) -> [Result<Baseline, BaselineError>; TAXEL_COUNT] {
        let temperature_c = (self.temperature_sum_c / self.seen.max(1) as f64) as f32;
        let needed = self.requested.div_ceil(2).max(1);
        let mut results = [Err(BaselineError::TooFewSamples); TAXEL_COUNT];
        for ((result, sums), parasitic_pf) in results.iter_mut().zip(&self.taxels).zip(parasitic_pf)
        {
            *result = sums.mean(needed).and_then(|mean| {
                Baseline::new(mean, *parasitic_pf, temperature_c, law, thresholds)
            });
        }
        results
    }
}
