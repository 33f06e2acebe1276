//! The device's state a recording's pressures were computed with: the `NAME.dev<n>.device.json`
//! file beside a recording (see [`crate::recorder`]), and how it is read from the device when a
//! recording starts ([`read_device_state`]); the session follows every pad's baselines while it
//! runs ([`crate::session`]).
//!
//! The file is JSON: `format` ([`DEVICE_STATE_FORMAT`]) and `version`
//! ([`DEVICE_STATE_VERSION`]); the device's identity (`firmware`, `protocol_version`,
//! `board_serial`, `converter_rate_sps`); then `pads`, one object per pad in pad order (one for
//! a single-pad device): `pad`, `calibration_source`, `tier`, `calibration` (the whole
//! calibration, as a calibration file holds it), `role` and `geometry` (the taxels' centres and
//! areas the device computes force and centre of pressure with), and `baselines` (in the order
//! they took effect, each `from_sequence`, the first sample computed with them, and the four
//! taxels' baselines, `null` for a taxel not tared). A pad the file does not describe is
//! converted with the defaults (and `taxel convert` says so).

use std::io::{Read, Write};
use std::path::Path;
use std::time::Duration;

use anyhow::{bail, Context};
use model_core::{BaselineRecord, Calibration, CalibrationSpec, PadGeometry, PadRole, TAXEL_COUNT};
use serde::{Deserialize, Serialize};
use wire::{DeviceEvent, DeviceFrame, EventFrame, InfoFrame, PadIndex, PadInfoFrame};

use crate::calibration_transfer::{pad_info, pull, pull_baselines};
use crate::device_link::DeviceLink;
use crate::device_words::{board_serial_hex, calibration_source_words, tier_words};
use crate::output_file::OutputFile;

/// The `format` field of a device-state file.
pub const DEVICE_STATE_FORMAT: &str = "taxel-recording-device-state";

/// The version of the device-state file format.
pub const DEVICE_STATE_VERSION: u64 = 2;

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
    /// What the pad is.
    pub role: PadRole,
    /// Its taxels' centres and areas (validated when read).
    pub geometry: PadGeometry,
    /// The pad's baselines, in the order they took effect; empty when the device could not say.
    pub baselines: Vec<BaselineChange>,
    /// The first sample (by sequence number) known to be computed with this calibration, tier
    /// and geometry: 0 when they held from the start. The pad's earlier samples may have been
    /// computed with others the file does not hold (they changed while the host was reading).
    #[serde(default)]
    pub state_from_sequence: u32,
}

impl RecordedPadState {
    /// A pad's state from its PadInfo and calibration, without baselines yet; fails when the
    /// device reports a geometry that is not one.
    pub fn new(pad_info: &PadInfoFrame, calibration: &Calibration) -> anyhow::Result<Self> {
        Ok(Self {
            pad: pad_info.pad.get(),
            calibration_source: calibration_source_words(pad_info.calibration_source).to_owned(),
            tier: tier_words(pad_info.model_tier),
            calibration: calibration.to_spec(),
            role: pad_info.role,
            geometry: pad_geometry(pad_info)?,
            baselines: Vec::new(),
            state_from_sequence: 0,
        })
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
    /// Converter conversions per second.
    pub converter_rate_sps: u16,
    /// How many pads the device reads.
    pub pad_count: u8,
    /// The state of each pad the file describes, in pad order.
    pub pads: Vec<RecordedPadState>,
}

impl RecordedDeviceState {
    /// The state of a device from its identity, without its pads' (added with
    /// [`RecordedDeviceState::add_pad`]).
    pub fn new(info: &InfoFrame) -> Self {
        let version = info.firmware_version;
        Self {
            format: DEVICE_STATE_FORMAT.to_owned(),
            version: DEVICE_STATE_VERSION,
            firmware: format!("{}.{}.{}", version.major, version.minor, version.patch),
            protocol_version: info.protocol_version,
            board_serial: board_serial_hex(info),
            converter_rate_sps: info.rate.sps(),
            pad_count: info.pad_count.max(1),
            pads: Vec::new(),
        }
    }

    /// Adds a pad's state (replacing any it had).
    pub fn add_pad(&mut self, pad: RecordedPadState) {
        self.pads.retain(|known| known.pad != pad.pad);
        let place = self.pads.partition_point(|known| known.pad < pad.pad);
        self.pads.insert(place, pad);
    }

    /// A pad's state; `None` for a pad the file does not describe.
    pub fn pad_state(&self, pad: u8) -> Option<RecordedPadState> {
        self.pads.iter().find(|known| known.pad == pad).cloned()
    }

    /// The pads of the device (below `pad_count`) whose state the file lacks.
    pub fn pads_without_state(&self) -> Vec<u8> {
        (0..self.pad_count)
            .filter(|&pad| self.pads.iter().all(|known| known.pad != pad))
            .collect()
    }

    /// A pad's baselines history, to add changes to; `None` for a pad the file does not
    /// describe.
    pub fn baselines_mut(&mut self, pad: u8) -> Option<&mut Vec<BaselineChange>> {
        self.pads
            .iter_mut()
            .find(|known| known.pad == pad)
            .map(|known| &mut known.baselines)
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
        for (index, known) in state.pads.iter().enumerate() {
            let repeated = state.pads[..index]
                .iter()
                .any(|earlier| earlier.pad == known.pad);
            if known.pad >= state.pad_count || repeated {
                bail!(
                    "{}: pads describes pad {}, which is not one of pads 0 to {} given once",
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

/// A pad's geometry as its PadInfo reports it, validated.
pub fn pad_geometry(pad_info: &PadInfoFrame) -> anyhow::Result<PadGeometry> {
    PadGeometry::new(pad_info.taxels).map_err(|error| {
        anyhow::anyhow!(
            "the device reports a geometry for pad {} that is not one: {error}",
            pad_info.pad.get()
        )
    })
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

/// Pad `pad`'s calibration, tier, role and geometry as the device reports them now (its
/// PadInfo and calibration: five requests and four per taxel), without baselines.
pub fn read_pad_state<P: Read + Write>(
    link: &mut DeviceLink<P>,
    pad: PadIndex,
    timeout: Duration,
) -> anyhow::Result<RecordedPadState> {
    let pad_info = pad_info(link, pad, timeout)?;
    let calibration = pull(link, pad, pad_info.calibration_id, timeout)
        .with_context(|| format!("reading the calibration of pad {}", pad.get()))?;
    RecordedPadState::new(&pad_info, &calibration)
        .with_context(|| format!("reading pad {}", pad.get()))
}

/// Reads every pad's whole calibration, geometry and baselines as the state a recording starts
/// with: per pad its PadInfo (tier, role, geometry, calibration id), four ReadCalibration and
/// four ReadBaseline requests.
/// Frames that arrived meanwhile are discarded: they were computed before the state was read,
/// so the recording starts after them. The baselines of a pad whose tare finished meanwhile
/// are read again.
pub fn read_device_state<P: Read + Write>(
    link: &mut DeviceLink<P>,
    info: &InfoFrame,
    timeout: Duration,
) -> anyhow::Result<RecordedDeviceState> {
    let mut state = RecordedDeviceState::new(info);
    let pads: Vec<PadIndex> = (0..state.pad_count).filter_map(PadIndex::new).collect();
    for &pad in &pads {
        state.add_pad(read_pad_state(link, pad, timeout)?);
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
            calibration_id,
            calibration_source: wire::CalibrationSource::Host,
            model_tier: wire::Tier::Linear,
            ..wire::testing::pad_info_frame(pad)
        }
    }

    fn pad_state(pad: u8, calibration_id: u32, calibration: &Calibration) -> RecordedPadState {
        RecordedPadState::new(&pad_info(pad, calibration_id), calibration).unwrap()
    }

    #[test]
    fn every_pad_keeps_its_own_calibration_tier_geometry_and_baselines() {
        let mut state = RecordedDeviceState::new(&info(4));
        let mut spec = Calibration::default().to_spec();
        spec.id = 42;
        let calibration = Calibration::new(&spec).unwrap();
        let mut palm = pad_info(2, 42);
        palm.role = PadRole::Palm;
        for taxel in &mut palm.taxels {
            taxel.area_mm2 = 100.0;
        }
        state.add_pad(RecordedPadState::new(&palm, &calibration).unwrap());
        state.add_pad(pad_state(0, 0, &Calibration::default()));
        state.add_pad(pad_state(1, 0, &Calibration::default()));
        assert_eq!(state.pads_without_state(), [3]);
        let change = BaselineChange {
            from_sequence: 7,
            taxels: [None; TAXEL_COUNT],
        };
        state.baselines_mut(2).unwrap().push(change.clone());
        assert!(state.baselines_mut(3).is_none());
        let text = serde_json::to_string_pretty(&state).unwrap();
        let read: RecordedDeviceState = serde_json::from_str(&text).unwrap();
        assert_eq!(read, state);
        let pads: Vec<u8> = read.pads.iter().map(|pad| pad.pad).collect();
        assert_eq!(pads, [0, 1, 2]);
        let two = read.pad_state(2).unwrap();
        assert_eq!(two.calibration().unwrap().id(), 42);
        assert_eq!(two.tier, "linear");
        assert_eq!(two.role, PadRole::Palm);
        assert_eq!(two.geometry.taxels()[3].area_mm2, 100.0);
        assert_eq!(two.baselines, [change]);
        assert_eq!(read.pad_state(0).unwrap().geometry, PadGeometry::ARTICLE);
        assert!(read.pad_state(5).is_none());
    }

    #[test]
    fn a_geometry_that_is_not_one_is_refused_when_read_from_the_device_or_a_file() {
        let mut broken = pad_info(0, 0);
        broken.taxels[1] = broken.taxels[0];
        let error = RecordedPadState::new(&broken, &Calibration::default()).unwrap_err();
        assert!(error.to_string().contains("pad 0"), "{error}");
        let mut state = RecordedDeviceState::new(&info(1));
        state.add_pad(pad_state(0, 0, &Calibration::default()));
        let text = serde_json::to_string(&state).unwrap().replacen(
            "\"area_mm2\":25.0",
            "\"area_mm2\":-1.0",
            1,
        );
        assert!(serde_json::from_str::<RecordedDeviceState>(&text).is_err());
    }

    #[test]
    fn a_file_naming_a_pad_the_device_lacks_is_refused() {
        let directory = tempfile::tempdir().unwrap();
        let path = directory.path().join("state.json");
        let mut state = RecordedDeviceState::new(&info(2));
        state.pads.push(pad_state(2, 0, &Calibration::default()));
        state.write(&path).unwrap();
        let error = RecordedDeviceState::read(&path).unwrap_err();
        assert!(error.to_string().contains("pad 2"), "{error}");
    }
}
