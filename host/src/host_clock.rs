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

/// The monotonic clock with the Unix time of its origin: arrivals are stamped on the monotonic
/// clock (it never goes back), and turned into Unix time for files and messages with the wall
/// clock read once, at the origin. Make it before opening any device: host times are µs since
/// the origin, so an instant before it (a set taken before the stream started) would be
/// clamped to the origin.
#[derive(Debug, Clone, Copy)]
pub struct UnixClock {
    monotonic: MonotonicClock,
    origin_unix_us: u64,
}

impl Default for UnixClock {
    fn default() -> Self {
        Self::new()
    }
}

impl UnixClock {
    /// A clock whose origin is now.
    pub fn new() -> Self {
        let monotonic = MonotonicClock::new();
        let origin_unix_us = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |since| {
                u64::try_from(since.as_micros()).unwrap_or(u64::MAX)
            });
        Self {
            monotonic,
            origin_unix_us,
        }
    }

    /// A host time (µs on the monotonic clock since the origin) as µs since the Unix epoch.
    pub fn unix_us(&self, host_us: u64) -> u64 {
        self.origin_unix_us.saturating_add(host_us)
    }

    /// The Unix time of the origin, µs.
    pub fn origin_unix_us(&self) -> u64 {
        self.origin_unix_us
    }
}

impl HostClock for UnixClock {
    fn now_us(&self) -> u64 {
        self.monotonic.now_us()
    }
}
