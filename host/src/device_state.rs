//! The device's state a recording's pressures were computed with: the `NAME.dev<n>.device.json`
//! file beside a recording (see [`crate::recorder`]), and how it is read from the device when a
//! recording starts ([`read_device_state`]); the session follows every pad's baselines while it
//! runs ([`crate::session`]).
//!
//! The file is JSON: `format` ([`DEVICE_STATE_FORMAT`]) and `version`
//! ([`DEVICE_STATE_VERSION`]); the device's identity (`firmware`, `protocol_version`,
//! `board_serial`, `converter_rate_sps`); then pad 0's state: `calibration_source`, `tier`,
//! `calibration` (the whole calibration, as a calibration file holds it) and `baselines` (in
//! the order they took effect, each `from_sequence`, the first sample computed with them, and
//! the four taxels' baselines, `null` for a taxel not tared).
//!
//! A device of several pads adds `pad_count` and `other_pads`: one object per pad from pad 1
//! on, `{"pad": n, "calibration_source", "tier", "calibration", "baselines"}` with the same
//! meaning as pad 0's fields. Pad 0 stays in the top-level fields so that a one-pad device's
//! file is exactly what it was before devices had several pads, and a reader that knows only
//! pad 0 still finds it. A pad the file does not describe is converted with the defaults (and
//! `taxel convert` says so).

use std::io::{Read, Write};
use std::path::Path;
use std::time::Duration;

use anyhow::{bail, Context};
use model_core::{BaselineRecord, Calibration, CalibrationSpec, TAXEL_COUNT};
use serde::{Deserialize, Serialize};
use wire::{DeviceEvent, DeviceFrame, EventFrame, InfoFrame, PadIndex, PadInfoFrame};

use crate::calibration_transfer::{pad_info, pull, pull_baselines};
use crate::device_link::DeviceLink;
use crate::device_words::{board_serial_hex, calibration_source_words, tier_words};
use crate::output_file::OutputFile;

/// The `format` field of a device-state file.
pub const DEVICE_STATE_FORMAT: &str = "taxel-recording-device-state";

/// The version of the device-state file format.
pub const DEVICE_STATE_VERSION: u64 = 1;

/// How often the baselines are read again at the start when a tare finished meanwhile.
const BASELINE_READ_ATTEMPTS: u32 = 3;

/// Baselines in use from a sample sequence number on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BaselineChange {
    /// The first sample (by sequence number) computed with these baselines; 0 for the ones in
    /// use when the recording started.
    pub from_sequence: u32,
    /// Per taxel in pad order; `None` for a taxel without a baseline (not tared).
    pub taxels: [Option<BaselineRecord>; TAXEL_COUNT],
}

/// One pad's state: what its pressures were computed with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedPadState {
    /// The pad's index on its device.
    pub pad: u8,
    /// Where the pad's calibration came from, in words.
    pub calibration_source: String,
    /// The pad's inversion tier's name.
    pub tier: String,
    /// The pad's whole calibration.
    pub calibration: CalibrationSpec,
    /// The pad's baselines, in the order they took effect; empty when the device could not say.
    pub baselines: Vec<BaselineChange>,
}

impl RecordedPadState {
    /// A pad's state from its PadInfo and calibration, without baselines yet.
    pub fn new(pad_info: &PadInfoFrame, calibration: &Calibration) -> Self {
        Self {
            pad: pad_info.pad.get(),
            calibration_source: calibration_source_words(pad_info.calibration_source).to_owned(),
            tier: tier_words(pad_info.model_tier),
            calibration: calibration.to_spec(),
            baselines: Vec::new(),
        }
    }

    /// The calibration, validated.
    pub fn calibration(&self) -> anyhow::Result<Calibration> {
        Calibration::new(&self.calibration).map_err(|error| {
            anyhow::anyhow!(
                "the recorded calibration of pad {} is not valid: {}",
                self.pad,
                crate::calibration_file::describe_calibration_error(&error)
            )
        })
    }
}

/// What the device computed a recording's pressures with (the `.device.json` file; see the
/// module documentation for its layout).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedDeviceState {
    /// Always [`DEVICE_STATE_FORMAT`].
    pub format: String,
    /// Always [`DEVICE_STATE_VERSION`].
    pub version: u64,
    /// Firmware version, dotted.
    pub firmware: String,
    /// Protocol version.
    pub protocol_version: u8,
    /// Board serial number, hex.
    pub board_serial: String,
    /// Where pad 0's calibration came from, in words.
    pub calibration_source: String,
    /// Pad 0's inversion tier's name.
    pub tier: String,
    /// Converter conversions per second.
    pub converter_rate_sps: u16,
    /// Pad 0's whole calibration.
    pub calibration: CalibrationSpec,
    /// Pad 0's baselines, in the order they took effect; empty when the device could not say.
    pub baselines: Vec<BaselineChange>,
    /// How many pads the device reads. Written only when above 1, so that a single-pad
    /// device's file stays as it was.
    #[serde(default = "one_pad", skip_serializing_if = "is_one_pad")]
    pub pad_count: u8,
    /// The state of pads 1 to `pad_count` − 1, in pad order; empty for one pad, and in files
    /// written before the other pads' state could be read back.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub other_pads: Vec<RecordedPadState>,
}

fn one_pad() -> u8 {
    1
}

fn is_one_pad(pad_count: &u8) -> bool {
    *pad_count == 1
}

impl RecordedDeviceState {
    /// The state of a device from its identity and pad 0's calibration (the other pads' state
    /// is added with [`RecordedDeviceState::add_pad`]).
    pub fn new(info: &InfoFrame, calibration: &Calibration) -> Self {
        let version = info.firmware_version;
        Self {
            format: DEVICE_STATE_FORMAT.to_owned(),
            version: DEVICE_STATE_VERSION,
            firmware: format!("{}.{}.{}", version.major, version.minor, version.patch),
            protocol_version: info.protocol_version,
            board_serial: board_serial_hex(info),
            calibration_source: calibration_source_words(info.calibration_source).to_owned(),
            tier: tier_words(info.model_tier),
            converter_rate_sps: info.rate.sps(),
            calibration: calibration.to_spec(),
            baselines: Vec::new(),
            pad_count: info.pad_count.max(1),
            other_pads: Vec::new(),
        }
    }

    /// Adds the state of a pad other than pad 0 (replacing any it had).
    pub fn add_pad(&mut self, pad: RecordedPadState) {
        self.other_pads.retain(|known| known.pad != pad.pad);
        let place = self.other_pads.partition_point(|known| known.pad < pad.pad);
        self.other_pads.insert(place, pad);
    }

    /// Pad 0's calibration, validated.
    pub fn calibration(&self) -> anyhow::Result<Calibration> {
        Calibration::new(&self.calibration).map_err(|error| {
            anyhow::anyhow!(
                "the recorded calibration is not valid: {}",
                crate::calibration_file::describe_calibration_error(&error)
            )
        })
    }

    /// A pad's state; `None` for a pad the file does not describe.
    pub fn pad_state(&self, pad: u8) -> Option<RecordedPadState> {
        if pad == 0 {
            return Some(RecordedPadState {
                pad: 0,
                calibration_source: self.calibration_source.clone(),
                tier: self.tier.clone(),
                calibration: self.calibration.clone(),
                baselines: self.baselines.clone(),
            });
        }
        self.other_pads
            .iter()
            .find(|known| known.pad == pad)
            .cloned()
    }

    /// The pads of the device (below `pad_count`) whose state the file lacks: none when it has
    /// every pad's, pads 1 and up for a file that describes pad 0 only.
    pub fn pads_without_state(&self) -> Vec<u8> {
        (1..self.pad_count)
            .filter(|&pad| self.other_pads.iter().all(|known| known.pad != pad))
            .collect()
    }

    /// A pad's baselines history, to add changes to; `None` for a pad the file does not
    /// describe.
    pub fn baselines_mut(&mut self, pad: u8) -> Option<&mut Vec<BaselineChange>> {
        if pad == 0 {
            return Some(&mut self.baselines);
        }
        self.other_pads
            .iter_mut()
            .find(|known| known.pad == pad)
            .map(|known| &mut known.baselines)
    }

    /// Pad 0's baselines in use for the sample with this sequence number.
    pub fn baselines_at(&self, sequence: u32) -> Option<&[Option<BaselineRecord>; TAXEL_COUNT]> {
        self.baselines
            .iter()
            .rev()
            .find(|change| change.from_sequence <= sequence)
            .or(self.baselines.first())
            .map(|change| &change.taxels)
    }

    /// Reads a device-state file.
    pub fn read(path: &Path) -> anyhow::Result<Self> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        let state: Self =
            serde_json::from_str(&text).with_context(|| format!("reading {}", path.display()))?;
        if state.format != DEVICE_STATE_FORMAT || state.version != DEVICE_STATE_VERSION {
            bail!(
                "{} is not a version-{DEVICE_STATE_VERSION} {DEVICE_STATE_FORMAT} file",
                path.display()
            );
        }
        for (index, known) in state.other_pads.iter().enumerate() {
            let repeated = state.other_pads[..index]
                .iter()
                .any(|earlier| earlier.pad == known.pad);
            if known.pad == 0 || known.pad >= state.pad_count || repeated {
                bail!(
                    "{}: other_pads describes pad {}, which is not one of pads 1 to {} given once",
                    path.display(),
                    known.pad,
                    state.pad_count.saturating_sub(1)
                );
            }
        }
        Ok(state)
    }

    /// Writes a device-state file (under a temporary name, renamed when complete).
    pub fn write(&self, path: &Path) -> anyhow::Result<()> {
        let mut file = OutputFile::create(path)?;
        serde_json::to_writer_pretty(&mut file, self)
            .with_context(|| format!("writing {}", path.display()))?;
        file.write_all(b"\n")
            .with_context(|| format!("writing {}", path.display()))?;
        file.commit()
    }
}

/// The pads named by the TareFinished events among some frames.
fn tared_pads(frames: &[DeviceFrame]) -> Vec<PadIndex> {
    let mut pads: Vec<PadIndex> = frames
        .iter()
        .filter_map(|frame| match frame {
            DeviceFrame::Event(EventFrame {
                event: DeviceEvent::TareFinished { pad, .. },
                ..
            }) => Some(*pad),
            _ => None,
        })
        .collect();
    pads.sort_unstable();
    pads.dedup();
    pads
}

/// Reads every pad's whole calibration and baselines as the state a recording starts with:
/// pad 0's calibration with the id of the device's Info, every other pad's with its PadInfo
/// (which also gives its tier), four ReadCalibration and four ReadBaseline requests per pad.
/// Frames that arrived meanwhile are discarded: they were computed before the state was read,
/// so the recording starts after them. The baselines of a pad whose tare finished meanwhile
/// are read again.
pub fn read_device_state<P: Read + Write>(
    link: &mut DeviceLink<P>,
    info: &InfoFrame,
    timeout: Duration,
) -> anyhow::Result<RecordedDeviceState> {
    let calibration = pull(link, PadIndex::default(), info.calibration_id, timeout)?;
    let mut state = RecordedDeviceState::new(info, &calibration);
    let pads: Vec<PadIndex> = (0..state.pad_count).filter_map(PadIndex::new).collect();
    for &pad in pads.iter().skip(1) {
        let pad_info = pad_info(link, pad, timeout)?;
        let calibration = pull(link, pad, pad_info.calibration_id, timeout)
            .with_context(|| format!("reading the calibration of pad {}", pad.get()))?;
        state.add_pad(RecordedPadState::new(&pad_info, &calibration));
    }
    let mut to_read = pads.clone();
    for attempt in 1..=BASELINE_READ_ATTEMPTS {
        for &pad in &to_read {
            let taxels = pull_baselines(link, pad, timeout)
                .with_context(|| format!("reading the baselines of pad {}", pad.get()))?;
            if let Some(history) = state.baselines_mut(pad.get()) {
                *history = vec![BaselineChange {
                    from_sequence: 0,
                    taxels,
                }];
            }
        }
        to_read = tared_pads(&link.take_queued());
        to_read.retain(|pad| pads.contains(pad));
        if to_read.is_empty() || attempt == BASELINE_READ_ATTEMPTS {
            break;
        }
    }
    Ok(state)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(pad_count: u8) -> InfoFrame {
        InfoFrame {
            protocol_version: wire::PROTOCOL_VERSION,
            firmware_version: wire::FirmwareVersion {
                major: 1,
                minor: 2,
                patch: 3,
            },
            board_serial: [1; 12],
            calibration_id: 0,
            calibration_source: wire::CalibrationSource::Defaults,
            rate: wire::SampleRate::Sps400,
            model_tier: wire::Tier::MonotoneCubic,
            streaming: false,
            text_mode: false,
            pad_count,
            clock_us_per_s: 1_000_000,
        }
    }

    fn pad_info(pad: u8, calibration_id: u32) -> PadInfoFrame {
        PadInfoFrame {
            pad: PadIndex::new(pad).unwrap(),
            channel: Some(pad),
            temperature_sensor: wire::TemperatureSensor::DieOnly,
            calibration_id,
            calibration_source: wire::CalibrationSource::Host,
            model_tier: wire::Tier::Linear,
        }
    }

    #[test]
    fn the_pad_count_and_other_pads_are_in_the_device_state_only_with_several_pads() {
        let one = RecordedDeviceState::new(&info(1), &Calibration::default());
        let text = serde_json::to_string(&one).unwrap();
        assert!(!text.contains("pad_count"), "{text}");
        assert!(!text.contains("other_pads"), "{text}");
        let read: RecordedDeviceState = serde_json::from_str(&text).unwrap();
        assert_eq!(read.pad_count, 1);
        assert!(read.pads_without_state().is_empty());
        let eight = RecordedDeviceState::new(&info(8), &Calibration::default());
        let text = serde_json::to_string(&eight).unwrap();
        assert!(text.contains("\"pad_count\":8"), "{text}");
        let read: RecordedDeviceState = serde_json::from_str(&text).unwrap();
        assert_eq!(read, eight);
        assert_eq!(read.pads_without_state(), [1, 2, 3, 4, 5, 6, 7]);
    }

    #[test]
    fn every_pad_keeps_its_own_calibration_tier_and_baselines() {
        let mut state = RecordedDeviceState::new(&info(3), &Calibration::default());
        let mut spec = Calibration::default().to_spec();
        spec.id = 42;
        let calibration = Calibration::new(&spec).unwrap();
        state.add_pad(RecordedPadState::new(&pad_info(2, 42), &calibration));
        state.add_pad(RecordedPadState::new(
            &pad_info(1, 0),
            &Calibration::default(),
        ));
        assert_eq!(state.pads_without_state(), Vec::<u8>::new());
        let change = BaselineChange {
            from_sequence: 7,
            taxels: [None; TAXEL_COUNT],
        };
        state.baselines_mut(2).unwrap().push(change.clone());
        assert!(state.baselines_mut(3).is_none());
        let text = serde_json::to_string_pretty(&state).unwrap();
        let read: RecordedDeviceState = serde_json::from_str(&text).unwrap();
        assert_eq!(read, state);
        let pads: Vec<u8> = read.other_pads.iter().map(|pad| pad.pad).collect();
        assert_eq!(pads, [1, 2]);
        let two = read.pad_state(2).unwrap();
        assert_eq!(two.calibration().unwrap().id(), 42);
        assert_eq!(two.tier, "linear");
        assert_eq!(two.baselines, [change]);
        assert_eq!(read.pad_state(0).unwrap().tier, "monotone-cubic");
        assert!(read.pad_state(5).is_none());
    }

    #[test]
    fn a_file_naming_a_pad_the_device_lacks_is_refused() {
        let directory = tempfile::tempdir().unwrap();
        let path = directory.path().join("state.json");
        let mut state = RecordedDeviceState::new(&info(2), &Calibration::default());
        state.other_pads.push(RecordedPadState::new(
            &pad_info(2, 0),
            &Calibration::default(),
        ));
        state.write(&path).unwrap();
        let error = RecordedDeviceState::read(&path).unwrap_err();
        assert!(error.to_string().contains("pad 2"), "{error}");
    }
}
