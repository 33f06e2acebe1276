//! The device application's side of the USB port: [`UsbHostPort`] implements `device::HostPort`
//! over the queues that the USB tasks drain and fill, and the DTR flag. Nothing here ever waits,
//! so the acquisition loop never blocks on the host.

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use device::{HostInputEvent, HostPort, Outgoing, QueueFull};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::{Channel, TrySendError};

/// Frames waiting for the USB writer: 80 ms of sample sets at the highest rate (400 S/s, four
/// conversions per set), so a host that is briefly slow loses nothing.
const OUTGOING_QUEUE_DEPTH: usize = 8;

/// Requests waiting for the acquisition loop, which takes them all once per cycle.
const HOST_EVENT_QUEUE_DEPTH: usize = 4;

/// What the device application sends, drained by the USB writer task.
pub static OUTGOING: Channel<CriticalSectionRawMutex, Outgoing, OUTGOING_QUEUE_DEPTH> =
    Channel::new();

static HOST_EVENTS: Channel<CriticalSectionRawMutex, HostInputEvent, HOST_EVENT_QUEUE_DEPTH> =
    Channel::new();
static HOST_CONNECTED: AtomicBool = AtomicBool::new(false);
static HOST_EVENTS_DROPPED: AtomicU32 = AtomicU32::new(0);

/// Records whether a host program has the port open (DTR); returns the previous state.
pub fn set_host_connected(connected: bool) -> bool {
    HOST_CONNECTED.swap(connected, Ordering::Relaxed)
}

/// Queues an event from the host for the acquisition loop; a full queue drops it and counts it.
/// Returns whether it was queued.
pub fn push_host_event(event: HostInputEvent) -> bool {
    match HOST_EVENTS.try_send(event) {
        Ok(()) => true,
        Err(TrySendError::Full(_)) => {
            HOST_EVENTS_DROPPED.fetch_add(1, Ordering::Relaxed);
            false
        }
    }
}

/// The device application's port: the static queues and the DTR flag.
#[derive(Debug, Default)]
pub struct UsbHostPort {
    reported_drops: u32,
}

impl UsbHostPort {
    /// A port with no dropped events reported yet.
    pub const fn new() -> Self {
        Self { reported_drops: 0 }
    }
}

impl HostPort for UsbHostPort {
    fn host_connected(&mut self) -> bool {
        HOST_CONNECTED.load(Ordering::Relaxed)
    }

    /// Queued events first; then one [`HostInputEvent::Rejected`] per event the reader had to
    /// drop, so that drops show up in the counters frame as refused host frames.
    fn try_receive(&mut self) -> Option<HostInputEvent> {
        if let Ok(event) = HOST_EVENTS.try_receive() {
            return Some(event);
        }
        let dropped = HOST_EVENTS_DROPPED.load(Ordering::Relaxed);
        if dropped != self.reported_drops {
            self.reported_drops = self.reported_drops.wrapping_add(1);
            return Some(HostInputEvent::Rejected);
        }
        None
    }

    fn try_send(&mut self, outgoing: Outgoing) -> Result<(), QueueFull> {
        OUTGOING.try_send(outgoing).map_err(|_| QueueFull)
    }
}
