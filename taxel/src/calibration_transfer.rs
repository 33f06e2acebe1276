//! Calibrations to and from a device: `taxel calibration pull` reads the calibration the device
//! uses into a calibration file, `taxel calibration push` writes a calibration file to it (and
//! with `--save` to its flash). The same functions serve `taxel calibrate --upload` and the
//! recording, which keeps the device's calibration beside the data.

use std::io::{Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{bail, Context};
use model_core::{BaselineRecord, Calibration, CalibrationSpec, TAXEL_COUNT, TAXEL_NAMES};
use wire::{Command, PadIndex, ReplyPayload};

use crate::calibration_file::{self, describe_calibration_error};
use crate::device_link::{self, BoardArgs, DeviceLink, RequestError};
use crate::device_words::{calibration_source_words, info_words};
use crate::noteln;

/// The long help of the subcommand.
pub const LONG_ABOUT: &str = "Read the calibration a device uses, or write one to it.\n\n\
`pull` writes the device's calibration in use (every taxel's curve, parasitic capacitance and \
C0, and the calibration id) to a calibration file, the format `taxel calibrate` writes and \
`taxel convert --calibration` reads. `push` writes a calibration file to the device (in RAM; \
--save also stores it in the device's flash).\n\n\
Examples:\n  taxel calibration pull /dev/ttyACM0 -o cal.json\n  taxel calibration push cal.json \
/dev/ttyACM0 --save";

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
    /// How long to wait for each reply from the device, ms.
    #[arg(long, value_name = "MS", default_value_t = 2000)]
    pub timeout_ms: u64,
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
    },
}

/// Reads the calibration a device uses: four ReadCalibration requests, taken together with
/// the calibration id the device reports in its Info.
pub fn pull<P: Read + Write>(
    link: &mut DeviceLink<P>,
    pad: PadIndex,
    calibration_id: u32,
    timeout: Duration,
) -> anyhow::Result<Calibration> {
    let mut spec = CalibrationSpec {
        id: calibration_id,
        ..CalibrationSpec::default()
    };
    for (taxel_index, taxel) in (0u8..).zip(spec.taxels.iter_mut()) {
        let command = Command::ReadCalibration { pad, taxel_index };
        let record = match link.request(command, timeout) {
            Ok(ReplyPayload::Calibration(record)) => record,
            Ok(_) => return Err(RequestError::UnexpectedReply("ReadCalibration").into()),
            Err(error) => {
                return Err(error).with_context(|| format!("ReadCalibration {taxel_index}"))
            }
        };
        *taxel = device::taxel_calibration_spec(&record.calibration)
            .map_err(|error| anyhow::anyhow!("taxel {taxel_index}: {error:?}"))?;
    }
    Calibration::new(&spec).map_err(|error| {
        anyhow::anyhow!(
            "the device's calibration is not valid here: {}",
            describe_calibration_error(&error)
        )
    })
}

/// Reads the baselines a pad's model uses now (four ReadBaseline requests); `None` for a taxel
/// that is not tared.
pub fn pull_baselines<P: Read + Write>(
    link: &mut DeviceLink<P>,
    pad: PadIndex,
    timeout: Duration,
) -> anyhow::Result<[Option<BaselineRecord>; TAXEL_COUNT]> {
    let mut baselines = [None; TAXEL_COUNT];
    for (taxel_index, baseline) in (0u8..).zip(baselines.iter_mut()) {
        let command = Command::ReadBaseline { pad, taxel_index };
        *baseline = match link.request(command, timeout) {
            Ok(ReplyPayload::Baseline(reply)) => {
                reply.baseline.as_ref().map(device::baseline_record)
            }
            Ok(_) => return Err(RequestError::UnexpectedReply("ReadBaseline").into()),
            Err(error) => return Err(error).with_context(|| format!("ReadBaseline {taxel_index}")),
        };
    }
    Ok(baselines)
}

/// Writes the calibration to every pad of the device (as many as its Info says, asked for when
/// the link has not seen it), taxel by taxel, then saves it to flash if `save`. Each request waits
/// for its reply; a refusal or a timeout stops the upload.
pub fn upload<P: Read + Write>(
    link: &mut DeviceLink<P>,
    calibration: &Calibration,
    save: bool,
    timeout: Duration,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<()> {
    let expect_ack = |result: Result<ReplyPayload, RequestError>, what: &str| match result {
        Ok(ReplyPayload::Ack) => Ok(()),
        Ok(_) => bail!("{what}: the device answered with a reply of another kind"),
        Err(error) => Err(anyhow::Error::new(error).context(what.to_owned())),
    };
    let pad_count = match link.pad_count() {
        Some(pad_count) => pad_count,
        // A fresh link has not seen the Info frame yet: writing pad 0 alone would leave the
        // other pads on their old calibration.
        None => match link.request(Command::Info, timeout) {
            Ok(ReplyPayload::Info(info)) => info.pad_count,
            Ok(_) => return Err(RequestError::UnexpectedReply("Info").into()),
            Err(error) => return Err(anyhow::Error::new(error).context("Info")),
        },
    };
    if pad_count == 0 {
        bail!("the device found no pad to calibrate");
    }
    let pads = (0..pad_count).filter_map(PadIndex::new);
    for pad in pads {
        for (taxel_index, name) in (0u8..).zip(TAXEL_NAMES) {
            let record = device::calibration_record(calibration, pad, taxel_index)
                .map_err(|error| anyhow::anyhow!("taxel {name}: {error:?}"))?;
            let what = if pad.get() == 0 {
                format!("WriteCalibration for taxel {name}")
            } else {
                format!("WriteCalibration for pad {} taxel {name}", pad.get())
            };
            expect_ack(
                link.request(Command::WriteCalibration(record), timeout),
                &what,
            )?;
            progress(&format!("{what}: acknowledged"));
        }
    }
    if save {
        expect_ack(
            link.request(Command::SaveCalibration, timeout),
            "SaveCalibration",
        )?;
        progress("SaveCalibration: acknowledged (saved to flash)");
    }
    Ok(())
}

fn open(port: &PortArgs) -> anyhow::Result<(String, DeviceLink<Box<dyn serialport::SerialPort>>)> {
    let path = port.board.select_port()?;
    let opened = device_link::open_serial(&path, Duration::from_millis(50))?;
    Ok((path, DeviceLink::new(opened.port)))
}

/// Runs `taxel calibration`.
pub fn run(args: &CalibrationArgs) -> anyhow::Result<ExitCode> {
    match &args.action {
        CalibrationAction::Pull { port, output } => {
            let timeout = Duration::from_millis(port.timeout_ms);
            let (path, mut link) = open(port)?;
            let (info, _) = link
                .synchronise(timeout)
                .with_context(|| format!("asking the device on {path} who it is"))?;
            noteln!("device on {path}: {}", info_words(&info));
            let calibration = pull(&mut link, PadIndex::default(), info.calibration_id, timeout)?;
            calibration_file::write(output, &calibration)?;
            noteln!(
                "wrote calibration id {} ({}) to {}",
                calibration.id(),
                calibration_source_words(info.calibration_source),
                output.display()
            );
        }
        CalibrationAction::Push { file, port, save } => {
            let calibration = calibration_file::read(file)
                .with_context(|| format!("reading {}", file.display()))?;
            let timeout = Duration::from_millis(port.timeout_ms);
            let (path, mut link) = open(port)?;
            noteln!("writing calibration id {} to {path}", calibration.id());
            upload(&mut link, &calibration, *save, timeout, &mut |message| {
                noteln!("{message}")
            })?;
        }
    }
    Ok(ExitCode::SUCCESS)
}
