//! Commands from the host to the device, the calibration they carry, the error codes the
//! device answers with, and the argument checks the device applies before acting.

use heapless::Vec;
use serde::{Deserialize, Serialize};

use crate::error::DecodeError;
use crate::{PadIndex, TAXEL_COUNT};
use model_core::{GeometryError, PadGeometry, PadRole, TaxelGeometry};

/// The most calibration points one taxel calibration holds.
pub const CALIBRATION_POINTS_MAX: usize = 16;

/// The number of [`Command`] variants; a discriminant at or above it is
/// [`ErrorCode::UnknownCommand`].
pub const COMMAND_COUNT: u32 = 16;

/// The discriminants of the commands whose arguments are typed values ([`SampleRate`], [`Tier`],
/// [`PadIndex`], also inside an `Option`) that refuse numbers outside their range when they are
/// decoded.
const SET_RATE_DISCRIMINANT: u32 = 4;
const TARE_DISCRIMINANT: u32 = 5;
const SET_MODEL_TIER_DISCRIMINANT: u32 = 6;
const READ_CALIBRATION_DISCRIMINANT: u32 = 8;
const READ_BASELINE_DISCRIMINANT: u32 = 13;
const PAD_INFO_DISCRIMINANT: u32 = 14;
const SET_PAD_GEOMETRY_DISCRIMINANT: u32 = 15;

/// Why the device refused a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ErrorCode {
    /// The command discriminant is not one this firmware knows.
    UnknownCommand,
    /// The request id was readable but the rest of the body was not.
    Malformed,
    /// The command is known and well formed but an argument is out of range.
    InvalidArgument,
    /// The device cannot do this now (for example a tare is already running).
    Busy,
    /// Writing or reading the calibration flash failed.
    FlashError,
    /// The device cannot do this with what it has (for example a tier the calibration in use
    /// cannot provide).
    NotSupported,
    /// A tare finished without a baseline for every taxel (the pad was loaded, or a taxel is
    /// open or shorted); the sample flags say which taxels stay untared.
    TareFailed,
    /// A tare was refused for at least one taxel because the pad was not still (pressed or
    /// moving: its readings spread more than converter noise explains); those taxels keep the
    /// baseline they had, if any. Tare again with the pad unloaded and at rest.
    TareNotStill,
}

/// The converter conversion rates the device supports (each of the four taxels, and so each
/// sample set, refreshes at about a quarter of the rate).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SampleRate {
    /// 100 conversions per second.
    Sps100,
    /// 200 conversions per second.
    Sps200,
    /// 400 conversions per second.
    Sps400,
}

impl SampleRate {
    /// The rate for a value in conversions per second, if it is supported.
    pub const fn from_sps(rate_sps: u16) -> Option<SampleRate> {
        match rate_sps {
            100 => Some(SampleRate::Sps100),
            200 => Some(SampleRate::Sps200),
            400 => Some(SampleRate::Sps400),
            _ => None,
        }
    }

    /// This rate in conversions per second.
    pub const fn sps(self) -> u16 {
        match self {
            SampleRate::Sps100 => 100,
            SampleRate::Sps200 => 200,
            SampleRate::Sps400 => 400,
        }
    }
}

/// On the wire a rate is its number of conversions per second (a u16 varint); any other number
/// fails to decode, and a request carrying one is answered [`ErrorCode::InvalidArgument`].
impl Serialize for SampleRate {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_u16(self.sps())
    }
}

impl<'de> Deserialize<'de> for SampleRate {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let rate_sps = u16::deserialize(deserializer)?;
        SampleRate::from_sps(rate_sps)
            .ok_or_else(|| serde::de::Error::custom("unsupported conversion rate"))
    }
}

/// The model tier: model-core's definition, carried as its id (one byte for every tier).
pub use model_core::Tier;

/// The measurement task the host asks the device to choose a model tier for: model-core's
/// definition, carried as postcard encodes it (four f32 in field order).
pub use model_core::UseCase;

/// The calibration of one taxel: its loading curve, its parasitic capacitance and, if known, its
/// unloaded sensor capacitance when it was calibrated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TaxelCalibrationWire {
    /// `(pressure_kpa, relative_change)` pairs, relative change = ΔC/C0, pressure ascending.
    pub points: Vec<(f32, f32), CALIBRATION_POINTS_MAX>,
    /// The capacitance in pF that does not belong to the sensor (cable, pads).
    pub parasitic_pf: f32,
    /// The unloaded sensor capacitance C0 - Cp at 25 °C when the taxel was calibrated, pF, if
    /// known; the device flags a tare far from it. Added in protocol version 2.
    pub unloaded_sensor_pf: Option<f32>,
}

/// A taxel calibration together with the taxel it belongs to and the calibration id.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TaxelCalibrationRecord {
    /// The pad (version 3).
    pub pad: PadIndex,
    /// The taxel, 0..=3 for C11, C12, C21, C22.
    pub taxel_index: u8,
    /// The calibration id reported by [`crate::InfoFrame::calibration_id`] once this is in use.
    pub calibration_id: u32,
    /// The calibration.
    pub calibration: TaxelCalibrationWire,
}

impl TaxelCalibrationRecord {
    /// The largest encoding: pad 1 + taxel 1 + id 5 (varint u32) + point count 1 + 16 points
    /// x 8 + parasitic 4 + unloaded capacitance 5 (option tag and f32).
    pub const MAX_LEN: usize = 1 + 1 + 5 + 1 + CALIBRATION_POINTS_MAX * 8 + 4 + 5;

    /// Checks what the wire can check: a taxel index below 4, at least two points, finite
    /// values, pressure and relative change both strictly increasing, a finite, non-negative
    /// parasitic capacitance, and an unloaded capacitance, if any, finite and positive. The
    /// device's model may refuse more.
    pub fn check(&self) -> Result<(), ErrorCode> {
        let points = &self.calibration.points;
        let parasitic_pf = self.calibration.parasitic_pf;
        let unloaded_valid = self
            .calibration
            .unloaded_sensor_pf
            .is_none_or(|unloaded_pf| unloaded_pf.is_finite() && unloaded_pf > 0.0);
        let strictly_increasing = points
            .iter()
            .zip(points.iter().skip(1))
            .all(|(previous, next)| next.0 > previous.0 && next.1 > previous.1);
        let finite = points.iter().all(|(pressure_kpa, relative_change)| {
            pressure_kpa.is_finite() && relative_change.is_finite()
        });
        if usize::from(self.taxel_index) < TAXEL_COUNT
            && points.len() >= 2
            && finite
            && strictly_increasing
            && parasitic_pf.is_finite()
            && parasitic_pf >= 0.0
            && unloaded_valid
        {
            Ok(())
        } else {
            Err(ErrorCode::InvalidArgument)
        }
    }
}

/// A command from the host. The postcard discriminant of each variant is its position here,
/// starting at 0; new commands are only ever appended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// Replies [`crate::ReplyPayload::Info`].
    Info,
    /// Replies [`crate::ReplyPayload::Counters`].
    ReadCounters,
    /// Starts sending sample frames (or CSV lines in text mode). Replies Ack.
    StartStreaming,
    /// Stops sending samples. Replies Ack.
    StopStreaming,
    /// Sets the converter rate; 100, 200 or 400 S/s on the wire, anything else is
    /// [`ErrorCode::InvalidArgument`]. Replies Ack.
    SetRate {
        /// The rate.
        rate: SampleRate,
    },
    /// Takes the unloaded reference of every taxel of one pad, or of every pad, as the mean of
    /// this many sample sets (at least 1). Replies Ack when every pad tared is done;
    /// [`ErrorCode::InvalidArgument`] for a pad the device lacks.
    Tare {
        /// The number of sample sets to average.
        sample_sets: u16,
        /// The pad to tare, the others left as they are; `None` tares every pad (version 6).
        pad: Option<PadIndex>,
    },
    /// Selects a model tier; an id that is no tier is [`ErrorCode::InvalidArgument`], a tier
    /// the calibration in use cannot provide or the device does not build (a research tier:
    /// `model_core::Tier::is_built`) [`ErrorCode::NotSupported`]. Replies Ack.
    SetModelTier {
        /// The tier.
        tier: Tier,
    },
    /// Lets the device choose the tier for a use case. Replies
    /// [`crate::ReplyPayload::ModelTier`], or [`ErrorCode::NotSupported`] if no tier fits.
    SetUseCase(UseCase),
    /// Replies [`crate::ReplyPayload::Calibration`] for one taxel of one pad.
    ReadCalibration {
        /// The pad (version 3).
        pad: PadIndex,
        /// The taxel, 0..=3.
        taxel_index: u8,
    },
    /// Replaces one taxel's calibration of one pad in RAM (that pad's calibration source
    /// becomes Host). Replies Ack.
    WriteCalibration(TaxelCalibrationRecord),
    /// Writes the calibration in use to flash, which every pad boots with. Replies Ack,
    /// [`ErrorCode::FlashError`], or [`ErrorCode::NotSupported`] (nothing written) while the
    /// pads hold different calibrations.
    SaveCalibration,
    /// Replaces every pad's calibration in RAM by the built-in defaults (flash is untouched
    /// until [`Command::SaveCalibration`]). Replies Ack.
    RestoreDefaults,
    /// Switches text mode (CSV lines instead of binary frames) on or off. Replies Ack, sent
    /// as a binary frame in either mode.
    SetTextMode {
        /// Text mode on.
        enabled: bool,
    },
    /// Replies [`crate::ReplyPayload::Baseline`] for one taxel of one pad: the unloaded
    /// reference the model uses now (added within version 2).
    ReadBaseline {
        /// The pad (version 3).
        pad: PadIndex,
        /// The taxel, 0..=3.
        taxel_index: u8,
    },
    /// Replies [`crate::ReplyPayload::PadInfo`]: where a pad is and what it runs with (version
    /// 3).
    PadInfo {
        /// The pad.
        pad: PadIndex,
    },
    /// Replaces one pad's geometry and role in RAM (version 5): what its force and centre of
    /// pressure are computed with from the next sample set on, and what `PadInfo` reports.
    /// Saved to flash with the pad's calibration by [`Command::SaveCalibration`]. Replies Ack;
    /// [`ErrorCode::InvalidArgument`] for a pad the device lacks or a geometry
    /// [`model_core::PadGeometry::new`] refuses (an area not above 0, a centre out of range,
    /// two centres equal, a value not finite).
    SetPadGeometry(PadGeometryRecord),
}

/// One pad's geometry and role, as [`Command::SetPadGeometry`] carries it and
/// [`crate::PadInfoFrame`] reports it: plain data, validated by the device.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PadGeometryRecord {
    /// The pad.
    pub pad: PadIndex,
    /// What the pad is (for the host's layouts).
    pub role: PadRole,
    /// Each taxel's electrode centre and area, in pad order (C11, C12, C21, C22).
    pub taxels: [TaxelGeometry; TAXEL_COUNT],
}

impl PadGeometryRecord {
    /// The largest body: pad 1 + role 1 + 4 × (x, y, area) f32.
    pub const MAX_LEN: usize = 1 + 1 + TAXEL_COUNT * 3 * 4;

    /// The validated geometry, or the reason it is refused.
    pub fn geometry(&self) -> Result<PadGeometry, GeometryError> {
        PadGeometry::new(self.taxels)
    }
}

impl Command {
    /// Checks the arguments the wire protocol constrains; `Err` is the error code to reply.
    pub fn check_arguments(&self) -> Result<(), ErrorCode> {
        match self {
            Command::Tare { sample_sets, .. } if *sample_sets == 0 => {
                Err(ErrorCode::InvalidArgument)
            }
            Command::SetUseCase(use_case) if !use_case.is_valid() => {
                Err(ErrorCode::InvalidArgument)
            }
            Command::ReadCalibration { taxel_index, .. }
            | Command::ReadBaseline { taxel_index, .. }
                if usize::from(*taxel_index) >= TAXEL_COUNT =>
            {
                Err(ErrorCode::InvalidArgument)
            }
            Command::WriteCalibration(record) => record.check(),
            Command::SetPadGeometry(record) if record.geometry().is_err() => {
                Err(ErrorCode::InvalidArgument)
            }
            _ => Ok(()),
        }
    }
}

/// A command with the id its reply will carry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Request {
    /// Chosen by the host (typically incrementing); echoed in [`crate::ReplyFrame::request_id`].
    pub request_id: u16,
    /// What to do.
    pub command: Command,
}

impl Request {
    /// The largest body, a calibration write: request id 3 + command tag 1
    /// + [`TaxelCalibrationRecord::MAX_LEN`].
    pub const MAX_BODY_LEN: usize = 3 + 1 + TaxelCalibrationRecord::MAX_LEN;
    /// The largest encoded frame, delimiter included.
    pub const MAX_ENCODED_LEN: usize = crate::frame_encoded_len_bound(Self::MAX_BODY_LEN);

    /// Parses a request body. When the request id is readable but the command is not, the
    /// error is [`DecodeError::InvalidRequest`] so that the device can still answer.
    pub(crate) fn from_body(body: &[u8]) -> Result<Request, DecodeError> {
        match postcard::take_from_bytes::<Request>(body) {
            Ok((request, [])) => Ok(request),
            Ok((request, _)) => Err(DecodeError::InvalidRequest {
                request_id: request.request_id,
                error: ErrorCode::Malformed,
            }),
            Err(error) => match postcard::take_from_bytes::<u16>(body) {
                Ok((request_id, rest)) => {
                    let discriminant = postcard::take_from_bytes::<u32>(rest)
                        .ok()
                        .map(|(discriminant, _)| discriminant);
                    let unknown = discriminant.is_some_and(|command| command >= COMMAND_COUNT);
                    // Only these commands carry typed arguments that refuse values; any other
                    // refusal (too many points, a bad enum, a pad index inside a calibration
                    // record) is a malformed body.
                    let typed_argument = matches!(
                        discriminant,
                        Some(
                            SET_RATE_DISCRIMINANT
                                | TARE_DISCRIMINANT
                                | SET_MODEL_TIER_DISCRIMINANT
                                | READ_CALIBRATION_DISCRIMINANT
                                | READ_BASELINE_DISCRIMINANT
                                | PAD_INFO_DISCRIMINANT
                                | SET_PAD_GEOMETRY_DISCRIMINANT
                        )
                    );
                    Err(DecodeError::InvalidRequest {
                        request_id,
                        error: if unknown {
                            ErrorCode::UnknownCommand
                        } else if typed_argument && error == postcard::Error::SerdeDeCustom {
                            // A typed argument refused its value (a rate, a tier id or a pad
                            // index that does not exist): the body parsed, the argument is out
                            // of range.
                            ErrorCode::InvalidArgument
                        } else {
                            ErrorCode::Malformed
                        },
                    })
                }
                Err(_) => Err(DecodeError::Postcard(error)),
            },
        }
    }
}
