//! Running one pad's pipeline over a stream of its readings: the model with its calibration
//! and tier, the baselines (a tare on the first rows, or the recorded ones installed at their
//! sequence numbers), force and centre of pressure on the pad's geometry, the contact detector,
//! and what the tare said. One [`PadRun`] per pad of each device.

use model_core::{
    BaselineRecord, ContactConfig, ForceAndContact, PadContact, PadModel, PadOutput, PadPipeline,
    PadReport, PadRole, SampleInput, TareStatus, TaxelFlags, TaxelReading, TAXEL_COUNT,
    TAXEL_NAMES,
};

use super::{PadOptions, TareSource};
use crate::device_state::BaselineChange;
use crate::schema::PadReading;
use wire::TemperatureSource;

/// Flags a recording's sample frames carry that come from the acquisition, not the model, and
/// so must be kept when the model runs again.
pub(super) const ACQUISITION_FLAGS: TaxelFlags = TaxelFlags::CONVERTER_ERROR
    .union(TaxelFlags::STUCK)
    .union(TaxelFlags::SATURATED);

fn new_model(options: &PadOptions) -> anyhow::Result<PadModel> {
    let mut pad = PadModel::new(options.calibration.clone());
    pad.set_tier(options.tier).map_err(|_| {
        anyhow::anyhow!(
            "tier {} is not available for this calibration (the saturating fit needs a concave curve on every taxel)",
            options.tier.name()
        )
    })?;
    if let TareSource::Rows(rows) = options.tare {
        pad.start_tare(rows);
    }
    Ok(pad)
}

/// Installs the recorded baselines in force at each sample's sequence number.
#[derive(Debug, Default)]
struct RecordedBaselines {
    changes: Vec<BaselineChange>,
    installed: Option<usize>,
    warnings: Vec<String>,
}

impl RecordedBaselines {
    fn new(tare: &TareSource) -> Self {
        match tare {
            TareSource::Recorded(changes) => Self {
                changes: changes.clone(),
                ..Self::default()
            },
            TareSource::Rows(_) => Self::default(),
        }
    }

    /// The index of the baselines that apply from `sequence` on (the first ones when the data
    /// has no sequence numbers), when they are not the ones installed.
    fn change_at(&self, sequence: Option<u32>) -> Option<usize> {
        // Conversions without recorded baselines ask this of every row.
        if self.changes.is_empty() {
            return None;
        }
        let wanted = match sequence {
            Some(sequence) => self
                .changes
                .iter()
                .rposition(|change| change.from_sequence <= sequence)
                .or(if self.changes.is_empty() {
                    None
                } else {
                    Some(0)
                }),
            None if self.changes.is_empty() => None,
            None => Some(0),
        };
        wanted.filter(|wanted| Some(*wanted) != self.installed)
    }

    /// Before a sample: installs the baselines that apply from `sequence` on.
    fn before_sample(&mut self, pad: &mut PadModel, sequence: Option<u32>) {
        let Some(index) = self.change_at(sequence) else {
            return;
        };
        self.installed = Some(index);
        if let Some(change) = self.changes.get(index) {
            install_baselines(pad, &change.taxels, &mut self.warnings);
        }
    }
}

fn install_baselines(
    pad: &mut PadModel,
    baselines: &[Option<BaselineRecord>; TAXEL_COUNT],
    warnings: &mut Vec<String>,
) {
    let restored = pad.restore_baselines(baselines);
    for (taxel, baseline) in baselines.iter().enumerate() {
        if baseline.is_some() && restored & (1 << taxel) == 0 {
            warnings.push(format!(
                "the recorded baseline of taxel {} is not valid with this calibration; it stays not_tared",
                TAXEL_NAMES[taxel]
            ));
        }
    }
}

/// Notices when the tare finishes and whether every taxel got a baseline.
#[derive(Debug, Default)]
struct TareWatch {
    reported: bool,
    warnings: Vec<String>,
}

impl TareWatch {
    fn observe(&mut self, pad: &PadModel) {
        if self.reported {
            return;
        }
        if let TareStatus::Finished { tared_mask } = pad.tare_status() {
            self.reported = true;
            let errors = pad.last_tare_errors();
            for taxel in 0..TAXEL_COUNT {
                if tared_mask & (1 << taxel) == 0 {
                    self.warnings.push(format!(
                        "taxel {} could not be tared ({}); it stays not_tared",
                        TAXEL_NAMES[taxel],
                        errors[taxel]
                            .map(|error| crate::device_words::baseline_error_words(&error))
                            .unwrap_or_else(|| "no usable reading".to_owned())
                    ));
                }
            }
        }
    }

    fn finish(mut self, pad: &PadModel) -> Vec<String> {
        if let TareStatus::Running { remaining } = pad.tare_status() {
            self.warnings.push(format!(
                "the tare never finished ({remaining} more readable rows were needed); every pressure is empty (not_tared)"
            ));
        }
        self.warnings
    }
}

/// One pad's pipeline (model, geometry, contact), baselines and tare watch over a stream.
#[derive(Debug)]
pub(super) struct PadRun {
    pipeline: PadPipeline,
    baselines: RecordedBaselines,
    tare_watch: TareWatch,
    // The sensor that gave the last temperature (TMP117 or the MCU's), as the device tells it.
    last_temperature_sensor: Option<TemperatureSource>,
    // No reading has been processed yet.
    first: bool,
    // Rows before this sequence number may have been computed with another state than the
    // recorded one; how many came.
    recorded_from_sequence: u32,
    rows_before_recorded_state: u64,
    // Only pressures and flags are computed (`ConvertSettings::pressures_only`).
    pressures_only: bool,
}

impl PadRun {
    /// A fresh run with a pad's calibration, tier and baselines; with `pressures_only` it
    /// computes pressures and flags and leaves force, centre of pressure and contact empty.
    pub(super) fn new(options: &PadOptions, pressures_only: bool) -> anyhow::Result<Self> {
        let force_and_contact = ForceAndContact::new(
            PadRole::Unspecified,
            options.geometry,
            ContactConfig::DEFAULT,
        );
        Ok(Self {
            pipeline: PadPipeline::new(new_model(options)?, force_and_contact),
            baselines: RecordedBaselines::new(&options.tare),
            tare_watch: TareWatch::default(),
            last_temperature_sensor: None,
            first: true,
            recorded_from_sequence: options.recorded_from_sequence,
            rows_before_recorded_state: 0,
            pressures_only,
        })
    }

    /// Runs readings of the pad, each with its set's sequence number, in order through the
    /// pad's pipeline, each replaced by what the device would have sent (its capacitances and
    /// temperature kept). With `timed` the model reads the readings' device times, else it takes
    /// the time between sets as unknown. The first reading's recorded contact bit is taken as
    /// the contact state the stream started in (a recording can start during a contact).
    ///
    /// Readings between changes of the model's state from outside (recorded baselines that
    /// apply from a sequence number, a change of temperature sensor) go through the pipeline's
    /// batch path together: the same results as one by one (tested), faster.
    pub(super) fn process<S: PadSets + ?Sized>(&mut self, readings: &mut S, timed: bool) {
        let mut start = 0;
        while start < readings.len() {
            let (sequence, source) = readings.identity(start);
            // A batch's first reading: what changes the model's state before it goes in first
            // (recorded baselines install only when they change).
            self.count_recorded_state(sequence);
            self.baselines
                .before_sample(self.pipeline.model_mut(), Some(sequence));
            self.note_temperature_sensor(source);
            let mut end = start + 1;
            // The first reading goes through alone, so the contact state it sets up is in place
            // before the second.
            if !self.first {
                while end < readings.len() {
                    let (sequence, source) = readings.identity(end);
                    if self.baselines.change_at(Some(sequence)).is_some()
                        || self.temperature_sensor_changes(source)
                    {
                        break;
                    }
                    self.count_recorded_state(sequence);
                    self.note_temperature_sensor(source);
                    end += 1;
                }
            }
            self.run_batch(readings, start..end, timed);
            start = end;
        }
    }

    /// Counts a row that may come from before the recorded state.
    fn count_recorded_state(&mut self, sequence: u32) {
        if sequence < self.recorded_from_sequence {
            self.rows_before_recorded_state += 1;
        }
    }

    /// Readings `sets` through the pipeline together (their model inputs made as they are
    /// needed); the results replace their outputs.
    fn run_batch<S: PadSets + ?Sized>(
        &mut self,
        readings: &mut S,
        sets: std::ops::Range<usize>,
        timed: bool,
    ) {
        if sets.is_empty() {
            return;
        }
        let first = std::mem::take(&mut self.first);
        let start = sets.start;
        let sample = |readings: &mut S, position: usize| {
            let index = start + position;
            sets.contains(&index).then(|| readings.input(index, timed))
        };
        if self.pressures_only {
            let write = |readings: &mut S, position: usize, output: &PadOutput, _: Option<u64>| {
                readings.write(start + position, output, None);
            };
            self.pipeline
                .model_mut()
                .process_all_in(readings, sample, write);
            self.tare_watch.observe(self.pipeline.model());
            return;
        }
        let mut assumed = None;
        let mut write = |readings: &mut S, position: usize, report: &PadReport| {
            let mut contact = report.contact;
            if first && position == 0 {
                let recorded = readings.recorded_contact(start);
                assumed = Some((recorded, contact.force));
                contact.in_contact = recorded;
            }
            readings.write(start + position, &report.output, Some(&contact));
        };
        // One set (a row at a time, as `taxel convert` reads a file) needs no batch.
        if sets.len() == 1 {
            if let Some(input) = sample(readings, 0) {
                let report = self.pipeline.process(&input);
                write(readings, 0, &report);
            }
        } else {
            self.pipeline.process_all_in(readings, sample, write);
        }
        // The first reading goes through alone, so the contact state it sets up is in place
        // before the second.
        if let Some((in_contact, force)) = assumed {
            self.pipeline
                .force_and_contact_mut()
                .assume_contact(in_contact, &force);
        }
        self.tare_watch.observe(self.pipeline.model());
    }

    /// Whether a reading from `source` changes the temperature sensor the model follows.
    fn temperature_sensor_changes(&self, source: TemperatureSource) -> bool {
        matches!(
            source,
            TemperatureSource::Tmp117 | TemperatureSource::McuInternal
        ) && self
            .last_temperature_sensor
            .is_some_and(|last| last != source)
    }

    /// As the device does: a change between the TMP117 and the MCU's sensor is no glitch, so
    /// the model applies the new sensor's level at once; a set without a new reading (none, or
    /// the last one held) changes nothing.
    fn note_temperature_sensor(&mut self, source: TemperatureSource) {
        if !matches!(
            source,
            TemperatureSource::Tmp117 | TemperatureSource::McuInternal
        ) {
            return;
        }
        if self.temperature_sensor_changes(source) {
            self.pipeline.model_mut().temperature_source_changed();
        }
        self.last_temperature_sensor = Some(source);
    }

    /// The tare's problems, at the end.
    pub(super) fn warnings(self) -> Vec<String> {
        let mut warnings = self.baselines.warnings;
        if self.rows_before_recorded_state > 0 {
            warnings.push(format!(
                "{} rows before sequence {} may have been computed by the device with another calibration, tier or geometry than the recorded one (it changed while the host was reading); they are converted with the recorded one and may differ from what the device sent",
                self.rows_before_recorded_state, self.recorded_from_sequence
            ));
        }
        warnings.extend(self.tare_watch.finish(self.pipeline.model()));
        warnings
    }
}

/// A pad's sample sets in order, as the conversion engine reads and writes them: recorded rows
/// (`[(sequence, reading)]`), or a caller's own columns (the Python package's arrays), so that
/// every input goes through one [`PadRun`] without being copied into rows first.
pub trait PadSets {
    /// How many sets.
    fn len(&self) -> usize;

    /// True when there are none.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Set `index`'s sequence number and the sensor its temperature came from.
    fn identity(&self, index: usize) -> (u32, TemperatureSource);

    /// Set `index`'s model input: its capacitances (a converter error or an empty one read as no
    /// reading), the acquisition's flags, its temperature and, with `timed`, its device time.
    fn input(&self, index: usize, timed: bool) -> SampleInput;

    /// The contact bit set `index` was recorded with (the first set's is the contact state the
    /// stream started in).
    fn recorded_contact(&self, index: usize) -> bool;

    /// Writes set `index`'s results: pressures and flags, and force, centre of pressure,
    /// partial and contact (empty without `contact`: `ConvertSettings::pressures_only`).
    fn write(&mut self, index: usize, output: &PadOutput, contact: Option<&PadContact>);
}

impl PadSets for [(u32, &mut PadReading)] {
    fn len(&self) -> usize {
        <[_]>::len(self)
    }

    fn identity(&self, index: usize) -> (u32, TemperatureSource) {
        self.get(index)
            .map_or((0, TemperatureSource::None), |(sequence, reading)| {
                (*sequence, reading.temperature_source)
            })
    }

    fn input(&self, index: usize, timed: bool) -> SampleInput {
        match self.get(index) {
            Some((_, reading)) => reading_input(reading, timed),
            None => SampleInput::new([TaxelReading::Unavailable; TAXEL_COUNT], None),
        }
    }

    fn recorded_contact(&self, index: usize) -> bool {
        self.get(index).is_some_and(|(_, reading)| reading.contact)
    }

    fn write(&mut self, index: usize, output: &PadOutput, contact: Option<&PadContact>) {
        let Some((_, reading)) = self.get_mut(index) else {
            return;
        };
        // Field by field: no whole reading built and copied back per set.
        for ((pressure_kpa, flags), taxel) in reading
            .pressure_kpa
            .iter_mut()
            .zip(&mut reading.flags)
            .zip(&output.taxels)
        {
            *pressure_kpa = taxel.pressure_kpa();
            *flags = taxel.flags();
        }
        reading.force_n = contact.and_then(PadContact::force_n);
        reading.centre_of_pressure_mm = contact.and_then(PadContact::centre_of_pressure_mm);
        reading.partial = contact.is_some_and(PadContact::partial);
        reading.contact = contact.is_some_and(|contact| contact.in_contact);
    }
}

/// The model input of a recorded reading: its capacitances and temperature (and with `timed`
/// its device time), the acquisition's flags kept, and a converter error (or an empty
/// capacitance) read as no reading.
fn reading_input(reading: &PadReading, timed: bool) -> SampleInput {
    let reading_flags = reading
        .flags
        .map(|flags| flags.intersection(ACQUISITION_FLAGS));
    let mut taxels = reading_flags.iter().zip(reading.capacitance_pf);
    let readings = std::array::from_fn(|_| match taxels.next() {
        Some((flags, Some(capacitance_pf))) if !flags.contains(TaxelFlags::CONVERTER_ERROR) => {
            TaxelReading::CapacitancePf(capacitance_pf)
        }
        _ => TaxelReading::Unavailable,
    });
    SampleInput {
        readings,
        reading_flags,
        temperature_c: reading.temperature_c.filter(|value| !value.is_nan()),
        time_us: timed.then_some(reading.device_time_us),
    }
}
