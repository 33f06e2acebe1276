//! Bytes from the host to requests: binary frames, and in text mode the plain line `binary`
//! that a terminal user can type to get back to binary frames.

use wire::{DecodeError, ReplyFrame, Request, RequestDecoder, TextCommand, TextCommandParser};

/// What a received byte completed.
#[derive(Debug, Clone, PartialEq)]
pub enum HostInputEvent {
    /// A well-formed request.
    Request(Request),
    /// A request that could not be executed but whose id is known: send this reply.
    ErrorReply(ReplyFrame),
    /// A frame that could not be decoded and cannot be answered: count it.
    Rejected,
    /// A frame of another protocol version: count it and announce ours (Info frame).
    UnsupportedVersion,
    /// The text line `binary`: leave text mode.
    LeaveTextMode,
}

/// Parses the byte stream from the host; any byte sequence is accepted without panicking.
#[derive(Debug)]
pub struct HostInput {
    decoder: RequestDecoder,
    text: TextCommandParser,
}

impl Default for HostInput {
    fn default() -> Self {
        Self::new()
    }
}

impl HostInput {
    /// A parser with empty buffers.
    pub const fn new() -> Self {
        Self {
            decoder: RequestDecoder::new(),
            text: TextCommandParser::new(),
        }
    }

    /// Feeds one byte.
    pub fn push(&mut self, byte: u8) -> Option<HostInputEvent> {
        if let Some(TextCommand::Binary) = self.text.push(byte) {
            self.decoder.reset();
            return Some(HostInputEvent::LeaveTextMode);
        }
        match self.decoder.push(byte)? {
            Ok(request) => Some(HostInputEvent::Request(request)),
            Err(DecodeError::UnsupportedVersion { .. }) => Some(HostInputEvent::UnsupportedVersion),
            Err(error) => Some(match error.error_reply() {
                Some(wire::DeviceFrame::Reply(reply)) => HostInputEvent::ErrorReply(reply),
                _ => HostInputEvent::Rejected,
            }),
        }
    }
}
