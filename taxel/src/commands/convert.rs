//! `taxel convert`: its arguments, and the command around the host library's conversion.

use anyhow::{bail, Context};
use model_core::Tier;
use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use taxel_host::noteln;
use taxel_host::output_file::{refuse_same_file, OutputFile};

use taxel_host::convert::*;

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
A recording of a device with several pads (header seq,pad0_time_s,pad0_temp_c,\
pad0_c11_pf..., then pad1_..., as `taxel record` writes it) is recognised from its header: \
each pad is converted with a model of its own (its own tare with --tare-rows), and the output \
is seq, then for each pad N: padN_time_s,padN_temp_c,padN_p11_kpa..padN_p22_kpa,\
padN_flags11..padN_flags22. A pad whose frame is missing from a set has every cell empty, in the \
input and the output. The device state holds every pad's calibration, tier and baselines, and \
each pad is converted with its own. A device-state file written before every pad's state was \
recorded describes pad 0 only: its calibration and baselines are then used for every pad, so \
the other pads' pressures may differ from the device's, and convert says so. A raw log of \
several pads is converted the same way when its device-state file says how many pads there \
are; without it, pad 0 only. A header whose pads are out of order or incomplete is an error.\n\n\
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

impl ConvertArgs {
    /// What the host library's conversion is asked.
    pub fn settings(&self) -> ConvertSettings {
        ConvertSettings {
            input: self.input.clone(),
            raw: self.raw.clone(),
            output: self.output.clone(),
            tare_rows: self.tare_rows,
            tier: self.tier,
            calibration: self.calibration.clone(),
            device_state: self.device_state.clone(),
            no_device_state: self.no_device_state,
        }
    }
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
    let (options, source) = resolve_options(&args.settings())?;
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
    if summary.missing_pad_frames > 0 {
        noteln!(
            "{} pad frames were missing from the recording's sample sets (those pads' cells are empty in their rows)",
            summary.missing_pad_frames
        );
    }
    if summary.frames_of_other_pads > 0 {
        noteln!(
            "warning: {} sample frames of pads other than pad 0 were skipped: the raw log holds several pads, and without its device-state file (which says how many) only pad 0 is converted",
            summary.frames_of_other_pads
        );
    }
    if args.raw.is_some() {
        noteln!(
            "{} {} converted; {} undecodable frames ({} bytes) skipped",
            summary.rows_written,
            if summary.pad_count > 1 {
                "sample sets"
            } else {
                "sample frames"
            },
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
