//! `taxel calibration pull|push`: its arguments, and the command around the host library's
//! calibration transfer.

use anyhow::Context;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;
use taxel_args::{BoardArgs, LinkArgs};
use taxel_host::calibration_file::{self};
use taxel_host::calibration_transfer::*;
use taxel_host::device_link::{self, DeviceLink};
use taxel_host::device_words::{calibration_source_words, info_words};
use taxel_host::noteln;

/// The long help of the subcommand.
pub const LONG_ABOUT: &str = "Read the calibration a device uses, or write one to it.\n\n\
`pull` writes the device's calibration in use (every taxel's curve, parasitic capacitance and \
C0, and the calibration id) to a calibration file, the format `taxel calibrate` writes and \
`taxel convert --calibration` reads. `push` writes a calibration file to the device (in RAM; \
--save also stores it in the device's flash).\n\n\
A device that reads several pads holds a calibration per pad. `pull` reads pad 0's, or with \
--pad N pad N's (its id from the pad's PadInfo). `push` writes every pad, or with --pad N pad N \
only; --save then fails while the pads hold different calibrations (the device's flash keeps \
one calibration for all its pads).\n\n\
Examples:\n  taxel calibration pull /dev/ttyACM0 -o cal.json\n  taxel calibration push cal.json \
/dev/ttyACM0 --save\n  taxel calibration push finger.json /dev/ttyACM0 --pad 1";

/// Arguments of `taxel calibration`.
#[derive(Debug, Clone, clap::Args)]
pub struct CalibrationArgs {
    /// What to do.
    #[command(subcommand)]
    pub action: CalibrationAction,
}

/// Where the device is.
#[derive(Debug, Clone, clap::Args)]
pub struct PortArgs {
    /// The device.
    #[command(flatten)]
    pub board: BoardArgs,
    /// How long to wait for the device.
    #[command(flatten)]
    pub link: LinkArgs,
}

/// `pull` or `push`.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum CalibrationAction {
    /// Read the device's calibration into a file.
    Pull {
        /// The device.
        #[command(flatten)]
        port: PortArgs,
        /// Calibration file to write.
        #[arg(short, long, value_name = "FILE")]
        output: PathBuf,
        /// The pad whose calibration to read, on a device of several pads.
        #[arg(long, value_name = "N", default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=7))]
        pad: u8,
    },
    /// Write a calibration file to the device.
    Push {
        /// Calibration file to send.
        #[arg(value_name = "FILE")]
        file: PathBuf,
        /// The device.
        #[command(flatten)]
        port: PortArgs,
        /// Also save it to the device's flash.
        #[arg(long)]
        save: bool,
        /// Write only this pad's calibration (default: every pad's).
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(0..=7))]
        pad: Option<u8>,
    },
}

fn open(port: &PortArgs) -> anyhow::Result<(String, DeviceLink<Box<dyn serialport::SerialPort>>)> {
    let path = port.board.select_port()?;
    let opened = device_link::open_serial(&path, Duration::from_millis(50))?;
    Ok((path, DeviceLink::new(opened.port)))
}

/// Runs `taxel calibration`.
pub fn run(args: &CalibrationArgs) -> anyhow::Result<ExitCode> {
    match &args.action {
        CalibrationAction::Pull { port, output, pad } => {
            let timeout = port.link.timeout();
            let (path, mut link) = open(port)?;
            let (info, _) = link
                .synchronise(timeout)
                .with_context(|| format!("asking the device on {path} who it is"))?;
            noteln!("device on {path}: {}", info_words(&info));
            let pad = pad_index(*pad)?;
            ensure_pad_exists(pad, info.pad_count)?;
            let (calibration_id, source) = if pad.get() == 0 {
                (info.calibration_id, info.calibration_source)
            } else {
                let pad_info = pad_info(&mut link, pad, timeout)?;
                (pad_info.calibration_id, pad_info.calibration_source)
            };
            let calibration = pull(&mut link, pad, calibration_id, timeout)?;
            calibration_file::write(output, &calibration)?;
            let of_pad = if info.pad_count > 1 {
                format!(" of pad {}", pad.get())
            } else {
                String::new()
            };
            noteln!(
                "wrote calibration id {}{of_pad} ({}) to {}",
                calibration.id(),
                calibration_source_words(source),
                output.display()
            );
        }
        CalibrationAction::Push {
            file,
            port,
            save,
            pad,
        } => {
            let calibration = calibration_file::read(file)
                .with_context(|| format!("reading {}", file.display()))?;
            let timeout = port.link.timeout();
            let (path, mut link) = open(port)?;
            let only_pad = pad.map(pad_index).transpose()?;
            match only_pad {
                Some(pad) => noteln!(
                    "writing calibration id {} to pad {} of {path}",
                    calibration.id(),
                    pad.get()
                ),
                None => noteln!("writing calibration id {} to {path}", calibration.id()),
            }
            upload_to_pads(
                &mut link,
                &calibration,
                only_pad,
                *save,
                timeout,
                &mut |message| noteln!("{message}"),
            )?;
        }
    }
    Ok(ExitCode::SUCCESS)
}
