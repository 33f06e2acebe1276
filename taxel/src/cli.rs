//! The command line: one subcommand per job, each with its own arguments and `run` function.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::{calibrate, calibration_transfer, convert, list, plot, record, sim, view};

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
    #[command(long_about = convert::LONG_ABOUT)]
    Convert(convert::ConvertArgs),
    /// Fit a calibration from reference loads, cross-validate the tiers, write and upload it.
    #[command(long_about = calibrate::LONG_ABOUT)]
    Calibrate(calibrate::CalibrateArgs),
    /// Read the calibration a device uses into a file, or write one to it.
    #[command(long_about = calibration_transfer::LONG_ABOUT)]
    Calibration(calibration_transfer::CalibrationArgs),
    /// Plot a recording or a calibration (SVG or PNG).
    #[command(long_about = plot::LONG_ABOUT)]
    Plot(plot::PlotArgs),
    /// List attached boards (USB VID:PID, serial numbers).
    #[command(long_about = list::LONG_ABOUT)]
    List(list::ListArgs),
    /// Record the device's stream to CSV and a raw byte log.
    #[command(long_about = record::LONG_ABOUT)]
    Record(record::RecordArgs),
    /// Live terminal view of the pad (heat map, flags, temperature, rates).
    #[command(long_about = view::LONG_ABOUT)]
    View(view::ViewArgs),
}

/// Runs a parsed command line; the exit code is the command's (errors are the caller's to
/// print).
pub fn run(cli: &Cli) -> anyhow::Result<ExitCode> {
    match &cli.command {
        Commands::Demo(args) => sim::run_demo(args),
        Commands::Sim(args) => sim::run(args),
        Commands::Convert(args) => convert::run(args),
        Commands::Calibrate(args) => calibrate::run(args),
        Commands::Calibration(args) => calibration_transfer::run(args),
        Commands::Plot(args) => plot::run(args),
        Commands::List(args) => list::run(args),
        Commands::Record(args) => record::run(args),
        Commands::View(args) => view::run(args),
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
}
