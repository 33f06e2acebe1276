//! The command line: one subcommand per job, each with its own arguments and `run` function.

use std::ffi::OsString;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, Parser, Subcommand};

use crate::commands::{calibrate, calibration, convert, record};
use crate::{list, plot, sim, view};

/// Host tool for the taxel tactile pad.
#[derive(Debug, Parser)]
#[command(
    name = "taxel",
    version,
    about = "Host tool for the taxel 2x2 capacitive tactile pad",
    long_about = "Host tool for the taxel 2x2 capacitive tactile pad: record and view the device's \
stream, re-process recordings, fit and upload calibrations, plot.\n\n\
Numbers in files use '.' as the decimal separator whatever the locale; flags are the documented \
flag names joined by '|'. Progress and warnings go to stderr."
)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Commands,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Commands {
    /// The simulated device and the live view together: see the pad work without hardware.
    #[command(long_about = sim::DEMO_LONG_ABOUT)]
    Demo(sim::DemoArgs),
    /// Run the simulated device on a pseudo-terminal (no hardware needed).
    #[command(long_about = sim::LONG_ABOUT)]
    Sim(sim::SimArgs),
    /// Re-process recorded data with another calibration or tier.
    #[command(long_about = convert::long_about())]
    Convert(convert::ConvertArgs),
    /// Fit a calibration from reference loads, cross-validate the tiers, write and upload it.
    #[command(long_about = calibrate::LONG_ABOUT)]
    Calibrate(calibrate::CalibrateArgs),
    /// Read the calibration a device uses into a file, or write one to it.
    #[command(long_about = calibration::LONG_ABOUT)]
    Calibration(calibration::CalibrationArgs),
    /// Plot a recording or a calibration (SVG or PNG).
    #[command(long_about = plot::LONG_ABOUT)]
    Plot(plot::PlotArgs),
    /// List attached boards (USB VID:PID, serial numbers).
    #[command(long_about = list::LONG_ABOUT)]
    List(list::ListArgs),
    /// Record the device's stream to CSV and a raw byte log.
    #[command(long_about = record::long_about())]
    Record(record::RecordArgs),
    /// Live terminal view of the pad (heat map, flags, temperature, rates).
    #[command(long_about = view::LONG_ABOUT)]
    View(view::ViewArgs),
    /// Publish the pads into Zenoh, ROS 2 compatible (runs the taxel-bridge program; see
    /// `taxel bridge --help`).
    #[command(disable_help_flag = true)]
    Bridge(BridgeForward),
}

/// `taxel bridge ARGS…`: ARGS go to the `taxel-bridge` program unchanged. The bridge is its own
/// program so that this tool does not carry the Zenoh dependency.
#[derive(Debug, Clone, Args)]
pub struct BridgeForward {
    /// The arguments of `taxel-bridge`.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, num_args = 0..)]
    pub args: Vec<OsString>,
}

/// The name of the bridge program.
const BRIDGE_PROGRAM: &str = "taxel-bridge";

/// Runs `taxel-bridge` with `forward`'s arguments: the one beside this program if there is one
/// (as `cargo build` and `cargo install` place them), else the first on the PATH.
fn run_bridge(forward: &BridgeForward) -> anyhow::Result<ExitCode> {
    let beside = std::env::current_exe()
        .ok()
        .and_then(|exe| exe.parent().map(|dir| dir.join(BRIDGE_PROGRAM)))
        .filter(|path| path.is_file());
    let program = beside.map_or_else(|| OsString::from(BRIDGE_PROGRAM), OsString::from);
    let status = std::process::Command::new(&program)
        .args(&forward.args)
        .status()
        .with_context(|| {
            format!(
                "running {}: build it with `cargo build --release -p taxel-bridge-cli` (or install it on the PATH)",
                program.to_string_lossy()
            )
        })?;
    Ok(match status.code() {
        Some(code) => ExitCode::from(u8::try_from(code).unwrap_or(1)),
        None => ExitCode::FAILURE,
    })
}

/// Runs a parsed command line; the exit code is the command's (errors are the caller's to
/// print).
pub fn run(cli: &Cli) -> anyhow::Result<ExitCode> {
    match &cli.command {
        Commands::Demo(args) => sim::run_demo(args),
        Commands::Sim(args) => sim::run(args),
        Commands::Convert(args) => convert::run(args),
        Commands::Calibrate(args) => calibrate::run(args),
        Commands::Calibration(args) => calibration::run(args),
        Commands::Plot(args) => plot::run(args),
        Commands::List(args) => list::run(args),
        Commands::Record(args) => record::run(args),
        Commands::View(args) => view::run(args),
        Commands::Bridge(forward) => run_bridge(forward),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn command_line_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn bridge_arguments_are_passed_on_unchanged() {
        let cli = Cli::try_parse_from(["taxel", "bridge", "--sim", "2", "--help"]).unwrap();
        let Commands::Bridge(forward) = cli.command else {
            panic!("not the bridge");
        };
        assert_eq!(forward.args, ["--sim", "2", "--help"]);
    }
}
