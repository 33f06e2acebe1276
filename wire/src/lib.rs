//! The byte-level protocol between the taxel pad and its host: frames, commands and their
//! encoding, shared unchanged by the firmware (no_std, no allocation) and the host tools.
//!
//! Every frame on the byte stream, in either direction, is
//! `COBS([version][kind][postcard body][CRC-16 little-endian]) 0x00`; see [`encode_frame`],
//! [`FrameDecoder`] and `docs/PROTOCOL.md` for the complete byte layout.
//!
//! - Device to host: [`DeviceFrame`] (info, samples, counters, replies, events).
//! - Host to device: [`Request`] = request id + [`Command`].
//! - Text mode: [`format_csv_line`] and [`TextCommandParser`].
//! - USB CDC-ACM packet rule: [`needs_zero_length_packet`].
#![no_std]
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

#[cfg(feature = "std")]
extern crate std;

mod checksum;
mod command;
mod device;
mod error;
pub mod flags;
mod frame;
mod sample;
#[cfg(feature = "testing")]
pub mod testing;
mod text;
mod usb;

pub use checksum::{crc16, CRC_ALGORITHM};
pub use command::{
    Command, ErrorCode, PadGeometryRecord, Request, SampleRate, TaxelCalibrationRecord,
    TaxelCalibrationWire, Tier, UseCase, CALIBRATION_POINTS_MAX, COMMAND_COUNT,
};
pub use device::{
    BaselineWire, CalibrationSource, CountersFrame, DeviceEvent, DeviceFrame, EventFrame,
    FirmwareVersion, InfoFrame, PadInfoFrame, ReplyFrame, ReplyPayload, TaxelBaselineWire,
    TemperatureSensor,
};
pub use error::{DecodeError, EncodeError};
pub use frame::{
    decode_frame, encode_frame, frame_encoded_len_bound, DeviceFrameDecoder, Frame, FrameDecoder,
    RequestDecoder, WireMessage, CRC_LEN, HEADER_LEN, MAX_FRAME_ENCODED_LEN, MAX_PAYLOAD_LEN,
};
pub use model_core::{PadGeometry, PadRole, TaxelGeometry};
pub use sample::{PadIndex, PadSummary, SampleFrame, TaxelSample, TemperatureSource};
pub use text::{
    format_csv_line, CsvLineTooLong, TextCommand, TextCommandParser, CSV_HEADER, CSV_LINE_MAX_LEN,
    TEXT_COMMAND_LINE_MAX_LEN,
};
pub use usb::{needs_zero_length_packet, usb_packets, USB_FULL_SPEED_PACKET_LEN};

#[cfg(feature = "std")]
pub use frame::encode_frame_to_vec;

/// The body (de)serialization error carried by [`DecodeError::Postcard`] and [`EncodeError::Postcard`].
pub use postcard::Error as PostcardError;

/// The protocol version carried in the first byte of every frame payload.
///
/// A decoder that sees another value reports [`DecodeError::UnsupportedVersion`]. Version 2
/// added `unloaded_sensor_pf` to [`TaxelCalibrationWire`], which changes the body of
/// `WriteCalibration` and of the calibration reply; postcard bodies carry no field names, so a
/// version-1 peer could not tell, and every frame of version 2 says so instead. Version 3 made
/// the device several pads: a sample frame per pad with its index, force, centre of pressure
/// and contact; contact events; the pad count in the info frame. Version 4 added the device
/// clock's rate to the info frame; version 5 each pad's role and geometry to `PadInfo` and the
/// `SetPadGeometry` command; version 6 the pad to tare (or every pad) to the `Tare` command.
pub const PROTOCOL_VERSION: u8 = 6;

/// The number of taxels on the pad: C11, C12, C21, C22 in this order (row, column).
pub const TAXEL_COUNT: usize = 4;

/// The frame kind byte (second payload byte) of every frame type.
pub mod kind {
    /// [`crate::DeviceFrame::Info`]: device identity and state.
    pub const INFO: u8 = 0x01;
    /// [`crate::DeviceFrame::Sample`]: one sample set of the four taxels.
    pub const SAMPLE: u8 = 0x02;
    /// [`crate::DeviceFrame::Counters`]: health counters.
    pub const COUNTERS: u8 = 0x03;
    /// [`crate::DeviceFrame::Reply`]: the answer to a [`crate::Request`].
    pub const REPLY: u8 = 0x04;
    /// [`crate::DeviceFrame::Event`]: an asynchronous device event.
    pub const EVENT: u8 = 0x05;
    /// [`crate::Request`]: a command from the host (bit 7 set = host to device).
    pub const REQUEST: u8 = 0x80;
}
