//! Finding and opening the boards the view shows: by port or by serial number, found again
//! after an unplug, each opened as the host library's [`DeviceSession`] (identified, the frames
//! that waited in the port discarded, its state read, its stream started) on a thread of its
//! own, so that the view never waits for a device.

use std::sync::mpsc::{self, Receiver};
use std::time::Duration;

use anyhow::Context;
use taxel_host::device_link::{self, attached_boards, choose_board, DeviceLink, LinkError};
use taxel_host::session::{DeviceSession, SessionConfig};

/// The port a board is read through.
pub(super) type Port = Box<dyn serialport::SerialPort>;

/// How long a read of the port waits: the device's thread looks at its requests between reads.
const READ_TIMEOUT: Duration = Duration::from_millis(20);

/// How to find a board, again after an unplug.
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

    /// The board in words.
    pub(super) fn describe(&self) -> String {
        match (&self.serial_number, &self.path) {
            (Some(serial), _) => format!("board {serial}"),
            (None, Some(path)) => path.clone(),
            (None, None) => format!("a board {:04x}:{:04x}", self.vid, self.pid),
        }
    }

    /// The port the board is on now.
    fn find(&mut self) -> Result<String, LinkError> {
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

/// A device opened and streaming.
pub(super) struct Opened {
    /// Its session, started.
    pub(super) session: DeviceSession<Port>,
    /// The port, with the board's description when that says more.
    pub(super) source: String,
}

/// Why a device could not be opened.
pub(super) struct OpenFailure {
    /// What went wrong.
    pub(super) error: anyhow::Error,
    /// Waiting cannot help: the path is not a serial port.
    pub(super) permanent: bool,
}

/// What an attempt to open a board gives: the target (which may have learnt the board's serial
/// number) and the device, or why not.
pub(super) type Attempt = (BoardTarget, Result<Opened, OpenFailure>);

fn failure(error: anyhow::Error) -> OpenFailure {
    let permanent = matches!(
        error.downcast_ref::<LinkError>(),
        Some(LinkError::NotSerialPort { .. })
    );
    OpenFailure { error, permanent }
}

/// Finds and opens the board, reads its state and starts its stream.
fn open(target: &mut BoardTarget, request_timeout: Duration) -> Result<Opened, OpenFailure> {
    let path = target.find().map_err(|error| failure(error.into()))?;
    // A pseudo-terminal has no DTR line; a real board that misses it shows up as silence.
    let port = device_link::open_serial(&path, READ_TIMEOUT)
        .map_err(|error| failure(error.into()))?
        .port;
    let config = SessionConfig {
        request_timeout,
        follow_state: true,
    };
    let mut session = DeviceSession::open(DeviceLink::new(port), config)
        .with_context(|| format!("the device on {path}"))
        .map_err(failure)?;
    session
        .start()
        .with_context(|| format!("the device on {path}"))
        .map_err(failure)?;
    let described = target.describe();
    let source = if described == path {
        path
    } else {
        format!("{path} ({described})")
    };
    Ok(Opened { session, source })
}

/// Opens the board on a thread of its own; the attempt arrives on the receiver.
pub(super) fn open_in_background(
    target: &BoardTarget,
    request_timeout: Duration,
) -> Receiver<Attempt> {
    let (sender, receiver) = mpsc::channel();
    let mut moved = target.clone();
    let thread_sender = sender.clone();
    let spawned = std::thread::Builder::new()
        .name("taxel-view-open".to_owned())
        .spawn(move || {
            let result = open(&mut moved, request_timeout);
            // The view may have ended meanwhile; the device is then nobody's.
            let _ = thread_sender.send((moved, result));
        });
    if let Err(error) = spawned {
        let error = anyhow::Error::new(error).context("starting a thread to open the device");
        let _ = sender.send((target.clone(), Err(failure(error))));
    }
    receiver
}
