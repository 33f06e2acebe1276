//! Frames sent by the device to the host, except the sample frame (see `sample.rs`): identity,
//! health counters, replies to commands and asynchronous events. Their bodies are plain derived
//! postcard encodings.

use serde::{Deserialize, Serialize};

use crate::command::{ErrorCode, SampleRate, TaxelCalibrationRecord, Tier};
use crate::sample::{PadIndex, SampleFrame, TemperatureSource};
use model_core::{PadRole, TaxelGeometry};

/// A frame from the device to the host.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DeviceFrame {
    /// Identity and state; sent unsolicited when the host opens the port and after a frame
    /// with an unsupported protocol version. Kind [`crate::kind::INFO`].
    Info(InfoFrame),
    /// One sample set. Kind [`crate::kind::SAMPLE`].
    Sample(SampleFrame),
    /// Health counters. Kind [`crate::kind::COUNTERS`].
    Counters(CountersFrame),
    /// The answer to one request. Kind [`crate::kind::REPLY`].
    Reply(ReplyFrame),
    /// An asynchronous event. Kind [`crate::kind::EVENT`].
    Event(EventFrame),
}

/// A firmware version, semantic-versioning style.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FirmwareVersion {
    /// Incompatible changes.
    pub major: u8,
    /// Compatible additions.
    pub minor: u8,
    /// Fixes.
    pub patch: u8,
}

/// Where the calibration in use came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CalibrationSource {
    /// Loaded from the device's flash at boot.
    Flash,
    /// The built-in defaults (nothing was saved, or restore-defaults was requested).
    Defaults,
    /// The built-in defaults because the flash copy failed its integrity check at boot.
    DefaultsAfterCorruptFlash,
    /// Written by the host since boot and not necessarily saved.
    Host,
}

/// Device identity and state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InfoFrame {
    /// The protocol version the firmware speaks ([`crate::PROTOCOL_VERSION`]).
    pub protocol_version: u8,
    /// The firmware version.
    pub firmware_version: FirmwareVersion,
    /// The MCU's 96-bit unique device ID, in the byte order it is read from memory.
    pub board_serial: [u8; 12],
    /// Identifies the calibration in use (chosen by whoever wrote it).
    pub calibration_id: u32,
    /// Where the calibration in use came from.
    pub calibration_source: CalibrationSource,
    /// The converter rate (a sample set arrives at about a quarter of it).
    pub rate: SampleRate,
    /// The pressure-model tier in use.
    pub model_tier: Tier,
    /// Whether sample frames are being sent.
    pub streaming: bool,
    /// Whether the device prints CSV lines instead of binary frames.
    pub text_mode: bool,
    /// How many pads the device reads (sample frames carry pad indices below it; version 3).
    pub pad_count: u8,
    /// How many µs the device clock counts per second of real time (version 4): 1,000,000 for
    /// a board (its crystal's small error aside, which the host measures); a simulated device
    /// running at speed `s` counts `s` × 1,000,000; 0 when it is not paced to real time at all,
    /// whose clock the host then cannot map onto its own.
    pub clock_us_per_s: u32,
}

impl InfoFrame {
    /// The largest body: 1 + 3 + 12 + 5 (varint u32) + 1 + 2 (the rate, at most 400 as a
    /// varint) + 1 + 1 + 1 + 1 + 5 (the clock rate, a varint u32).
    pub const MAX_BODY_LEN: usize = 1 + 3 + 12 + 5 + 1 + 2 + 1 + 1 + 1 + 1 + 5;
    /// The largest encoded frame, delimiter included.
    pub const MAX_ENCODED_LEN: usize = crate::frame_encoded_len_bound(Self::MAX_BODY_LEN);
}

/// Health counters since boot; each saturates at `u32::MAX`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CountersFrame {
    /// Sample frames produced while streaming that were not sent — one per pad per sample set
    /// (a device of 8 pads counts 8 for a set it could not send): no host had the port open, or
    /// the output queue towards it was full. A gap in the sequence numbers of one uninterrupted
    /// stream that this does not explain was lost between the device and the host.
    pub dropped_sample_frames: u32,
    /// Times the converter was reset and reconfigured after an error.
    pub converter_reinits: u32,
    /// Failed I2C transfers (converter and temperature sensor).
    pub i2c_errors: u32,
    /// Failed or implausible temperature-sensor readings.
    pub temperature_sensor_errors: u32,
    /// Frames of any kind discarded because no host had the port open or the output queue
    /// towards it was full.
    pub frames_dropped_no_host: u32,
    /// Frames from the host that were rejected without a reply (bad COBS, CRC, version, kind).
    pub host_frames_rejected: u32,
}

impl CountersFrame {
    /// The largest body: six varint u32 of 5 bytes.
    pub const MAX_BODY_LEN: usize = 6 * 5;
    /// The largest encoded frame, delimiter included.
    pub const MAX_ENCODED_LEN: usize = crate::frame_encoded_len_bound(Self::MAX_BODY_LEN);
}

/// What a successful request returns.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReplyPayload {
    /// Done, nothing to return.
    Ack,
    /// The answer to [`crate::Command::Info`].
    Info(InfoFrame),
    /// The answer to [`crate::Command::ReadCounters`].
    Counters(CountersFrame),
    /// The answer to [`crate::Command::ReadCalibration`].
    Calibration(TaxelCalibrationRecord),
    /// The answer to [`crate::Command::SetUseCase`]: the model tier the device selected.
    ModelTier(Tier),
    /// The answer to [`crate::Command::ReadBaseline`] (added within version 2).
    Baseline(TaxelBaselineWire),
    /// The answer to [`crate::Command::PadInfo`] (version 3).
    PadInfo(PadInfoFrame),
}

/// Where a pad's temperature comes from, as the device found it at boot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TemperatureSensor {
    /// A TMP117 on the pad's own board, behind its multiplexer channel.
    OwnTmp117 {
        /// Its 7-bit address, 0x48..=0x4B.
        address: u8,
    },
    /// The TMP117 on the main bus, shared by every pad without one of its own.
    SharedTmp117 {
        /// Its 7-bit address, 0x48..=0x4B.
        address: u8,
    },
    /// No TMP117: the MCU's die sensor, every sample flagged TEMPERATURE_FALLBACK.
    DieOnly,
}

/// One pad: where it is, what it runs with, and its geometry (version 3; the role and geometry
/// since version 5).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PadInfoFrame {
    /// The pad.
    pub pad: PadIndex,
    /// The TCA9548A channel it hangs on, 0..=7; `None`: on the bus itself (no multiplexer).
    pub channel: Option<u8>,
    /// Its temperature sensor.
    pub temperature_sensor: TemperatureSensor,
    /// Its calibration's id.
    pub calibration_id: u32,
    /// Where its calibration came from.
    pub calibration_source: CalibrationSource,
    /// Its model tier.
    pub model_tier: Tier,
    /// What the pad is (for the host's layouts).
    pub role: PadRole,
    /// Each taxel's electrode centre and area in the pad's frame, in pad order: what the
    /// device computes the pad's force and centre of pressure with.
    pub taxels: [TaxelGeometry; crate::TAXEL_COUNT],
}

impl PadInfoFrame {
    /// The largest body: pad 1 + channel 2 + sensor 2 + id 5 + source 1 + tier 1 + role 1
    /// + 4 × (x, y, area) f32.
    pub const MAX_BODY_LEN: usize = 1 + 2 + 2 + 5 + 1 + 1 + 1 + crate::TAXEL_COUNT * 3 * 4;
}

/// A taxel's baseline as the model holds it: the tared capacitance, split into two parts that
/// are each exact in f32 (the CAPDAC offset and the converter's fine part), and the temperature
/// at the tare. With it a host reproduces the device's pressures exactly.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BaselineWire {
    /// The coarse part of the tared capacitance (CAPDAC offset), pF.
    pub offset_pf: f32,
    /// The fine part of the tared capacitance (converter code), pF.
    pub fine_pf: f32,
    /// The temperature at the tare, °C.
    pub temperature_c: f32,
}

/// One taxel's baseline, or none when the taxel is not tared.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TaxelBaselineWire {
    /// The pad (version 3).
    pub pad: PadIndex,
    /// The taxel, 0..=3.
    pub taxel_index: u8,
    /// Its baseline, `None` when it is not tared.
    pub baseline: Option<BaselineWire>,
}

/// The answer to one request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReplyFrame {
    /// The request id of the request this answers.
    pub request_id: u16,
    /// The outcome.
    pub result: Result<ReplyPayload, ErrorCode>,
}

impl ReplyFrame {
    /// The largest body, a calibration reply with 16 points: request id 3 + result tag 1
    /// + payload tag 1 + [`TaxelCalibrationRecord::MAX_LEN`].
    pub const MAX_BODY_LEN: usize = 3 + 1 + 1 + TaxelCalibrationRecord::MAX_LEN;
    /// The largest encoded frame, delimiter included (more than one USB packet).
    pub const MAX_ENCODED_LEN: usize = crate::frame_encoded_len_bound(Self::MAX_BODY_LEN);
    /// The largest encoded frame of every reply except calibration replies: a reply carrying
    /// a PadInfo frame (its body, 60 bytes since version 5, is the largest of Info, Counters,
    /// ModelTier, Baseline and PadInfo).
    pub const MAX_ENCODED_LEN_WITHOUT_CALIBRATION: usize = crate::frame_encoded_len_bound(
        3 + 1
            + 1
            + max(
                PadInfoFrame::MAX_BODY_LEN,
                max(InfoFrame::MAX_BODY_LEN, CountersFrame::MAX_BODY_LEN),
            ),
    );
    /// The most calibration points a calibration reply can carry and still fit one 63-byte
    /// frame in the worst case of its other fields (an unloaded capacitance included).
    pub const CALIBRATION_POINTS_IN_ONE_PACKET: usize = 4;
}

/// An asynchronous device event.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DeviceEvent {
    /// A pad's converter was reset and reconfigured after an error; samples were lost.
    ConverterReinitialised {
        /// The pad (version 3).
        pad: PadIndex,
        /// The pad's count since boot (the sum over pads is
        /// [`CountersFrame::converter_reinits`]).
        reinit_count: u32,
    },
    /// A pad's temperature source changed: a fallback when it is no longer a TMP117, a recovery
    /// when it is again.
    TemperatureSourceChanged {
        /// The pad (version 3).
        pad: PadIndex,
        /// The source now in use.
        source: TemperatureSource,
    },
    /// At boot the calibration in flash failed its integrity check; defaults are in use.
    CalibrationFlashCorrupt,
    /// The baselines changed: a tare finished (at boot, on command) or baselines were restored
    /// after a reset. Samples after this event use the new baselines (added within version 2).
    TareFinished {
        /// The pad (version 3).
        pad: PadIndex,
        /// Bit n set: taxel n of the pad has a baseline now.
        tared_mask: u8,
    },
    /// A pad came into contact: its force stayed above the contact threshold for the debounce
    /// time. The event's timestamp is that of the sample set that confirmed it (version 3).
    ContactStarted {
        /// The pad.
        pad: PadIndex,
    },
    /// A pad's contact ended: its force stayed below the release threshold for the debounce
    /// time (version 3).
    ContactEnded {
        /// The pad.
        pad: PadIndex,
    },
    /// A pad's tare finished without a new baseline for every taxel (version 5): the taxels
    /// named were loaded, not still, open or shorted, and keep their previous baseline if they
    /// had one ([`DeviceEvent::TareFinished`]'s mask says which taxels have one). Sent before
    /// the tare's reply, whether the tare was asked for or ran at boot.
    TareRefused {
        /// The pad.
        pad: PadIndex,
        /// Bit n set: taxel n got no new baseline.
        refused_mask: u8,
    },
}

/// An asynchronous device event with the time it happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EventFrame {
    /// The device clock when the event happened, in microseconds since boot.
    pub timestamp_us: u64,
    /// What happened.
    pub event: DeviceEvent,
}

impl EventFrame {
    /// The largest body: timestamp 10 (varint u64) + event tag 1 + pad 1 + count 5 (varint
    /// u32).
    pub const MAX_BODY_LEN: usize = 10 + 1 + 1 + 5;
    /// The largest encoded frame, delimiter included.
    pub const MAX_ENCODED_LEN: usize = crate::frame_encoded_len_bound(Self::MAX_BODY_LEN);
}

impl DeviceFrame {
    /// The largest encoded device frame, delimiter included (a calibration reply).
    pub const MAX_ENCODED_LEN: usize = ReplyFrame::MAX_ENCODED_LEN;

    /// The kind byte of this frame.
    pub const fn kind(&self) -> u8 {
        match self {
            DeviceFrame::Info(_) => crate::kind::INFO,
            DeviceFrame::Sample(_) => crate::kind::SAMPLE,
            DeviceFrame::Counters(_) => crate::kind::COUNTERS,
            DeviceFrame::Reply(_) => crate::kind::REPLY,
            DeviceFrame::Event(_) => crate::kind::EVENT,
        }
    }
}

const fn max(a: usize, b: usize) -> usize {
    if a > b {
        a
    } else {
        b
    }
}
