//! A pad's record body, the one definition of what the store keeps for a pad:
//! `[body format version = 1][postcard CalibrationSpec]`, at most [`MAX_BODY_LEN`] bytes.
//!
//! The store frames the body (length, pads, save counter, CRC-32: see the `format` module) and
//! knows nothing of it beyond [`MAX_BODY_LEN`]; this module encodes and decodes it. A body is
//! accepted only if its version is one this firmware reads, it parses completely, and the
//! calibration validates with [`Calibration::new`]: a body that parses into a calibration the
//! model would refuse is as corrupt as one that does not parse. Changing what a body holds means
//! changing this module, [`BODY_FORMAT_VERSION`] and [`MAX_BODY_LEN`].

use core::fmt;

use model_core::calibration::{
    Calibration, CalibrationError, CalibrationSpec, MAX_CURVE_POINTS, MAX_TEMPERATURE_POINTS,
    TAXEL_COUNT,
};

/// The format version of the bodies this firmware writes and reads, their first byte.
pub const BODY_FORMAT_VERSION: u8 = 1;

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

// The one-byte length prefixes above hold only while the capacities stay below 128.
const _: () = assert!(MAX_CURVE_POINTS < 128 && MAX_TEMPERATURE_POINTS < 128);

/// The longest postcard [`CalibrationSpec`]: id (varint, 5), four taxels of 16 points with a
/// calibrated C0 (4 x (1 + 16 x 8 + 4 + 1 + 4) = 552), the temperature law (1 + 8 x 8 + 2 x 4 =
/// 73) and the thresholds (12): 642 bytes.
const MAX_SPEC_LEN: usize =
    VARINT_U32_MAX_LEN + TAXEL_COUNT * TAXEL_MAX_LEN + TEMPERATURE_LAW_MAX_LEN + THRESHOLDS_LEN;

/// The longest body: the version byte and the longest postcard calibration, 643 bytes.
pub const MAX_BODY_LEN: usize = VERSION_LEN + MAX_SPEC_LEN;

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
    /// Decoding: the bytes after the version are not a postcard `CalibrationSpec`.
    Postcard(postcard::Error),
    /// Decoding: the calibration parsed but bytes were left over.
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

/// Writes `spec` as a body at the start of `out` and returns the body's length.
///
/// The calibration is validated first: a spec the model would refuse is never written.
pub fn encode_body(spec: &CalibrationSpec, out: &mut [u8]) -> Result<usize, RecordError> {
    Calibration::new(spec).map_err(RecordError::Invalid)?;
    let (version, spec_space) = out.split_first_mut().ok_or(RecordError::BufferTooSmall)?;
    *version = BODY_FORMAT_VERSION;
    let spec_len = postcard::to_slice(spec, spec_space)
        .map_err(|error| match error {
            postcard::Error::SerializeBufferFull => RecordError::BufferTooSmall,
            other => RecordError::Postcard(other),
        })?
        .len();
    Ok(VERSION_LEN + spec_len)
}

/// Reads a body that fills `bytes` exactly and returns its calibration, validated.
pub fn decode_body(bytes: &[u8]) -> Result<CalibrationSpec, RecordError> {
    if bytes.len() > MAX_BODY_LEN {
        return Err(RecordError::TooLong);
    }
    let (&version, spec) = bytes.split_first().ok_or(RecordError::Empty)?;
    if version != BODY_FORMAT_VERSION {
        return Err(RecordError::UnsupportedVersion { found: version });
    }
    let spec = match postcard::take_from_bytes::<CalibrationSpec>(spec) {
        Ok((spec, [])) => spec,
        Ok(_) => return Err(RecordError::TrailingBytes),
        Err(error) => return Err(RecordError::Postcard(error)),
    };
    Calibration::new(&spec).map_err(RecordError::Invalid)?;
    Ok(spec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maximum_lengths_add_up() {
        assert_eq!(MAX_SPEC_LEN, 642);
        assert_eq!(MAX_BODY_LEN, 643);
    }

    #[test]
    fn default_spec_round_trips() {
        let spec = CalibrationSpec::default();
        let mut buffer = [0u8; MAX_BODY_LEN];
        let length = encode_body(&spec, &mut buffer).unwrap();
        assert_eq!(buffer[0], BODY_FORMAT_VERSION);
        assert_eq!(decode_body(&buffer[..length]), Ok(spec));
    }
}
