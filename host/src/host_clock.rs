//! The host's clock as the device readers stamp arrivals with it: one origin for every thread
//! and every device, so that several devices share one timeline.

use std::time::Instant;

/// The host's clock as the reader threads stamp arrivals with it: µs since an origin, never
/// going back, the same for every thread.
pub trait HostClock: Send + Sync {
    /// µs since the clock's origin.
    fn now_us(&self) -> u64;
}

/// The operating system's monotonic clock, µs since [`MonotonicClock::new`].
#[derive(Debug, Clone, Copy)]
pub struct MonotonicClock {
    origin: Instant,
}

impl MonotonicClock {
    /// A clock whose origin is now.
    pub fn new() -> Self {
        Self {
            origin: Instant::now(),
        }
    }
}

impl Default for MonotonicClock {
    fn default() -> Self {
        Self::new()
    }
}

impl HostClock for MonotonicClock {
    fn now_us(&self) -> u64 {
        u64::try_from(self.origin.elapsed().as_micros()).unwrap_or(u64::MAX)
    }
}
