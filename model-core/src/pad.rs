//! The whole pad: four taxel models, their baselines, the temperature, the tare in progress and
//! the chosen tier. One call per converter cycle turns four readings into four pressures.

use crate::baseline::{Baseline, BaselineError, BaselineRecord, BaselineTracking, TareAccumulator};
use crate::calibration::{Calibration, TAXEL_COUNT};
use crate::conditioning::NOMINAL_SENSOR_PF;
use crate::flags::TaxelFlags;
use crate::inverse::Tier;
use crate::reading::{ReadingValue, TaxelReading};
use crate::taxel::{TaxelModel, TaxelOutput};
use crate::temperature::{TemperatureTracker, TemperatureUsed};
use crate::use_case::{select_tier_for_taxels, SelectionError, TaxelEvidence, TierChoice, UseCase};

/// One converter cycle's input.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SampleInput {
    /// The four readings in pad order.
    pub readings: [TaxelReading; TAXEL_COUNT],
    /// Flags the acquisition already knows (CONVERTER_ERROR, STUCK), per taxel.
    pub reading_flags: [TaxelFlags; TAXEL_COUNT],
    /// Pad temperature in °C, if one was read.
    pub temperature_c: Option<f32>,
    /// When the set was measured, µs on a clock that only moves forward, if known: lets the
    /// temperature plausibility rule allow for the time between sets (see
    /// [`crate::temperature`]).
    pub time_us: Option<u64>,
}

impl SampleInput {
    /// Four readings with no acquisition flags.
    pub fn new(readings: [TaxelReading; TAXEL_COUNT], temperature_c: Option<f32>) -> Self {
        Self {
            readings,
            reading_flags: [TaxelFlags::empty(); TAXEL_COUNT],
            temperature_c,
            time_us: None,
        }
    }

    /// The same input measured at `time_us`.
    pub fn at_time_us(mut self, time_us: u64) -> Self {
        self.time_us = Some(time_us);
        self
    }
}

/// One converter cycle's result.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PadOutput {
    /// The four taxels in pad order.
    pub taxels: [TaxelOutput; TAXEL_COUNT],
    /// The temperature the sample was corrected with.
    pub temperature: TemperatureUsed,
}

/// State of the tare.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TareStatus {
    /// No tare has been asked for.
    Never,
    /// A tare is averaging; this many sample sets are still to come.
    Running {
        /// Sets still to come.
        remaining: u16,
    },
    /// The last tare finished; per taxel whether it produced a baseline (a taxel that failed
    /// keeps its previous baseline, if any).
    Finished {
        /// Bit n set = taxel n was tared.
        tared_mask: u8,
    },
}

/// The model of the whole pad.
#[derive(Debug, Clone, PartialEq)]
pub struct PadModel {
    calibration: Calibration,
    taxels: [TaxelModel; TAXEL_COUNT],
    baselines: [Option<Baseline>; TAXEL_COUNT],
    tier: Tier,
    tracking: BaselineTracking,
    temperature: TemperatureTracker,
    tare: Option<TareAccumulator>,
    tare_status: TareStatus,
    last_tare_errors: [Option<BaselineError>; TAXEL_COUNT],
}

/// A tier the calibration cannot provide.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TierUnavailable(pub Tier);

impl PadModel {
    /// A model with the default tier, no baselines and tracking off.
    pub fn new(calibration: Calibration) -> Self {
        let taxels = core::array::from_fn(|taxel| TaxelModel::new(&calibration.taxels()[taxel]));
        Self {
            calibration,
            taxels,
            baselines: [None; TAXEL_COUNT],
            tier: Tier::default(),
            tracking: BaselineTracking::default(),
            temperature: TemperatureTracker::default(),
            tare: None,
            tare_status: TareStatus::Never,
            last_tare_errors: [None; TAXEL_COUNT],
        }
    }

    /// Replaces the calibration. Each baseline is derived again from its tared capacitance and
    /// temperature with the new parasitic capacitance, temperature law and thresholds (a
    /// baseline keeps no number computed with the old ones); a taxel whose baseline does not
    /// validate under the new calibration becomes untared. A tier the new curves cannot provide
    /// falls back to the default.
    pub fn set_calibration(&mut self, calibration: Calibration) {
        let tier = self.tier;
        let records = self.baseline_records();
        *self = Self {
            tracking: self.tracking,
            temperature: self.temperature,
            tare: self.tare.take(),
            tare_status: self.tare_status,
            last_tare_errors: self.last_tare_errors,
            ..Self::new(calibration)
        };
        self.restore_baselines(&records);
        if self.set_tier(tier).is_err() {
            self.tier = Tier::default();
        }
    }

    /// The calibration in use.
    pub fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    /// The taxel models.
    pub fn taxels(&self) -> &[TaxelModel; TAXEL_COUNT] {
        &self.taxels
    }

    /// Selects an inversion tier for all taxels.
    pub fn set_tier(&mut self, tier: Tier) -> Result<(), TierUnavailable> {
        if self
            .taxels
            .iter()
            .all(|taxel| taxel.inverses().supports(tier))
        {
            self.tier = tier;
            Ok(())
        } else {
            Err(TierUnavailable(tier))
        }
    }

    /// The tier in use.
    pub fn tier(&self) -> Tier {
        self.tier
    }

    /// The cheapest tier that fits a use case on all four taxels (see
    /// [`select_tier_for_taxels`]); each taxel's C0 is its baseline's when tared, else nominal.
    pub fn select_tier_for(&self, use_case: &UseCase) -> Result<TierChoice, SelectionError> {
        let evidence = core::array::from_fn::<_, TAXEL_COUNT, _>(|taxel| TaxelEvidence {
            inverses: self.taxels[taxel].inverses(),
            curve: &self.calibration.taxels()[taxel].curve,
            sensor_pf: self.baselines[taxel]
                .as_ref()
                .map_or(NOMINAL_SENSOR_PF, Baseline::sensor_pf),
        });
        select_tier_for_taxels(&evidence, self.calibration.temperature_law(), use_case)
    }

    /// Selects and applies the cheapest tier for a use case.
    pub fn apply_use_case(&mut self, use_case: &UseCase) -> Result<TierChoice, SelectionError> {
        let choice = self.select_tier_for(use_case)?;
        self.tier = choice.tier;
        Ok(choice)
    }

    /// Configures slow baseline tracking.
    pub fn set_baseline_tracking(&mut self, tracking: BaselineTracking) {
        self.tracking = tracking;
    }

    /// Starts a tare over the next `sample_sets` sample sets (the pad must be unloaded).
    pub fn start_tare(&mut self, sample_sets: u16) {
        let accumulator = TareAccumulator::new(sample_sets);
        self.tare_status = TareStatus::Running {
            remaining: accumulator.remaining(),
        };
        self.tare = Some(accumulator);
    }

    /// State of the tare.
    pub fn tare_status(&self) -> TareStatus {
        self.tare_status
    }

    /// Why the last tare failed per taxel (None = succeeded or never ran).
    pub fn last_tare_errors(&self) -> [Option<BaselineError>; TAXEL_COUNT] {
        self.last_tare_errors
    }

    /// The last valid temperature seen, °C (None until one arrives).
    pub fn last_valid_temperature_c(&self) -> Option<f32> {
        self.temperature.last_valid_c()
    }

    /// Baselines per taxel.
    pub fn baselines(&self) -> &[Option<Baseline>; TAXEL_COUNT] {
        &self.baselines
    }

    /// Restores baselines taken earlier (e.g. kept across an MCU reset): each is re-validated
    /// against this calibration's parasitic capacitance, temperature law and thresholds, and a
    /// taxel whose baseline does not validate stays untared. Returns which taxels were restored
    /// (bit n = taxel n).
    pub fn restore_baselines(&mut self, baselines: &[Option<BaselineRecord>; TAXEL_COUNT]) -> u8 {
        let mut restored_mask = 0u8;
        for (taxel, record) in baselines.iter().enumerate() {
            let Some(record) = record else {
                continue;
            };
            let restored = Baseline::new(
                record.capacitance,
                self.taxels[taxel].parasitic_pf(),
                record.temperature_c,
                self.calibration.temperature_law(),
                self.calibration.thresholds(),
            );
            if let Ok(baseline) = restored {
                self.baselines[taxel] = Some(baseline);
                restored_mask |= 1 << taxel;
            }
        }
        restored_mask
    }

    /// The baselines as plain records (to keep them across an MCU reset).
    pub fn baseline_records(&self) -> [Option<BaselineRecord>; TAXEL_COUNT] {
        self.baselines.map(|baseline| {
            baseline.map(|baseline| BaselineRecord {
                capacitance: baseline.tared_capacitance(),
                temperature_c: baseline.temperature_c(),
            })
        })
    }

    /// Sets one taxel's baseline directly (e.g. restored from a recording).
    pub fn set_baseline(&mut self, taxel: usize, baseline: Baseline) {
        if let Some(slot) = self.baselines.get_mut(taxel) {
            *slot = Some(baseline);
        }
    }

    /// Converts one converter cycle.
    pub fn process(&mut self, sample: &SampleInput) -> PadOutput {
        let tare_temperature_c = self
            .baselines
            .iter()
            .flatten()
            .next()
            .map(Baseline::temperature_c);
        let temperature = self.temperature.resolve_at(
            sample.temperature_c,
            tare_temperature_c,
            self.calibration.temperature_law(),
            sample.time_us,
        );
        let inverse_permittivity_ratio = 1.0 / temperature.permittivity_ratio;
        let thresholds = *self.calibration.thresholds();
        let mut tare_capacitances = [None; TAXEL_COUNT];
        let taxels = core::array::from_fn(|taxel| {
            let value = sample.readings[taxel].value();
            let acquisition_flags = sample.reading_flags[taxel];
            let output = self.taxels[taxel]
                .convert(
                    self.tier,
                    value,
                    self.baselines[taxel].as_ref(),
                    inverse_permittivity_ratio,
                    &thresholds,
                )
                .with_flags(acquisition_flags | temperature.flags);
            let unusable_for_tare = TaxelFlags::FAULTS.difference(TaxelFlags::NOT_TARED);
            if let ReadingValue::Capacitance(capacitance) = value {
                if !output.flags().intersects(unusable_for_tare) {
                    tare_capacitances[taxel] = Some(capacitance);
                }
            }
            let tracking_hit_limit = match (output.relative_change(), &mut self.baselines[taxel]) {
                (Some(relative_change), Some(baseline)) if !output.flags().is_fault() => {
                    self.tracking.update(baseline, relative_change)
                }
                _ => false,
            };
            if tracking_hit_limit {
                output.with_flags(TaxelFlags::BASELINE_TRACKING_LIMIT)
            } else {
                output
            }
        });
        self.advance_tare(&tare_capacitances, temperature.temperature_c);
        PadOutput {
            taxels,
            temperature,
        }
    }

    fn advance_tare(
        &mut self,
        capacitances: &[Option<crate::reading::SplitCapacitance>; TAXEL_COUNT],
        temperature_c: f32,
    ) {
        let Some(accumulator) = self.tare.as_mut() else {
            return;
        };
        if !accumulator.add(capacitances, temperature_c) {
            self.tare_status = TareStatus::Running {
                remaining: accumulator.remaining(),
            };
            return;
        }
        let parasitic_pf = core::array::from_fn(|taxel| self.taxels[taxel].parasitic_pf());
        let results = accumulator.finish(
            &parasitic_pf,
            self.calibration.temperature_law(),
            self.calibration.thresholds(),
        );
        let mut tared_mask = 0u8;
        for (taxel, result) in results.into_iter().enumerate() {
            match result {
                Ok(baseline) => {
                    self.baselines[taxel] = Some(baseline);
                    self.last_tare_errors[taxel] = None;
                    tared_mask |= 1 << taxel;
                }
                Err(error) => self.last_tare_errors[taxel] = Some(error),
            }
        }
        self.tare = None;
        self.tare_status = TareStatus::Finished { tared_mask };
    }
}
