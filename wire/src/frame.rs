//! Framing shared by both directions: `COBS([version][kind][body][CRC-16 LE]) 0x00`.
//! Encoding writes one complete frame, delimiter included; decoding is a byte-at-a-time state
//! machine that never panics and always resynchronises at the next 0x00.

use core::marker::PhantomData;

use serde::{Deserialize, Serialize};

use crate::checksum::crc16;
use crate::command::Request;
use crate::device::{CountersFrame, DeviceFrame, EventFrame, InfoFrame, ReplyFrame};
use crate::error::{DecodeError, EncodeError};
use crate::sample::SampleFrame;
use crate::{kind, PROTOCOL_VERSION};

/// Version byte + kind byte.
pub const HEADER_LEN: usize = 2;

/// The CRC trailer.
pub const CRC_LEN: usize = 2;

/// The largest decoded payload (header + body + CRC) of any frame in either direction.
pub const MAX_PAYLOAD_LEN: usize =
    HEADER_LEN + max(ReplyFrame::MAX_BODY_LEN, Request::MAX_BODY_LEN) + CRC_LEN;

/// The largest encoded frame in either direction, delimiter included; a [`FrameDecoder`] of this
/// size accepts every valid frame.
pub const MAX_FRAME_ENCODED_LEN: usize =
    max(DeviceFrame::MAX_ENCODED_LEN, Request::MAX_ENCODED_LEN);

const fn max(first: usize, second: usize) -> usize {
    if first > second {
        first
    } else {
        second
    }
}

/// The largest encoded frame, delimiter included, for a body of at most `body_len` bytes:
/// COBS adds one byte per started 254 bytes, and the delimiter one more.
pub const fn frame_encoded_len_bound(body_len: usize) -> usize {
    cobs::max_encoding_length(HEADER_LEN + body_len + CRC_LEN) + 1
}

/// A message type that travels in frames: it names its kind byte and (de)serializes its body.
pub trait WireMessage: Sized {
    /// The kind byte of this message.
    fn kind(&self) -> u8;

    /// Writes the body into `body` and returns its length.
    fn write_body(&self, body: &mut [u8]) -> Result<usize, postcard::Error>;

    /// Parses the body of a frame of kind `kind`. Kinds this type does not accept are
    /// [`DecodeError::UnknownKind`]; the whole body must be consumed.
    fn from_body(kind: u8, body: &[u8]) -> Result<Self, DecodeError>;
}

/// Any frame, in either direction: what a decoder that does not know the direction (a sniffer,
/// a test) receives.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Frame {
    /// Device to host.
    Device(DeviceFrame),
    /// Host to device.
    Request(Request),
}

impl Frame {
    /// The largest encoded frame, delimiter included.
    pub const MAX_ENCODED_LEN: usize = MAX_FRAME_ENCODED_LEN;
}

fn write_postcard<T: Serialize>(value: &T, body: &mut [u8]) -> Result<usize, postcard::Error> {
    postcard::to_slice(value, body).map(|written| written.len())
}

fn read_postcard<'de, T: Deserialize<'de>>(body: &'de [u8]) -> Result<T, DecodeError> {
    match postcard::take_from_bytes::<T>(body) {
        Ok((value, [])) => Ok(value),
        Ok(_) => Err(DecodeError::TrailingBytes),
        Err(error) => Err(DecodeError::Postcard(error)),
    }
}

impl WireMessage for DeviceFrame {
    fn kind(&self) -> u8 {
        DeviceFrame::kind(self)
    }

    fn write_body(&self, body: &mut [u8]) -> Result<usize, postcard::Error> {
        match self {
            DeviceFrame::Info(info) => write_postcard(info, body),
            DeviceFrame::Sample(sample) => write_postcard(sample, body),
            DeviceFrame::Counters(counters) => write_postcard(counters, body),
            DeviceFrame::Reply(reply) => write_postcard(reply, body),
            DeviceFrame::Event(event) => write_postcard(event, body),
        }
    }

    fn from_body(kind: u8, body: &[u8]) -> Result<Self, DecodeError> {
        match kind {
            kind::INFO => read_postcard::<InfoFrame>(body).map(DeviceFrame::Info),
            kind::SAMPLE => read_postcard::<SampleFrame>(body).map(DeviceFrame::Sample),
            kind::COUNTERS => read_postcard::<CountersFrame>(body).map(DeviceFrame::Counters),
            kind::REPLY => read_postcard::<ReplyFrame>(body).map(DeviceFrame::Reply),
            kind::EVENT => read_postcard::<EventFrame>(body).map(DeviceFrame::Event),
            other => Err(DecodeError::UnknownKind(other)),
        }
    }
}

impl WireMessage for Request {
    fn kind(&self) -> u8 {
        kind::REQUEST
    }

    fn write_body(&self, body: &mut [u8]) -> Result<usize, postcard::Error> {
        write_postcard(self, body)
    }

    fn from_body(kind: u8, body: &[u8]) -> Result<Self, DecodeError> {
        if kind == kind::REQUEST {
            Request::from_body(body)
        } else {
            Err(DecodeError::UnknownKind(kind))
        }
    }
}

impl WireMessage for Frame {
    fn kind(&self) -> u8 {
        match self {
            Frame::Device(frame) => frame.kind(),
            Frame::Request(request) => WireMessage::kind(request),
        }
    }

    fn write_body(&self, body: &mut [u8]) -> Result<usize, postcard::Error> {
        match self {
            Frame::Device(frame) => frame.write_body(body),
            Frame::Request(request) => request.write_body(body),
        }
    }

    fn from_body(kind: u8, body: &[u8]) -> Result<Self, DecodeError> {
        if kind == kind::REQUEST {
            Request::from_body(body).map(Frame::Request)
        } else {
            DeviceFrame::from_body(kind, body).map(Frame::Device)
        }
    }
}

/// Encodes `message` as one complete frame (COBS bytes and the 0x00 delimiter) into `out` and
/// returns the number of bytes written. `out` of [`MAX_FRAME_ENCODED_LEN`] bytes always suffices.
pub fn encode_frame<M: WireMessage>(message: &M, out: &mut [u8]) -> Result<usize, EncodeError> {
    // MAX_PAYLOAD_LEN holds the header, the largest body and the CRC, so none of the lookups
    // into the payload below can fail; they are checked rather than indexed all the same.
    let mut payload = [0u8; MAX_PAYLOAD_LEN];
    let (header, after_header) = payload
        .split_first_chunk_mut::<HEADER_LEN>()
        .ok_or(EncodeError::BufferTooSmall)?;
    *header = [PROTOCOL_VERSION, message.kind()];
    let body_capacity = after_header.len().saturating_sub(CRC_LEN);
    let body = after_header
        .get_mut(..body_capacity)
        .ok_or(EncodeError::BufferTooSmall)?;
    let body_len = message.write_body(body).map_err(EncodeError::Postcard)?;
    let payload_len = HEADER_LEN + body_len + CRC_LEN;
    let (checked, crc) = payload
        .get_mut(..payload_len)
        .and_then(<[u8]>::split_last_chunk_mut::<CRC_LEN>)
        .ok_or(EncodeError::BufferTooSmall)?;
    *crc = crc16(checked).to_le_bytes();
    let framed = payload
        .get(..payload_len)
        .ok_or(EncodeError::BufferTooSmall)?;
    let encoded_len = cobs::try_encode(framed, out).map_err(|_| EncodeError::BufferTooSmall)?;
    let delimiter = out
        .get_mut(encoded_len)
        .ok_or(EncodeError::BufferTooSmall)?;
    *delimiter = 0;
    Ok(encoded_len + 1)
}

/// Encodes `message` as one complete frame into a new vector (host convenience).
#[cfg(feature = "std")]
pub fn encode_frame_to_vec<M: WireMessage>(message: &M) -> Result<std::vec::Vec<u8>, EncodeError> {
    let mut out = [0u8; MAX_FRAME_ENCODED_LEN];
    let len = encode_frame(message, &mut out)?;
    let encoded = out.get(..len).ok_or(EncodeError::BufferTooSmall)?;
    Ok(encoded.to_vec())
}

/// Decodes one frame in place: `encoded` holds the COBS bytes of one frame, with or without its
/// 0x00 delimiter, and is overwritten by the decoded payload.
pub fn decode_frame<M: WireMessage>(encoded: &mut [u8]) -> Result<M, DecodeError> {
    let encoded = match encoded.split_last_mut() {
        Some((0, rest)) => rest,
        _ => encoded,
    };
    if encoded.is_empty() || encoded.contains(&0) {
        return Err(DecodeError::Cobs);
    }
    let report = cobs::decode_in_place_report(encoded).map_err(|_| DecodeError::Cobs)?;
    if report.parsed_size() != encoded.len() {
        return Err(DecodeError::Cobs);
    }
    let payload = encoded
        .get(..report.frame_size())
        .ok_or(DecodeError::Cobs)?;
    let Some((checked, crc_bytes)) = payload.split_last_chunk::<CRC_LEN>() else {
        return Err(DecodeError::TooShort);
    };
    let Some((&[version, kind], body)) = checked.split_first_chunk::<HEADER_LEN>() else {
        return Err(DecodeError::TooShort);
    };
    if crc16(checked).to_le_bytes() != *crc_bytes {
        return Err(DecodeError::Crc);
    }
    if version != PROTOCOL_VERSION {
        return Err(DecodeError::UnsupportedVersion {
            found: version,
            supported: PROTOCOL_VERSION,
        });
    }
    M::from_body(kind, body)
}

/// A streaming frame decoder holding up to `N` encoded bytes of one frame.
///
/// Feed it every received byte; each 0x00 ends a frame and yields at most one result, so a
/// garbage, truncated, corrupted or oversized frame costs exactly that frame. `M` is the message
/// type accepted: [`DeviceFrame`] on the host, [`Request`] on the device, [`Frame`] for both.
#[derive(Debug, Clone)]
pub struct FrameDecoder<const N: usize, M = Frame> {
    buffer: [u8; N],
    length: usize,
    overflowed: bool,
    message: PhantomData<fn() -> M>,
}

/// The host-side decoder, sized for every device frame.
pub type DeviceFrameDecoder = FrameDecoder<{ DeviceFrame::MAX_ENCODED_LEN }, DeviceFrame>;

/// The device-side decoder, sized for every request.
pub type RequestDecoder = FrameDecoder<{ Request::MAX_ENCODED_LEN }, Request>;

impl<const N: usize, M: WireMessage> Default for FrameDecoder<N, M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize, M: WireMessage> FrameDecoder<N, M> {
    /// An empty decoder.
    pub const fn new() -> Self {
        FrameDecoder {
            buffer: [0; N],
            length: 0,
            overflowed: false,
            message: PhantomData,
        }
    }

    /// Takes one received byte. Returns `Some` when the byte was a delimiter that ended a
    /// non-empty frame; repeated delimiters yield nothing.
    pub fn push(&mut self, byte: u8) -> Option<Result<M, DecodeError>> {
        if byte == 0 {
            let result = if self.overflowed {
                Some(Err(DecodeError::Overflow))
            } else if self.length == 0 {
                None
            } else {
                let length = self.length;
                Some(
                    self.buffer
                        .get_mut(..length)
                        .ok_or(DecodeError::Overflow)
                        .and_then(decode_frame::<M>),
                )
            };
            self.reset();
            return result;
        }
        if !self.overflowed {
            match self.buffer.get_mut(self.length) {
                Some(slot) => {
                    *slot = byte;
                    self.length += 1;
                }
                None => self.overflowed = true,
            }
        }
        None
    }

    /// Takes a chunk of received bytes and yields the result of every frame it completes.
    pub fn feed<'a>(
        &'a mut self,
        bytes: &'a [u8],
    ) -> impl Iterator<Item = Result<M, DecodeError>> + 'a {
        bytes.iter().filter_map(move |&byte| self.push(byte))
    }

    /// Drops any partial frame.
    pub fn reset(&mut self) {
        self.length = 0;
        self.overflowed = false;
    }

    /// The number of bytes of the partial frame held (at most `N`).
    pub fn pending_len(&self) -> usize {
        self.length
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::command::Command;

    #[test]
    fn every_too_small_output_buffer_is_an_error() {
        let request = Request {
            request_id: 0xBEEF,
            command: Command::SetRate {
                rate: crate::SampleRate::Sps400,
            },
        };
        let mut out = [0u8; MAX_FRAME_ENCODED_LEN];
        let len = encode_frame(&request, &mut out).unwrap();
        for size in 0..len {
            let mut small = [0u8; MAX_FRAME_ENCODED_LEN];
            assert_eq!(
                encode_frame(&request, &mut small[..size]),
                Err(EncodeError::BufferTooSmall),
                "size {size}"
            );
        }
        let mut exact = [0u8; MAX_FRAME_ENCODED_LEN];
        assert_eq!(encode_frame(&request, &mut exact[..len]), Ok(len));
        assert_eq!(exact[..len], out[..len]);
    }

    #[cfg(feature = "std")]
    #[test]
    fn vector_encoding_equals_slice_encoding() {
        let request = Request {
            request_id: 1,
            command: Command::Info,
        };
        let mut out = [0u8; MAX_FRAME_ENCODED_LEN];
        let len = encode_frame(&request, &mut out).unwrap();
        assert_eq!(encode_frame_to_vec(&request).unwrap(), out[..len]);
    }
}
