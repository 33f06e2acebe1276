//! An in-memory link between the simulated device and a host in the same process (tests,
//! benchmarks, the reliability harness): bytes both ways, a connection switch, and a bounded
//! buffer towards the host so that a host that reads slowly fills it as it would fill a real one.

use std::collections::VecDeque;

use device::{encode_outgoing, HostInput, HostInputEvent, HostPort, Outgoing, QueueFull};

/// The device's port on an in-memory link.
#[derive(Debug)]
pub struct MemoryPort {
    /// Whether a host has the port open.
    pub connected: bool,
    /// Bytes on their way to the device.
    pub to_device: VecDeque<u8>,
    /// Bytes on their way to the host.
    pub to_host: VecDeque<u8>,
    /// Most bytes `to_host` holds; a frame that does not fit is refused (and counted by the
    /// device).
    pub capacity_bytes: usize,
    input: HostInput,
}

impl MemoryPort {
    /// A connected link holding at most `capacity_bytes` towards the host.
    pub fn new(capacity_bytes: usize) -> Self {
        Self {
            connected: true,
            to_device: VecDeque::new(),
            to_host: VecDeque::new(),
            capacity_bytes,
            input: HostInput::new(),
        }
    }

    /// Takes up to `max_bytes` of what the device sent.
    pub fn take_for_host(&mut self, max_bytes: usize) -> Vec<u8> {
        let count = self.to_host.len().min(max_bytes);
        self.to_host.drain(..count).collect()
    }
}

impl HostPort for MemoryPort {
    fn host_connected(&mut self) -> bool {
        self.connected
    }

    fn try_receive(&mut self) -> Option<HostInputEvent> {
        while let Some(byte) = self.to_device.pop_front() {
            if let Some(event) = self.input.push(byte) {
                return Some(event);
            }
        }
        None
    }

    fn try_send(&mut self, outgoing: Outgoing) -> Result<(), QueueFull> {
        let mut buffer = [0u8; device::MAX_OUTGOING_LEN];
        let length = encode_outgoing(&outgoing, &mut buffer).ok_or(QueueFull)?;
        if self.to_host.len() + length > self.capacity_bytes {
            return Err(QueueFull);
        }
        self.to_host.extend(&buffer[..length]);
        Ok(())
    }
}
