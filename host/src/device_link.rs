//! The link to a taxel pad: finding attached boards by USB VID:PID and serial number, opening
//! the serial port (DTR asserted, so the device starts sending), decoding frames with
//! resynchronisation, sending requests and matching their replies.
//!
//! [`DeviceLink`] is generic over `Read + Write`, so the same code runs over a serial port, a
//! pseudo-terminal or an in-memory stream in tests. [`FrameReceiver`] is the decoding half on
//! its own (used for raw byte logs).

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::time::{Duration, Instant};

use wire::{
    encode_frame_to_vec, Command, DeviceFrame, EncodeError, ErrorCode, InfoFrame, ReplyFrame,
    ReplyPayload, Request,
};

pub use crate::frame_receiver::{FrameReceiver, LinkStatistics};

/// The pad's USB vendor id (pid.codes).
pub const DEFAULT_VID: u16 = 0x1209;
/// The pad's USB product id.
pub const DEFAULT_PID: u16 = 0x0001;

/// Parses a USB id written in hexadecimal, with or without `0x`.
pub fn parse_hex_u16(text: &str) -> Result<u16, String> {
    let digits = text
        .trim()
        .trim_start_matches("0x")
        .trim_start_matches("0X");
    u16::from_str_radix(digits, 16).map_err(|_| format!("'{text}' is not a 16-bit hex number"))
}

/// Frames kept for the caller while a request waits for its reply; older ones are dropped (and
/// counted) beyond this.
pub const QUEUE_CAPACITY: usize = 65_536;

/// Why the link failed (the transport, not the device's answer).
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// Listing the serial ports failed.
    #[error("listing serial ports: {0}")]
    Enumerate(serialport::Error),
    /// No board with the VID:PID is attached.
    #[error("no board attached (looked for USB {vid:04x}:{pid:04x})")]
    NoBoard {
        /// Vendor id looked for.
        vid: u16,
        /// Product id looked for.
        pid: u16,
    },
    /// No attached board has this serial number.
    #[error("no attached board has serial number {serial_number} (attached: {attached})")]
    SerialNumberNotFound {
        /// The serial number asked for.
        serial_number: String,
        /// The attached boards, for the message.
        attached: String,
    },
    /// Several boards are attached and none was chosen.
    #[error("{count} boards attached, choose one by port or with --serial: {attached}")]
    SeveralBoards {
        /// How many.
        count: usize,
        /// Port and serial number of each.
        attached: String,
    },
    /// The port path does not exist (the board is unplugged).
    #[error("{path} does not exist (unplugged?)")]
    PortMissing {
        /// The port.
        path: String,
    },
    /// The path is not a serial port (a regular file, a directory, /dev/null).
    #[error("{path} is not a serial port ({what}); give the board's port (see `taxel list`) or a simulated device's terminal (see `taxel sim`)")]
    NotSerialPort {
        /// The path.
        path: String,
        /// What it is instead.
        what: String,
    },
    /// The serial port could not be opened or configured.
    #[error("opening {path}: {description}")]
    Open {
        /// The port.
        path: String,
        /// The cause, as the serial library says it.
        description: String,
    },
    /// The stream ended: the device was unplugged or the port closed.
    #[error("the device closed the connection (unplugged?)")]
    Disconnected,
    /// Reading from or writing to the port failed.
    #[error("serial I/O: {0}")]
    Io(io::Error),
    /// Writing the raw byte log failed.
    #[error("writing the raw byte log: {0}")]
    RawLog(io::Error),
    /// A request could not be encoded.
    #[error("encoding a request: {0}")]
    Encode(EncodeError),
}

/// Why a request got no successful answer: the transport failed, nobody answered in time, or the
/// device said no.
#[derive(Debug, thiserror::Error)]
pub enum RequestError {
    /// The link failed.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// No reply with the request id arrived in time.
    #[error("no reply to request {request_id} within {timeout_ms} ms")]
    Timeout {
        /// The request id sent.
        request_id: u16,
        /// The timeout.
        timeout_ms: u128,
    },
    /// The device answered with an error code.
    #[error("the device refused the request: {0:?}")]
    Refused(ErrorCode),
    /// The device answered with a payload of another kind.
    #[error("the device answered {0} with a reply of another kind")]
    UnexpectedReply(&'static str),
    /// No reply came, and the device sends frames of a protocol version this host does not
    /// speak.
    #[error(
        "the device speaks protocol version {found} and this host tool version {supported}: update the firmware or the host tool so that both match"
    )]
    OtherProtocolVersion {
        /// The device's version.
        found: u8,
        /// This host's version.
        supported: u8,
    },
}

/// One attached board.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BoardPort {
    /// The serial port path (e.g. a ttyACM device).
    pub port_name: String,
    /// USB vendor id.
    pub vid: u16,
    /// USB product id.
    pub pid: u16,
    /// USB serial number string.
    pub serial_number: Option<String>,
    /// USB manufacturer string.
    pub manufacturer: Option<String>,
    /// USB product string.
    pub product: Option<String>,
}

impl BoardPort {
    fn describe(&self) -> String {
        format!(
            "{} (serial {})",
            self.port_name,
            self.serial_number.as_deref().unwrap_or("unknown")
        )
    }
}

fn describe_all(boards: &[BoardPort]) -> String {
    if boards.is_empty() {
        "none".to_owned()
    } else {
        boards
            .iter()
            .map(BoardPort::describe)
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Boards attached by USB with this VID:PID, sorted by port name.
pub fn attached_boards(vid: u16, pid: u16) -> Result<Vec<BoardPort>, LinkError> {
    let ports = serialport::available_ports().map_err(LinkError::Enumerate)?;
    let mut boards: Vec<BoardPort> = ports
        .into_iter()
        .filter_map(|port| match port.port_type {
            serialport::SerialPortType::UsbPort(usb) if usb.vid == vid && usb.pid == pid => {
                Some(BoardPort {
                    port_name: port.port_name,
                    vid: usb.vid,
                    pid: usb.pid,
                    serial_number: usb.serial_number,
                    manufacturer: usb.manufacturer,
                    product: usb.product,
                })
            }
            _ => None,
        })
        .collect();
    boards.sort_by(|first, second| first.port_name.cmp(&second.port_name));
    Ok(boards)
}

/// Chooses among attached boards: the one with `serial_number` if given (case-insensitive),
/// else the only one.
pub fn choose_board(
    boards: &[BoardPort],
    serial_number: Option<&str>,
    vid: u16,
    pid: u16,
) -> Result<BoardPort, LinkError> {
    if let Some(wanted) = serial_number {
        return boards
            .iter()
            .find(|board| {
                board
                    .serial_number
                    .as_deref()
                    .is_some_and(|serial| serial.eq_ignore_ascii_case(wanted.trim()))
            })
            .cloned()
            .ok_or_else(|| LinkError::SerialNumberNotFound {
                serial_number: wanted.to_owned(),
                attached: describe_all(boards),
            });
    }
    match boards {
        [] => Err(LinkError::NoBoard { vid, pid }),
        [only] => Ok(only.clone()),
        several => Err(LinkError::SeveralBoards {
            count: several.len(),
            attached: describe_all(several),
        }),
    }
}

/// The port to open: `path` if given, else the attached board chosen by [`choose_board`].
pub fn select_port(
    path: Option<&str>,
    serial_number: Option<&str>,
    vid: u16,
    pid: u16,
) -> Result<String, LinkError> {
    match path {
        Some(path) => Ok(path.to_owned()),
        None => {
            let boards = attached_boards(vid, pid)?;
            choose_board(&boards, serial_number, vid, pid).map(|board| board.port_name)
        }
    }
}

/// A serial port opened by [`open_serial`].
pub struct OpenedPort {
    /// The port, readable and writable.
    pub port: Box<dyn serialport::SerialPort>,
    /// Why DTR could not be asserted, if it could not. Pseudo-terminals (a simulated device)
    /// have no modem-control lines, so this is not fatal; a real board that does not see DTR
    /// stays silent, which the first request's timeout then reports.
    pub dtr_error: Option<serialport::Error>,
}

/// Opens a serial port with a read timeout and asserts DTR (the device only sends to an open
/// port). The baud rate is irrelevant for CDC-ACM.
pub fn open_serial(path: &str, read_timeout: Duration) -> Result<OpenedPort, LinkError> {
    check_is_serial_port(path)?;
    let mut port = serialport::new(path, 115_200)
        .timeout(read_timeout)
        .open()
        .map_err(|source| {
            if source.description.contains("typewriter") {
                // ENOTTY: a character device that is not a terminal, such as /dev/null.
                LinkError::NotSerialPort {
                    path: path.to_owned(),
                    what: "a device that is not a terminal".to_owned(),
                }
            } else {
                LinkError::Open {
                    path: path.to_owned(),
                    description: source.description,
                }
            }
        })?;
    let dtr_error = port.write_data_terminal_ready(true).err();
    Ok(OpenedPort { port, dtr_error })
}

/// Refuses, before trying to open it, a path that cannot be a serial port: a missing path, a
/// regular file or a directory.
pub fn check_is_serial_port(path: &str) -> Result<(), LinkError> {
    let metadata = std::fs::metadata(path).map_err(|_| LinkError::PortMissing {
        path: path.to_owned(),
    })?;
    let what = if metadata.is_dir() {
        Some("a directory")
    } else if metadata.is_file() {
        Some("a regular file")
    } else {
        None
    };
    match what {
        Some(what) => Err(LinkError::NotSerialPort {
            path: path.to_owned(),
            what: what.to_owned(),
        }),
        None => Ok(()),
    }
}

/// Requests sent and not yet answered whose replies are kept for [`DeviceLink::wait_reply`];
/// beyond this the oldest is forgotten (its reply, if it comes, is an ordinary frame).
pub const AWAITED_CAPACITY: usize = 16;

/// A link to one device over any byte stream. It is the host's one matcher of requests and
/// replies: the reply to a request sent here is kept for [`DeviceLink::wait_reply`] (and
/// [`DeviceLink::request`]), never handed out by [`DeviceLink::next_frame`], whoever reads the
/// stream meanwhile.
pub struct DeviceLink<P> {
    port: P,
    receiver: FrameReceiver,
    frames: VecDeque<DeviceFrame>,
    frames_dropped_from_queue: u64,
    raw_log: Option<Box<dyn Write + Send>>,
    next_request_id: u16,
    read_buffer: Vec<u8>,
    awaited: VecDeque<u16>,
    replies: VecDeque<ReplyFrame>,
}

impl<P: Read + Write> DeviceLink<P> {
    /// A link over an open port (for a serial port, see [`open_serial`]).
    pub fn new(port: P) -> Self {
        Self {
            port,
            receiver: FrameReceiver::new(),
            frames: VecDeque::new(),
            frames_dropped_from_queue: 0,
            raw_log: None,
            next_request_id: 1,
            read_buffer: vec![0; 4096],
            awaited: VecDeque::new(),
            replies: VecDeque::new(),
        }
    }

    /// Copies every received byte, as received, to `log`.
    pub fn set_raw_log(&mut self, log: Box<dyn Write + Send>) {
        self.raw_log = Some(log);
    }

    /// Takes the raw byte log back (to flush and close it).
    pub fn take_raw_log(&mut self) -> Option<Box<dyn Write + Send>> {
        self.raw_log.take()
    }

    /// Flushes the raw byte log.
    pub fn flush_raw_log(&mut self) -> Result<(), LinkError> {
        match self.raw_log.as_mut() {
            Some(log) => log.flush().map_err(LinkError::RawLog),
            None => Ok(()),
        }
    }

    /// The port.
    pub fn port(&self) -> &P {
        &self.port
    }

    /// The port, mutably.
    pub fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }

    /// Gives the port back.
    pub fn into_port(self) -> P {
        self.port
    }

    /// Decoding counters.
    pub fn statistics(&self) -> &LinkStatistics {
        self.receiver.statistics()
    }

    /// How many pads the device reads, once its Info has been seen (see [`FrameReceiver`]).
    pub fn pad_count(&self) -> Option<u8> {
        self.receiver.pad_count()
    }

    /// Takes the device's pad count as known (from an Info frame read elsewhere, or a test's
    /// fake device), so that what depends on it does not ask the device.
    pub fn set_pad_count(&mut self, pad_count: u8) {
        self.receiver.set_pad_count(pad_count);
    }

    /// Frames dropped because the caller did not take them while a request waited.
    pub fn frames_dropped_from_queue(&self) -> u64 {
        self.frames_dropped_from_queue
    }

    /// Reads once from the port and decodes what arrived. Returns the number of bytes read;
    /// 0 means the read timed out with nothing. End of stream is [`LinkError::Disconnected`].
    pub fn poll(&mut self) -> Result<usize, LinkError> {
        let count = match self.port.read(&mut self.read_buffer) {
            Ok(0) => return Err(LinkError::Disconnected),
            Ok(count) => count,
            Err(error)
                if matches!(
                    error.kind(),
                    io::ErrorKind::TimedOut
                        | io::ErrorKind::WouldBlock
                        | io::ErrorKind::Interrupted
                ) =>
            {
                return Ok(0)
            }
            Err(error) => return Err(LinkError::Io(error)),
        };
        let bytes = &self.read_buffer[..count];
        if let Some(log) = self.raw_log.as_mut() {
            log.write_all(bytes).map_err(LinkError::RawLog)?;
        }
        self.receiver.push_bytes(bytes, &mut self.frames);
        let excess = self.frames.len().saturating_sub(QUEUE_CAPACITY);
        if excess > 0 {
            self.frames.drain(..excess);
            self.frames_dropped_from_queue += excess as u64;
        }
        Ok(count)
    }

    /// Takes every frame queued so far (received while requests waited, not yet taken).
    pub fn take_queued(&mut self) -> Vec<DeviceFrame> {
        self.frames.drain(..).collect()
    }

    /// The next frame: a queued one, else whatever one read brings (`None` if it brought no
    /// complete frame). The reply to a request still awaited is kept for
    /// [`DeviceLink::wait_reply`] instead.
    pub fn next_frame(&mut self) -> Result<Option<DeviceFrame>, LinkError> {
        if self.frames.is_empty() {
            self.poll()?;
        }
        while let Some(frame) = self.frames.pop_front() {
            match frame {
                DeviceFrame::Reply(reply) if self.awaited.contains(&reply.request_id) => {
                    self.keep_reply(reply);
                }
                frame => return Ok(Some(frame)),
            }
        }
        Ok(None)
    }

    fn keep_reply(&mut self, reply: ReplyFrame) {
        if self.replies.len() >= AWAITED_CAPACITY {
            self.replies.pop_front();
        }
        self.replies.push_back(reply);
    }

    /// The reply to request `request_id` (sent with [`DeviceLink::send_awaited`]) if it arrives by
    /// `deadline` (`None` then; the request stays awaited until its reply is taken or
    /// [`DeviceLink::forget`] is called). Frames that arrive meanwhile stay queued, in order,
    /// for [`DeviceLink::next_frame`]. A refusal is the device's error code.
    pub fn wait_reply(
        &mut self,
        request_id: u16,
        deadline: Instant,
    ) -> Result<Option<Result<ReplyPayload, ErrorCode>>, LinkError> {
        loop {
            if let Some(position) = self
                .replies
                .iter()
                .position(|reply| reply.request_id == request_id)
            {
                let reply = self.replies.remove(position);
                self.forget(request_id);
                return Ok(reply.map(|reply| reply.result));
            }
            let queued = self.frames.iter().position(|frame| {
                matches!(frame, DeviceFrame::Reply(ReplyFrame { request_id: id, .. }) if *id == request_id)
            });
            if let Some(DeviceFrame::Reply(reply)) =
                queued.and_then(|position| self.frames.remove(position))
            {
                self.forget(request_id);
                return Ok(Some(reply.result));
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            self.poll()?;
        }
    }

    /// Stops awaiting request `request_id`: its reply, if it still comes, is an ordinary frame.
    pub fn forget(&mut self, request_id: u16) {
        self.awaited.retain(|id| *id != request_id);
        self.replies.retain(|reply| reply.request_id != request_id);
    }

    /// Why request `request_id` got no reply within `timeout`: a device that speaks another
    /// protocol version is named as such, anything else is a timeout.
    pub fn no_reply_error(&self, request_id: u16, timeout: Duration) -> RequestError {
        match self.statistics().other_protocol_version {
            Some(found) => RequestError::OtherProtocolVersion {
                found,
                supported: wire::PROTOCOL_VERSION,
            },
            None => RequestError::Timeout {
                request_id,
                timeout_ms: timeout.as_millis(),
            },
        }
    }

    /// Sends a request without waiting; returns its request id, awaited from now on: its reply
    /// is taken with [`DeviceLink::wait_reply`] (or given up with [`DeviceLink::forget`]).
    pub fn send_awaited(&mut self, command: Command) -> Result<u16, LinkError> {
        let request_id = self.send(command)?;
        if self.awaited.len() >= AWAITED_CAPACITY {
            self.awaited.pop_front();
        }
        self.awaited.push_back(request_id);
        Ok(request_id)
    }

    /// Sends a request without waiting; returns its request id. Its reply arrives as an
    /// ordinary [`DeviceFrame::Reply`] (see [`DeviceLink::send_awaited`] to wait for it). A 00
    /// goes before the frame so that anything the device holds (a partial frame, typed text)
    /// cannot be glued to its front.
    pub fn send(&mut self, command: Command) -> Result<u16, LinkError> {
        let request_id = self.next_request_id;
        self.next_request_id = self.next_request_id.wrapping_add(1).max(1);
        let request = Request {
            request_id,
            command,
        };
        let mut bytes = vec![0u8];
        bytes.extend(encode_frame_to_vec(&request).map_err(LinkError::Encode)?);
        self.port.write_all(&bytes).map_err(LinkError::Io)?;
        self.port.flush().map_err(LinkError::Io)?;
        Ok(request_id)
    }

    /// Sends a request and waits up to `timeout` for its reply. Frames that arrive meanwhile
    /// stay queued, in order, for [`DeviceLink::next_frame`].
    pub fn request(
        &mut self,
        command: Command,
        timeout: Duration,
    ) -> Result<ReplyPayload, RequestError> {
        let request_id = self.send_awaited(command)?;
        match self.wait_reply(request_id, Instant::now() + timeout)? {
            Some(result) => result.map_err(RequestError::Refused),
            None => {
                self.forget(request_id);
                Err(self.no_reply_error(request_id, timeout))
            }
        }
    }

    /// Starts a session on a freshly opened port: asks for the device's identity and discards
    /// every frame queued before the answer. Those were waiting in the port's buffer from
    /// before this connection (a device that streamed while nobody read, such as a simulated
    /// device on a pseudo-terminal), so their samples are stale. Returns the identity and the
    /// number of frames discarded.
    pub fn synchronise(&mut self, timeout: Duration) -> Result<(InfoFrame, u64), RequestError> {
        let request_id = self.send(Command::Info)?;
        let deadline = Instant::now() + timeout;
        let mut discarded = 0u64;
        loop {
            // Everything queued before the reply is stale; so is everything while it is awaited.
            while let Some(frame) = self.frames.pop_front() {
                match frame {
                    DeviceFrame::Reply(reply) if reply.request_id == request_id => {
                        return match reply.result {
                            Ok(ReplyPayload::Info(info)) => Ok((info, discarded)),
                            Ok(_) => Err(RequestError::UnexpectedReply("Info")),
                            Err(code) => Err(RequestError::Refused(code)),
                        };
                    }
                    _ => discarded += 1,
                }
            }
            if Instant::now() >= deadline {
                return Err(self.no_reply_error(request_id, timeout));
            }
            self.poll()?;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A port that hands out `incoming` and swallows what is written.
    struct Scripted {
        incoming: std::io::Cursor<Vec<u8>>,
    }

    impl Read for Scripted {
        fn read(&mut self, buffer: &mut [u8]) -> std::io::Result<usize> {
            // Once the script is out, nothing more arrives (a serial port's read timeout).
            match self.incoming.read(buffer)? {
                0 => Err(std::io::ErrorKind::TimedOut.into()),
                read => Ok(read),
            }
        }
    }

    impl Write for Scripted {
        fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
            Ok(bytes.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_device_of_another_protocol_version_is_named_not_timed_out() {
        // An intact frame of version 2 (COBS of version, kind Info, an empty body, CRC), as an
        // older firmware sends when it cannot read our request.
        let mut payload = vec![2u8, wire::kind::INFO];
        let crc = wire::crc16(&payload);
        payload.extend(crc.to_le_bytes());
        assert!(!payload.contains(&0));
        let mut frame = vec![payload.len() as u8 + 1];
        frame.extend(&payload);
        frame.push(0);
        let mut link = DeviceLink::new(Scripted {
            incoming: std::io::Cursor::new(frame),
        });
        let error = link.synchronise(Duration::from_millis(50)).unwrap_err();
        assert_eq!(
            error.to_string(),
            format!(
                "the device speaks protocol version 2 and this host tool version {}: update the firmware or the host tool so that both match",
                wire::PROTOCOL_VERSION
            )
        );
    }

    fn board(port_name: &str, serial_number: &str) -> BoardPort {
        BoardPort {
            port_name: port_name.to_owned(),
            vid: DEFAULT_VID,
            pid: DEFAULT_PID,
            serial_number: Some(serial_number.to_owned()),
            manufacturer: None,
            product: None,
        }
    }

    #[test]
    fn board_choice_by_serial_number_or_the_only_one() {
        let boards = [board("/dev/a", "AB12"), board("/dev/b", "CD34")];
        let chosen = choose_board(&boards, Some("cd34"), DEFAULT_VID, DEFAULT_PID).unwrap();
        assert_eq!(chosen.port_name, "/dev/b");
        assert!(matches!(
            choose_board(&boards, None, DEFAULT_VID, DEFAULT_PID),
            Err(LinkError::SeveralBoards { count: 2, .. })
        ));
        assert!(matches!(
            choose_board(&boards, Some("EF56"), DEFAULT_VID, DEFAULT_PID),
            Err(LinkError::SerialNumberNotFound { .. })
        ));
        assert_eq!(
            choose_board(&boards[..1], None, DEFAULT_VID, DEFAULT_PID)
                .unwrap()
                .port_name,
            "/dev/a"
        );
        let error = choose_board(&[], None, DEFAULT_VID, DEFAULT_PID).unwrap_err();
        assert_eq!(
            error.to_string(),
            "no board attached (looked for USB 1209:0001)"
        );
    }
}
