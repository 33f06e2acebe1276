//! A recording of the device's stream, as `taxel record` and the live view's record key write
//! it: three files written under temporary names and renamed when the recording ends cleanly.
//!
//! - `NAME.csv`: for a device with one pad, one row per sample frame: `seq,time_s,temp_c,
//!   temp_source,c11_pf..c22_pf,p11_kpa..p22_kpa,flags11..flags22,marker` (RFC 4180, '.'
//!   decimals; an empty pressure is a faulted taxel; `marker` is empty except on the first
//!   sample after a marker was dropped). For a device with several pads, one row per sample
//!   set with every pad's columns prefixed `pad<n>_` (see [`crate::pad_set`] and
//!   [`crate::record_rows`]).
//! - `NAME.csv.raw`: every byte received, for `taxel convert --raw`.
//! - `NAME.csv.device.json`: the device's state the pressures were computed with: identity,
//!   and for every pad its tier, the whole calibration in use and the baselines (tares) with the
//!   sequence number from which each applies (see [`crate::device_state`] for the layout).
//!   `taxel convert` finds it beside the CSV and uses it, so a re-processed recording agrees
//!   with the device, pad by pad.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use wire::{PadIndex, SampleFrame};

use crate::csv_format::{
    format_number, format_optional, format_time_us, temperature_source_name, wire_flag_names,
    CAPACITANCE_COLUMNS, FLAGS_COLUMNS, PRESSURE_COLUMNS,
};
use crate::output_file::{OutputFile, PendingRename};
use crate::record_rows::RecordRows;

pub use crate::device_state::{
    read_device_state, BaselineChange, BaselineFollower, RecordedDeviceState, RecordedPadState,
    DEVICE_STATE_FORMAT, DEVICE_STATE_VERSION,
};

/// The marker column of a recording.
pub const MARKER_COLUMN: &str = "marker";

/// The sequence-number column of a recording.
pub const SEQUENCE_COLUMN: &str = "seq";

/// The CSV header of a recording.
pub fn record_header() -> Vec<&'static str> {
    let mut header = vec![SEQUENCE_COLUMN, "time_s", "temp_c", "temp_source"];
    header.extend(CAPACITANCE_COLUMNS);
    header.extend(PRESSURE_COLUMNS);
    header.extend(FLAGS_COLUMNS);
    header.push(MARKER_COLUMN);
    header
}

/// The CSV cells of one sample frame, in [`record_header`] order.
pub fn sample_cells(sample: &SampleFrame, marker: &str) -> Vec<String> {
    let mut cells = vec![
        sample.sequence.to_string(),
        format_time_us(sample.timestamp_us),
        format_optional(sample.temperature_c),
        temperature_source_name(sample.temperature_source).to_owned(),
    ];
    cells.extend(
        sample
            .taxels
            .iter()
            .map(|taxel| format_number(taxel.capacitance_pf)),
    );
    cells.extend(
        sample
            .taxels
            .iter()
            .map(|taxel| format_optional(taxel.pressure_kpa)),
    );
    cells.extend(
        sample
            .taxels
            .iter()
            .map(|taxel| wire_flag_names(taxel.flags)),
    );
    cells.push(marker.to_owned());
    cells
}

/// The device-state file beside a recording's CSV (or beside a raw log named `X.raw`, the one
/// of `X`).
pub fn device_state_path(recording: &Path) -> PathBuf {
    let base = match recording.extension() {
        Some(extension) if extension == "raw" => recording.with_extension(""),
        _ => recording.to_path_buf(),
    };
    let mut name = base.into_os_string();
    name.push(".device.json");
    PathBuf::from(name)
}

/// The raw log path beside a CSV: the CSV path with `.raw` appended.
pub fn default_raw_path(csv_path: &Path) -> PathBuf {
    let mut name = csv_path.as_os_str().to_owned();
    name.push(".raw");
    PathBuf::from(name)
}

/// The sample sets a sink has seen, counted by sequence number (the frames of one set share
/// it), for [`SampleSink::rows`] and [`SampleSink::would_close_set`] of sinks that take whole
/// frames.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct SetCounter {
    current: Option<u32>,
    started: u64,
}

impl SetCounter {
    /// Notes a frame's set.
    pub(crate) fn observe(&mut self, sample: &SampleFrame) {
        if self.current != Some(sample.sequence) {
            self.current = Some(sample.sequence);
            self.started += 1;
        }
    }

    /// Sets closed: every set started but the one in progress.
    pub(crate) fn closed(&self) -> u64 {
        self.started.saturating_sub(1)
    }

    /// Whether `sample` belongs to a later set than the one in progress.
    pub(crate) fn would_close(&self, sample: &SampleFrame) -> bool {
        self.current.is_some_and(|set| set != sample.sequence)
    }
}

/// Where recorded samples go: a [`Recording`], [`RecordRows`] over any writer, or any CSV
/// writer (one pad only: it writes one single-pad row per frame).
pub trait SampleSink {
    /// Takes one sample frame (a sink of several pads writes its set's row once complete).
    fn write_sample(&mut self, sample: &SampleFrame) -> anyhow::Result<()>;
    /// Pushes buffered rows out.
    fn flush(&mut self) -> anyhow::Result<()>;
    /// Rows written so far, when the sink counts them (one per sample set).
    fn rows(&self) -> Option<u64> {
        None
    }
    /// Whether taking `sample` would first close the sample set in progress (a frame of a later
    /// set); never with one pad.
    fn would_close_set(&self, sample: &SampleFrame) -> bool {
        let _ = sample;
        false
    }
    /// The baselines of one of the device's pads changed (a tare finished); they apply from
    /// that pad's sample with `change.from_sequence` on. Sinks that keep no device state ignore it.
    fn baselines_changed(&mut self, pad: PadIndex, change: BaselineChange) {
        let _ = (pad, change);
    }
    /// A device event arrived (between sample frames, in order). Sinks that record only
    /// samples ignore it.
    fn device_event(&mut self, event: &wire::EventFrame) -> anyhow::Result<()> {
        let _ = event;
        Ok(())
    }
}

impl<W: Write> SampleSink for csv::Writer<W> {
    fn write_sample(&mut self, sample: &SampleFrame) -> anyhow::Result<()> {
        if sample.pad.get() != 0 {
            bail!(
                "a frame of pad {} reached a single-pad CSV writer",
                sample.pad.get()
            );
        }
        self.write_record(sample_cells(sample, ""))
            .context("writing the CSV")
    }

    fn flush(&mut self) -> anyhow::Result<()> {
        csv::Writer::flush(self).context("writing the CSV")
    }
}

impl SampleSink for Recording {
    fn write_sample(&mut self, sample: &SampleFrame) -> anyhow::Result<()> {
        Recording::write_sample(self, sample)
    }

    fn flush(&mut self) -> anyhow::Result<()> {
        Recording::flush(self)
    }

    fn rows(&self) -> Option<u64> {
        Some(self.rows.rows())
    }

    fn would_close_set(&self, sample: &SampleFrame) -> bool {
        self.rows.would_close_set(sample)
    }

    fn baselines_changed(&mut self, pad: PadIndex, change: BaselineChange) {
        if let Some(history) = self
            .device_state
            .as_mut()
            .and_then(|state| state.baselines_mut(pad.get()))
        {
            history.push(change);
        }
    }
}

/// The files of a recording and what went into them.
#[derive(Debug)]
pub struct Recording {
    rows: RecordRows<BufWriter<File>>,
    csv_pending: PendingRename,
    raw: Option<PendingRename>,
    device_state: Option<RecordedDeviceState>,
    device_state_path: PathBuf,
}

/// Where a finished recording is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordingFiles {
    /// The CSV file.
    pub csv: PathBuf,
    /// The raw log, if one was written.
    pub raw: Option<PathBuf>,
    /// The device-state file, if the device's state was known.
    pub device_state: Option<PathBuf>,
    /// Rows written: sample frames with one pad, sample sets with several.
    pub samples: u64,
    /// Markers written.
    pub markers: u64,
    /// With several pads: words on the rows that lack a pad's frame, if any.
    pub incomplete: Option<String>,
}

impl Recording {
    /// Starts a recording of a single-pad device into `csv_path` and, if given, a raw log whose
    /// writer is returned to be handed to the link ([`crate::device_link::DeviceLink::set_raw_log`]). Nothing
    /// existing is touched until [`Recording::finish`].
    pub fn create(
        csv_path: &Path,
        raw_path: Option<&Path>,
    ) -> anyhow::Result<(Self, Option<BufWriter<File>>)> {
        Self::create_with_pads(csv_path, raw_path, 1)
    }

    /// Starts a recording of a device of `pad_count` pads (one row per sample set; with one
    /// pad, the same as [`Recording::create`]).
    pub fn create_with_pads(
        csv_path: &Path,
        raw_path: Option<&Path>,
        pad_count: u8,
    ) -> anyhow::Result<(Self, Option<BufWriter<File>>)> {
        let (csv_writer, csv_pending) = OutputFile::create(csv_path)?.into_parts();
        let rows = RecordRows::from_writer(csv_writer, pad_count)
            .with_context(|| format!("writing {}", csv_path.display()))?;
        let (raw_writer, raw) = match raw_path {
            Some(path) => {
                let (writer, pending) = OutputFile::create(path)?.into_parts();
                (Some(writer), Some(pending))
            }
            None => (None, None),
        };
        Ok((
            Self {
                rows,
                csv_pending,
                raw,
                device_state: None,
                device_state_path: device_state_path(csv_path),
            },
            raw_writer,
        ))
    }

    /// Records the device's state (written beside the CSV at the end).
    pub fn set_device_state(&mut self, state: RecordedDeviceState) {
        self.device_state = Some(state);
    }

    /// The device's state, if known, to add baseline changes to.
    pub fn device_state_mut(&mut self) -> Option<&mut RecordedDeviceState> {
        self.device_state.as_mut()
    }

    /// Puts a marker on the next sample row (markers dropped before it are joined with '|').
    pub fn mark(&mut self, label: &str) {
        self.rows.mark(label);
    }

    /// Takes one sample frame: writes its row (one pad), or its set's row once complete
    /// (several pads).
    pub fn write_sample(&mut self, sample: &SampleFrame) -> anyhow::Result<()> {
        self.rows.write_frame(sample)
    }

    /// Rows written so far.
    pub fn samples(&self) -> u64 {
        self.rows.rows()
    }

    /// The rows, for their counts.
    pub fn rows(&self) -> &RecordRows<BufWriter<File>> {
        &self.rows
    }

    /// Pushes buffered rows to the file (the file still has its temporary name).
    pub fn flush(&mut self) -> anyhow::Result<()> {
        self.rows.flush()
    }

    /// Ends the recording: writes the device state, then renames every file to its name. The
    /// raw log's writer (taken back from the link) must be given back here.
    pub fn finish(self, raw_writer: Option<BufWriter<File>>) -> anyhow::Result<RecordingFiles> {
        let Self {
            mut rows,
            csv_pending,
            raw,
            device_state,
            device_state_path,
        } = self;
        rows.end_of_stream()?;
        let markers = rows.markers();
        let samples = rows.rows();
        let incomplete = rows.incomplete_words();
        let csv = rows.finish()?;
        let csv_file = csv
            .into_inner()
            .map_err(|error| anyhow::anyhow!("writing the CSV: {}", error.error()))?
            .into_inner()
            .map_err(|error| error.into_error())
            .context("writing the CSV")?;
        let csv_path = csv_pending.target().to_path_buf();
        let raw_path = match (raw, raw_writer) {
            (Some(pending), Some(writer)) => {
                let path = pending.target().to_path_buf();
                let file = writer
                    .into_inner()
                    .map_err(|error| error.into_error())
                    .context("writing the raw log")?;
                pending.commit_file(file)?;
                Some(path)
            }
            (Some(pending), None) => {
                let path = pending.target().to_path_buf();
                pending.commit()?;
                Some(path)
            }
            (None, _) => None,
        };
        let device_state_written = match &device_state {
            Some(state) => {
                state.write(&device_state_path)?;
                Some(device_state_path)
            }
            None => None,
        };
        csv_pending.commit_file(csv_file)?;
        Ok(RecordingFiles {
            csv: csv_path,
            raw: raw_path,
            device_state: device_state_written,
            samples,
            markers,
            incomplete,
        })
    }

    /// Gives up without renaming, keeping what was written under the temporary names (a
    /// recording that failed half-way keeps its data); returns those names.
    pub fn abandon(self, raw_writer: Option<BufWriter<File>>) -> Vec<PathBuf> {
        let Self {
            mut rows,
            csv_pending,
            raw,
            ..
        } = self;
        let mut kept = Vec::new();
        let _ = rows.end_of_stream();
        let _ = rows.flush();
        drop(rows);
        if let Ok(path) = csv_pending.keep() {
            kept.push(path);
        }
        if let Some(pending) = raw {
            if let Some(mut writer) = raw_writer {
                let _ = writer.flush();
            }
            if let Ok(path) = pending.keep() {
                kept.push(path);
            }
        }
        kept
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_state_sits_beside_the_csv_for_either_file() {
        assert_eq!(
            device_state_path(Path::new("dir/rec.csv")),
            PathBuf::from("dir/rec.csv.device.json")
        );
        assert_eq!(
            device_state_path(Path::new("dir/rec.csv.raw")),
            PathBuf::from("dir/rec.csv.device.json")
        );
    }
}
