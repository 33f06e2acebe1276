//! `taxel convert`: re-processes recorded capacitances with another calibration or inversion
//! tier, from a CSV file or from the raw byte log written by `taxel record`.
//!
//! Contract (input): a header row naming at least `time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf`
//! in any order (other columns are ignored); RFC 4180 quoting. Output: `time_s,temp_c` as given
//! (text preserved), then `p11_kpa..p22_kpa` and `flags11..flags22`, one row per input row in
//! order. A faulted taxel has an empty pressure cell and its flags cell says why. A row that
//! cannot be read becomes a row of empty cells (its `time_s` kept when readable) and is reported
//! with its line number; the run then ends with [`EXIT_BAD_ROWS`].

use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context};
use model_core::{
    Calibration, PadModel, SampleInput, TareStatus, TaxelFlags, TaxelReading, Tier, TAXEL_COUNT,
    TAXEL_NAMES,
};
use wire::DeviceFrame;

use crate::csv_format::{
    find_columns, flag_names, format_optional, format_time_us, parse_optional_number,
    CAPACITANCE_COLUMNS, FLAGS_COLUMNS, PRESSURE_COLUMNS, TEMPERATURE_COLUMN, TIME_COLUMN,
};
use crate::device_link::FrameReceiver;

/// Exit status when at least one input row could not be read.
pub const EXIT_BAD_ROWS: u8 = 3;

/// Flags a recording's sample frames carry that come from the acquisition, not the model, and
/// so must be kept when the model runs again.
const ACQUISITION_FLAGS: TaxelFlags = TaxelFlags::CONVERTER_ERROR
    .union(TaxelFlags::STUCK)
    .union(TaxelFlags::SATURATED);

/// The long help of the subcommand.
pub const LONG_ABOUT: &str =
    "Re-process recorded data with another calibration or inversion tier.\n\n\
Input: a CSV file with the columns time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf (any order, other \
columns ignored; an empty temp_c cell means no temperature, an empty capacitance cell means no \
reading), or with --raw the raw byte log written by `taxel record`.\n\n\
Output: time_s,temp_c (as given), p11_kpa..p22_kpa, flags11..flags22; one row per input row. A \
faulted taxel has an empty pressure cell; flags are documented flag names joined by '|'.\n\n\
The baseline (tare) is the mean of the first --tare-rows readable rows; those rows themselves \
are reported as not_tared.\n\n\
Exit status: 0 when every row was read, 3 when some rows could not be read (each is reported \
on stderr with its line number and written as empty cells), 1 on any other error.";

/// Arguments of `taxel convert`.
#[derive(Debug, Clone, clap::Args)]
pub struct ConvertArgs {
    /// Input CSV file ('-' for stdin). Not used with --raw.
    #[arg(
        value_name = "INPUT",
        required_unless_present = "raw",
        conflicts_with = "raw"
    )]
    pub input: Option<PathBuf>,
    /// Read the raw byte log written by `taxel record` instead of a CSV file.
    #[arg(long, value_name = "FILE")]
    pub raw: Option<PathBuf>,
    /// Output CSV file (default: stdout).
    #[arg(short, long, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Number of first rows whose mean is the unloaded baseline (tare).
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..))]
    pub tare_rows: u16,
    /// Inversion tier: linear, piecewise-linear, monotone-cubic (default), saturating,
    /// saturating-micromath, table.
    #[arg(long, value_name = "NAME", value_parser = parse_tier)]
    pub tier: Option<Tier>,
    /// Calibration file written by `taxel calibrate` (default: the article's curve).
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
}

/// Parses a tier name for the command line, listing the valid names on error.
pub fn parse_tier(name: &str) -> Result<Tier, String> {
    Tier::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = Tier::ALL.iter().map(|tier| tier.name()).collect();
        format!("unknown tier '{name}'; valid tiers: {}", names.join(", "))
    })
}

/// What the model needs besides the data.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvertOptions {
    /// The calibration.
    pub calibration: Calibration,
    /// The inversion tier.
    pub tier: Tier,
    /// Rows averaged for the tare.
    pub tare_rows: u16,
}

impl Default for ConvertOptions {
    fn default() -> Self {
        Self {
            calibration: Calibration::default(),
            tier: Tier::default(),
            tare_rows: 1,
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
}

/// Header of the output.
pub fn output_header() -> Vec<&'static str> {
    let mut header = vec![TIME_COLUMN, TEMPERATURE_COLUMN];
    header.extend(PRESSURE_COLUMNS);
    header.extend(FLAGS_COLUMNS);
    header
}

fn csv_writer<W: Write>(output: W) -> csv::Writer<W> {
    csv::WriterBuilder::new()
        .terminator(csv::Terminator::CRLF)
        .from_writer(output)
}

fn new_model(options: &ConvertOptions) -> anyhow::Result<PadModel> {
    let mut pad = PadModel::new(options.calibration.clone());
    pad.set_tier(options.tier).map_err(|_| {
        anyhow::anyhow!(
            "tier {} is not available for this calibration (the saturating fit needs a concave curve on every taxel)",
            options.tier.name()
        )
    })?;
    pad.start_tare(options.tare_rows);
    Ok(pad)
}

/// Runs one sample through the model and returns the output cells after `time_s,temp_c`.
fn model_cells(
    pad: &mut PadModel,
    sample: &SampleInput,
    tare_watch: &mut TareWatch,
) -> Vec<String> {
    let output = pad.process(sample);
    tare_watch.observe(pad);
    let mut cells: Vec<String> = output
        .taxels
        .iter()
        .map(|taxel| format_optional(taxel.pressure_kpa()))
        .collect();
    cells.extend(output.taxels.iter().map(|taxel| flag_names(taxel.flags())));
    cells
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
                            .map(|error| format!("{error:?}"))
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

/// Parses one CSV record into a model input, or says why it cannot.
fn parse_sample(
    record: &csv::StringRecord,
    columns: &[usize; 6],
    expected_len: usize,
) -> Result<SampleInput, String> {
    if record.len() != expected_len {
        return Err(format!(
            "expected {expected_len} fields, found {}",
            record.len()
        ));
    }
    let cell = |index: usize| record.get(columns[index]).unwrap_or("");
    let time_s = parse_optional_number(cell(0)).map_err(|error| format!("time_s: {error}"))?;
    if time_s.is_none() {
        return Err("time_s is empty".to_owned());
    }
    let temperature_c = parse_optional_number(cell(1))
        .map_err(|error| format!("{TEMPERATURE_COLUMN}: {error}"))?
        .map(|value| value as f32)
        .filter(|value| !value.is_nan());
    let mut readings = [TaxelReading::Unavailable; TAXEL_COUNT];
    for (taxel, reading) in readings.iter_mut().enumerate() {
        let value = parse_optional_number(cell(2 + taxel))
            .map_err(|error| format!("{}: {error}", CAPACITANCE_COLUMNS[taxel]))?;
        if let Some(capacitance_pf) = value {
            *reading = TaxelReading::CapacitancePf(capacitance_pf as f32);
        }
    }
    let input = SampleInput::new(readings, temperature_c);
    // A time the plausibility rule can use: finite, not negative, within u64 microseconds.
    Ok(match time_s {
        Some(time_s) if (0.0..1.8e13).contains(&time_s) => {
            input.at_time_us((time_s * 1.0e6) as u64)
        }
        _ => input,
    })
}

/// Converts a CSV input. Bad rows are written as empty cells and listed in the summary;
/// only a missing column or an I/O failure is an error.
pub fn convert_csv<R: Read, W: Write>(
    input: R,
    output: W,
    options: &ConvertOptions,
) -> anyhow::Result<ConvertSummary> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .from_reader(input);
    let header = reader.headers().context("reading the header row")?.clone();
    let wanted = [
        TIME_COLUMN,
        TEMPERATURE_COLUMN,
        CAPACITANCE_COLUMNS[0],
        CAPACITANCE_COLUMNS[1],
        CAPACITANCE_COLUMNS[2],
        CAPACITANCE_COLUMNS[3],
    ];
    let columns = find_columns(&header, wanted).map_err(|missing| {
        anyhow::anyhow!(
            "the header lacks the column(s) {} (found: {})",
            missing.join(", "),
            header.iter().collect::<Vec<_>>().join(",")
        )
    })?;
    let mut pad = new_model(options)?;
    let mut tare_watch = TareWatch::default();
    let mut writer = csv_writer(output);
    writer.write_record(output_header())?;
    let mut summary = ConvertSummary::default();
    let mut record = csv::StringRecord::new();
    let empty_cells = vec![String::new(); 2 * TAXEL_COUNT];
    loop {
        let line_hint = reader.position().line();
        let (line, parsed) = match reader.read_record(&mut record) {
            Ok(false) => break,
            Ok(true) => {
                let line = record
                    .position()
                    .map_or(line_hint, |position| position.line());
                (line, parse_sample(&record, &columns, header.len()))
            }
            Err(error) => {
                let line = error
                    .position()
                    .map_or(line_hint, |position| position.line());
                if matches!(error.kind(), csv::ErrorKind::Io(_)) {
                    return Err(error).context(format!("reading line {line}"));
                }
                record.clear();
                (line, Err(format!("unreadable row: {error}")))
            }
        };
        let time_cell = record.get(columns[0]).unwrap_or("");
        let temperature_cell = record.get(columns[1]).unwrap_or("");
        match parsed {
            Ok(sample) => {
                let mut cells = vec![time_cell.to_owned(), temperature_cell.to_owned()];
                cells.extend(model_cells(&mut pad, &sample, &mut tare_watch));
                writer.write_record(&cells)?;
            }
            Err(reason) => {
                let readable_time = parse_optional_number(time_cell)
                    .ok()
                    .flatten()
                    .map(|_| time_cell.to_owned())
                    .unwrap_or_default();
                let mut cells = vec![readable_time, String::new()];
                cells.extend(empty_cells.iter().cloned());
                writer.write_record(&cells)?;
                summary.bad_rows.push(BadRow { line, reason });
            }
        }
        summary.rows_written += 1;
    }
    writer.flush()?;
    summary.tare_warnings = tare_watch.finish(&pad);
    Ok(summary)
}

/// Converts a raw byte log: every sample frame becomes a row; undecodable bytes are skipped and
/// counted.
pub fn convert_raw<R: Read, W: Write>(
    mut input: R,
    output: W,
    options: &ConvertOptions,
) -> anyhow::Result<ConvertSummary> {
    let mut pad = new_model(options)?;
    let mut tare_watch = TareWatch::default();
    let mut writer = csv_writer(output);
    writer.write_record(output_header())?;
    let mut summary = ConvertSummary::default();
    let mut receiver = FrameReceiver::new();
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
            let DeviceFrame::Sample(sample) = frame else {
                continue;
            };
            let mut input = SampleInput::new(
                [TaxelReading::Unavailable; TAXEL_COUNT],
                sample.temperature_c.filter(|value| !value.is_nan()),
            )
            .at_time_us(sample.timestamp_us);
            for (taxel, recorded) in sample.taxels.iter().enumerate() {
                let acquisition_flags =
                    TaxelFlags::from_bits_retain(recorded.flags).intersection(ACQUISITION_FLAGS);
                input.reading_flags[taxel] = acquisition_flags;
                if !acquisition_flags.contains(TaxelFlags::CONVERTER_ERROR) {
                    input.readings[taxel] = TaxelReading::CapacitancePf(recorded.capacitance_pf);
                }
            }
            let mut cells = vec![
                format_time_us(sample.timestamp_us),
                format_optional(input.temperature_c),
            ];
            cells.extend(model_cells(&mut pad, &input, &mut tare_watch));
            writer.write_record(&cells)?;
            summary.rows_written += 1;
        }
    }
    receiver.finish();
    writer.flush()?;
    summary.undecodable_frames = receiver.statistics().frames_rejected;
    summary.undecodable_bytes = receiver.statistics().bytes_rejected;
    summary.tare_warnings = tare_watch.finish(&pad);
    Ok(summary)
}

fn open_input(path: &Path) -> anyhow::Result<Box<dyn Read>> {
    if path.as_os_str() == "-" {
        Ok(Box::new(io::stdin().lock()))
    } else {
        let file = File::open(path).with_context(|| format!("opening {}", path.display()))?;
        Ok(Box::new(BufReader::new(file)))
    }
}

/// Runs `taxel convert`.
pub fn run(args: &ConvertArgs) -> anyhow::Result<ExitCode> {
    let calibration = match &args.calibration {
        Some(path) => crate::calibration_file::read(path)
            .with_context(|| format!("reading the calibration {}", path.display()))?,
        None => Calibration::default(),
    };
    let options = ConvertOptions {
        calibration,
        tier: args.tier.unwrap_or_default(),
        tare_rows: args.tare_rows,
    };
    let output: Box<dyn Write> = match &args.output {
        Some(path) => Box::new(BufWriter::new(
            File::create(path).with_context(|| format!("creating {}", path.display()))?,
        )),
        None => Box::new(BufWriter::new(io::stdout().lock())),
    };
    let summary = match (&args.raw, &args.input) {
        (Some(raw), _) => convert_raw(open_input(raw)?, output, &options)?,
        (None, Some(input)) => convert_csv(open_input(input)?, output, &options)?,
        (None, None) => bail!("give an input CSV file or --raw FILE"),
    };
    let mut stderr = io::stderr().lock();
    for bad_row in &summary.bad_rows {
        writeln!(stderr, "line {}: {}", bad_row.line, bad_row.reason)?;
    }
    for warning in &summary.tare_warnings {
        writeln!(stderr, "warning: {warning}")?;
    }
    if args.raw.is_some() {
        writeln!(
            stderr,
            "{} sample frames converted; {} undecodable frames ({} bytes) skipped",
            summary.rows_written, summary.undecodable_frames, summary.undecodable_bytes
        )?;
    }
    if summary.bad_rows.is_empty() {
        Ok(ExitCode::SUCCESS)
    } else {
        writeln!(
            stderr,
            "{} of {} rows could not be read (written as empty cells)",
            summary.bad_rows.len(),
            summary.rows_written
        )?;
        Ok(ExitCode::from(EXIT_BAD_ROWS))
    }
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
