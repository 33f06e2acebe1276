//! `taxel calibrate`: its arguments, and the command around the host library's fitting.

use anyhow::{bail, Context};
use model_core::{Calibration, TAXEL_COUNT};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;
use taxel_host::calibrate::*;
use taxel_host::calibration_file::{self};
use taxel_host::calibration_transfer::upload;
use taxel_host::device_link::{self, DeviceLink};
use taxel_host::noteln;
use taxel_host::output_file::refuse_same_file;

/// The long help of the subcommand.
pub const LONG_ABOUT: &str = "Fit a calibration from reference loads.\n\n\
Input: a CSV with pressure_kpa,c11_pf,c12_pf,c21_pf,c22_pf and optionally temp_c (°C); several \
rows per load level are averaged. The rows at 0 kPa give C0 per taxel. The curve of each taxel is \
the averaged levels (pressure, dC/C0); it must start at 0 kPa and increase strictly, otherwise the \
data set is refused with the taxel and level that fail.\n\n\
Each tier's error is reported with leave-one-out cross-validation: every interior level is \
predicted from a curve built without it.\n\n\
Conditioning: per taxel and interval, the rms pressure noise that 0.5 fF of converter noise \
causes there; intervals over --budget-kpa are warned about (the calibration is still written: \
a nearly flat stretch of the curve is information, not an error).\n\n\
Output: a calibration file (JSON, format taxel-calibration version 1) with each taxel's curve, \
parasitic capacitance and C0 - Cp at 25 °C; a later tare more than 5 % from that C0 is flagged \
baseline_far_from_calibration. With --upload the calibration is written to the device \
(WriteCalibration per taxel, then SaveCalibration with --save). To upload an existing file, give --calibration FILE instead of a load file (or use `taxel calibration push`).\n\n\
The calibration file is written (under a temporary name, renamed when complete) before the report is printed on stdout.\n\n\
Example: taxel calibrate loads.csv -o cal.json --id 7 --parasitic-pf 1.2";

/// Arguments of `taxel calibrate`.
#[derive(Debug, Clone, clap::Args)]
pub struct CalibrateArgs {
    /// Reference-load CSV file.
    #[arg(value_name = "LOADS", required_unless_present = "calibration")]
    pub loads: Option<PathBuf>,
    /// Calibration file to write.
    #[arg(
        short,
        long,
        value_name = "FILE",
        required_unless_present = "calibration"
    )]
    pub output: Option<PathBuf>,
    /// Upload this existing calibration file instead of fitting one (needs --upload).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["loads", "output"], requires = "upload")]
    pub calibration: Option<PathBuf>,
    /// Calibration id stored in the file and reported by the device.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub id: u32,
    /// Parasitic capacitance of every taxel (leads, converter input), pF.
    #[arg(long, value_name = "PF", default_value_t = 0.0)]
    pub parasitic_pf: f32,
    /// Serial port of the device to upload the calibration to.
    #[arg(long, value_name = "PORT")]
    pub upload: Option<String>,
    /// After uploading, make the device save the calibration to its flash.
    #[arg(long, requires = "upload")]
    pub save: bool,
    /// How long to wait for the device.
    #[command(flatten)]
    pub link: taxel_args::LinkArgs,
    /// Pressure noise budget of the use case, kPa: intervals where 0.5 fF of converter noise
    /// moves the pressure by more are warned about (the gripper use case's 0.5 kPa by default).
    #[arg(long, value_name = "KPA", default_value_t = model_core::UseCase::GRIPPER.error_budget_kpa)]
    pub budget_kpa: f32,
}

/// Runs `taxel calibrate`. The calibration file is written (and uploaded) first and the
/// report printed after, so a closed or full stdout never costs the result.
pub fn run(args: &CalibrateArgs) -> anyhow::Result<ExitCode> {
    let mut report = String::new();
    let calibration = match (&args.calibration, &args.loads, &args.output) {
        (Some(path), _, _) => {
            calibration_file::read(path).with_context(|| format!("reading {}", path.display()))?
        }
        (None, Some(loads_path), Some(output_path)) => {
            refuse_same_file(loads_path, output_path)?;
            let file = std::fs::File::open(loads_path)
                .with_context(|| format!("opening {}", loads_path.display()))?;
            let rows = read_loads(std::io::BufReader::new(file))
                .with_context(|| format!("reading {}", loads_path.display()))?;
            let law = Calibration::default().temperature_law().clone();
            let data = reference_data(&rows, [f64::from(args.parasitic_pf); TAXEL_COUNT], &law)?;
            if data.rows_temperature_clamped > 0 {
                noteln!(
                    "warning: {} row(s) outside the characterised {}..{} °C were corrected as if at the nearest end",
                    data.rows_temperature_clamped,
                    law.characterised_min_c(),
                    law.characterised_max_c()
                );
            }
            let calibration = fit_calibration(&data, args.id, args.parasitic_pf)?;
            calibration_file::write(output_path, &calibration)?;
            noteln!(
                "wrote calibration id {} to {}",
                calibration.id(),
                output_path.display()
            );
            let warnings;
            (report, warnings) =
                taxel_host::calibrate_report::fit_report(&data, &calibration, args.budget_kpa);
            for warning in &warnings {
                noteln!("{warning}");
            }
            calibration
        }
        _ => bail!("give a load file and -o FILE, or --calibration FILE with --upload"),
    };
    if let Some(port_path) = &args.upload {
        let opened = device_link::open_serial(port_path, Duration::from_millis(50))?;
        let mut link = DeviceLink::new(opened.port);
        noteln!(
            "uploading calibration id {} to {port_path}",
            calibration.id()
        );
        upload(
            &mut link,
            &calibration,
            args.save,
            args.link.timeout(),
            &mut |message| noteln!("{message}"),
        )?;
    }
    taxel_host::console::out(format_args!("{report}")).context("writing the report to stdout")?;
    Ok(ExitCode::SUCCESS)
}
