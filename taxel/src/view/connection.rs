//! Finding, opening and setting up the board the view shows: by port or serial number, found
//! again after an unplug, its stale frames discarded and its stream started.

use std::time::Duration;

use anyhow::Context;
use wire::Command;

use super::state::ViewState;
use super::{ViewArgs, VIEW_REQUEST_TIMEOUT};
use taxel_host::device_link::{self, attached_boards, choose_board, DeviceLink, LinkError};

/// How to find the board again after an unplug.
#[derive(Debug, Clone)]
pub(super) struct BoardTarget {
    path: Option<String>,
    serial_number: Option<String>,
    vid: u16,
    pid: u16,
}

impl BoardTarget {
    /// The board on `path` or with `serial_number` (neither: the only attached board).
    pub(super) fn new(
        path: Option<String>,
        serial_number: Option<String>,
        vid: u16,
        pid: u16,
    ) -> Self {
        let mut target = Self {
            path,
            serial_number,
            vid,
            pid,
        };
        if target.serial_number.is_none() {
            if let Some(path) = &target.path {
                // Knowing the serial number lets a replugged board be found under a new name.
                target.serial_number = attached_boards(vid, pid)
                    .ok()
                    .and_then(|boards| boards.into_iter().find(|board| &board.port_name == path))
                    .and_then(|board| board.serial_number);
            }
        }
        target
    }

    /// The one board `args` name (the first PORT, else the first --serial).
    pub(super) fn single(args: &ViewArgs) -> Self {
        let board = &args.board;
        Self::new(
            board.ports.first().cloned(),
            board.serial.first().cloned(),
            board.vid,
            board.pid,
        )
    }

    pub(super) fn describe(&self) -> String {
        match (&self.serial_number, &self.path) {
            (Some(serial), _) => format!("board {serial}"),
            (None, Some(path)) => path.clone(),
            (None, None) => format!("a board {:04x}:{:04x}", self.vid, self.pid),
        }
    }

    pub(super) fn find(&mut self) -> Result<String, LinkError> {
        if self.serial_number.is_some() || self.path.is_none() {
            let boards = attached_boards(self.vid, self.pid)?;
            match choose_board(&boards, self.serial_number.as_deref(), self.vid, self.pid) {
                Ok(board) => {
                    if self.serial_number.is_none() {
                        self.serial_number = board.serial_number.clone();
                    }
                    return Ok(board.port_name);
                }
                Err(error) if self.path.is_none() => return Err(error),
                Err(_) => {}
            }
        }
        match &self.path {
            Some(path) => {
                device_link::check_is_serial_port(path)?;
                Ok(path.clone())
            }
            None => Err(LinkError::NoBoard {
                vid: self.vid,
                pid: self.pid,
            }),
        }
    }
}

pub(super) type SerialLink = DeviceLink<Box<dyn serialport::SerialPort>>;

/// An open link that knows the device and has asked it to stream, with the request id of the
/// StartStreaming whose reply the loop waits for.
pub(super) struct Connection {
    pub(super) link: SerialLink,
    pub(super) start_request_id: u16,
}

/// A new connection and what the view learns from it.
pub(super) struct Opened {
    pub(super) connection: Connection,
    /// The port, with the board's description when that says more.
    pub(super) source: String,
    pub(super) info: wire::InfoFrame,
    /// Frames discarded as waiting from before the connection.
    pub(super) stale: u64,
}

impl Opened {
    /// Tells the view about the connection: the accounting starts over.
    pub(super) fn apply_to(&self, state: &mut ViewState) {
        state.connected_to(self.source.clone());
        state.info = Some(self.info);
        state.accounting.stale_discarded(self.stale);
    }
}

/// Opens the port, discards what waited in it from before (stale samples), learns the device's
/// identity, asks for its counters (the accounting's origin) and starts the stream.
pub(super) fn open_connection(
    target: &mut BoardTarget,
    read_timeout: Duration,
) -> anyhow::Result<Opened> {
    let path = target.find()?;
    // A pseudo-terminal has no DTR line; a real board that misses it shows up as silence.
    let port = device_link::open_serial(&path, read_timeout)?.port;
    let mut link = DeviceLink::new(port);
    let (info, stale) = link
        .synchronise(VIEW_REQUEST_TIMEOUT)
        .with_context(|| format!("asking the device on {path} who it is"))?;
    let described = target.describe();
    let source = if described == path {
        path.clone()
    } else {
        format!("{path} ({described})")
    };
    link.send(Command::ReadCounters)?;
    let start_request_id = link.send(Command::StartStreaming)?;
    Ok(Opened {
        connection: Connection {
            link,
            start_request_id,
        },
        source,
        info,
        stale,
    })
}

/// [`open_connection`], told to the view.
pub(super) fn connect(
    target: &mut BoardTarget,
    read_timeout: Duration,
    state: &mut ViewState,
) -> anyhow::Result<Connection> {
    let opened = open_connection(target, read_timeout)?;
    opened.apply_to(state);
    Ok(opened.connection)
}
