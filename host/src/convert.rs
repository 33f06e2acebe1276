//! The conversion engine: recorded readings through the pad pipeline again — the model with
//! its calibration, tier and baselines, force and centre of pressure, the contact detector —
//! for every pad of every device, each with its own state. `taxel convert` runs it over a
//! recording of the schema ([`crate::schema`]) or a raw byte log, and the Python package's
//! `convert_recording` over a recording and `convert` over arrays. Each pad's rows run through
//! its pipeline's batch path ([`ConversionEngine::convert_rows`]), which gives what the
//! pipeline gives one set at a time. With the device's recorded state
//! (`NAME.dev<n>.device.json` beside the recording), re-processing reproduces what the device
//! computed; options given replace its parts.
//!
//! Output: the same rows (identity, times, capacitances and temperature kept) with the
//! pressures, flags, force, centre of pressure, partial and contact computed again; or, with
//! [`WideWriter`], one row per sample set of a device with every pad's columns prefixed
//! `pad<n>_` (an export, never an input).

mod pad_run;

use std::collections::btree_map::Entry;
use std::collections::BTreeMap;
use std::io::{BufRead, Read, Write};
use std::path::{Path, PathBuf};

use anyhow::Context;
use model_core::{Calibration, PadGeometry, Tier};
use wire::DeviceFrame;

use crate::device_state::{BaselineChange, RecordedDeviceState, RecordedPadState};
use crate::frame_receiver::FrameReceiver;
use crate::pad_set::PadSetAssembler;
use crate::recorder::device_file;
use crate::schema::{self, PadReading, PadRow, RowReader, RowWriter, SchemaError};
use pad_run::PadRun;
pub use pad_run::PadSets;

/// Exit status when at least one input row could not be read.
pub const EXIT_BAD_ROWS: u8 = 3;

/// Parses a tier name for the command line, listing the valid names on error.
pub fn parse_tier(name: &str) -> Result<Tier, String> {
    Tier::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = Tier::ALL.iter().map(|tier| tier.name()).collect();
        format!("unknown tier '{name}'; valid tiers: {}", names.join(", "))
    })
}

/// What replaces the recorded state: a calibration, a tier, a tare on the first rows.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ConvertSettings {
    /// Tare each pad on the mean of its first N readable rows instead of the recorded
    /// baselines.
    pub tare_rows: Option<u16>,
    /// Inversion tier (default: the recording's, else the default tier).
    pub tier: Option<Tier>,
    /// Calibration (default: the recording's, else the built-in default).
    pub calibration: Option<Calibration>,
    /// Ignore the recording's device states.
    pub no_device_state: bool,
    /// Compute only the pressures and flags: force, centre of pressure, partial and contact
    /// are left empty (`None`, false). For a caller that reads nothing else; the pressures and
    /// flags are the same either way (nothing in them depends on the rest).
    pub pressures_only: bool,
}

/// Where the baselines come from.
#[derive(Debug, Clone, PartialEq)]
pub enum TareSource {
    /// The mean of the first this many readable rows.
    Rows(u16),
    /// The device's baselines, each from its sequence number on.
    Recorded(Vec<BaselineChange>),
}

/// One pad's calibration, tier and baselines.
#[derive(Debug, Clone, PartialEq)]
pub struct PadOptions {
    /// The calibration.
    pub calibration: Calibration,
    /// The inversion tier.
    pub tier: Tier,
    /// The baselines.
    pub tare: TareSource,
    /// The taxels' centres and areas, for force and centre of pressure.
    pub geometry: PadGeometry,
    /// Rows before this sequence number may have been computed by the device with another
    /// calibration, tier or geometry than the recorded ones used here (they changed while the
    /// host was reading); 0 when none.
    pub recorded_from_sequence: u32,
}

impl PadOptions {
    /// A pad's options: `settings`, and for what they do not give the pad's recorded state
    /// (`None`: the built-in defaults and a tare on the first row).
    pub fn resolve(
        settings: &ConvertSettings,
        recorded: Option<&RecordedPadState>,
    ) -> anyhow::Result<Self> {
        let calibration = match (&settings.calibration, recorded) {
            (Some(calibration), _) => calibration.clone(),
            (None, Some(recorded)) => recorded.calibration()?,
            (None, None) => Calibration::default(),
        };
        let tier = match (settings.tier, recorded) {
            (Some(tier), _) => tier,
            (None, Some(recorded)) => Tier::from_name(&recorded.tier).with_context(|| {
                format!(
                    "the recording's tier '{}' of pad {} is unknown here",
                    recorded.tier, recorded.pad
                )
            })?,
            (None, None) => Tier::default(),
        };
        let tare = match (settings.tare_rows, recorded) {
            (Some(rows), _) => TareSource::Rows(rows),
            (None, Some(recorded)) if !recorded.baselines.is_empty() => {
                TareSource::Recorded(recorded.baselines.clone())
            }
            (None, _) => TareSource::Rows(1),
        };
        // The device's geometry is what its force was computed with; without a recorded state,
        // the built-in one (the device's too until a geometry is set).
        let geometry = recorded.map_or(PadGeometry::ARTICLE, |recorded| recorded.geometry);
        let recorded_from_sequence = match recorded {
            Some(recorded) if settings.calibration.is_none() || settings.tier.is_none() => {
                recorded.state_from_sequence
            }
            _ => 0,
        };
        Ok(Self {
            calibration,
            tier,
            tare,
            geometry,
            recorded_from_sequence,
        })
    }
}

/// The most devices whose states are looked for beside a recording.
pub const MAX_DEVICES: u32 = 256;

/// The recorded state of each device of a recording, read from beside it.
#[derive(Debug, Clone, Default)]
pub struct RecordedStates {
    devices: BTreeMap<u32, RecordedDeviceState>,
    /// The files read.
    pub files: Vec<PathBuf>,
}

impl RecordedStates {
    /// The states beside `recording` (`NAME.dev<n>.device.json`) of every device number up to
    /// [`MAX_DEVICES`] that has one (a device without its file does not hide the next).
    pub fn beside(recording: &Path) -> anyhow::Result<Self> {
        let mut states = Self::default();
        for device in 0..MAX_DEVICES {
            let path = device_file(recording, device as usize, "device.json");
            if !path.exists() {
                continue;
            }
            states
                .devices
                .insert(device, RecordedDeviceState::read(&path)?);
            states.files.push(path);
        }
        Ok(states)
    }

    /// One device's state read from `path`.
    pub fn of_one_device(device: u32, path: &Path) -> anyhow::Result<Self> {
        let mut states = Self::default();
        states
            .devices
            .insert(device, RecordedDeviceState::read(path)?);
        states.files.push(path.to_path_buf());
        Ok(states)
    }

    /// Device `device`'s state.
    pub fn device(&self, device: u32) -> Option<&RecordedDeviceState> {
        self.devices.get(&device)
    }
}

/// The pipelines of every pad of every device, made as their rows come.
pub struct ConversionEngine {
    settings: ConvertSettings,
    states: RecordedStates,
    runs: BTreeMap<(u32, u8), PadRun>,
    /// Pads without a recorded state of their own (converted with the defaults or the
    /// settings): (device, pad).
    pub pads_without_state: Vec<(u32, u8)>,
}

impl ConversionEngine {
    /// An engine with `settings` over `states` (ignored with
    /// [`ConvertSettings::no_device_state`]).
    pub fn new(settings: ConvertSettings, states: RecordedStates) -> Self {
        let states = if settings.no_device_state {
            RecordedStates::default()
        } else {
            states
        };
        Self {
            settings,
            states,
            runs: BTreeMap::new(),
            pads_without_state: Vec::new(),
        }
    }

    fn run(&mut self, device: u32, pad: u8) -> anyhow::Result<&mut PadRun> {
        // One lookup per row: the pipeline is made the first time its pad comes.
        match self.runs.entry((device, pad)) {
            Entry::Occupied(run) => Ok(run.into_mut()),
            Entry::Vacant(slot) => {
                let recorded = self
                    .states
                    .device(device)
                    .and_then(|state| state.pad_state(pad));
                if recorded.is_none() {
                    self.pads_without_state.push((device, pad));
                }
                let options = PadOptions::resolve(&self.settings, recorded.as_ref())
                    .with_context(|| format!("device {device} pad {pad}"))?;
                let run = PadRun::new(&options, self.settings.pressures_only)
                    .with_context(|| format!("device {device} pad {pad}"))?;
                Ok(slot.insert(run))
            }
        }
    }

    /// Computes the row's pad outputs again, in place (a missing frame stays missing).
    pub fn convert(&mut self, row: &mut PadRow) -> anyhow::Result<()> {
        self.convert_rows(std::slice::from_mut(row), true)
    }

    /// As [`convert`](Self::convert), for a row whose device time is not known (arrays given
    /// without times): the model takes the time between a pad's sets as unknown.
    pub fn convert_untimed(&mut self, row: &mut PadRow) -> anyhow::Result<()> {
        self.convert_rows(std::slice::from_mut(row), false)
    }

    /// [`convert`](Self::convert) (or, without `timed`, [`convert_untimed`](Self::convert_untimed))
    /// of every row in turn, faster: each pad's rows go through its pipeline's batch path
    /// together. Pads are independent, so the result is that of converting the rows one by one
    /// in order (tested).
    pub fn convert_rows(&mut self, rows: &mut [PadRow], timed: bool) -> anyhow::Result<()> {
        if let [row] = rows {
            // A row at a time: no lists to make.
            if let Some(reading) = &mut row.reading {
                let run = self.run(row.device, row.pad)?;
                run.process(&mut [(row.sequence, reading)][..], timed);
            }
            return Ok(());
        }
        let mut pads: Vec<(u32, u8)> = Vec::new();
        for row in rows.iter() {
            let key = (row.device, row.pad);
            // The pad of the row before, most often: no search.
            if row.reading.is_some() && pads.last() != Some(&key) && !pads.contains(&key) {
                pads.push(key);
            }
        }
        for (device, pad) in pads {
            let mut readings: Vec<(u32, &mut PadReading)> = Vec::with_capacity(rows.len());
            readings.extend(
                rows.iter_mut()
                    .filter(|row| (row.device, row.pad) == (device, pad))
                    .filter_map(|row| row.reading.as_mut().map(|reading| (row.sequence, reading))),
            );
            self.run(device, pad)?
                .process(readings.as_mut_slice(), timed);
        }
        Ok(())
    }

    /// Converts sets of one pad of one device that the caller holds in its own form (see
    /// [`PadSets`]: the Python package's arrays), in order after the pad's sets converted
    /// before, exactly as [`convert_rows`](Self::convert_rows) converts rows holding them.
    pub fn convert_sets<S: PadSets + ?Sized>(
        &mut self,
        device: u32,
        pad: u8,
        sets: &mut S,
        timed: bool,
    ) -> anyhow::Result<()> {
        if sets.is_empty() {
            return Ok(());
        }
        self.run(device, pad)?.process(sets, timed);
        Ok(())
    }

    /// The problems with the tares, pad by pad, at the end.
    pub fn finish(self) -> Vec<String> {
        self.runs
            .into_iter()
            .flat_map(|((device, pad), run)| {
                run.warnings()
                    .into_iter()
                    .map(move |warning| format!("device {device} pad {pad}: {warning}"))
            })
            .collect()
    }
}

/// Where converted rows go: the schema's rows, or the wide export.
pub trait RowSink {
    /// Takes one converted row.
    fn write_row(&mut self, row: &PadRow) -> anyhow::Result<()>;
    /// Writes what is still held and flushes.
    fn finish(&mut self) -> anyhow::Result<()>;
}

impl<W: Write> RowSink for RowWriter<W> {
    fn write_row(&mut self, row: &PadRow) -> anyhow::Result<()> {
        Ok(self.write(row)?)
    }

    fn finish(&mut self) -> anyhow::Result<()> {
        Ok(self.flush()?)
    }
}

/// The wide export: one row per sample set of a device — `host_time_s,device,seq`, then for
/// each pad `n` below `pad_count` the schema's other columns prefixed `pad<n>_`, then
/// `marker` (a set's pads that are not in the input have empty cells).
pub struct WideWriter<W: Write> {
    output: csv::Writer<W>,
    pad_count: usize,
    set: Vec<PadRow>,
}

impl<W: Write> WideWriter<W> {
    /// A writer of sets of `pad_count` pads (the header is written first).
    pub fn new(output: W, pad_count: usize) -> anyhow::Result<Self> {
        let mut output = csv::Writer::from_writer(output);
        let mut header = vec![
            "host_time_s".to_owned(),
            "device".to_owned(),
            "seq".to_owned(),
        ];
        for pad in 0..pad_count {
            header.extend(
                schema::COLUMNS[4..]
                    .iter()
                    .map(|column| format!("pad{pad}_{}", column.name)),
            );
        }
        header.push(schema::MARKER.name.to_owned());
        output.write_record(&header)?;
        Ok(Self {
            output,
            pad_count: pad_count.max(1),
            set: Vec::new(),
        })
    }

    fn flush_set(&mut self) -> anyhow::Result<()> {
        let Some(first) = self.set.first() else {
            return Ok(());
        };
        let mut cells = vec![
            String::new(),
            first.device.to_string(),
            first.sequence.to_string(),
        ];
        let mut line = Vec::new();
        schema::format_row(first, &mut line);
        let first_cells = String::from_utf8_lossy(&line).into_owned();
        cells[0] = first_cells.split(',').next().unwrap_or_default().to_owned();
        let mut marker = String::new();
        for pad in 0..self.pad_count {
            match self.set.iter().find(|row| usize::from(row.pad) == pad) {
                Some(row) => {
                    let mut record = csv::ByteRecord::new();
                    let mut line = Vec::new();
                    schema::format_row(row, &mut line);
                    let mut reader = csv::ReaderBuilder::new()
                        .has_headers(false)
                        .from_reader(line.as_slice());
                    if reader.read_byte_record(&mut record)? {
                        cells.extend(
                            record
                                .iter()
                                .skip(4)
                                .take(schema::COLUMNS.len() - 4)
                                .map(|cell| String::from_utf8_lossy(cell).into_owned()),
                        );
                    }
                    if marker.is_empty() {
                        marker = row.marker.clone();
                    }
                }
                None => cells.extend(std::iter::repeat_n(
                    String::new(),
                    schema::COLUMNS.len() - 4,
                )),
            }
        }
        cells.push(marker);
        self.output.write_record(&cells)?;
        self.set.clear();
        Ok(())
    }
}

impl<W: Write> RowSink for WideWriter<W> {
    fn write_row(&mut self, row: &PadRow) -> anyhow::Result<()> {
        if self
            .set
            .first()
            .is_some_and(|first| first.device != row.device || first.sequence != row.sequence)
        {
            self.flush_set()?;
        }
        self.set.push(row.clone());
        Ok(())
    }

    fn finish(&mut self) -> anyhow::Result<()> {
        self.flush_set()?;
        self.output.flush()?;
        Ok(())
    }
}

/// A row that could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BadRow {
    /// 1-based line number in the input (the header is line 1).
    pub line: u64,
    /// Why.
    pub reason: String,
}

/// The outcome of a conversion.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ConvertSummary {
    /// Rows converted and written.
    pub rows_written: u64,
    /// Rows that could not be read (skipped; the conversion goes on).
    pub bad_rows: Vec<BadRow>,
    /// Raw logs only: frames that could not be decoded.
    pub undecodable_frames: u64,
    /// Raw logs only: bytes that belonged to no decoded frame.
    pub undecodable_bytes: u64,
    /// Problems with the tares.
    pub tare_warnings: Vec<String>,
    /// Pads converted without a recorded state of their own: (device, pad).
    pub pads_without_state: Vec<(u32, u8)>,
    /// Pad frames missing from the recording's sets (their rows kept as they are).
    pub missing_frames: u64,
    /// Raw logs only: sample frames of pads beyond the pad count the log was read with (left
    /// out: the pad count comes from the device's state file, 1 without it).
    pub frames_beyond_pad_count: u64,
}

/// Converts a recording of the schema from `input` into `sink`.
pub fn convert_recording<R: BufRead>(
    input: R,
    sink: &mut dyn RowSink,
    mut engine: ConversionEngine,
) -> anyhow::Result<ConvertSummary> {
    let mut reader = RowReader::new(input)?;
    let mut summary = ConvertSummary::default();
    while let Some(row) = reader.next_row() {
        match row {
            Ok(mut row) => {
                if row.reading.is_none() {
                    summary.missing_frames += 1;
                }
                engine.convert(&mut row)?;
                sink.write_row(&row)?;
                summary.rows_written += 1;
            }
            Err(SchemaError::Row { line, reason }) => {
                summary.bad_rows.push(BadRow { line, reason })
            }
            Err(error) => return Err(error.into()),
        }
    }
    anyhow::ensure!(
        summary.rows_written > 0 || !summary.bad_rows.is_empty(),
        "the recording has no rows"
    );
    sink.finish()?;
    summary.pads_without_state = engine.pads_without_state.clone();
    summary.tare_warnings = engine.finish();
    Ok(summary)
}

/// Converts device `device`'s raw byte log (as `taxel record` writes it) into `sink`: its
/// frames gathered into sets of `pad_count` pads, each pad's row converted. A raw log has no
/// host times: `host_time_s` is the set's device time and `sync_error_ms` is empty.
pub fn convert_raw<R: Read>(
    mut input: R,
    device: u32,
    pad_count: u8,
    sink: &mut dyn RowSink,
    mut engine: ConversionEngine,
) -> anyhow::Result<ConvertSummary> {
    let mut receiver = FrameReceiver::new();
    receiver.set_pad_count(pad_count.max(1));
    let mut assembler = PadSetAssembler::new(pad_count.max(1));
    let mut summary = ConvertSummary::default();
    let mut buffer = vec![0u8; 64 * 1024];
    let mut frames = Vec::new();
    let mut sets = Vec::new();
    loop {
        let read = match input.read(&mut buffer) {
            Ok(0) => {
                receiver.finish();
                sets.extend(assembler.finish());
                0
            }
            Ok(read) => read,
            Err(error) if error.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(error) => return Err(error).context("reading the raw log"),
        };
        receiver.push_bytes(&buffer[..read], &mut frames);
        for frame in frames.drain(..) {
            if let DeviceFrame::Sample(sample) = frame {
                sets.extend(assembler.push(sample));
            }
        }
        for set in sets.drain(..) {
            let Some(time_us) = set
                .pads
                .iter()
                .flatten()
                .map(|frame| frame.timestamp_us)
                .next()
            else {
                continue;
            };
            for (pad, frame) in set.pads.iter().enumerate() {
                let mut row = PadRow {
                    host_time_us: time_us,
                    device,
                    pad: u8::try_from(pad).unwrap_or(u8::MAX),
                    sequence: set.sequence,
                    sync_error_us: None,
                    reading: frame.as_ref().map(PadReading::from_frame),
                    marker: String::new(),
                };
                if row.reading.is_none() {
                    summary.missing_frames += 1;
                }
                engine.convert(&mut row)?;
                sink.write_row(&row)?;
                summary.rows_written += 1;
            }
        }
        if read == 0 {
            break;
        }
    }
    anyhow::ensure!(
        summary.rows_written > 0,
        "the raw log holds no sample frames"
    );
    sink.finish()?;
    let statistics = receiver.statistics();
    summary.undecodable_frames = statistics.frames_rejected;
    summary.undecodable_bytes = statistics.bytes_rejected;
    summary.frames_beyond_pad_count =
        statistics.samples_beyond_pad_count + assembler.frames_beyond_pad_count();
    summary.pads_without_state = engine.pads_without_state.clone();
    summary.tare_warnings = engine.finish();
    Ok(summary)
}
