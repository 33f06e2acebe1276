//! The calibration record: `[format version][save counter, u32 LE][postcard body of
//! CalibrationSpec][CRC-32 LE]`.
//!
//! The CRC covers the version byte, the save counter and the body. A record is accepted only if it
//! is intact (length, CRC), of the current version, parses completely, and validates with
//! [`Calibration::new`]: a record that parses into a calibration the model would refuse is as
//! corrupt as one with a bad CRC. Version 1 (the same without the save counter) was never shipped
//! and is refused like any other unknown version.
//!
//! The save counter orders records independently of where the flash layer put them: the store
//! gives every save the highest counter it can read plus one, and loads the valid record with the
//! highest counter.

use core::fmt;

use crc::{Algorithm, Crc, CRC_32_ISO_HDLC};
use model_core::calibration::{
    Calibration, CalibrationError, CalibrationSpec, MAX_CURVE_POINTS, MAX_TEMPERATURE_POINTS,
    TAXEL_COUNT,
};

/// The format version written in the first byte of every record.
pub const RECORD_FORMAT_VERSION: u8 = 2;

/// The record CRC: CRC-32/ISO-HDLC (poly 0x04C11DB7, init and xorout 0xFFFFFFFF, reflected,
/// check value 0xCBF43926), appended little-endian.
pub const RECORD_CRC_ALGORITHM: &Algorithm<u32> = &CRC_32_ISO_HDLC;

const RECORD_CRC: Crc<u32> = Crc::<u32>::new(RECORD_CRC_ALGORITHM);

const VERSION_LEN: usize = 1;
const SAVE_COUNTER_LEN: usize = 4;
const HEADER_LEN: usize = VERSION_LEN + SAVE_COUNTER_LEN;
const CRC_LEN: usize = 4;
const F32_LEN: usize = 4;
/// postcard writes a u32 as a varint: 7 bits per byte, so up to 5 bytes.
const VARINT_U32_MAX_LEN: usize = 5;
/// postcard prefixes a sequence with its length as a varint; lengths up to 127 take one byte.
const SEQUENCE_LENGTH_LEN: usize = 1;
const POINT_LEN: usize = 2 * F32_LEN;
const TAXEL_MAX_LEN: usize = SEQUENCE_LENGTH_LEN + MAX_CURVE_POINTS * POINT_LEN + F32_LEN;
const TEMPERATURE_LAW_MAX_LEN: usize =
    SEQUENCE_LENGTH_LEN + MAX_TEMPERATURE_POINTS * POINT_LEN + 2 * F32_LEN;
const THRESHOLDS_LEN: usize = 3 * F32_LEN;

// The one-byte length prefixes above hold only while the capacities stay below 128.
const _: () = assert!(MAX_CURVE_POINTS < 128 && MAX_TEMPERATURE_POINTS < 128);

/// The longest postcard body of a [`CalibrationSpec`]: id (varint, 5), four taxels of 16 points
/// (4 x (1 + 16 x 8 + 4) = 532), the temperature law (1 + 8 x 8 + 2 x 4 = 73) and the thresholds
/// (12): 622 bytes.
pub const MAX_BODY_LEN: usize =
    VARINT_U32_MAX_LEN + TAXEL_COUNT * TAXEL_MAX_LEN + TEMPERATURE_LAW_MAX_LEN + THRESHOLDS_LEN;

/// The longest record: version + save counter + [`MAX_BODY_LEN`] + CRC = 631 bytes.
pub const MAX_RECORD_LEN: usize = HEADER_LEN + MAX_BODY_LEN + CRC_LEN;

/// A decoded record: the calibration and the save counter it was written with.
#[derive(Debug, Clone, PartialEq)]
pub struct SavedRecord {
    /// The save counter: higher is newer.
    pub save_counter: u32,
    /// The calibration, validated.
    pub spec: CalibrationSpec,
}

#[cfg(feature = "defmt")]
impl defmt::Format for SavedRecord {
    fn format(&self, formatter: defmt::Formatter) {
        defmt::write!(
            formatter,
            "SavedRecord(save {=u32}, id {=u32})",
            self.save_counter,
            self.spec.id
        );
    }
}

/// Why a record could not be written or read.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RecordError {
    /// Encoding: the output buffer is shorter than the record ([`MAX_RECORD_LEN`] always fits).
    BufferTooSmall,
    /// Decoding: fewer bytes than a version, a save counter, an empty body and a CRC.
    TooShort,
    /// Decoding: the CRC does not match; the record was corrupted or torn.
    BadCrc,
    /// Decoding: the record is intact but written in a format this firmware does not know.
    UnsupportedVersion {
        /// The version byte found.
        found: u8,
    },
    /// Decoding: the body is intact but is not a postcard `CalibrationSpec`.
    Postcard(postcard::Error),
    /// Decoding: the body parsed but bytes were left over before the CRC.
    TrailingBytes,
    /// The calibration does not validate: refused before encoding, or found in a record.
    Invalid(CalibrationError),
}

impl fmt::Display for RecordError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RecordError::BufferTooSmall => write!(formatter, "record buffer too small"),
            RecordError::TooShort => write!(formatter, "record too short"),
            RecordError::BadCrc => write!(formatter, "record CRC mismatch"),
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

/// Writes `spec` with `save_counter` as a record at the start of `out` and returns the record's
/// length.
///
/// The calibration is validated first: a spec the model would refuse is never written.
pub fn encode_record(
    spec: &CalibrationSpec,
    save_counter: u32,
    out: &mut [u8],
) -> Result<usize, RecordError> {
    Calibration::new(spec).map_err(RecordError::Invalid)?;
    let (header, body_space) = out
        .split_first_chunk_mut::<HEADER_LEN>()
        .ok_or(RecordError::BufferTooSmall)?;
    header[0] = RECORD_FORMAT_VERSION;
    header[VERSION_LEN..].copy_from_slice(&save_counter.to_le_bytes());
    let body_len = postcard::to_slice(spec, body_space)
        .map_err(|error| match error {
            postcard::Error::SerializeBufferFull => RecordError::BufferTooSmall,
            other => RecordError::Postcard(other),
        })?
        .len();
    let record_len = HEADER_LEN + body_len + CRC_LEN;
    let (checked, crc) = out
        .get_mut(..record_len)
        .and_then(<[u8]>::split_last_chunk_mut::<CRC_LEN>)
        .ok_or(RecordError::BufferTooSmall)?;
    *crc = RECORD_CRC.checksum(checked).to_le_bytes();
    Ok(record_len)
}

/// Reads a record that fills `bytes` exactly and returns its calibration, validated.
pub fn decode_record(bytes: &[u8]) -> Result<CalibrationSpec, RecordError> {
    decode_saved_record(bytes).map(|record| record.spec)
}

/// Reads a record that fills `bytes` exactly and returns its save counter and its calibration,
/// validated.
pub fn decode_saved_record(bytes: &[u8]) -> Result<SavedRecord, RecordError> {
    let (checked, crc_bytes) = bytes
        .split_last_chunk::<CRC_LEN>()
        .ok_or(RecordError::TooShort)?;
    let (header, body) = checked
        .split_first_chunk::<HEADER_LEN>()
        .ok_or(RecordError::TooShort)?;
    if RECORD_CRC.checksum(checked) != u32::from_le_bytes(*crc_bytes) {
        return Err(RecordError::BadCrc);
    }
    let [version, counter @ ..] = *header;
    if version != RECORD_FORMAT_VERSION {
        return Err(RecordError::UnsupportedVersion { found: version });
    }
    let (spec, rest) =
        postcard::take_from_bytes::<CalibrationSpec>(body).map_err(RecordError::Postcard)?;
    if !rest.is_empty() {
        return Err(RecordError::TrailingBytes);
    }
    Calibration::new(&spec).map_err(RecordError::Invalid)?;
    Ok(SavedRecord {
        save_counter: u32::from_le_bytes(counter),
        spec,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maximum_lengths_add_up() {
        assert_eq!(MAX_BODY_LEN, 622);
        assert_eq!(MAX_RECORD_LEN, 631);
    }

    #[test]
    fn crc_is_the_catalogued_iso_hdlc() {
        assert_eq!(RECORD_CRC.checksum(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn default_spec_round_trips() {
        let spec = CalibrationSpec::default();
        let mut buffer = [0u8; MAX_RECORD_LEN];
        let length = encode_record(&spec, 7, &mut buffer).unwrap();
        assert_eq!(
            decode_saved_record(&buffer[..length]),
            Ok(SavedRecord {
                save_counter: 7,
                spec
            })
        );
    }
}
