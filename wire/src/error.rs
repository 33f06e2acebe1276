//! Errors of frame encoding and decoding. Decoding errors never stop the stream: the decoder
//! drops the bad frame and continues after the next 0x00 delimiter.

use core::fmt;

use crate::command::ErrorCode;
use crate::device::{DeviceFrame, ReplyFrame};

/// Why a frame could not be encoded.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The output buffer cannot hold the encoded frame and its delimiter.
    BufferTooSmall,
    /// The body did not serialize (only possible for a message larger than [`crate::MAX_PAYLOAD_LEN`]).
    Postcard(postcard::Error),
}

/// Why a frame received between two 0x00 delimiters was rejected.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DecodeError {
    /// The bytes before the delimiter are not a valid COBS encoding (garbage or a truncated frame).
    Cobs,
    /// More bytes arrived before a delimiter than the decoder buffer holds; they were dropped.
    Overflow,
    /// The decoded payload is shorter than version + kind + CRC (4 bytes).
    TooShort,
    /// The CRC does not match: the frame was corrupted.
    Crc,
    /// The frame is intact (CRC correct) but written in another protocol version.
    UnsupportedVersion {
        /// The version byte of the frame.
        found: u8,
        /// The version this decoder understands ([`crate::PROTOCOL_VERSION`]).
        supported: u8,
    },
    /// The kind byte names no frame this decoder accepts.
    UnknownKind(u8),
    /// The body of a known kind did not parse.
    Postcard(postcard::Error),
    /// The body parsed but bytes were left over.
    TrailingBytes,
    /// A request whose request id could be read but whose command could not: the device answers
    /// it with [`DecodeError::error_reply`].
    InvalidRequest {
        /// The request id read from the start of the body.
        request_id: u16,
        /// [`ErrorCode::UnknownCommand`] or [`ErrorCode::Malformed`].
        error: ErrorCode,
    },
}

impl DecodeError {
    /// The reply the device sends for this error, if the request id is known; every other decode
    /// error is a counted drop (there is nobody to answer).
    pub fn error_reply(&self) -> Option<DeviceFrame> {
        match *self {
            DecodeError::InvalidRequest { request_id, error } => {
                Some(DeviceFrame::Reply(ReplyFrame {
                    request_id,
                    result: Err(error),
                }))
            }
            _ => None,
        }
    }
}

impl fmt::Display for EncodeError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EncodeError::BufferTooSmall => formatter.write_str("output buffer too small for frame"),
            EncodeError::Postcard(error) => write!(formatter, "body serialization failed: {error}"),
        }
    }
}

impl fmt::Display for DecodeError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::Cobs => formatter.write_str("invalid COBS encoding"),
            DecodeError::Overflow => formatter.write_str("frame longer than the decoder buffer"),
            DecodeError::TooShort => formatter.write_str("frame shorter than header and CRC"),
            DecodeError::Crc => formatter.write_str("CRC mismatch"),
            DecodeError::UnsupportedVersion { found, supported } => write!(
                formatter,
                "protocol version {found} not supported (this side speaks {supported})"
            ),
            DecodeError::UnknownKind(kind) => write!(formatter, "unknown frame kind {kind:#04x}"),
            DecodeError::Postcard(error) => write!(formatter, "body did not parse: {error}"),
            DecodeError::TrailingBytes => formatter.write_str("bytes left over after the body"),
            DecodeError::InvalidRequest { request_id, error } => {
                write!(formatter, "request {request_id} rejected: {error:?}")
            }
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for EncodeError {}

#[cfg(feature = "std")]
impl std::error::Error for DecodeError {}
