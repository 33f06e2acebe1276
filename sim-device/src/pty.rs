//! The simulated device's USB port: a pseudo-terminal whose other end any serial program opens
//! exactly like the board's /dev/ttyACM* (a terminal, pyserial, or `taxel` itself).
//!
//! A pseudo-terminal has no DTR line; "a host has the port open" is read from the master side
//! instead: while nobody holds the terminal end open, the master reports a hang-up.

use std::collections::VecDeque;
use std::io;
use std::os::fd::AsFd;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

use device::{encode_outgoing, HostInput, HostInputEvent, HostPort, Outgoing, QueueFull};
use nix::errno::Errno;
use nix::fcntl::OFlag;
use nix::poll::{poll, PollFd, PollFlags, PollTimeout};
use nix::pty::{grantpt, posix_openpt, ptsname_r, unlockpt, PtyMaster};
use nix::sys::termios::{cfmakeraw, tcgetattr, tcsetattr, SetArg};

/// Bytes the port buffers for a host that reads slowly before frames are dropped (and counted).
pub const OUTPUT_BUFFER_LIMIT: usize = 64 * 1024;

/// The master side of a pseudo-terminal, speaking the device protocol.
pub struct PtyPort {
    master: PtyMaster,
    terminal_path: PathBuf,
    input: HostInput,
    events: VecDeque<HostInputEvent>,
    output: VecDeque<u8>,
    connected: bool,
}

impl PtyPort {
    /// Opens a new pseudo-terminal in raw mode (no echo, no line editing, no newline
    /// translation: binary frames pass unchanged).
    pub fn open() -> io::Result<Self> {
        // Close-on-exec: a child process (a bridge or recorder the host starts) must not keep
        // the master open, or the device would never look unplugged when the simulator stops.
        let master =
            posix_openpt(OFlag::O_RDWR | OFlag::O_NOCTTY | OFlag::O_NONBLOCK | OFlag::O_CLOEXEC)?;
        grantpt(&master)?;
        unlockpt(&master)?;
        let terminal_path = PathBuf::from(ptsname_r(&master)?);
        // Until the terminal end has been opened once, Linux reports no hang-up on the master;
        // opening and closing it here makes "nobody connected" visible from the start.
        drop(
            std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .custom_flags(OFlag::O_NOCTTY.bits())
                .open(&terminal_path)?,
        );
        let mut termios = tcgetattr(master.as_fd())?;
        cfmakeraw(&mut termios);
        tcsetattr(master.as_fd(), SetArg::TCSANOW, &termios)?;
        Ok(Self {
            master,
            terminal_path,
            input: HostInput::new(),
            events: VecDeque::new(),
            output: VecDeque::new(),
            connected: false,
        })
    }

    /// The terminal end to open, e.g. /dev/pts/7.
    pub fn path(&self) -> &Path {
        &self.terminal_path
    }

    /// Moves bytes both ways without waiting and updates whether a host is connected.
    pub fn pump(&mut self) {
        let mut poll_fds = [PollFd::new(
            self.master.as_fd(),
            PollFlags::POLLIN | PollFlags::POLLOUT,
        )];
        let revents = match poll(&mut poll_fds, PollTimeout::ZERO) {
            Ok(_) => poll_fds[0].revents().unwrap_or(PollFlags::empty()),
            Err(_) => PollFlags::empty(),
        };
        // Linux reports a hang-up once the terminal end was opened and closed again, and fails
        // reads with EIO while it was never opened: either means no host.
        let mut connected = !revents.contains(PollFlags::POLLHUP);
        let mut buffer = [0u8; 512];
        while connected {
            match nix::unistd::read(&self.master, &mut buffer) {
                Ok(0) | Err(Errno::EAGAIN) => break,
                Ok(length) => {
                    for &byte in &buffer[..length] {
                        if let Some(event) = self.input.push(byte) {
                            self.events.push_back(event);
                        }
                    }
                }
                Err(_) => connected = false,
            }
        }
        self.connected = connected;
        if !connected {
            // Nobody will read what is queued; a host that opens the port later starts fresh.
            self.output.clear();
            return;
        }
        self.flush();
    }

    /// Writes what is queued, as far as the terminal takes it now.
    fn flush(&mut self) {
        while !self.output.is_empty() {
            let (front, _) = self.output.as_slices();
            match nix::unistd::write(&self.master, front) {
                Ok(written) => {
                    self.output.drain(..written);
                }
                Err(_) => break,
            }
        }
    }
}

impl HostPort for PtyPort {
    fn host_connected(&mut self) -> bool {
        self.pump();
        self.connected
    }

    fn try_receive(&mut self) -> Option<HostInputEvent> {
        if self.events.is_empty() {
            self.pump();
        }
        self.events.pop_front()
    }

    fn try_send(&mut self, outgoing: Outgoing) -> Result<(), QueueFull> {
        let mut encoded = [0u8; device::MAX_OUTGOING_LEN];
        let length = encode_outgoing(&outgoing, &mut encoded).ok_or(QueueFull)?;
        if self.output.len() + length > OUTPUT_BUFFER_LIMIT {
            return Err(QueueFull);
        }
        self.output.extend(&encoded[..length]);
        self.flush();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::PtyPort;

    #[test]
    fn a_child_process_does_not_inherit_the_master() {
        let port = match PtyPort::open() {
            Ok(port) => port,
            Err(error) => panic!("opening a pseudo-terminal: {error}"),
        };
        // The child lists its own open files: the master is /dev/ptmx (or /dev/pts/ptmx).
        let listing = std::process::Command::new("ls")
            .args(["-l", "/proc/self/fd"])
            .output();
        let listing = match listing {
            Ok(output) => String::from_utf8_lossy(&output.stdout).into_owned(),
            Err(error) => panic!("running ls: {error}"),
        };
        assert!(
            listing.contains("/proc/self/fd") || listing.contains("->"),
            "{listing}"
        );
        assert!(
            !listing.contains("ptmx"),
            "the child holds the master:\n{listing}"
        );
        drop(port);
    }
}
