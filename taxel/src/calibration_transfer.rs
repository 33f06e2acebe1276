//! Calibrations to and from a device: `taxel calibration pull` reads the calibration the device
//! uses into a calibration file, `taxel calibration push` writes a calibration file to it (and
//! with `--save` to its flash). On a device of several pads, each pad has its own calibration:
//! `pull` reads one pad's (pad 0's unless `--pad` says), `push` writes every pad's unless
//! `--pad` names one. The same functions serve `taxel calibrate --upload` and the
//! recording, which keeps the device's calibration beside the data.

use std::io::{Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{bail, Context};
use model_core::{BaselineRecord, Calibration, CalibrationSpec, TAXEL_COUNT, TAXEL_NAMES};
use wire::{Command, PadIndex, PadInfoFrame, ReplyPayload};

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
    upload_to_pads(link, calibration, None, save, timeout, progress)
}

/// The pad count of the device: the link's, or asked with Info when the link has not seen it.
fn device_pad_count<P: Read + Write>(
    link: &mut DeviceLink<P>,
    timeout: Duration,
) -> anyhow::Result<u8> {
    match link.pad_count() {
        Some(pad_count) => Ok(pad_count),
        // A fresh link has not seen the Info frame yet: writing pad 0 alone would leave the
        // other pads on their old calibration.
        None => match link.request(Command::Info, timeout) {
            Ok(ReplyPayload::Info(info)) => Ok(info.pad_count),
            Ok(_) => Err(RequestError::UnexpectedReply("Info").into()),
            Err(error) => Err(anyhow::Error::new(error).context("Info")),
        },
    }
}

/// Refuses a pad the device does not have, naming how many it has.
fn ensure_pad_exists(pad: PadIndex, pad_count: u8) -> anyhow::Result<()> {
    if pad.get() >= pad_count {
        bail!(
            "the device reads {pad_count} pad{}: there is no pad {}",
            if pad_count == 1 { "" } else { "s" },
            pad.get()
        );
    }
    Ok(())
}

/// As [`upload`], to one pad only when `only_pad` is given (every pad otherwise).
pub fn upload_to_pads<P: Read + Write>(
    link: &mut DeviceLink<P>,
    calibration: &Calibration,
    only_pad: Option<PadIndex>,
    save: bool,
    timeout: Duration,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<()> {
    let expect_ack = |result: Result<ReplyPayload, RequestError>, what: &str| match result {
        Ok(ReplyPayload::Ack) => Ok(()),
        Ok(_) => bail!("{what}: the device answered with a reply of another kind"),
        Err(error) => Err(anyhow::Error::new(error).context(what.to_owned())),
    };
    let pad_count = device_pad_count(link, timeout)?;
    if pad_count == 0 {
        bail!("the device found no pad to calibrate");
    }
    if let Some(pad) = only_pad {
        ensure_pad_exists(pad, pad_count)?;
    }
    let pads = (0..pad_count)
        .filter_map(PadIndex::new)
        .filter(|pad| only_pad.is_none_or(|only| only == *pad));
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

/// A pad index from the command line (its parser keeps it in range; this says so if not).
fn pad_index(pad: u8) -> anyhow::Result<PadIndex> {
    PadIndex::new(pad)
        .with_context(|| format!("pad {pad}: a device has at most {} pads", PadIndex::MAX + 1))
}

/// A pad's PadInfo: its calibration id and source, its tier.
pub fn pad_info<P: Read + Write>(
    link: &mut DeviceLink<P>,
    pad: PadIndex,
    timeout: Duration,
) -> anyhow::Result<PadInfoFrame> {
    match link.request(Command::PadInfo { pad }, timeout) {
        Ok(ReplyPayload::PadInfo(pad_info)) => Ok(pad_info),
        Ok(_) => Err(RequestError::UnexpectedReply("PadInfo").into()),
        Err(error) => Err(error).with_context(|| format!("PadInfo {}", pad.get())),
    }
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
            let timeout = Duration::from_millis(port.timeout_ms);
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
            let timeout = Duration::from_millis(port.timeout_ms);
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
