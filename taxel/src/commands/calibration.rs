//! `taxel calibration pull|push|geometry`: its arguments, and the command around the host
//! library's calibration transfer.

use anyhow::Context;
use model_core::{PadGeometry, PadRole, TaxelGeometry};
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
pub const LONG_ABOUT: &str = "Read the calibration a device uses, or write one to it; read or \
set a pad's geometry.\n\n\
`pull` writes the device's calibration in use (every taxel's curve, parasitic capacitance and \
C0, and the calibration id) to a calibration file, the format `taxel calibrate` writes and \
`taxel convert --calibration` reads. `push` writes a calibration file to the device (in RAM; \
--save also stores it in the device's flash).\n\n\
A device that reads several pads holds a calibration per pad. `pull` reads pad 0's, or with \
--pad N pad N's (its id from the pad's PadInfo). `push` writes every pad, or with --pad N pad N \
only; --save stores every pad's calibration in flash under its pad.\n\n\
`geometry` prints a pad's role and each taxel's electrode centre (mm, in the pad's frame: x \
along a row towards C12, y towards row 1) and area (mm²), which the device computes the pad's \
force and centre of pressure with; with --role and four --taxel X,Y,AREA (C11, C12, C21, C22) \
it sets them (--save also stores them in flash with the pad's calibration). A palm pad of 10 mm \
electrodes: --role palm --taxel=-6,6,100 --taxel 6,6,100 --taxel=-6,-6,100 --taxel=6,-6,100.\n\n\
Examples:\n  taxel calibration pull /dev/ttyACM0 -o cal.json\n  taxel calibration push cal.json \
/dev/ttyACM0 --save\n  taxel calibration push finger.json /dev/ttyACM0 --pad 1\n  \
taxel calibration geometry /dev/ttyACM0 --pad 5";

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
    /// Print a pad's geometry, or set it.
    Geometry {
        /// The device.
        #[command(flatten)]
        port: PortArgs,
        /// The pad.
        #[arg(long, value_name = "N", default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=7))]
        pad: u8,
        /// What the pad is: unspecified, fingertip, finger, palm, gripper-jaw.
        #[arg(long, value_name = "ROLE", value_parser = parse_role, requires = "taxel")]
        role: Option<PadRole>,
        /// A taxel's electrode centre and area, X_MM,Y_MM,AREA_MM2; four, in pad order.
        #[arg(long, value_name = "X,Y,AREA", value_parser = parse_taxel, num_args = 1, requires = "role")]
        taxel: Vec<TaxelGeometry>,
        /// Also save it to the device's flash (with the pad's calibration).
        #[arg(long, requires = "role")]
        save: bool,
    },
}

fn parse_role(text: &str) -> Result<PadRole, String> {
    PadRole::from_name(text).ok_or_else(|| {
        let names: Vec<&str> = PadRole::ALL.iter().map(|role| role.name()).collect();
        format!("no role `{text}` (roles: {})", names.join(", "))
    })
}

fn parse_taxel(text: &str) -> Result<TaxelGeometry, String> {
    let values: Vec<f32> = text
        .split(',')
        .map(|value| value.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|error| format!("`{text}`: {error}; give X_MM,Y_MM,AREA_MM2"))?;
    match values.as_slice() {
        [x_mm, y_mm, area_mm2] => Ok(TaxelGeometry::new(*x_mm, *y_mm, *area_mm2)),
        _ => Err(format!("`{text}`: give three numbers, X_MM,Y_MM,AREA_MM2")),
    }
}

/// A pad's geometry in words, one taxel per line.
fn geometry_words(info: &wire::PadInfoFrame) -> String {
    let mut words = format!("pad {}: {}", info.pad.get(), info.role.name());
    for (name, taxel) in model_core::TAXEL_NAMES.iter().zip(&info.taxels) {
        words.push_str(&format!(
            "\n  {name}: centre ({:.3}, {:.3}) mm, area {:.3} mm²",
            taxel.x_mm, taxel.y_mm, taxel.area_mm2
        ));
    }
    words
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
        CalibrationAction::Geometry {
            port,
            pad,
            role,
            taxel,
            save,
        } => {
            let timeout = port.link.timeout();
            let (path, mut link) = open(port)?;
            let (info, _) = link
                .synchronise(timeout)
                .with_context(|| format!("asking the device on {path} who it is"))?;
            let pad = pad_index(*pad)?;
            ensure_pad_exists(pad, info.pad_count)?;
            let pad_info = match role {
                None => pad_info(&mut link, pad, timeout)?,
                Some(role) => {
                    let taxels: [TaxelGeometry; model_core::TAXEL_COUNT] =
                        taxel.as_slice().try_into().map_err(|_| {
                            anyhow::anyhow!(
                                "{} --taxel given: a pad has four taxels (C11, C12, C21, C22)",
                                taxel.len()
                            )
                        })?;
                    let geometry = PadGeometry::new(taxels)
                        .map_err(|error| anyhow::anyhow!("the geometry: {error}"))?;
                    let pad_info = set_geometry(&mut link, pad, *role, &geometry, *save, timeout)?;
                    noteln!(
                        "set pad {}'s geometry on {path}{}",
                        pad.get(),
                        if *save {
                            " and saved it to flash"
                        } else {
                            " (in RAM; --save keeps it)"
                        }
                    );
                    pad_info
                }
            };
            taxel_host::outln!("{}", geometry_words(&pad_info)).context("writing to stdout")?;
        }
    }
    Ok(ExitCode::SUCCESS)
}
