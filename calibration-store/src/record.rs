//! The calibration record: `[format version][pad, version 4 only][save counter, u32 LE][postcard
//! body of CalibrationSpec][CRC-32 LE]`.
//!
//! The CRC covers everything before it. A record is accepted only if it
//! is intact (length, CRC), of a version this firmware reads, parses completely, and validates
//! with [`Calibration::new`]: a record that parses into a calibration the model would refuse is
//! as corrupt as one with a bad CRC.
//!
//! Versions:
//! - 4 (written for one pad, [`RecordScope::Pad`]): a version-3 record with the pad's index
//!   (0 to [`MAX_PADS`] - 1) after the version byte. Firmware that reads only version 3 refuses
//!   it (as it refuses anything it does not know), so going back to such firmware boots on the
//!   defaults with the corrupt flag rather than on another pad's calibration.
//! - 3 (written for every pad, [`RecordScope::EveryPad`]): the body is today's [`CalibrationSpec`], whose taxels carry
//!   `unloaded_sensor_pf` (postcard `Option<f32>`: `00`, or `01` and the f32) after
//!   `parasitic_pf`.
//! - 2 (read, never written): the same record with the body as it was before that field existed,
//!   which is the version-3 body of the same calibration without the four `None` tags. It is read
//!   by putting them back and decoding as version 3, so it loads with `unloaded_sensor_pf: None`
//!   on every taxel and a calibration saved by an older firmware survives the update; the next
//!   save writes version 3. (Rewriting the bytes, rather than deserializing a mirror of the old
//!   type, keeps a single `CalibrationSpec` deserializer in the firmware's flash.)
//! - 1 (the same without the save counter) was never shipped and is refused like any other
//!   unknown version.
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

/// The format version of a record for every pad (the one format the single-pad firmware wrote).
pub const RECORD_FORMAT_VERSION: u8 = 3;

/// The format version of a record for one pad: [`RECORD_FORMAT_VERSION`] with the pad's index.
pub const PAD_RECORD_FORMAT_VERSION: u8 = 4;

/// Pads a device can hold a calibration for (the TCA9548A's eight channels).
pub const MAX_PADS: u8 = 8;

/// Which pads a record's calibration is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RecordScope {
    /// Every pad without a newer record of its own (a version-3 record).
    EveryPad,
    /// One pad, by index (0 to [`MAX_PADS`] - 1; a version-4 record).
    Pad(u8),
}

impl RecordScope {
    /// Whether the record's calibration is for `pad`.
    pub fn covers(self, pad: u8) -> bool {
        match self {
            RecordScope::EveryPad => true,
            RecordScope::Pad(own) => own == pad,
        }
    }
}

/// The previous format version, still read: its body has no `unloaded_sensor_pf`.
const VERSION_2: u8 = 2;

/// The record CRC: CRC-32/ISO-HDLC (poly 0x04C11DB7, init and xorout 0xFFFFFFFF, reflected,
/// check value 0xCBF43926), appended little-endian.
pub const RECORD_CRC_ALGORITHM: &Algorithm<u32> = &CRC_32_ISO_HDLC;

const RECORD_CRC: Crc<u32> = Crc::<u32>::new(RECORD_CRC_ALGORITHM);

const VERSION_LEN: usize = 1;
const SAVE_COUNTER_LEN: usize = 4;
const PAD_LEN: usize = 1;
const HEADER_LEN: usize = VERSION_LEN + SAVE_COUNTER_LEN;
const PAD_HEADER_LEN: usize = VERSION_LEN + PAD_LEN + SAVE_COUNTER_LEN;
const CRC_LEN: usize = 4;
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

/// The longest postcard body of a [`CalibrationSpec`]: id (varint, 5), four taxels of 16 points
/// with a calibrated C0 (4 x (1 + 16 x 8 + 4 + 1 + 4) = 552), the temperature law
/// (1 + 8 x 8 + 2 x 4 = 73) and the thresholds (12): 642 bytes. A version-2 body is 20 bytes
/// shorter at most.
pub const MAX_BODY_LEN: usize =
    VARINT_U32_MAX_LEN + TAXEL_COUNT * TAXEL_MAX_LEN + TEMPERATURE_LAW_MAX_LEN + THRESHOLDS_LEN;

/// The longest record: version + pad + save counter + [`MAX_BODY_LEN`] + CRC = 652 bytes.
pub const MAX_RECORD_LEN: usize = PAD_HEADER_LEN + MAX_BODY_LEN + CRC_LEN;

/// A decoded record: the calibration, which pads it is for and the save counter it was written
/// with.
#[derive(Debug, Clone, PartialEq)]
pub struct SavedRecord {
    /// The save counter: higher is newer.
    pub save_counter: u32,
    /// The pads the calibration is for.
    pub scope: RecordScope,
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
    /// Decoding: the body is intact but is not a postcard `CalibrationSpec` (in the layout of the
    /// record's version).
    Postcard(postcard::Error),
    /// Decoding: the body parsed but bytes were left over before the CRC.
    TrailingBytes,
    /// A pad index of [`MAX_PADS`] or more: refused before encoding, or found in a record.
    PadOutOfRange {
        /// The pad index.
        pad: u8,
    },
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
            RecordError::PadOutOfRange { pad } => {
                write!(
                    formatter,
                    "pad {pad} out of range (at most {MAX_PADS} pads)"
                )
            }
            RecordError::Invalid(error) => write!(formatter, "invalid calibration: {error:?}"),
        }
    }
}

impl core::error::Error for RecordError {}

/// Writes `spec` with `save_counter` as a record for every pad (version 3) at the start of `out`
/// and returns the record's length.
///
/// The calibration is validated first: a spec the model would refuse is never written.
pub fn encode_record(
    spec: &CalibrationSpec,
    save_counter: u32,
    out: &mut [u8],
) -> Result<usize, RecordError> {
    encode_scoped_record(RecordScope::EveryPad, spec, save_counter, out)
}

/// Writes `spec` with `save_counter` as a record for `scope` at the start of `out` (version 3
/// for every pad, version 4 for one pad) and returns the record's length.
///
/// The calibration and the pad index are validated first: nothing invalid is ever written.
pub fn encode_scoped_record(
    scope: RecordScope,
    spec: &CalibrationSpec,
    save_counter: u32,
    out: &mut [u8],
) -> Result<usize, RecordError> {
    Calibration::new(spec).map_err(RecordError::Invalid)?;
    let header_len = match scope {
        RecordScope::EveryPad => {
            let version = out.first_mut().ok_or(RecordError::BufferTooSmall)?;
            *version = RECORD_FORMAT_VERSION;
            HEADER_LEN
        }
        RecordScope::Pad(pad) if pad >= MAX_PADS => {
            return Err(RecordError::PadOutOfRange { pad });
        }
        RecordScope::Pad(pad) => {
            let (version_and_pad, _) = out
                .split_first_chunk_mut::<2>()
                .ok_or(RecordError::BufferTooSmall)?;
            *version_and_pad = [PAD_RECORD_FORMAT_VERSION, pad];
            PAD_HEADER_LEN
        }
    };
    let counter_at = header_len - SAVE_COUNTER_LEN;
    out.get_mut(counter_at..header_len)
        .ok_or(RecordError::BufferTooSmall)?
        .copy_from_slice(&save_counter.to_le_bytes());
    let body_space = out
        .get_mut(header_len..)
        .ok_or(RecordError::BufferTooSmall)?;
    let body_len = postcard::to_slice(spec, body_space)
        .map_err(|error| match error {
            postcard::Error::SerializeBufferFull => RecordError::BufferTooSmall,
            other => RecordError::Postcard(other),
        })?
        .len();
    let record_len = header_len + body_len + CRC_LEN;
    let (checked, crc) = out
        .get_mut(..record_len)
        .and_then(<[u8]>::split_last_chunk_mut::<CRC_LEN>)
        .ok_or(RecordError::BufferTooSmall)?;
    *crc = RECORD_CRC.checksum(checked).to_le_bytes();
    Ok(record_len)
}

/// The scope, save counter, version and body of a record without its CRC.
fn split_header(checked: &[u8]) -> Result<(RecordScope, u32, u8, &[u8]), RecordError> {
    let (&version, rest) = checked.split_first().ok_or(RecordError::TooShort)?;
    let (scope, rest) = match version {
        PAD_RECORD_FORMAT_VERSION => {
            let (&pad, rest) = rest.split_first().ok_or(RecordError::TooShort)?;
            if pad >= MAX_PADS {
                return Err(RecordError::PadOutOfRange { pad });
            }
            (RecordScope::Pad(pad), rest)
        }
        RECORD_FORMAT_VERSION | VERSION_2 => (RecordScope::EveryPad, rest),
        found => return Err(RecordError::UnsupportedVersion { found }),
    };
    let (counter, body) = rest
        .split_first_chunk::<SAVE_COUNTER_LEN>()
        .ok_or(RecordError::TooShort)?;
    Ok((scope, u32::from_le_bytes(*counter), version, body))
}

/// Reads a record that fills `bytes` exactly and returns its calibration, validated.
pub fn decode_record(bytes: &[u8]) -> Result<CalibrationSpec, RecordError> {
    decode_saved_record(bytes).map(|record| record.spec)
}

/// Reads a record that fills `bytes` exactly and returns its save counter, its scope and its
/// calibration, validated.
pub fn decode_saved_record(bytes: &[u8]) -> Result<SavedRecord, RecordError> {
    let (checked, crc_bytes) = bytes
        .split_last_chunk::<CRC_LEN>()
        .ok_or(RecordError::TooShort)?;
    if checked.len() < HEADER_LEN {
        return Err(RecordError::TooShort);
    }
    if RECORD_CRC.checksum(checked) != u32::from_le_bytes(*crc_bytes) {
        return Err(RecordError::BadCrc);
    }
    let (scope, save_counter, version, body) = split_header(checked)?;
    let mut upgraded = [0u8; MAX_BODY_LEN];
    let body = if version == VERSION_2 {
        version_3_body(body, &mut upgraded)?
    } else {
        body
    };
    let spec = take_body(body)?;
    Calibration::new(&spec).map_err(RecordError::Invalid)?;
    Ok(SavedRecord {
        save_counter,
        scope,
        spec,
    })
}

/// The whole body as one calibration.
fn take_body(body: &[u8]) -> Result<CalibrationSpec, RecordError> {
    match postcard::take_from_bytes::<CalibrationSpec>(body) {
        Ok((spec, [])) => Ok(spec),
        Ok(_) => Err(RecordError::TrailingBytes),
        Err(error) => Err(RecordError::Postcard(error)),
    }
}

/// Writes into `out` the version-3 body of the calibration in the version-2 `body` and returns
/// it. Version 2 lacked only each taxel's `unloaded_sensor_pf`, so this is `body` with a `00`
/// (None) after each taxel's parasitic capacitance; postcard itself reads the id and the point
/// counts that locate them. What follows the taxels is copied unchecked: the version-3 decoder
/// checks it, as it does for a version-3 record.
fn version_3_body<'out>(
    body: &[u8],
    out: &'out mut [u8; MAX_BODY_LEN],
) -> Result<&'out [u8], RecordError> {
    const TRUNCATED: RecordError = RecordError::Postcard(postcard::Error::DeserializeUnexpectedEnd);
    // A valid version-2 body is 20 bytes shorter than MAX_BODY_LEN at most, so a body that does
    // not fit once the tags are added can only have bytes after the calibration.
    const TOO_LONG: RecordError = RecordError::TrailingBytes;
    let (_id, mut rest) = postcard::take_from_bytes::<u32>(body).map_err(RecordError::Postcard)?;
    let mut taxel_ends = [0usize; TAXEL_COUNT];
    for taxel_end in &mut taxel_ends {
        // A sequence length is a varint usize, which on the firmware's target is a u32 (serde's
        // usize would be read as a u64 varint, with 64-bit shifts the firmware does not need).
        let (point_count, points) =
            postcard::take_from_bytes::<u32>(rest).map_err(RecordError::Postcard)?;
        let point_count = point_count as usize;
        if point_count > MAX_CURVE_POINTS {
            // What the version-3 decoder reports for a curve longer than its capacity.
            return Err(RecordError::Postcard(postcard::Error::SerdeDeCustom));
        }
        rest = points
            .get(point_count * POINT_LEN + F32_LEN..)
            .ok_or(TRUNCATED)?;
        *taxel_end = body.len() - rest.len();
    }
    let mut written = 0;
    let mut start = 0;
    for end in taxel_ends {
        let taxel = body.get(start..end).ok_or(TRUNCATED)?;
        let (none_tag, destination) = out
            .get_mut(written..=written + taxel.len())
            .and_then(<[u8]>::split_last_mut)
            .ok_or(TOO_LONG)?;
        destination.copy_from_slice(taxel);
        *none_tag = 0;
        written += taxel.len() + 1;
        start = end;
    }
    let tail = body.get(start..).ok_or(TRUNCATED)?;
    let length = written + tail.len();
    out.get_mut(written..length)
        .ok_or(TOO_LONG)?
        .copy_from_slice(tail);
    out.get(..length).ok_or(TOO_LONG)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maximum_lengths_add_up() {
        assert_eq!(MAX_BODY_LEN, 642);
        assert_eq!(MAX_RECORD_LEN, 652);
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
                scope: RecordScope::EveryPad,
                spec: spec.clone()
            })
        );
        let length = encode_scoped_record(RecordScope::Pad(5), &spec, 8, &mut buffer).unwrap();
        assert_eq!(&buffer[..2], &[PAD_RECORD_FORMAT_VERSION, 5]);
        assert_eq!(
            decode_saved_record(&buffer[..length]),
            Ok(SavedRecord {
                save_counter: 8,
                scope: RecordScope::Pad(5),
                spec
            })
        );
        assert_eq!(
            encode_scoped_record(
                RecordScope::Pad(MAX_PADS),
                &CalibrationSpec::default(),
                0,
                &mut buffer
            ),
            Err(RecordError::PadOutOfRange { pad: MAX_PADS })
        );
    }
}
