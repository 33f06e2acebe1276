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

use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context};
use model_core::{
    BaselineRecord, Calibration, PadModel, SampleInput, TareStatus, TaxelFlags, TaxelReading, Tier,
    TAXEL_COUNT, TAXEL_NAMES,
};
use wire::DeviceFrame;

use crate::csv_format::{
    detect_dialect, find_column, find_columns, flag_names, format_optional, format_time_us,
    parse_flag_names, parse_number, parse_time_s, CsvDialect, CAPACITANCE_COLUMNS, FLAGS_COLUMNS,
    PRESSURE_COLUMNS, TEMPERATURE_COLUMN, TIME_COLUMN,
};
use crate::device_link::FrameReceiver;
use crate::noteln;
use crate::output_file::{refuse_same_file, OutputFile};
use crate::recording::{device_state_path, BaselineChange, RecordedDeviceState, SEQUENCE_COLUMN};

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
reading), or with --raw the raw byte log written by `taxel record`. Files separated by ';' or \
tabs (spreadsheet exports) are recognised from the header, with ',' decimals, and said so. \
time_s must be a finite number of seconds.\n\n\
Output: time_s,temp_c (as given), p11_kpa..p22_kpa, flags11..flags22; one row per input row. A \
faulted taxel has an empty pressure cell; flags are documented flag names joined by '|'. The \
output file is written under a temporary name and renamed when complete: a failed run never \
touches an existing file, and the output may not be the input.\n\n\
A recording made by `taxel record` has the device's state beside it (NAME.csv.device.json: \
calibration, tier and baselines). It is used when present, so the pressures agree with the \
device's; --calibration, --tier and --tare-rows replace its parts, --no-device-state ignores \
it. Without it: the built-in default calibration (the article's curve), the monotone-cubic \
tier, and a baseline (tare) that is the mean of the first --tare-rows readable rows (default \
1), which are themselves reported as not_tared. Which calibration was used is said on stderr.\n\n\
Exit status: 0 when every row was read, 3 when some rows could not be read (each is reported \
on stderr with its line number and written as empty cells), 1 on any other error (no data rows \
or frames at all, a missing column, a file that cannot be read or written).\n\n\
Example: taxel convert rec.csv --tier polynomial -o rec-polynomial.csv";

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
    /// Tare on the mean of the first N rows instead of the device's recorded baselines
    /// (default without a device-state file: 1).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub tare_rows: Option<u16>,
    /// Inversion tier (default: the recording's, else monotone-cubic).
    #[arg(long, value_name = "NAME", value_parser = parse_tier, help = tier_help())]
    pub tier: Option<Tier>,
    /// Calibration file written by `taxel calibrate` or `taxel calibration pull` (default: the
    /// recording's, else the built-in default, the article's curve).
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// The device-state file of the recording (default: INPUT.device.json beside it).
    #[arg(long, value_name = "FILE", conflicts_with = "no_device_state")]
    pub device_state: Option<PathBuf>,
    /// Ignore the recording's device-state file.
    #[arg(long)]
    pub no_device_state: bool,
}

/// The help of a `--tier` option, listing every tier.
pub fn tier_help() -> String {
    let names: Vec<&str> = Tier::ALL.iter().map(|tier| tier.name()).collect();
    format!(
        "Inversion tier: {} (default {})",
        names.join(", "),
        Tier::default().name()
    )
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

/// What the model needs besides the data.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvertOptions {
    /// The calibration.
    pub calibration: Calibration,
    /// The inversion tier.
    pub tier: Tier,
    /// The baselines.
    pub tare: TareSource,
}

impl Default for ConvertOptions {
    fn default() -> Self {
        Self {
            calibration: Calibration::default(),
            tier: Tier::default(),
            tare: TareSource::Rows(1),
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

    /// Before a sample: installs the baselines that apply from `sequence` on (the first ones
    /// when the data has no sequence numbers).
    fn before_sample(&mut self, pad: &mut PadModel, sequence: Option<u32>) {
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
        if wanted.is_none() || wanted == self.installed {
            return;
        }
        self.installed = wanted;
        let Some(change) = wanted.and_then(|index| self.changes.get(index)) else {
            return;
        };
        install_baselines(pad, &change.taxels, &mut self.warnings);
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

/// Where the cells of a CSV input are: the six columns the model needs, and in a recording
/// also the sequence number and the flags the acquisition set.
#[derive(Debug, Clone)]
struct CsvColumns {
    needed: [usize; 6],
    sequence: Option<usize>,
    flags: Option<[usize; TAXEL_COUNT]>,
    field_count: usize,
    dialect: CsvDialect,
}

impl CsvColumns {
    fn find(header: &csv::StringRecord, dialect: CsvDialect) -> anyhow::Result<Self> {
        let wanted = [
            TIME_COLUMN,
            TEMPERATURE_COLUMN,
            CAPACITANCE_COLUMNS[0],
            CAPACITANCE_COLUMNS[1],
            CAPACITANCE_COLUMNS[2],
            CAPACITANCE_COLUMNS[3],
        ];
        let needed = find_columns(header, wanted).map_err(|missing| {
            if header.iter().all(|field| field.trim().is_empty()) {
                anyhow::anyhow!("the file is empty: it has no header row")
            } else {
                anyhow::anyhow!(
                    "the header lacks the column(s) {} (found: {})",
                    missing.join(", "),
                    shortened(&header.iter().collect::<Vec<_>>().join(","))
                )
            }
        })?;
        Ok(Self {
            needed,
            sequence: find_column(header, SEQUENCE_COLUMN),
            flags: find_columns(header, FLAGS_COLUMNS).ok(),
            field_count: header.len(),
            dialect,
        })
    }
}

/// At most 80 characters of a text that goes into a message.
fn shortened(text: &str) -> String {
    const LIMIT: usize = 80;
    if text.chars().count() <= LIMIT {
        text.to_owned()
    } else {
        format!("{}…", text.chars().take(LIMIT).collect::<String>())
    }
}

/// One CSV row read as a model input, with its sequence number if the file has them.
struct ParsedRow {
    input: SampleInput,
    sequence: Option<u32>,
}

/// Parses one CSV record into a model input, or says why it cannot.
fn parse_sample(record: &csv::StringRecord, columns: &CsvColumns) -> Result<ParsedRow, String> {
    if record.len() != columns.field_count {
        return Err(format!(
            "expected {} fields, found {}",
            columns.field_count,
            record.len()
        ));
    }
    let decimal_comma = columns.dialect.decimal_comma;
    let cell = |index: usize| record.get(index).unwrap_or("");
    let time_s = parse_time_s(cell(columns.needed[0]), decimal_comma)?;
    let temperature_c = parse_number(cell(columns.needed[1]), decimal_comma)
        .map_err(|error| format!("{TEMPERATURE_COLUMN}: {error}"))?
        .map(|value| value as f32)
        .filter(|value| !value.is_nan());
    let mut readings = [TaxelReading::Unavailable; TAXEL_COUNT];
    for (taxel, reading) in readings.iter_mut().enumerate() {
        let value = parse_number(cell(columns.needed[2 + taxel]), decimal_comma)
            .map_err(|error| format!("{}: {error}", CAPACITANCE_COLUMNS[taxel]))?;
        if let Some(capacitance_pf) = value {
            *reading = TaxelReading::CapacitancePf(capacitance_pf as f32);
        }
    }
    let sequence = match columns.sequence {
        Some(index) => Some(cell(index).trim().parse::<u32>().map_err(|_| {
            format!(
                "{SEQUENCE_COLUMN}: '{}' is not a sequence number",
                cell(index).trim()
            )
        })?),
        None => None,
    };
    let mut input = SampleInput::new(readings, temperature_c);
    if let Some(flag_columns) = columns.flags {
        // A recording's flags say which readings the acquisition already knew to be bad.
        for (taxel, column) in flag_columns.iter().enumerate() {
            let flags = parse_flag_names(cell(*column))
                .map_err(|name| format!("{}: unknown flag '{name}'", FLAGS_COLUMNS[taxel]))?
                .intersection(ACQUISITION_FLAGS);
            input.reading_flags[taxel] = flags;
            if flags.contains(TaxelFlags::CONVERTER_ERROR) {
                input.readings[taxel] = TaxelReading::Unavailable;
            }
        }
    }
    // The plausibility rule wants a non-negative time in microseconds.
    let input = if time_s >= 0.0 {
        input.at_time_us((time_s * 1.0e6) as u64)
    } else {
        input
    };
    Ok(ParsedRow { input, sequence })
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
    let columns = CsvColumns::find(&header, dialect)?;
    let mut pad = new_model(options)?;
    let mut baselines = RecordedBaselines::new(&options.tare);
    let mut tare_watch = TareWatch::default();
    let mut writer = csv_writer(output);
    writer.write_record(output_header())?;
    let mut summary = ConvertSummary {
        dialect: (dialect != CsvDialect::default()).then_some(dialect),
        ..ConvertSummary::default()
    };
    let mut record = csv::StringRecord::new();
    let empty_cells = vec![String::new(); 2 * TAXEL_COUNT];
    let time_column = columns.needed[0];
    loop {
        let line_hint = reader.position().line();
        let (line, parsed) = match reader.read_record(&mut record) {
            Ok(false) => break,
            Ok(true) => {
                let line = record
                    .position()
                    .map_or(line_hint, |position| position.line());
                (line, parse_sample(&record, &columns))
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
        let time_cell = record.get(time_column).unwrap_or("");
        let temperature_cell = record.get(columns.needed[1]).unwrap_or("");
        match parsed {
            Ok(row) => {
                baselines.before_sample(&mut pad, row.sequence);
                // The output is ','-separated with '.' decimals whatever the input was.
                let as_written = |cell: &str| {
                    if dialect.decimal_comma {
                        cell.replace(',', ".")
                    } else {
                        cell.to_owned()
                    }
                };
                let mut cells = vec![as_written(time_cell), as_written(temperature_cell)];
                cells.extend(model_cells(&mut pad, &row.input, &mut tare_watch));
                writer.write_record(&cells)?;
            }
            Err(reason) => {
                let readable_time = parse_time_s(time_cell, dialect.decimal_comma)
                    .map(|time_s| {
                        if dialect.decimal_comma {
                            format!("{time_s}")
                        } else {
                            time_cell.to_owned()
                        }
                    })
                    .unwrap_or_default();
                let mut cells = vec![readable_time, String::new()];
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
    summary.tare_warnings = baselines.warnings;
    summary.tare_warnings.extend(tare_watch.finish(&pad));
    Ok(summary)
}

/// Converts a raw byte log: every sample frame becomes a row; undecodable bytes are skipped and
/// counted. A log without a single sample frame is an error.
pub fn convert_raw<R: Read, W: Write>(
    mut input: R,
    output: W,
    options: &ConvertOptions,
) -> anyhow::Result<ConvertSummary> {
    let mut pad = new_model(options)?;
    let mut baselines = RecordedBaselines::new(&options.tare);
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
            baselines.before_sample(&mut pad, Some(sample.sequence));
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
    let statistics = receiver.statistics();
    summary.undecodable_frames = statistics.frames_rejected;
    summary.undecodable_bytes = statistics.bytes_rejected;
    if summary.rows_written == 0 {
        bail!(
            "no sample frame in {} bytes ({} undecodable frames): this is not a raw log written by `taxel record` (a CSV file is converted without --raw)",
            statistics.bytes_received,
            statistics.frames_rejected
        );
    }
    writer.flush()?;
    summary.tare_warnings = baselines.warnings;
    summary.tare_warnings.extend(tare_watch.finish(&pad));
    Ok(summary)
}

fn open_input(path: &Path) -> anyhow::Result<Box<dyn Read>> {
    if path.as_os_str() == "-" {
        Ok(Box::new(io::stdin().lock()))
    } else {
        if path.is_dir() {
            bail!("{} is a directory, not a file", path.display());
        }
        let file = File::open(path).with_context(|| format!("opening {}", path.display()))?;
        Ok(Box::new(BufReader::new(file)))
    }
}

/// The options a conversion runs with, and a sentence saying where each came from.
pub fn resolve_options(args: &ConvertArgs) -> anyhow::Result<(ConvertOptions, String)> {
    let input = args.raw.as_ref().or(args.input.as_ref());
    let state_path = match (&args.device_state, input) {
        _ if args.no_device_state => None,
        (Some(path), _) => Some(path.clone()),
        (None, Some(input)) if input.as_os_str() != "-" => {
            Some(device_state_path(input)).filter(|path| path.exists())
        }
        (None, _) => None,
    };
    let state = match &state_path {
        Some(path) => Some(RecordedDeviceState::read(path)?),
        None => None,
    };
    let mut said = Vec::new();
    let calibration = match (&args.calibration, &state) {
        (Some(path), _) => {
            let calibration = crate::calibration_file::read(path)
                .with_context(|| format!("reading the calibration {}", path.display()))?;
            said.push(format!(
                "the calibration in {} (id {})",
                path.display(),
                calibration.id()
            ));
            calibration
        }
        (None, Some(state)) => {
            let calibration = state.calibration()?;
            said.push(format!(
                "the device's calibration recorded with it (id {}, {})",
                calibration.id(),
                state.calibration_source
            ));
            calibration
        }
        (None, None) => {
            said.push(
                "the built-in default calibration (the article's curve; no device-state file beside the input)"
                    .to_owned(),
            );
            Calibration::default()
        }
    };
    let tier = match (args.tier, &state) {
        (Some(tier), _) => tier,
        (None, Some(state)) => Tier::from_name(&state.tier)
            .with_context(|| format!("the recording's tier '{}' is unknown here", state.tier))?,
        (None, None) => Tier::default(),
    };
    said.push(format!("tier {}", tier.name()));
    let tare = match (args.tare_rows, &state) {
        (Some(rows), _) => TareSource::Rows(rows),
        (None, Some(state)) if !state.baselines.is_empty() => {
            said.push(format!(
                "the device's baselines ({} recorded)",
                state.baselines.len()
            ));
            TareSource::Recorded(state.baselines.clone())
        }
        (None, _) => TareSource::Rows(1),
    };
    if let TareSource::Rows(rows) = tare {
        said.push(format!("a tare on the first {rows} readable row(s)"));
    }
    let source = match &state_path {
        Some(path) => format!(
            "converting with {} (from {})",
            said.join(", "),
            path.display()
        ),
        None => format!("converting with {}", said.join(", ")),
    };
    Ok((
        ConvertOptions {
            calibration,
            tier,
            tare,
        },
        source,
    ))
}

/// Runs `taxel convert`.
pub fn run(args: &ConvertArgs) -> anyhow::Result<ExitCode> {
    let input = match (&args.raw, &args.input) {
        (Some(raw), _) => raw,
        (None, Some(input)) => input,
        (None, None) => bail!("give an input CSV file or --raw FILE"),
    };
    if let Some(output) = &args.output {
        refuse_same_file(input, output)?;
    }
    let (options, source) = resolve_options(args)?;
    noteln!("{source}");
    let reader = open_input(input)?;
    let convert = |output: &mut dyn Write| match &args.raw {
        Some(_) => convert_raw(reader, output, &options),
        None => convert_csv(reader, output, &options),
    };
    let summary = match &args.output {
        Some(path) => {
            let mut file = OutputFile::create(path)?;
            let summary =
                convert(&mut file).with_context(|| format!("converting {}", input.display()))?;
            file.commit()?;
            summary
        }
        None => {
            let mut stdout = BufWriter::new(io::stdout().lock());
            let summary =
                convert(&mut stdout).with_context(|| format!("converting {}", input.display()))?;
            stdout.flush().context("writing to stdout")?;
            summary
        }
    };
    if let Some(dialect) = summary.dialect {
        noteln!("read {} as {}", input.display(), dialect.describe());
    }
    for bad_row in &summary.bad_rows {
        noteln!("line {}: {}", bad_row.line, bad_row.reason);
    }
    for warning in &summary.tare_warnings {
        noteln!("warning: {warning}");
    }
    if args.raw.is_some() {
        noteln!(
            "{} sample frames converted; {} undecodable frames ({} bytes) skipped",
            summary.rows_written,
            summary.undecodable_frames,
            summary.undecodable_bytes
        );
    }
    if summary.bad_rows.is_empty() {
        Ok(ExitCode::SUCCESS)
    } else {
        noteln!(
            "{} of {} rows could not be read (written as empty cells)",
            summary.bad_rows.len(),
            summary.rows_written
        );
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
