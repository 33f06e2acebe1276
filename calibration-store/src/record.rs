//! A pad's record body, the one definition of what the store keeps for a pad ([`PadRecord`]: its
//! calibration, role and geometry): `[body format version = 2][postcard PadRecord]`, at most
//! [`MAX_BODY_LEN`] bytes.
//!
//! The store frames the body (length, pads, save counter, CRC-32: see the `format` module) and
//! knows nothing of it beyond [`MAX_BODY_LEN`]; this module encodes and decodes it. A body is
//! accepted only if its version is one this firmware reads, it parses completely, the
//! calibration validates with [`Calibration::new`] and the geometry with [`PadGeometry::new`]
//! (deserialization goes through it): a body that parses into a calibration or geometry the
//! model would refuse is as corrupt as one that does not parse. Changing what a body holds means
//! changing this module, [`BODY_FORMAT_VERSION`] and [`MAX_BODY_LEN`].

use core::fmt;

use model_core::calibration::{
    Calibration, CalibrationError, CalibrationSpec, MAX_CURVE_POINTS, MAX_TEMPERATURE_POINTS,
    TAXEL_COUNT,
};
use model_core::{PadGeometry, PadRole};
use serde::{Deserialize, Serialize};

/// The format version of the bodies this firmware writes and reads, their first byte (1 held
/// the calibration alone).
pub const BODY_FORMAT_VERSION: u8 = 2;

/// What flash keeps for a pad: its calibration, and its role and geometry (what its force and
/// centre of pressure are computed with, and what PadInfo reports).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PadRecord {
    /// The calibration.
    pub calibration: CalibrationSpec,
    /// What the pad is.
    pub role: PadRole,
    /// Its taxels' centres and areas.
    pub geometry: PadGeometry,
}

impl PadRecord {
    /// `calibration` on a pad of the built-in geometry and no role.
    pub fn new(calibration: CalibrationSpec) -> Self {
        Self {
            calibration,
            role: PadRole::Unspecified,
            geometry: PadGeometry::ARTICLE,
        }
    }
}

const VERSION_LEN: usize = 1;
const F32_LEN: usize = 4;
/// postcard writes a u32 as a varint: 7 bits per byte, so up to 5 bytes.
const VARINT_U32_MAX_LEN: usize = 5;
/// postcard prefixes a sequence with its length as a varint; lengths up to 127 take one byte.
const SEQUENCE_LENGTH_LEN: usize = 1;
/// postcard writes an `Option<f32>` as a tag byte, then the f32 when it is Some.
const OPTION_F32_MAX_LEN: usize = 1 + F32_LEN;
const POINT_LEN: usize = 2 * F32_LEN;
const TAXEL_MAX_LEN: usize =
    SEQUENCE_LENGTH_LEN + MAX_CURVE_POINTS * POINT_LEN + F32_LEN + OPTION_F32_MAX_LEN;
const TEMPERATURE_LAW_MAX_LEN: usize =
    SEQUENCE_LENGTH_LEN + MAX_TEMPERATURE_POINTS * POINT_LEN + 2 * F32_LEN;
const THRESHOLDS_LEN: usize = 3 * F32_LEN;
/// postcard writes an enum's variant index as a varint: one byte for the five roles.
const ROLE_LEN: usize = 1;
/// Four taxels' centre (x, y) and area, f32 each.
const GEOMETRY_LEN: usize = TAXEL_COUNT * 3 * F32_LEN;

// The one-byte length prefixes above hold only while the capacities stay below 128.
const _: () = assert!(MAX_CURVE_POINTS < 128 && MAX_TEMPERATURE_POINTS < 128);

/// The longest postcard [`CalibrationSpec`]: id (varint, 5), four taxels of 16 points with a
/// calibrated C0 (4 x (1 + 16 x 8 + 4 + 1 + 4) = 552), the temperature law (1 + 8 x 8 + 2 x 4 =
/// 73) and the thresholds (12): 642 bytes.
const MAX_SPEC_LEN: usize =
    VARINT_U32_MAX_LEN + TAXEL_COUNT * TAXEL_MAX_LEN + TEMPERATURE_LAW_MAX_LEN + THRESHOLDS_LEN;

/// The longest body: the version byte, the longest postcard calibration, the role and the
/// geometry, 692 bytes.
pub const MAX_BODY_LEN: usize = VERSION_LEN + MAX_SPEC_LEN + ROLE_LEN + GEOMETRY_LEN;

/// Why a body could not be written or read.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RecordError {
    /// Encoding: the output buffer is shorter than the body ([`MAX_BODY_LEN`] always fits).
    BufferTooSmall,
    /// Decoding: no bytes at all.
    Empty,
    /// Decoding: more than [`MAX_BODY_LEN`] bytes (a later firmware's body, or damage).
    TooLong,
    /// Decoding: written in a body format this firmware does not know.
    UnsupportedVersion {
        /// The version byte found.
        found: u8,
    },
    /// Decoding: the bytes after the version are not a postcard [`PadRecord`] (also: a geometry
    /// that does not validate).
    Postcard(postcard::Error),
    /// Decoding: the record parsed but bytes were left over.
    TrailingBytes,
    /// The calibration does not validate: refused before encoding, or found in a body.
    Invalid(CalibrationError),
}

impl fmt::Display for RecordError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RecordError::BufferTooSmall => write!(formatter, "record buffer too small"),
            RecordError::Empty => write!(formatter, "empty record"),
            RecordError::TooLong => write!(formatter, "record longer than {MAX_BODY_LEN} bytes"),
            RecordError::UnsupportedVersion { found } => {
                write!(formatter, "unsupported record format version {found}")
            }
            RecordError::Postcard(error) => write!(formatter, "record body: {error}"),
            RecordError::TrailingBytes => write!(formatter, "bytes left over after record body"),
            RecordError::Invalid(error) => write!(formatter, "invalid calibration: {error:?}"),
        }
    }
}

impl core::error::Error for RecordError {}

/// Writes `record` as a body at the start of `out` and returns the body's length.
///
/// The calibration is validated first: a spec the model would refuse is never written (the
/// geometry is valid by construction).
pub fn encode_body(record: &PadRecord, out: &mut [u8]) -> Result<usize, RecordError> {
    Calibration::new(&record.calibration).map_err(RecordError::Invalid)?;
    let (version, spec_space) = out.split_first_mut().ok_or(RecordError::BufferTooSmall)?;
    *version = BODY_FORMAT_VERSION;
    let spec_len = postcard::to_slice(record, spec_space)
        .map_err(|error| match error {
            postcard::Error::SerializeBufferFull => RecordError::BufferTooSmall,
            other => RecordError::Postcard(other),
        })?
        .len();
    Ok(VERSION_LEN + spec_len)
}

/// Reads a body that fills `bytes` exactly and returns its record, validated.
pub fn decode_body(bytes: &[u8]) -> Result<PadRecord, RecordError> {
    if bytes.len() > MAX_BODY_LEN {
        return Err(RecordError::TooLong);
    }
    let (&version, spec) = bytes.split_first().ok_or(RecordError::Empty)?;
    if version != BODY_FORMAT_VERSION {
        return Err(RecordError::UnsupportedVersion { found: version });
    }
    let record = match postcard::take_from_bytes::<PadRecord>(spec) {
        Ok((record, [])) => record,
        Ok(_) => return Err(RecordError::TrailingBytes),
        Err(error) => return Err(RecordError::Postcard(error)),
    };
    Calibration::new(&record.calibration).map_err(RecordError::Invalid)?;
    Ok(record)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maximum_lengths_add_up() {
        assert_eq!(MAX_SPEC_LEN, 642);
        assert_eq!(MAX_BODY_LEN, 692);
    }

    #[test]
    fn default_record_round_trips() {
        let record = PadRecord::new(CalibrationSpec::default());
        let mut buffer = [0u8; MAX_BODY_LEN];
        let length = encode_body(&record, &mut buffer).unwrap();
        assert_eq!(buffer[0], BODY_FORMAT_VERSION);
        assert_eq!(decode_body(&buffer[..length]), Ok(record));
    }
}
