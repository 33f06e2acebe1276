//! One device read on its own thread: identity and pads, then the stream; every sample frame
//! and contact event stamped with the device time mapped onto the host clock, handed to the
//! publisher through a bounded queue that never blocks the reader.
//!
//! # Timestamps
//!
//! Each device's clock is mapped with its own [`ClockMapper`] (see `taxel_host::clock_sync`), fed with
//! each sample frame's device time and arrival. A message's stamp is that mapping of its device
//! time, never later than its arrival, turned into Unix time with the wall clock read once when
//! the bridge started ([`BridgeClock`]). The mapper needs about 1.5 s of frames before its
//! first estimate; until then frames wait (at most [`MAX_WAITING_FRAMES`], the oldest dropped
//! and counted beyond that) and go out with the first estimate, so nothing is ever stamped with
//! its arrival, which would make it look fresher than it is.
//!
//! # Back-pressure
//!
//! The queue to the publisher has a fixed capacity; when it is full the frame is dropped and
//! counted in the device's health ([`DeviceHealth::queue_dropped`]), and the reader goes on.

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{SyncSender, TrySendError};
use std::sync::Mutex;
use std::time::{Duration, SystemTime};

use anyhow::Context;
use taxel_host::clock_sync::{ClockEstimate, ClockMapper};
use taxel_host::device_link::DeviceLink;
use taxel_host::multi_record::{HostClock, MonotonicClock};
use taxel_host::stream_accounting::StreamAccounting;
use wire::{
    Command, CountersFrame, DeviceEvent, DeviceFrame, InfoFrame, PadIndex, PadInfoFrame,
    ReplyPayload, SampleFrame,
};

/// Frames of one device held while its clock has no estimate yet (10 s of 8 pads at 100 sets
/// per second).
pub const MAX_WAITING_FRAMES: usize = 8_000;

/// The host's clock for the bridge: monotonic µs since the start for the clock mapping, and the
/// Unix time of that start for stamps.
#[derive(Debug, Clone, Copy)]
pub struct BridgeClock {
    monotonic: MonotonicClock,
    start_unix_ns: u64,
}

impl Default for BridgeClock {
    fn default() -> Self {
        Self::new()
    }
}

impl BridgeClock {
    /// A clock starting now.
    pub fn new() -> Self {
        let monotonic = MonotonicClock::new();
        let start_unix_ns = SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .map_or(0, |since| {
                u64::try_from(since.as_nanos()).unwrap_or(u64::MAX)
            });
        Self {
            monotonic,
            start_unix_ns,
        }
    }

    /// µs of the monotonic clock since the start.
    pub fn now_us(&self) -> u64 {
        self.monotonic.now_us()
    }

    /// A host time (µs since the start) as ns since the Unix epoch.
    pub fn unix_ns(&self, host_us: u64) -> u64 {
        self.start_unix_ns
            .saturating_add(host_us.saturating_mul(1_000))
    }
}

/// What a reader hands to the publisher.
#[derive(Debug, Clone, PartialEq)]
pub enum Outgoing {
    /// One pad's sample set.
    Sample {
        /// The device's index.
        device: usize,
        /// The frame as received.
        sample: SampleFrame,
        /// Its device time on the host clock, ns since the Unix epoch.
        stamp_ns: u64,
        /// When it arrived, ns since the Unix epoch.
        arrival_ns: u64,
    },
    /// A pad came into contact or left it.
    Contact {
        /// The device's index.
        device: usize,
        /// The pad.
        pad: u8,
        /// True when the contact started, false when it ended.
        started: bool,
        /// When it happened on the host clock, ns since the Unix epoch.
        stamp_ns: u64,
    },
}

/// Where a device's reading stands.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum ReaderState {
    /// Opening, asking who it is.
    #[default]
    Connecting,
    /// Streaming.
    Streaming,
    /// Stopped: asked to, or the device went away (the reason).
    Stopped(String),
}

/// One device's health as the publisher reports it.
#[derive(Debug, Clone, Default)]
pub struct DeviceHealth {
    /// The device's name (its port).
    pub name: String,
    /// Where reading stands.
    pub state: ReaderState,
    /// Its identity.
    pub info: Option<InfoFrame>,
    /// Each pad's place, temperature sensor and calibration.
    pub pads: Vec<PadInfoFrame>,
    /// The device's counters, as last sent.
    pub counters: Option<CountersFrame>,
    /// Sample frames received, lost on the link, dropped by the device.
    pub accounting: StreamAccounting,
    /// Each pad's temperature source in its last sample, by pad index.
    pub temperature_sources: Vec<Option<wire::TemperatureSource>>,
    /// The clock mapping at the last frame.
    pub clock: Option<ClockEstimate>,
    /// Frames dropped because the queue to the publisher was full.
    pub queue_dropped: u64,
    /// Frames dropped while waiting for the first clock estimate (more than
    /// [`MAX_WAITING_FRAMES`]).
    pub waiting_dropped: u64,
    /// Frames handed to the publisher.
    pub queued: u64,
}

enum Waiting {
    Sample(SampleFrame, u64),
    Contact(u8, bool, u64),
}

/// The reader's stamping and queueing, apart from the link so it can be tested alone.
pub struct Stamper<'a> {
    device: usize,
    clock: &'a BridgeClock,
    mapper: ClockMapper,
    waiting: VecDeque<Waiting>,
    sender: SyncSender<Outgoing>,
}

impl<'a> Stamper<'a> {
    /// A stamper for device `device` sending to `sender`.
    pub fn new(device: usize, clock: &'a BridgeClock, sender: SyncSender<Outgoing>) -> Self {
        Self {
            device,
            clock,
            mapper: ClockMapper::new(),
            waiting: VecDeque::new(),
            sender,
        }
    }

    /// Takes a sample frame that arrived at host µs `arrival_us`; false when the publisher is
    /// gone.
    pub fn sample(
        &mut self,
        sample: SampleFrame,
        arrival_us: u64,
        health: &mut DeviceHealth,
    ) -> bool {
        self.mapper.observe(sample.timestamp_us, arrival_us);
        health.clock = self.mapper.estimate();
        self.hold(Waiting::Sample(sample, arrival_us), health);
        self.release(health)
    }

    /// Takes a contact event of `pad` at device time `device_us`. Events do not feed the clock
    /// mapping: it is made of the sample frames, which leave the device as they are taken.
    pub fn contact(
        &mut self,
        pad: u8,
        started: bool,
        device_us: u64,
        health: &mut DeviceHealth,
    ) -> bool {
        self.hold(Waiting::Contact(pad, started, device_us), health);
        self.release(health)
    }

    fn hold(&mut self, waiting: Waiting, health: &mut DeviceHealth) {
        self.waiting.push_back(waiting);
        if self.waiting.len() > MAX_WAITING_FRAMES {
            self.waiting.pop_front();
            health.waiting_dropped += 1;
        }
    }

    fn release(&mut self, health: &mut DeviceHealth) -> bool {
        let Some(estimate) = self.mapper.estimate() else {
            return true;
        };
        while let Some(waiting) = self.waiting.pop_front() {
            let outgoing = match waiting {
                Waiting::Sample(sample, arrival_us) => {
                    let host_us = estimate.to_host_us(sample.timestamp_us).min(arrival_us);
                    Outgoing::Sample {
                        device: self.device,
                        sample,
                        stamp_ns: self.clock.unix_ns(host_us),
                        arrival_ns: self.clock.unix_ns(arrival_us),
                    }
                }
                Waiting::Contact(pad, started, device_us) => Outgoing::Contact {
                    device: self.device,
                    pad,
                    started,
                    stamp_ns: self.clock.unix_ns(estimate.to_host_us(device_us)),
                },
            };
            match self.sender.try_send(outgoing) {
                Ok(()) => health.queued += 1,
                Err(TrySendError::Full(_)) => health.queue_dropped += 1,
                Err(TrySendError::Disconnected(_)) => return false,
            }
        }
        true
    }
}

/// Reads one device until `stop` is set or it goes away, updating `health` as frames arrive.
/// Fails when the device cannot be set up (no answer, streaming refused).
pub fn read_device<P: Read + Write>(
    device: usize,
    port: P,
    clock: &BridgeClock,
    sender: SyncSender<Outgoing>,
    health: &Mutex<DeviceHealth>,
    stop: &AtomicBool,
    timeout: Duration,
) -> anyhow::Result<()> {
    let mut link = DeviceLink::new(port);
    let (info, stale) = link
        .synchronise(timeout)
        .context("asking the device who it is")?;
    let mut pads = Vec::new();
    for pad in 0..info.pad_count {
        let Some(pad) = PadIndex::new(pad) else {
            break;
        };
        if let Ok(ReplyPayload::PadInfo(pad_info)) = link.request(Command::PadInfo { pad }, timeout)
        {
            pads.push(pad_info);
        }
    }
    link.request(Command::StartStreaming, timeout)
        .context("starting the stream")?;
    let mut local = lock(health).clone();
    local.info = Some(info);
    local.pads = pads;
    local.state = ReaderState::Streaming;
    local.temperature_sources = vec![None; usize::from(info.pad_count)];
    local.accounting.stale_discarded(stale);
    *lock(health) = local.clone();
    let mut stamper = Stamper::new(device, clock, sender);
    let mut last_shared = std::time::Instant::now();
    let ended = loop {
        if stop.load(Ordering::Relaxed) {
            break "stopped".to_owned();
        }
        let open = match link.next_frame() {
            Ok(Some(DeviceFrame::Sample(sample))) => {
                let arrival_us = clock.now_us();
                local.accounting.sample(&sample);
                if let Some(source) = local
                    .temperature_sources
                    .get_mut(usize::from(sample.pad.get()))
                {
                    *source = Some(sample.temperature_source);
                }
                stamper.sample(sample, arrival_us, &mut local)
            }
            Ok(Some(DeviceFrame::Event(event))) => match event.event {
                DeviceEvent::ContactStarted { pad } | DeviceEvent::ContactEnded { pad } => {
                    let started = matches!(event.event, DeviceEvent::ContactStarted { .. });
                    stamper.contact(pad.get(), started, event.timestamp_us, &mut local)
                }
                _ => true,
            },
            Ok(Some(DeviceFrame::Counters(counters))) => {
                local.accounting.counters(&counters);
                local.counters = Some(counters);
                true
            }
            Ok(Some(DeviceFrame::Reply(reply))) => {
                if let Ok(ReplyPayload::Counters(counters)) = reply.result {
                    local.accounting.counters(&counters);
                    local.counters = Some(counters);
                }
                true
            }
            Ok(Some(DeviceFrame::Info(info))) => {
                local.info = Some(info);
                true
            }
            Ok(None) => true,
            Err(error) => break format!("the device went away: {error}"),
        };
        if !open {
            break "the publisher stopped".to_owned();
        }
        // The publisher reads the health once a second: sharing it ten times a second keeps the
        // lock off the per-frame path.
        if last_shared.elapsed() >= Duration::from_millis(100) {
            *lock(health) = local.clone();
            last_shared = std::time::Instant::now();
        }
    };
    let _ = link.send(Command::StopStreaming);
    local.state = ReaderState::Stopped(ended);
    *lock(health) = local;
    Ok(())
}

/// The health behind its lock, also when a thread panicked while holding it (the figures are
/// still the best there are).
pub fn lock(health: &Mutex<DeviceHealth>) -> std::sync::MutexGuard<'_, DeviceHealth> {
    health
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc::sync_channel;
    use wire::{PadSummary, TaxelSample, TemperatureSource};

    fn frame(sequence: u32, timestamp_us: u64) -> SampleFrame {
        SampleFrame {
            pad: PadIndex::default(),
            sequence,
            timestamp_us,
            temperature_c: None,
            temperature_source: TemperatureSource::None,
            taxels: [TaxelSample {
                pressure_kpa: Some(0.0),
                capacitance_pf: 4.5,
                flags: 0,
            }; 4],
            summary: PadSummary::default(),
        }
    }

    #[test]
    fn frames_wait_for_the_clock_and_are_never_stamped_after_their_arrival() {
        let clock = BridgeClock::new();
        let (sender, receiver) = sync_channel(10_000);
        let mut stamper = Stamper::new(0, &clock, sender);
        let mut health = DeviceHealth::default();
        // The device clock runs 7 s ahead; frames arrive 0.1 to 2.1 ms after they are taken
        // (the smallest latency below the mapper's assumed bound).
        for step in 0..300_u64 {
            let true_us = 1_000_000 + step * 10_000;
            let arrival_us = true_us + 100 + (step * 7919) % 2_000;
            assert!(stamper.sample(
                frame(step as u32, true_us + 7_000_000),
                arrival_us,
                &mut health
            ));
            if step == 10 {
                assert!(
                    receiver.try_recv().is_err(),
                    "no estimate yet: the frames wait"
                );
            }
        }
        let out: Vec<Outgoing> = receiver.try_iter().collect();
        assert_eq!(out.len(), 300 - stamper.waiting.len());
        assert!(out.len() > 100);
        for (index, outgoing) in out.iter().enumerate() {
            let Outgoing::Sample {
                sample,
                stamp_ns,
                arrival_ns,
                ..
            } = outgoing
            else {
                panic!("not a sample");
            };
            assert_eq!(sample.sequence, index as u32);
            assert!(stamp_ns <= arrival_ns);
            let true_ns = clock.unix_ns(1_000_000 + u64::from(sample.sequence) * 10_000);
            // Early by at most the mapper's latency bound and fit error, never late.
            let early_ns = true_ns as i64 - *stamp_ns as i64;
            assert!((0..3_000_000).contains(&early_ns), "{index}: {early_ns} ns");
        }
        assert_eq!(health.queue_dropped, 0);
    }

    #[test]
    fn a_full_queue_drops_and_counts_without_waiting() {
        let clock = BridgeClock::new();
        let (sender, receiver) = sync_channel(5);
        let mut stamper = Stamper::new(0, &clock, sender);
        let mut health = DeviceHealth::default();
        for step in 0..300_u64 {
            let true_us = step * 10_000;
            assert!(stamper.sample(frame(step as u32, true_us), true_us + 500, &mut health));
        }
        assert_eq!(receiver.try_iter().count(), 5);
        assert_eq!(health.queued, 5);
        assert_eq!(
            health.queue_dropped + health.queued + stamper.waiting.len() as u64,
            300
        );
        drop(receiver);
        assert!(!stamper.sample(frame(300, 3_000_000), 3_000_500, &mut health));
    }
}
