//! The files of a recording of several devices (see [`crate::multi_record`]): the CSV in long
//! format, one row per sample frame of any device and pad on the host timeline, and each
//! device's raw log and state beside it:
//!
//! - `FILE`: the rows, columns [`timeline_header`] (RFC 4180, '.' decimals, CRLF);
//! - `FILE.dev<n>.raw`: every byte received from device n, for `taxel convert --raw`;
//! - `FILE.dev<n>.device.json`: device n's state (as [`crate::recording`] writes it beside a
//!   single device's recording), which `taxel convert --raw FILE.dev<n>.raw` finds beside the
//!   raw log.
//!
//! Every file is written under a temporary name and renamed when the recording ends cleanly.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::csv_format::{format_time_us, TIME_COLUMN};
use crate::host_timeline::TimelineRow;
use crate::output_file::{OutputFile, PendingRename};
use crate::pad_set::{pad_cells, pad_record_columns};
use crate::recording::{device_state_path, RecordedDeviceState, SEQUENCE_COLUMN};

/// Host time of the row: seconds of the host's monotonic clock since the recording started.
pub const HOST_TIME_COLUMN: &str = "host_time_s";
/// The device's index: its place among the devices of the command line (ports, then boards
/// chosen by serial number), from 0.
pub const DEVICE_COLUMN: &str = "device";
/// The pad's index on its device.
pub const PAD_COLUMN: &str = "pad";
/// The frame's device timestamp in seconds (the device's clock since it booted).
pub const DEVICE_TIME_COLUMN: &str = "device_time_s";
/// Estimated bound on the distance of the host time from the true sampling instant, ms; empty
/// when the device's clock had no estimate (the host time is then the arrival time).
pub const SYNC_ERROR_COLUMN: &str = "sync_error_ms";

/// The CSV header of a recording of several devices: `host_time_s,device,pad,seq,
/// device_time_s,sync_error_ms`, then a pad's columns ([`pad_record_columns`]) without its time.
pub fn timeline_header() -> Vec<&'static str> {
    let mut header = vec![
        HOST_TIME_COLUMN,
        DEVICE_COLUMN,
        PAD_COLUMN,
        SEQUENCE_COLUMN,
        DEVICE_TIME_COLUMN,
        SYNC_ERROR_COLUMN,
    ];
    header.extend(
        pad_record_columns()
            .into_iter()
            .filter(|&column| column != TIME_COLUMN),
    );
    header
}

/// An error bound in µs as milliseconds with 3 decimals (exact); empty when unknown.
pub fn format_sync_error_ms(error_us: Option<u64>) -> String {
    error_us.map_or_else(String::new, |error_us| {
        format!("{}.{:03}", error_us / 1_000, error_us % 1_000)
    })
}

/// The CSV cells of one row, in [`timeline_header`] order.
pub fn timeline_cells(row: &TimelineRow) -> Vec<String> {
    // A pad's cells begin with its device time ([`pad_record_columns`] begins with TIME_COLUMN).
    let mut pad = pad_cells(Some(&row.sample));
    let rest = pad.split_off(1.min(pad.len()));
    let mut cells = vec![
        format_time_us(row.host_us),
        row.device.to_string(),
        row.sample.pad.get().to_string(),
        row.sample.sequence.to_string(),
    ];
    cells.extend(pad);
    cells.push(format_sync_error_ms(row.sync_error_us));
    cells.extend(rest);
    cells
}

/// Device `device`'s files are named from this: the CSV path with `.dev<n>` appended.
fn device_file_base(csv_path: &Path, device: usize) -> PathBuf {
    let mut name = csv_path.as_os_str().to_owned();
    name.push(format!(".dev{device}"));
    PathBuf::from(name)
}

/// Device `device`'s raw byte log: `FILE.dev<n>.raw`.
pub fn device_raw_path(csv_path: &Path, device: usize) -> PathBuf {
    let mut name = device_file_base(csv_path, device).into_os_string();
    name.push(".raw");
    PathBuf::from(name)
}

/// Device `device`'s state: `FILE.dev<n>.device.json`, beside its raw log as `taxel convert
/// --raw` looks for it.
pub fn device_state_file(csv_path: &Path, device: usize) -> PathBuf {
    device_state_path(&device_raw_path(csv_path, device))
}

/// The CSV and raw logs of a recording in progress.
pub(crate) struct TimelineFiles {
    csv: csv::Writer<BufWriter<File>>,
    csv_pending: PendingRename,
    raw: Vec<PendingRename>,
    csv_path: PathBuf,
    pub(crate) rows: u64,
}

impl TimelineFiles {
    /// Starts the files (under temporary names); returns the raw logs' writers, one per device.
    pub(crate) fn create(
        csv_path: &Path,
        device_count: usize,
    ) -> anyhow::Result<(Self, Vec<BufWriter<File>>)> {
        let (writer, csv_pending) = OutputFile::create(csv_path)?.into_parts();
        let mut csv = csv::WriterBuilder::new()
            .terminator(csv::Terminator::CRLF)
            .from_writer(writer);
        csv.write_record(timeline_header())
            .with_context(|| format!("writing {}", csv_path.display()))?;
        let mut raw = Vec::new();
        let mut raw_writers = Vec::new();
        for device in 0..device_count {
            let (writer, pending) =
                OutputFile::create(&device_raw_path(csv_path, device))?.into_parts();
            raw.push(pending);
            raw_writers.push(writer);
        }
        let files = Self {
            csv,
            csv_pending,
            raw,
            csv_path: csv_path.to_path_buf(),
            rows: 0,
        };
        Ok((files, raw_writers))
    }

    pub(crate) fn write_row(&mut self, row: &TimelineRow) -> anyhow::Result<()> {
        self.csv
            .write_record(timeline_cells(row))
            .with_context(|| format!("writing the CSV after {} rows", self.rows))?;
        self.rows += 1;
        Ok(())
    }

    pub(crate) fn flush(&mut self) -> anyhow::Result<()> {
        self.csv.flush().context("writing the CSV")
    }

    /// Writes the device states and renames every file into place. The raw logs' writers must
    /// have been flushed and dropped.
    pub(crate) fn finish(self, states: &[&RecordedDeviceState]) -> anyhow::Result<Vec<PathBuf>> {
        let csv_file = self
            .csv
            .into_inner()
            .map_err(|error| anyhow::anyhow!("writing the CSV: {}", error.error()))?
            .into_inner()
            .map_err(|error| error.into_error())
            .context("writing the CSV")?;
        let mut written = Vec::new();
        for pending in self.raw {
            written.push(pending.target().to_path_buf());
            pending.commit()?;
        }
        for (device, state) in states.iter().enumerate() {
            let path = device_state_file(&self.csv_path, device);
            state.write(&path)?;
            written.push(path);
        }
        self.csv_pending.commit_file(csv_file)?;
        written.insert(0, self.csv_path);
        Ok(written)
    }

    /// Gives up, keeping what was written under the temporary names; returns them.
    pub(crate) fn abandon(mut self) -> Vec<PathBuf> {
        let _ = self.csv.flush();
        drop(self.csv);
        std::iter::once(self.csv_pending)
            .chain(self.raw)
            .filter_map(|pending| pending.keep().ok())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_and_the_cells_line_up() {
        let header = timeline_header();
        assert_eq!(
            &header[..8],
            [
                "host_time_s",
                "device",
                "pad",
                "seq",
                "device_time_s",
                "sync_error_ms",
                "temp_c",
                "temp_source"
            ]
        );
        assert_eq!(header.last(), Some(&"contact"));
        let row = TimelineRow {
            device: 1,
            sample: wire::SampleFrame {
                pad: wire::PadIndex::new(2).unwrap(),
                sequence: 42,
                timestamp_us: 3_000_007,
                temperature_c: Some(24.5),
                temperature_source: wire::TemperatureSource::Tmp117,
                taxels: [wire::TaxelSample {
                    pressure_kpa: Some(1.5),
                    capacitance_pf: 4.5,
                    flags: 0,
                }; 4],
                summary: wire::PadSummary::default(),
            },
            arrival_us: 0,
            host_us: 12_345_678,
            sync_error_us: Some(1_234),
        };
        let cells = timeline_cells(&row);
        assert_eq!(cells.len(), header.len());
        assert_eq!(
            &cells[..8],
            [
                "12.345678",
                "1",
                "2",
                "42",
                "3.000007",
                "1.234",
                "24.5",
                "tmp117"
            ]
        );
        assert_eq!(format_sync_error_ms(None), "");
        assert_eq!(format_sync_error_ms(Some(5)), "0.005");
    }

    #[test]
    fn device_files_sit_beside_the_csv_and_find_each_other() {
        let csv = Path::new("dir/rec.csv");
        assert_eq!(
            device_raw_path(csv, 1),
            PathBuf::from("dir/rec.csv.dev1.raw")
        );
        assert_eq!(
            device_state_file(csv, 1),
            PathBuf::from("dir/rec.csv.dev1.device.json")
        );
    }
}
