//! `taxel convert`: a recording (or one device's raw byte log) through the host library's
//! conversion engine again, with the devices' recorded states or other options; written in the
//! recording schema, or as the wide export.

use std::fs::File;
use std::io::{self, BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::OnceLock;

use anyhow::{bail, Context};
use model_core::Tier;
use taxel_host::convert::{
    convert_raw, convert_recording, parse_tier, ConversionEngine, ConvertSettings, ConvertSummary,
    RecordedStates, RowSink, WideWriter, EXIT_BAD_ROWS,
};
use taxel_host::noteln;
use taxel_host::output_file::{refuse_same_file, OutputFile};
use taxel_host::schema::{self, RowReader, RowWriter};

/// The long help of the subcommand.
pub fn long_about() -> &'static str {
    static TEXT: OnceLock<String> = OnceLock::new();
    TEXT.get_or_init(|| {
        format!(
            "Re-process a recording with its devices' states, or another calibration or tier.\n\n\
Input: a recording written by `taxel record` or the live view (one row per pad per sample set, \
of any number of devices and pads), or with --raw one device's raw byte log (FILE.dev<n>.raw). \
Recordings of earlier versions of taxel are not read. Every pad of every device runs through \
the pad pipeline again — the model with its calibration, tier and baselines, force and centre of \
pressure, the contact detector — each with its own state: device n's is read from FILE.dev<n>.\
device.json beside the recording (calibration, tier, geometry, and the baselines with the set each \
applies from), and a pad's contact detector starts in the contact state of the pad's first row \
(a recording can start during a contact), so that converting with the defaults reproduces what \
the devices computed. --calibration, \
--tier and --tare-rows replace those parts for every pad; --no-device-state ignores the states \
(the built-in calibration, the default tier and a tare on the first readable row). The state \
files used, and every pad without a recorded state of its own (converted with those defaults), \
are said on stderr.\n\n\
Output: the same rows and columns (identity, times, capacitances and temperature as recorded; \
pressures, flags, force, centre of pressure, partial and contact computed again):\n{}\n\n\
--wide writes the export of one row per sample set of a device instead: host_time_s,device,seq, \
then each pad's columns prefixed pad<n>_, then marker (for spreadsheets; `taxel convert` and \
`taxel plot` read only the recording schema). The output is written under a temporary name and \
renamed when complete, and may not be the input.\n\n\
Exit status: 0 when every row was read, 3 when some rows could not be read (each is reported on \
stderr with its line number and left out), 1 on any other error.\n\n\
Example: taxel convert rec.csv --tier table -o rec-table.csv",
            schema::describe()
        )
    })
}

/// Arguments of `taxel convert`.
#[derive(Debug, Clone, clap::Args)]
pub struct ConvertArgs {
    /// The recording ('-' for stdin). Not used with --raw.
    #[arg(
        value_name = "INPUT",
        required_unless_present = "raw",
        conflicts_with = "raw"
    )]
    pub input: Option<PathBuf>,
    /// Read one device's raw byte log (FILE.dev<n>.raw, written by `taxel record`) instead.
    #[arg(long, value_name = "FILE")]
    pub raw: Option<PathBuf>,
    /// Output file (default: stdout).
    #[arg(short, long, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Write the wide export (one row per sample set of a device) instead of the schema.
    #[arg(long)]
    pub wide: bool,
    /// Tare each pad on the mean of its first N readable rows instead of the recorded
    /// baselines.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub tare_rows: Option<u16>,
    /// Inversion tier (default: each pad's recorded one, else monotone-cubic).
    #[arg(long, value_name = "NAME", value_parser = parse_tier, help = tier_help())]
    pub tier: Option<Tier>,
    /// Calibration file written by `taxel calibrate` or `taxel calibration pull`, for every pad
    /// (default: each pad's recorded one, else the built-in default, the article's curve).
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// Ignore the devices' recorded states.
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

fn open_input(path: &Path) -> anyhow::Result<Box<dyn BufRead>> {
    if path.as_os_str() == "-" {
        return Ok(Box::new(BufReader::new(io::stdin().lock())));
    }
    if path.is_dir() {
        bail!("{} is a directory, not a file", path.display());
    }
    let file = File::open(path).with_context(|| format!("opening {}", path.display()))?;
    Ok(Box::new(BufReader::with_capacity(1 << 20, file)))
}

/// The device a raw log belongs to (`NAME.dev<n>.raw`), and its state file.
fn raw_device(raw: &Path) -> (u32, Option<PathBuf>) {
    let name = raw.to_string_lossy();
    let device = name
        .strip_suffix(".raw")
        .and_then(|stem| stem.rsplit_once(".dev"))
        .and_then(|(_, device)| device.parse().ok());
    let state = name
        .strip_suffix(".raw")
        .map(|stem| PathBuf::from(format!("{stem}.device.json")))
        .filter(|path| path.exists());
    (device.unwrap_or(0), state)
}

/// The most pads of a device in a recording file (for the wide export's columns).
fn pads_in(path: &Path) -> anyhow::Result<usize> {
    let mut reader = RowReader::new(open_input(path)?)?;
    let mut pads = 0;
    while let Some(row) = reader.next_row() {
        if let Ok(row) = row {
            pads = pads.max(usize::from(row.pad) + 1);
        }
    }
    Ok(pads.max(1))
}

/// Runs `taxel convert`.
pub fn run(args: &ConvertArgs) -> anyhow::Result<ExitCode> {
    let input = match (&args.raw, &args.input) {
        (Some(raw), _) => raw,
        (None, Some(input)) => input,
        (None, None) => bail!("give an input recording or --raw FILE"),
    };
    if let Some(output) = &args.output {
        refuse_same_file(input, output)?;
    }
    let calibration = match &args.calibration {
        Some(path) => Some(
            taxel_host::calibration_file::read(path)
                .with_context(|| format!("reading the calibration {}", path.display()))?,
        ),
        None => None,
    };
    let settings = ConvertSettings {
        tare_rows: args.tare_rows,
        tier: args.tier,
        calibration,
        no_device_state: args.no_device_state,
        pressures_only: false,
    };
    let (states, raw_device) = match &args.raw {
        Some(raw) => {
            let (device, state) = raw_device(raw);
            // The pad count is a fact of the log, read even when the state is not used.
            let states = match state {
                Some(path) => RecordedStates::of_one_device(device, &path)?,
                None => RecordedStates::default(),
            };
            (states, Some(device))
        }
        None if input.as_os_str() == "-" || args.no_device_state => {
            (RecordedStates::default(), None)
        }
        None => (RecordedStates::beside(input)?, None),
    };
    for file in &states.files {
        noteln!("converting with the device state in {}", file.display());
    }
    let pad_count = raw_device
        .and_then(|device| states.device(device))
        .map_or(1, |state| state.pad_count.max(1));

    let wide_pads = if args.wide {
        match (&args.raw, input.as_os_str() == "-") {
            (Some(_), _) => usize::from(pad_count),
            (None, false) => pads_in(input)?,
            (None, true) => bail!("--wide reads the recording twice: give a file, not stdin"),
        }
    } else {
        0
    };
    let engine = ConversionEngine::new(settings, states);
    let convert = |output: &mut dyn Write| -> anyhow::Result<ConvertSummary> {
        let mut sink: Box<dyn RowSink + '_> = if args.wide {
            Box::new(WideWriter::new(output, wide_pads)?)
        } else {
            Box::new(RowWriter::new(output)?)
        };
        let reader = open_input(input)?;
        match raw_device {
            Some(device) => convert_raw(reader, device, pad_count, sink.as_mut(), engine),
            None => convert_recording(reader, sink.as_mut(), engine),
        }
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
    report(&summary, args.raw.is_some());
    if summary.bad_rows.is_empty() {
        Ok(ExitCode::SUCCESS)
    } else {
        noteln!(
            "{} rows could not be read (left out); {} rows converted",
            summary.bad_rows.len(),
            summary.rows_written
        );
        Ok(ExitCode::from(EXIT_BAD_ROWS))
    }
}

fn report(summary: &ConvertSummary, raw: bool) {
    if !summary.pads_without_state.is_empty() {
        let pads: Vec<String> = summary
            .pads_without_state
            .iter()
            .map(|(device, pad)| format!("device {device} pad {pad}"))
            .collect();
        noteln!(
            "{} had no recorded state: converted with the built-in calibration, the default tier and a tare on the first readable row unless options said otherwise",
            pads.join(", ")
        );
    }
    for bad_row in &summary.bad_rows {
        noteln!("line {}: {}", bad_row.line, bad_row.reason);
    }
    for warning in &summary.tare_warnings {
        noteln!("warning: {warning}");
    }
    if summary.missing_frames > 0 {
        noteln!(
            "{} pad frames were missing from the recording's sample sets (their rows are kept as they are)",
            summary.missing_frames
        );
    }
    if summary.frames_beyond_pad_count > 0 {
        noteln!(
            "warning: {} sample frames of pads beyond the log's pad count were left out (the pad count comes from the device's state file beside the log, 1 without it)",
            summary.frames_beyond_pad_count
        );
    }
    if raw {
        noteln!(
            "{} rows converted; {} undecodable frames ({} bytes) skipped",
            summary.rows_written,
            summary.undecodable_frames,
            summary.undecodable_bytes
        );
    }
}
