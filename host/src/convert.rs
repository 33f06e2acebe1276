//! `taxel convert`: re-processes recorded capacitances with another calibration or inversion
//! tier, from a CSV file or from the raw byte log written by `taxel record`.
//!
//! Contract (input): a header row naming at least `time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf`
//! in any order (other columns are ignored); RFC 4180 quoting. Output: `time_s,temp_c` as given
//! (text preserved), then `p11_kpa..p22_kpa` and `flags11..flags22`, one row per input row in
//! order. A faulted taxel has an empty pressure cell and its flags cell says why. A row that
//! cannot be read becomes a row of empty cells (its `time_s` kept when readable) and is reported
//! with its line number; the run then ends with [`EXIT_BAD_ROWS`].
//!
//! A recording carries the device's state beside it (`NAME.csv.device.json`, see
//! [`crate::recording`]): its calibration, tier and baselines. When it is there, the conversion
//! uses it and says so, so that converting a recording with the defaults reproduces the
//! device's pressures; options given on the command line replace its parts.
//!
//! A recording of several pads (pad-prefixed columns, see [`crate::pad_set`]) is recognised
//! from its header and converted pad by pad into the same prefixed layout ([`multi_pad`]).

mod csv_input;
pub mod multi_pad;
mod pad_run;
mod resolve;

use std::io::{self, BufReader, Read, Write};
use std::path::PathBuf;

use anyhow::{bail, Context};
use model_core::{Calibration, Tier, TAXEL_COUNT};
use wire::DeviceFrame;

use crate::csv_format::{
    detect_dialect, format_optional, format_time_us, parse_time_s, CsvDialect, FLAGS_COLUMNS,
    PRESSURE_COLUMNS, TEMPERATURE_COLUMN, TIME_COLUMN,
};
use crate::device_link::FrameReceiver;
use crate::recording::BaselineChange;
use csv_input::{parse_sample, CsvColumns};
use pad_run::{frame_input, PadRun};
pub use resolve::resolve_options;

/// Exit status when at least one input row could not be read.
pub const EXIT_BAD_ROWS: u8 = 3;

/// What `taxel convert` was asked: the input, and the options that replace the recording's
/// device state (see [`resolve_options`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ConvertSettings {
    /// Input CSV file ('-' for stdin); not used with `raw`.
    pub input: Option<PathBuf>,
    /// The raw byte log written by `taxel record`, read instead of a CSV file.
    pub raw: Option<PathBuf>,
    /// Output CSV file (default: stdout).
    pub output: Option<PathBuf>,
    /// Tare on the mean of the first N rows instead of the recorded baselines.
    pub tare_rows: Option<u16>,
    /// Inversion tier (default: the recording's, else the default tier).
    pub tier: Option<Tier>,
    /// Calibration file (default: the recording's, else the built-in default).
    pub calibration: Option<PathBuf>,
    /// The device-state file of the recording (default: beside the input).
    pub device_state: Option<PathBuf>,
    /// Ignore the recording's device-state file.
    pub no_device_state: bool,
}

/// Parses a tier name for the command line, listing the valid names on error.
pub fn parse_tier(name: &str) -> Result<Tier, String> {
    Tier::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = Tier::ALL.iter().map(|tier| tier.name()).collect();
        format!("unknown tier '{name}'; valid tiers: {}", names.join(", "))
    })
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
}

/// What the model needs besides the data.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvertOptions {
    /// The calibration of pad 0, and of every pad without options of its own.
    pub calibration: Calibration,
    /// The inversion tier of pad 0, and of every pad without options of its own.
    pub tier: Tier,
    /// The baselines of pad 0, and of every pad without options of its own.
    pub tare: TareSource,
    /// The pads of the recording, from its device state: a raw log of several pads is converted
    /// to the pad-prefixed layout (a CSV file says it in its header).
    pub pad_count: u8,
    /// Pads 1 and up with options of their own (from a device state holding every pad's), in
    /// pad order: pad n at index n − 1.
    pub other_pads: Vec<PadOptions>,
}

impl ConvertOptions {
    /// The options pad `pad` is converted with: its own, else pad 0's.
    pub fn pad_options(&self, pad: usize) -> PadOptions {
        match pad
            .checked_sub(1)
            .and_then(|index| self.other_pads.get(index))
        {
            Some(options) => options.clone(),
            None => PadOptions {
                calibration: self.calibration.clone(),
                tier: self.tier,
                tare: self.tare.clone(),
            },
        }
    }
}

impl Default for ConvertOptions {
    fn default() -> Self {
        Self {
            calibration: Calibration::default(),
            tier: Tier::default(),
            tare: TareSource::Rows(1),
            pad_count: 1,
            other_pads: Vec::new(),
        }
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
    /// Output rows written (one per input row or sample frame).
    pub rows_written: u64,
    /// Rows that could not be read.
    pub bad_rows: Vec<BadRow>,
    /// Raw logs only: frames that could not be decoded, and their bytes.
    pub undecodable_frames: u64,
    /// Raw logs only: bytes that belonged to no decoded frame.
    pub undecodable_bytes: u64,
    /// Problems with the tare (taxels that could not be tared, a tare that never finished).
    pub tare_warnings: Vec<String>,
    /// How the file was read, when not the default dialect (for the user).
    pub dialect: Option<CsvDialect>,
    /// The pads of the input (1 for the single-pad layout).
    pub pad_count: u8,
    /// Several pads: frames missing from the recording's sample sets (their cells empty).
    pub missing_pad_frames: u64,
    /// Raw logs converted as one pad: frames of other pads, skipped.
    pub frames_of_other_pads: u64,
}

/// Header of the output.
pub fn output_header() -> Vec<&'static str> {
    let mut header = vec![TIME_COLUMN, TEMPERATURE_COLUMN];
    header.extend(PRESSURE_COLUMNS);
    header.extend(FLAGS_COLUMNS);
    header
}

/// The next record of a CSV reader with its line number; `None` at the end. A row the reader
/// cannot split gives the reason (and an empty record); an I/O failure is an error.
fn next_record<R: Read>(
    reader: &mut csv::Reader<R>,
    record: &mut csv::StringRecord,
) -> anyhow::Result<Option<(u64, Result<(), String>)>> {
    let line_hint = reader.position().line();
    match reader.read_record(record) {
        Ok(false) => Ok(None),
        Ok(true) => {
            let line = record
                .position()
                .map_or(line_hint, |position| position.line());
            Ok(Some((line, Ok(()))))
        }
        Err(error) => {
            let line = error
                .position()
                .map_or(line_hint, |position| position.line());
            if matches!(error.kind(), csv::ErrorKind::Io(_)) {
                return Err(error).context(format!("reading line {line}"));
            }
            record.clear();
            Ok(Some((line, Err(format!("unreadable row: {error}")))))
        }
    }
}

/// A cell as the output writes it: ','-separated with '.' decimals whatever the input was.
fn as_written(cell: &str, dialect: CsvDialect) -> String {
    if dialect.decimal_comma {
        cell.replace(',', ".")
    } else {
        cell.to_owned()
    }
}

/// The time cell of a row that could not be converted: kept when it is a readable time.
fn readable_time(cell: &str, dialect: CsvDialect) -> String {
    parse_time_s(cell, dialect.decimal_comma)
        .map(|time_s| {
            if dialect.decimal_comma {
                format!("{time_s}")
            } else {
                cell.to_owned()
            }
        })
        .unwrap_or_default()
}

fn csv_writer<W: Write>(output: W) -> csv::Writer<W> {
    csv::WriterBuilder::new()
        .terminator(csv::Terminator::CRLF)
        .from_writer(output)
}

/// Converts a CSV input. Bad rows are written as empty cells and listed in the summary; a
/// missing column, an input without any data row, or an I/O failure is an error.
pub fn convert_csv<R: Read, W: Write>(
    input: R,
    output: W,
    options: &ConvertOptions,
) -> anyhow::Result<ConvertSummary> {
    let (dialect, input) =
        detect_dialect(BufReader::new(input), TIME_COLUMN).context("reading the header row")?;
    let mut reader = dialect.reader(input);
    let header = reader.headers().context("reading the header row")?.clone();
    if let Some(pad_count) = multi_pad::header_pad_count(&header)? {
        return multi_pad::convert_csv(reader, &header, dialect, pad_count, output, options);
    }
    let columns = CsvColumns::find(&header, dialect)?;
    let mut run = PadRun::new(&options.pad_options(0))?;
    let mut writer = csv_writer(output);
    writer.write_record(output_header())?;
    let mut summary = ConvertSummary {
        dialect: (dialect != CsvDialect::default()).then_some(dialect),
        pad_count: 1,
        ..ConvertSummary::default()
    };
    let mut record = csv::StringRecord::new();
    let empty_cells = vec![String::new(); 2 * TAXEL_COUNT];
    let time_column = columns.needed[0];
    while let Some((line, readable)) = next_record(&mut reader, &mut record)? {
        let parsed = readable.and_then(|()| parse_sample(&record, &columns));
        let time_cell = record.get(time_column).unwrap_or("");
        let temperature_cell = record.get(columns.needed[1]).unwrap_or("");
        match parsed {
            Ok(row) => {
                let mut cells = vec![
                    as_written(time_cell, dialect),
                    as_written(temperature_cell, dialect),
                ];
                cells.extend(run.cells(row.sequence, &row.input));
                writer.write_record(&cells)?;
            }
            Err(reason) => {
                let mut cells = vec![readable_time(time_cell, dialect), String::new()];
                cells.extend(empty_cells.iter().cloned());
                writer.write_record(&cells)?;
                summary.bad_rows.push(BadRow { line, reason });
            }
        }
        summary.rows_written += 1;
    }
    if summary.rows_written == 0 {
        bail!("the file has a header but no data rows: nothing to convert");
    }
    writer.flush()?;
    summary.tare_warnings = run.warnings();
    Ok(summary)
}

/// Converts a raw byte log: every sample frame becomes a row; undecodable bytes are skipped and
/// counted. A log without a single sample frame is an error.
pub fn convert_raw<R: Read, W: Write>(
    input: R,
    output: W,
    options: &ConvertOptions,
) -> anyhow::Result<ConvertSummary> {
    if options.pad_count > 1 {
        return multi_pad::convert_raw(input, output, options);
    }
    let mut run = PadRun::new(&options.pad_options(0))?;
    let mut writer = csv_writer(output);
    writer.write_record(output_header())?;
    let mut summary = ConvertSummary {
        pad_count: 1,
        ..ConvertSummary::default()
    };
    let statistics = read_frames(input, None, |frame| {
        let DeviceFrame::Sample(sample) = frame else {
            return Ok(());
        };
        if sample.pad.get() != 0 {
            summary.frames_of_other_pads += 1;
            return Ok(());
        }
        let input = frame_input(&sample);
        let mut cells = vec![
            format_time_us(sample.timestamp_us),
            format_optional(input.temperature_c),
        ];
        cells.extend(run.cells(Some(sample.sequence), &input));
        writer.write_record(&cells)?;
        summary.rows_written += 1;
        Ok(())
    })?;
    summary.undecodable_frames = statistics.frames_rejected;
    summary.undecodable_bytes = statistics.bytes_rejected;
    ensure_samples_decoded(summary.rows_written, &statistics)?;
    writer.flush()?;
    summary.tare_warnings = run.warnings();
    Ok(summary)
}

/// Refuses a raw log in which no sample frame decoded: it is not one `taxel record` wrote.
fn ensure_samples_decoded(
    rows_written: u64,
    statistics: &crate::device_link::LinkStatistics,
) -> anyhow::Result<()> {
    if rows_written == 0 {
        bail!(
            "no sample frame in {} bytes ({} undecodable frames): this is not a raw log written by `taxel record` (a CSV file is converted without --raw)",
            statistics.bytes_received,
            statistics.frames_rejected
        );
    }
    Ok(())
}

/// Decodes a raw byte log and hands every frame to `take`, in order; returns the decoding
/// counters (a partial frame at the end counted as rejected). With a pad count, frames of other
/// pads are set aside by the receiver (and counted in its statistics).
fn read_frames<R: Read>(
    mut input: R,
    pad_count: Option<u8>,
    mut take: impl FnMut(DeviceFrame) -> anyhow::Result<()>,
) -> anyhow::Result<crate::device_link::LinkStatistics> {
    let mut receiver = FrameReceiver::new();
    if let Some(pad_count) = pad_count {
        receiver.set_pad_count(pad_count);
    }
    let mut buffer = vec![0u8; 64 * 1024];
    let mut frames = Vec::new();
    loop {
        let count = match input.read(&mut buffer) {
            Ok(0) => break,
            Ok(count) => count,
            Err(error) if error.kind() == io::ErrorKind::Interrupted => continue,
            Err(error) => return Err(error).context("reading the raw log"),
        };
        receiver.push_bytes(&buffer[..count], &mut frames);
        for frame in frames.drain(..) {
            take(frame)?;
        }
    }
    receiver.finish();
    Ok(receiver.statistics().clone())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn convert_text(input: &str, options: &ConvertOptions) -> (String, ConvertSummary) {
        let mut output = Vec::new();
        let summary = convert_csv(input.as_bytes(), &mut output, options).unwrap();
        (String::from_utf8(output).unwrap(), summary)
    }

    #[test]
    fn tare_row_is_not_tared_and_a_loaded_row_reads_the_curve() {
        let input = "time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n\
                     0.0,25,4.5,4.5,4.5,4.5\n\
                     0.1,25,4.87305,4.5,4.5,4.5\n";
        let (text, summary) = convert_text(input, &ConvertOptions::default());
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "time_s,temp_c,p11_kpa,p12_kpa,p21_kpa,p22_kpa,flags11,flags12,flags21,flags22"
        );
        assert_eq!(
            lines[1],
            "0.0,25,,,,,not_tared,not_tared,not_tared,not_tared"
        );
        let cells: Vec<&str> = lines[2].split(',').collect();
        let pressure_kpa: f32 = cells[2].parse().unwrap();
        assert!((pressure_kpa - 10.0).abs() < 0.01, "{pressure_kpa}");
        assert_eq!(&cells[3..6], ["0", "0", "0"]);
        assert!(summary.bad_rows.is_empty());
        assert_eq!(summary.rows_written, 2);
    }

    #[test]
    fn missing_column_is_an_error_naming_it() {
        let error = convert_csv(
            "time_s,c11_pf,c12_pf,c21_pf,c22_pf\n".as_bytes(),
            Vec::new(),
            &ConvertOptions::default(),
        )
        .unwrap_err();
        assert!(error.to_string().contains("temp_c"), "{error}");
    }
}
