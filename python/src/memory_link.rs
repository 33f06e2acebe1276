//! The in-process link between the simulated device and the host: the simulated device's
//! [`MemoryPort`] shared between the device's thread and the host's reader, with a condition
//! variable so that a host read waits for bytes (up to its read timeout) instead of spinning.
//!
//! The port keeps its bounded buffer towards the host: a host that reads too slowly fills it,
//! and the device refuses and counts the frames that do not fit, as a real board does when the
//! USB host does not take its packets.

use std::io::{self, Read, Write};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;

use device::{HostInputEvent, HostPort, Outgoing, QueueFull};
use sim_device::MemoryPort;

/// The port and the condition the host waits on.
#[derive(Debug)]
struct Shared {
    port: Mutex<MemoryPort>,
    bytes_arrived: Condvar,
}

/// Locks the port; a thread that panicked while holding it left plain bytes, still usable.
fn lock(shared: &Shared) -> MutexGuard<'_, MemoryPort> {
    shared
        .port
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The device's end of the link.
#[derive(Debug, Clone)]
pub struct DeviceEnd(Arc<Shared>);

/// The host's end of the link: a byte stream (`Read + Write`) like a serial port.
#[derive(Debug, Clone)]
pub struct HostEnd {
    shared: Arc<Shared>,
    read_timeout: Duration,
}

/// A connected link whose buffer towards the host holds at most `capacity_bytes`.
pub fn memory_link(capacity_bytes: usize, read_timeout: Duration) -> (DeviceEnd, HostEnd) {
    let shared = Arc::new(Shared {
        port: Mutex::new(MemoryPort::new(capacity_bytes)),
        bytes_arrived: Condvar::new(),
    });
    (
        DeviceEnd(Arc::clone(&shared)),
        HostEnd {
            shared,
            read_timeout,
        },
    )
}

impl HostEnd {
    /// Closes the host's side: the device sees no host and stops sending.
    pub fn disconnect(&self) {
        lock(&self.shared).connected = false;
    }
}

impl HostPort for DeviceEnd {
    fn host_connected(&mut self) -> bool {
        lock(&self.0).host_connected()
    }

    fn try_receive(&mut self) -> Option<HostInputEvent> {
        lock(&self.0).try_receive()
    }

    fn try_send(&mut self, outgoing: Outgoing) -> Result<(), QueueFull> {
        let result = lock(&self.0).try_send(outgoing);
        if result.is_ok() {
            self.0.bytes_arrived.notify_all();
        }
        result
    }
}

impl Read for HostEnd {
    fn read(&mut self, buffer: &mut [u8]) -> io::Result<usize> {
        let port = lock(&self.shared);
        let (mut port, _) = self
            .shared
            .bytes_arrived
            .wait_timeout_while(port, self.read_timeout, |port| port.to_host.is_empty())
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        let bytes = port.take_for_host(buffer.len());
        if bytes.is_empty() {
            return Err(io::ErrorKind::TimedOut.into());
        }
        buffer[..bytes.len()].copy_from_slice(&bytes);
        Ok(bytes.len())
    }
}

impl Write for HostEnd {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        lock(&self.shared).to_device.extend(bytes);
        Ok(bytes.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}
