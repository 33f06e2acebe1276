//! The whole pad: four taxel models, their baselines, the temperature, the tare in progress and
//! the chosen tier. One call per converter cycle turns four readings into four pressures.

use crate::baseline::{Baseline, BaselineError, BaselineRecord, BaselineTracking, TareAccumulator};
use crate::calibration::{
    Calibration, FaultThresholds, TaxelCalibration, TemperatureLaw, TAXEL_COUNT,
};
use crate::conditioning::NOMINAL_SENSOR_PF;
use crate::flags::TaxelFlags;
use crate::inverse::{ActiveInverse, TaxelInverses, Tier};
use crate::reading::{ReadingValue, SplitCapacitance, TaxelReading};
use crate::taxel::{TaxelModel, TaxelOutput};
use crate::temperature::{TemperatureTracker, TemperatureUsed};
use crate::use_case::{select_tier_for_taxels, SelectionError, TaxelEvidence, TierChoice, UseCase};

/// Largest relative difference between a taxel's tared C0 (brought to 25 °C) and the C0 in its
/// calibration before the baseline is flagged `baseline_far_from_calibration` (0.05: about 6 kPa
/// of static load at the tare on the article's curve, or the article's 5.7 % loss after 5000
/// cycles).
pub const TARE_FAR_FROM_CALIBRATION_RELATIVE: f32 = 0.05;

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

/// One taxel's state in the pad's model: its converter for the tier in use, its baseline with
/// the flag that baseline carries, and what the last tare said about it.
// In this order (`repr(C)`): the small per-set state first and each taxel's large model last
// keeps what every set reads at short offsets from the pad's address, which the M4 loads
// without computing an address first (3.5 fewer M4 instructions a taxel in `process`).
#[derive(Debug, Clone, PartialEq)]
#[repr(C)]
pub(crate) struct TaxelState {
    baseline: Option<Baseline>,
    // BASELINE_FAR_FROM_CALIBRATION, set with the baseline (`PadModel::set_baseline`).
    baseline_flags: TaxelFlags,
    last_tare_error: Option<BaselineError>,
    pub(crate) model: TaxelModel,
}

impl TaxelState {
    fn new(model: TaxelModel) -> Self {
        Self {
            model,
            baseline: None,
            baseline_flags: TaxelFlags::empty(),
            last_tare_error: None,
        }
    }

    /// The taxel's output for one reading, its pressure (when in range) given by
    /// `in_range(dC/C0)`, and its capacitance when it may go into a tare. Baseline tracking
    /// moves the baseline here.
    #[inline(always)]
    fn convert(
        &mut self,
        calibration: &TaxelCalibration,
        reading: &TaxelReading,
        flags: TaxelFlags,
        conditions: &Conditions,
        tracking: &BaselineTracking,
        in_range: impl FnOnce(&TaxelModel, f32) -> f32,
    ) -> (TaxelOutput, Option<SplitCapacitance>) {
        let value = reading.value();
        let model = &self.model;
        let output = model
            .convert_with(
                calibration,
                value,
                self.baseline.as_ref(),
                conditions.inverse_permittivity_ratio,
                &conditions.thresholds,
                |relative_change| in_range(model, relative_change),
            )
            .with_flags(flags | conditions.temperature_flags | self.baseline_flags);
        // Only a running tare takes capacitances, only enabled tracking moves baselines: the
        // usual set (neither) skips both.
        let unusable_for_tare = TaxelFlags::FAULTS.difference(TaxelFlags::NOT_TARED);
        let tare = match value {
            ReadingValue::Capacitance(capacitance)
                if conditions.taring && !output.flags().intersects(unusable_for_tare) =>
            {
                Some(capacitance)
            }
            _ => None,
        };
        if !tracking.enabled {
            return (output, tare);
        }
        let tracking_hit_limit = match (output.relative_change(), self.baseline.as_mut()) {
            (Some(relative_change), Some(baseline)) if !output.flags().is_fault() => {
                tracking.update(baseline, relative_change)
            }
            _ => false,
        };
        let output = if tracking_hit_limit {
            output.with_flags(TaxelFlags::BASELINE_TRACKING_LIMIT)
        } else {
            output
        };
        (output, tare)
    }
}

/// What every taxel of one sample set is converted under.
struct Conditions {
    inverse_permittivity_ratio: f32,
    thresholds: FaultThresholds,
    temperature_flags: TaxelFlags,
    /// A tare is averaging: taxels hand it their capacitances.
    taring: bool,
}

/// The tare: never asked for, averaging, or finished.
#[derive(Debug, Clone, PartialEq)]
enum Tare {
    Never,
    Running(TareAccumulator),
    Finished { tared_mask: u8 },
}

/// The model of the whole pad.
// Ordered as `TaxelState` is, for the same reason.
#[derive(Debug, Clone, PartialEq)]
#[repr(C)]
pub struct PadModel {
    baseline_generation: u32,
    tier: Tier,
    tracking: BaselineTracking,
    temperature: TemperatureTracker,
    permittivity: Permittivity,
    tare: Tare,
    calibration: Calibration,
    taxels: [TaxelState; TAXEL_COUNT],
}

/// The permittivity ratio of the last temperature used, and its reciprocal: the temperature
/// rarely changes between sets, and the law's interpolation and the division cost about 35 M4
/// instructions a set.
#[derive(Debug, Clone, Copy)]
struct Permittivity {
    /// The temperature the ratios are for, °C (NaN: none yet).
    temperature_c: f32,
    /// eps(T) / eps(25 °C).
    ratio: f32,
    /// eps(25 °C) / eps(T).
    inverse_ratio: f32,
}

// A cache, not state: two models convert alike whatever they cached (and NaN, "nothing yet",
// equals nothing).
impl PartialEq for Permittivity {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Permittivity {
    /// Nothing computed yet (a model with a new calibration starts here: its law may differ).
    const NONE: Self = Self {
        temperature_c: f32::NAN,
        ratio: 1.0,
        inverse_ratio: 1.0,
    };

    /// The ratio and its reciprocal at `temperature_c` under `law`, the same bits as computing
    /// them afresh.
    #[inline(always)]
    fn at(&mut self, temperature_c: f32, law: &TemperatureLaw) -> (f32, f32) {
        if temperature_c != self.temperature_c {
            let ratio = law.permittivity_ratio(temperature_c);
            *self = Self {
                temperature_c,
                ratio,
                inverse_ratio: 1.0 / ratio,
            };
        }
        (self.ratio, self.inverse_ratio)
    }
}

// A device reads up to eight pads, each with its own model, in the firmware's static RAM
// (budget 64 KiB on the Cortex-M4F), so the model keeps only the tier in use. On a 32-bit
// target its parts are the calibration (668 bytes), four taxel states of 1,028 (the default
// tier's model, the largest at 972 with its per-interval cubics and seed grid
// — the table tier's needs 204 — with its baseline, flag and last tare result), the tare of 176
// and the temperature state, with the last permittivity (12 bytes for about 9 M4 instructions a
// taxel). The seed grid is what makes the default tier's inverse one Newton step without a
// search for the interval (`inverse/cubic.rs`) for 2,208 bytes a pad (17.3 KiB for eight);
// growing the model further should be a decision, not an accident. The fixed field order
// (see `PadModel`) costs 8 bytes of padding.
#[cfg(target_pointer_width = "32")]
const _: () = assert!(core::mem::size_of::<PadModel>() <= 5_024);

/// A tier the calibration cannot provide.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TierUnavailable(pub Tier);

impl PadModel {
    /// A model with the default tier, no baselines and tracking off.
    pub fn new(calibration: Calibration) -> Self {
        let taxels = calibration
            .taxels()
            .each_ref()
            .map(|calibration| TaxelState::new(TaxelModel::new(calibration)));
        Self {
            calibration,
            taxels,
            baseline_generation: 0,
            tier: Tier::default(),
            tracking: BaselineTracking::default(),
            temperature: TemperatureTracker::default(),
            permittivity: Permittivity::NONE,
            tare: Tare::Never,
        }
    }

    /// Replaces the calibration. Each baseline is derived again from its record (tared
    /// capacitance, temperature, tracked drift) with the new parasitic capacitance, temperature
    /// law and thresholds (a
    /// baseline keeps no number computed with the old ones); a taxel whose baseline does not
    /// validate under the new calibration becomes untared. A tier the new curves cannot provide
    /// falls back to the default.
    pub fn set_calibration(&mut self, calibration: Calibration) {
        let tier = self.tier;
        let records = self.baseline_records();
        let last_tare_errors = self.last_tare_errors();
        let tare = core::mem::replace(&mut self.tare, Tare::Never);
        *self = Self {
            tracking: self.tracking,
            temperature: self.temperature,
            tare,
            baseline_generation: self.baseline_generation.wrapping_add(1),
            ..Self::new(calibration)
        };
        for (taxel, error) in self.taxels.iter_mut().zip(last_tare_errors) {
            taxel.last_tare_error = error;
        }
        self.restore_baselines(&records);
        if self.set_tier(tier).is_err() {
            self.tier = Tier::default();
        }
    }

    /// Each taxel's model with its calibration, in pad order.
    #[cfg(feature = "batch")]
    pub(crate) fn taxel_models(
        &self,
    ) -> impl Iterator<Item = (&TaxelModel, &TaxelCalibration)> + '_ {
        self.taxels
            .iter()
            .map(|taxel| &taxel.model)
            .zip(self.calibration.taxels())
    }

    /// The calibration in use.
    pub fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    /// Taxel `index`'s model (`None` outside 0..4).
    pub fn taxel(&self, index: usize) -> Option<&TaxelModel> {
        self.taxels.get(index).map(|taxel| &taxel.model)
    }

    /// Selects an inversion tier for all taxels, building it from the calibration; when a curve
    /// does not support the tier, nothing changes.
    pub fn set_tier(&mut self, tier: Tier) -> Result<(), TierUnavailable> {
        let inverses = self
            .calibration
            .taxels()
            .each_ref()
            .map(|calibration| ActiveInverse::new(calibration.curve(), tier));
        self.install(inverses, tier)
    }

    /// Installs one inverse per taxel if every taxel has one.
    fn install(
        &mut self,
        inverses: [Option<ActiveInverse>; TAXEL_COUNT],
        tier: Tier,
    ) -> Result<(), TierUnavailable> {
        let [Some(a), Some(b), Some(c), Some(d)] = inverses else {
            return Err(TierUnavailable(tier));
        };
        for (taxel, inverse) in self.taxels.iter_mut().zip([a, b, c, d]) {
            taxel.model = TaxelModel::from_inverse(inverse);
        }
        self.tier = tier;
        Ok(())
    }

    /// The tier in use.
    pub fn tier(&self) -> Tier {
        self.tier
    }

    /// Every tier of every taxel, built for tier selection (about 1 KiB each, on the stack).
    fn all_inverses(&self) -> [TaxelInverses; TAXEL_COUNT] {
        self.calibration
            .taxels()
            .each_ref()
            .map(|calibration| TaxelInverses::new(calibration.curve()))
    }

    /// The cheapest tier that fits a use case on all four taxels (see
    /// [`select_tier_for_taxels`]); each taxel's C0 is its baseline's when tared, else nominal.
    pub fn select_tier_for(&self, use_case: &UseCase) -> Result<TierChoice, SelectionError> {
        self.select_among(&self.all_inverses(), use_case)
    }

    fn select_among(
        &self,
        inverses: &[TaxelInverses; TAXEL_COUNT],
        use_case: &UseCase,
    ) -> Result<TierChoice, SelectionError> {
        let calibrations = self.calibration.taxels();
        let mut evidence = inverses.each_ref().map(|inverses| TaxelEvidence {
            inverses,
            curve: calibrations[0].curve(),
            sensor_pf: NOMINAL_SENSOR_PF,
        });
        for ((evidence, calibration), taxel) in
            evidence.iter_mut().zip(calibrations).zip(&self.taxels)
        {
            evidence.curve = calibration.curve();
            evidence.sensor_pf = taxel
                .baseline
                .as_ref()
                .map_or(NOMINAL_SENSOR_PF, Baseline::sensor_pf);
        }
        select_tier_for_taxels(&evidence, self.calibration.temperature_law(), use_case)
    }

    /// Selects and applies the cheapest tier for a use case.
    pub fn apply_use_case(&mut self, use_case: &UseCase) -> Result<TierChoice, SelectionError> {
        let inverses = self.all_inverses();
        let choice = self.select_among(&inverses, use_case)?;
        let active = inverses
            .each_ref()
            .map(|inverses| inverses.active(choice.tier));
        // Selection only offers a tier every taxel supports, and `active` builds exactly those.
        self.install(active, choice.tier)
            .map_err(|_| SelectionError::InvalidUseCase)?;
        Ok(choice)
    }

    /// Configures slow baseline tracking.
    pub fn set_baseline_tracking(&mut self, tracking: BaselineTracking) {
        self.tracking = tracking;
    }

    /// Starts a tare over the next `sample_sets` sample sets (the pad must be unloaded).
    pub fn start_tare(&mut self, sample_sets: u16) {
        self.tare = Tare::Running(TareAccumulator::new(sample_sets));
    }

    /// State of the tare.
    pub fn tare_status(&self) -> TareStatus {
        match &self.tare {
            Tare::Never => TareStatus::Never,
            Tare::Running(accumulator) => TareStatus::Running {
                remaining: accumulator.remaining(),
            },
            Tare::Finished { tared_mask } => TareStatus::Finished {
                tared_mask: *tared_mask,
            },
        }
    }

    /// Why the last tare failed per taxel (None = succeeded or never ran).
    pub fn last_tare_errors(&self) -> [Option<BaselineError>; TAXEL_COUNT] {
        self.taxels.each_ref().map(|taxel| taxel.last_tare_error)
    }

    /// The last valid temperature seen, °C (None until one arrives).
    pub fn last_valid_temperature_c(&self) -> Option<f32> {
        self.temperature.last_valid_c()
    }

    /// The next temperature comes from another sensor (the acquisition switched between the
    /// pad's sensor and the fallback): it is applied as measured, not judged as a jump (see
    /// [`crate::temperature`]).
    pub fn temperature_source_changed(&mut self) {
        self.temperature.source_changed();
    }

    /// Baselines per taxel.
    pub fn baselines(&self) -> [Option<Baseline>; TAXEL_COUNT] {
        self.taxels.each_ref().map(|taxel| taxel.baseline)
    }

    /// A number that changes (wrapping) whenever a baseline is installed or the calibration is
    /// replaced, but not when tracking moves a baseline: a cheap "did the tare change" test.
    pub fn baseline_generation(&self) -> u32 {
        self.baseline_generation
    }

    /// Restores baselines taken earlier (e.g. kept across an MCU reset): each is re-validated
    /// against this calibration's parasitic capacitance, temperature law and thresholds, and a
    /// taxel whose baseline does not validate stays untared. Returns which taxels were restored
    /// (bit n = taxel n).
    pub fn restore_baselines(&mut self, baselines: &[Option<BaselineRecord>; TAXEL_COUNT]) -> u8 {
        let mut restored_mask = 0u8;
        let parasitic_pf = parasitic_pf(&self.calibration);
        for ((taxel, record), parasitic_pf) in baselines.iter().enumerate().zip(parasitic_pf) {
            let Some(record) = record else {
                continue;
            };
            let restored = Baseline::from_record(
                record,
                parasitic_pf,
                self.calibration.temperature_law(),
                self.calibration.thresholds(),
            );
            if let Ok(baseline) = restored {
                self.set_baseline(taxel, baseline);
                restored_mask |= 1 << taxel;
            }
        }
        restored_mask
    }

    /// The baselines as plain records (to keep them across an MCU reset).
    pub fn baseline_records(&self) -> [Option<BaselineRecord>; TAXEL_COUNT] {
        self.taxels
            .each_ref()
            .map(|taxel| taxel.baseline.as_ref().map(Baseline::record))
    }

    /// Sets one taxel's baseline directly (e.g. restored from a recording).
    /// Every path that installs a baseline goes through here, so its flag is always current.
    pub fn set_baseline(&mut self, taxel: usize, baseline: Baseline) {
        let far_from_calibration = self
            .calibration
            .taxels()
            .get(taxel)
            .and_then(|calibration| calibration.unloaded_sensor_pf())
            .is_some_and(|calibrated_pf| {
                let law = self.calibration.temperature_law();
                let tared_pf =
                    baseline.sensor_pf() / law.permittivity_ratio(baseline.temperature_c());
                !((tared_pf / calibrated_pf - 1.0).abs() <= TARE_FAR_FROM_CALIBRATION_RELATIVE)
            });
        if let Some(state) = self.taxels.get_mut(taxel) {
            state.baseline = Some(baseline);
            self.baseline_generation = self.baseline_generation.wrapping_add(1);
            state.baseline_flags = if far_from_calibration {
                TaxelFlags::BASELINE_FAR_FROM_CALIBRATION
            } else {
                TaxelFlags::empty()
            };
        }
    }

    /// Converts one converter cycle.
    // Never inlined: the firmware builds model-core for speed (`[profile.firmware.package.
    // model-core]`) and its callers for size, and code inlined into a caller takes the caller's
    // code generation (opt-level "z", machine outlining).
    #[inline(never)]
    pub fn process(&mut self, sample: &SampleInput) -> PadOutput {
        self.process_with(sample, |_, model, calibration, relative_change| {
            model
                .inverse()
                .pressure_kpa(calibration.curve(), relative_change)
        })
    }

    /// A sample set's outputs and state changes, the pressure of an in-range taxel (`0 < dC/C0
    /// <= top`) given by `in_range(taxel, model, calibration, dC/C0)`: the tier's inverse, or a
    /// placeholder when a batch of inverses fills the pressures in afterwards (nothing here
    /// depends on them).
    #[inline(always)]
    pub(crate) fn process_with(
        &mut self,
        sample: &SampleInput,
        mut in_range: impl FnMut(usize, &TaxelModel, &TaxelCalibration, f32) -> f32,
    ) -> PadOutput {
        let (temperature, conditions) = self.conditions(sample);
        let tracking = self.tracking;
        let mut taxels = self.taxels.iter_mut().zip(self.calibration.taxels());
        let mut inputs = sample.readings.iter().zip(sample.reading_flags);
        // Four taxels, four calibrations, four readings: every call finds its three.
        let converted = core::array::from_fn(|index| match (taxels.next(), inputs.next()) {
            (Some((taxel, calibration)), Some((reading, flags))) => taxel.convert(
                calibration,
                reading,
                flags,
                &conditions,
                &tracking,
                |model, relative_change| in_range(index, model, calibration, relative_change),
            ),
            _ => (TaxelOutput::fault(TaxelFlags::NOT_TARED, None), None),
        });
        self.advance_tare(&converted.map(|(_, tare)| tare), temperature.temperature_c);
        PadOutput {
            taxels: converted.map(|(output, _)| output),
            temperature,
        }
    }

    /// What every taxel of `sample` is converted under: the temperature used (the temperature
    /// state moves on) and the conditions it gives.
    #[inline(always)]
    fn conditions(&mut self, sample: &SampleInput) -> (TemperatureUsed, Conditions) {
        let tare_temperature_c = self
            .taxels
            .iter()
            .find_map(|taxel| taxel.baseline.as_ref())
            .map(Baseline::temperature_c);
        let law = self.calibration.temperature_law();
        let (temperature_c, temperature_flags) = self.temperature.temperature_at(
            sample.temperature_c,
            tare_temperature_c,
            law,
            sample.time_us,
        );
        let (permittivity_ratio, inverse_permittivity_ratio) =
            self.permittivity.at(temperature_c, law);
        let temperature = TemperatureUsed {
            temperature_c,
            permittivity_ratio,
            flags: temperature_flags,
        };
        let conditions = Conditions {
            inverse_permittivity_ratio,
            thresholds: *self.calibration.thresholds(),
            temperature_flags: temperature.flags,
            taring: matches!(self.tare, Tare::Running(_)),
        };
        (temperature, conditions)
    }

    /// Whether a taxel's conversion in one set is independent of the other taxels' readings in
    /// the sets before it: no tare is averaging (whose end sets every baseline) and no
    /// baseline tracking runs. Then sample sets can be converted taxel by taxel
    /// ([`PadModel::process_columns`]).
    #[cfg(feature = "batch")]
    pub(crate) fn taxels_independent(&self) -> bool {
        !matches!(self.tare, Tare::Running(_)) && !self.tracking.enabled
    }

    /// [`PadModel::process_with`] of every set of `samples` into `outputs`, when
    /// [`PadModel::taxels_independent`]: the temperature of every set first (it depends only on
    /// the sets before), then each taxel over every set, its calibration, baseline and
    /// thresholds read once. The same outputs and state bit for bit (the same functions, in
    /// another order that nothing they read depends on), and for a host several times faster.
    /// `in_range(taxel, set, dC/C0)` gives an in-range reading's pressure.
    #[cfg(feature = "batch")]
    #[inline(always)]
    pub(crate) fn process_columns(
        &mut self,
        samples: &[SampleInput],
        outputs: &mut [PadOutput],
        mut in_range: impl FnMut(usize, usize, f32) -> f32,
    ) {
        let mut inverse_ratios = [1.0f32; crate::pad_batch::BATCH_SAMPLE_SETS];
        for ((sample, output), inverse_ratio) in samples
            .iter()
            .zip(outputs.iter_mut())
            .zip(&mut inverse_ratios)
        {
            let (temperature, conditions) = self.conditions(sample);
            output.temperature = temperature;
            *inverse_ratio = conditions.inverse_permittivity_ratio;
        }
        let thresholds = *self.calibration.thresholds();
        let tracking = self.tracking;
        for (taxel, (state, calibration)) in self
            .taxels
            .iter_mut()
            .zip(self.calibration.taxels())
            .enumerate()
        {
            let sets = samples.iter().zip(outputs.iter_mut()).zip(&inverse_ratios);
            for (set, ((sample, output), inverse_ratio)) in sets.enumerate() {
                let (Some(reading), Some(flags), Some(slot)) = (
                    sample.readings.get(taxel),
                    sample.reading_flags.get(taxel),
                    output.taxels.get_mut(taxel),
                ) else {
                    continue;
                };
                let conditions = Conditions {
                    inverse_permittivity_ratio: *inverse_ratio,
                    thresholds,
                    temperature_flags: output.temperature.flags,
                    taring: false,
                };
                (*slot, _) = state.convert(
                    calibration,
                    reading,
                    *flags,
                    &conditions,
                    &tracking,
                    |_, relative_change| in_range(taxel, set, relative_change),
                );
            }
        }
    }

    fn advance_tare(
        &mut self,
        capacitances: &[Option<crate::reading::SplitCapacitance>; TAXEL_COUNT],
        temperature_c: f32,
    ) {
        let Tare::Running(accumulator) = &mut self.tare else {
            return;
        };
        if !accumulator.add(capacitances, temperature_c) {
            return;
        }
        let parasitic_pf = parasitic_pf(&self.calibration);
        let results = accumulator.finish(
            &parasitic_pf,
            self.calibration.temperature_law(),
            self.calibration.thresholds(),
        );
        let mut tared_mask = 0u8;
        for (taxel, result) in results.into_iter().enumerate() {
            let error = match result {
                Ok(baseline) => {
                    self.set_baseline(taxel, baseline);
                    tared_mask |= 1 << taxel;
                    None
                }
                Err(error) => Some(error),
            };
            if let Some(state) = self.taxels.get_mut(taxel) {
                state.last_tare_error = error;
            }
        }
        self.tare = Tare::Finished { tared_mask };
    }
}

/// Each taxel's parasitic capacitance, pF.
fn parasitic_pf(calibration: &Calibration) -> [f32; TAXEL_COUNT] {
    calibration
        .taxels()
        .each_ref()
        .map(|taxel| taxel.parasitic_pf())
}
