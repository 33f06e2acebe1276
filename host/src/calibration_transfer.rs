//! Calibrations to and from a device: `taxel calibration pull` reads the calibration the device
//! uses into a calibration file, `taxel calibration push` writes a calibration file to it (and
//! with `--save` to its flash). On a device of several pads, each pad has its own calibration:
//! `pull` reads one pad's (pad 0's unless `--pad` says), `push` writes every pad's unless
//! `--pad` names one. The same functions serve `taxel calibrate --upload` and the
//! recording, which keeps the device's calibration beside the data.

use std::io::{Read, Write};
use std::time::Duration;

use anyhow::{bail, Context};
use model_core::{
    BaselineRecord, Calibration, CalibrationSpec, PadGeometry, PadRole, TAXEL_COUNT, TAXEL_NAMES,
};
use wire::{Command, PadGeometryRecord, PadIndex, PadInfoFrame, ReplyPayload};

use crate::calibration_file::describe_calibration_error;
use crate::device_link::{DeviceLink, RequestError};

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
pub fn ensure_pad_exists(pad: PadIndex, pad_count: u8) -> anyhow::Result<()> {
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

/// A pad index given by a user (a parser that keeps it in range makes this infallible; this
/// says so if not).
pub fn pad_index(pad: u8) -> anyhow::Result<PadIndex> {
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

/// Gives pad `pad` the role and geometry `geometry` (SetPadGeometry), and with `save` stores it
/// in flash with the pad's calibration (SaveCalibration). Returns the pad's PadInfo afterwards,
/// as the device reports it.
pub fn set_geometry<P: Read + Write>(
    link: &mut DeviceLink<P>,
    pad: PadIndex,
    role: PadRole,
    geometry: &PadGeometry,
    save: bool,
    timeout: Duration,
) -> anyhow::Result<PadInfoFrame> {
    ensure_pad_exists(pad, device_pad_count(link, timeout)?)?;
    let record = PadGeometryRecord {
        pad,
        role,
        taxels: *geometry.taxels(),
    };
    match link.request(Command::SetPadGeometry(record), timeout) {
        Ok(ReplyPayload::Ack) => {}
        Ok(_) => return Err(RequestError::UnexpectedReply("Ack").into()),
        Err(error) => {
            return Err(error).with_context(|| format!("SetPadGeometry for pad {}", pad.get()))
        }
    }
    if save {
        match link.request(Command::SaveCalibration, timeout) {
            Ok(ReplyPayload::Ack) => {}
            Ok(_) => return Err(RequestError::UnexpectedReply("Ack").into()),
            Err(error) => return Err(error).context("SaveCalibration"),
        }
    }
    pad_info(link, pad, timeout)
}
