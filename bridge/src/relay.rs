//! The devices' events, as the host library's worker delivers them (`taxel_host::worker`: one
//! thread per device, one queue), turned into stamped messages for a publisher, and each
//! device's health kept up to date.
//!
//! # Timestamps
//!
//! Stamps follow the host library's one policy, `taxel_host::stamping`: one [`Stamper`] per
//! device, fed with every sample frame's device time and arrival, holds the device's sample
//! frames and contact events. An item goes out stamped with its device time mapped onto the
//! host clock, never later than its arrival, once the device's clock has its first estimate
//! (about 1.5 s of frames); an item that waited `taxel_host::stamping::MAX_WAIT_US` (3 s)
//! without one goes out stamped with its arrival, and is counted in the device's health.
//! Nothing is dropped there and each device's order is kept. Host times become Unix time with
//! [`UnixClock`] (the wall clock read once, when the bridge starts).
//!
//! # Back-pressure
//!
//! The worker's queue is bounded with `Overflow::DropOldestSet`: a publisher that falls behind
//! never blocks the device readers; the oldest sample sets are dropped and counted
//! (`EventQueue::dropped_sets`, reported in every device's health).

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Receiver;
use std::sync::Arc;
use std::time::{Duration, Instant};

use taxel_host::host_clock::{HostClock, UnixClock};
use taxel_host::session::{contact_change, SessionEvent};
use taxel_host::stamping::{Stamped, Stamper};
use taxel_host::stream_accounting::StreamAccounting;
use taxel_host::worker::{ArrivedEvent, EventQueue, Worker, WorkerEvent};
use wire::{InfoFrame, PadInfoFrame, SampleFrame};

use crate::commands::DeviceCommands;
use crate::health::{DeviceHealth, ReaderState};
use crate::publisher::{FramePublisher, Outgoing, PublishCounts, TimingLog};

/// What a device's stamper holds.
#[derive(Debug, Clone, PartialEq)]
enum Item {
    Sample(SampleFrame),
    Contact { pad: u8, started: bool },
}

/// One device as the relay follows it.
struct DeviceStream {
    stamper: Stamper<Item>,
    health: DeviceHealth,
    /// The session's accounting, asked of the device's thread and not yet arrived.
    accounting: Option<Receiver<StreamAccounting>>,
}

/// Every device's stamper and health (see the module documentation).
pub struct Relay {
    clock: UnixClock,
    devices: Vec<DeviceStream>,
    /// The bridge's device number of each of the worker's devices (the devices that could not
    /// be opened are not the worker's).
    worker_devices: Vec<usize>,
    /// A device that went away is looked for again ([`crate::reconnect`]).
    reconnect: bool,
}

impl Relay {
    /// A relay of the devices `healths` (in the bridge's numbering), the worker's device `n`
    /// being the bridge's `worker_devices[n]`, whose arrivals are on `clock`.
    pub fn new(clock: UnixClock, healths: Vec<DeviceHealth>, worker_devices: Vec<usize>) -> Self {
        Self {
            clock,
            devices: healths
                .into_iter()
                .map(|health| {
                    let mut stamper = Stamper::default();
                    if let Some(info) = &health.info {
                        stamper.set_clock_us_per_s(info.clock_us_per_s);
                    }
                    DeviceStream {
                        stamper,
                        health,
                        accounting: None,
                    }
                })
                .collect(),
            worker_devices,
            reconnect: false,
        }
    }

    /// From now on a device that goes away is looked for again: its state becomes
    /// [`ReaderState::Reconnecting`] (the run goes on) instead of stopped.
    pub fn reconnect_devices(&mut self) {
        self.reconnect = true;
    }

    /// The devices looking for their board again: (the bridge's number, the worker's).
    pub fn reconnecting(&self) -> Vec<(usize, usize)> {
        self.worker_devices
            .iter()
            .enumerate()
            .filter(|(_, &device)| {
                self.devices.get(device).is_some_and(|stream| {
                    matches!(stream.health.state, ReaderState::Reconnecting(_))
                })
            })
            .map(|(worker_device, &device)| (device, worker_device))
            .collect()
    }

    /// Device `device` is read again (its session started and handed to the worker): a board
    /// of `info` with `pads`. Its clock is estimated anew (the board may have restarted), so
    /// its first items wait for the estimate again. A board whose pads differ from the ones
    /// the bridge publishes (their number or geometry) is refused: its state becomes stopped
    /// and the reason is returned.
    pub fn reattached(
        &mut self,
        device: usize,
        info: InfoFrame,
        pads: Vec<PadInfoFrame>,
    ) -> Result<(), String> {
        let Some(stream) = self.devices.get_mut(device) else {
            return Err(format!("there is no device {device}"));
        };
        let layout = |pads: &[PadInfoFrame]| -> Vec<_> {
            pads.iter().map(|pad| (pad.pad, pad.taxels)).collect()
        };
        if layout(&pads) != layout(&stream.health.pads) {
            let reason = format!(
                "another board came back on {} (its pads differ: {} instead of {}); restart the bridge to publish it",
                stream.health.name,
                pads.len(),
                stream.health.pads.len()
            );
            stream.health.state = ReaderState::Stopped(reason.clone());
            return Err(reason);
        }
        let mut stamper = Stamper::default();
        stamper.set_clock_us_per_s(info.clock_us_per_s);
        stream.stamper = stamper;
        stream.health.info = Some(info);
        stream.health.pads = pads;
        stream.health.state = ReaderState::Streaming;
        stream.health.reconnections += 1;
        stream.health.clock = None;
        stream.accounting = None;
        Ok(())
    }

    /// The clock arrivals are on.
    pub fn clock(&self) -> &UnixClock {
        &self.clock
    }

    /// Now on the relay's clock, ns since the Unix epoch.
    pub fn now_ns(&self) -> u64 {
        self.unix_ns(self.clock.now_us())
    }

    fn unix_ns(&self, host_us: u64) -> u64 {
        self.clock.unix_us(host_us).saturating_mul(1_000)
    }

    /// The worker's number of bridge device `device`, where a command to it goes; or why it
    /// cannot take one (it could not be opened, or its stream ended).
    pub fn command_target(&self, device: usize) -> Result<usize, String> {
        let stream = self
            .devices
            .get(device)
            .ok_or_else(|| format!("there is no device {device}"))?;
        let name = &stream.health.name;
        match &stream.health.state {
            ReaderState::Stopped(reason) => {
                return Err(format!(
                    "device {device} ({name}) is not connected: {reason}"
                ));
            }
            ReaderState::Connecting | ReaderState::Reconnecting(_) => {
                return Err(format!("device {device} ({name}) is not connected"));
            }
            ReaderState::Streaming => {}
        }
        self.worker_devices
            .iter()
            .position(|&worker_device| worker_device == device)
            .ok_or_else(|| format!("device {device} ({name}) is not read by the bridge"))
    }

    /// Whether any of the worker's devices is still streaming, or looking for its board.
    pub fn is_running(&self) -> bool {
        self.worker_devices.iter().any(|&device| {
            self.devices
                .get(device)
                .is_some_and(|stream| !matches!(stream.health.state, ReaderState::Stopped(_)))
        })
    }

    /// Takes one event of the worker; returns the messages that can go out now, in order.
    pub fn take(&mut self, arrived: ArrivedEvent) -> Vec<Outgoing> {
        let ArrivedEvent {
            device,
            arrival_us,
            event,
        } = arrived;
        let Some(&device) = self.worker_devices.get(device) else {
            return Vec::new();
        };
        let Some(stream) = self.devices.get_mut(device) else {
            return Vec::new();
        };
        let released = match event {
            WorkerEvent::Session(event) => {
                stream.take(event, arrival_us);
                stream.stamper.release(arrival_us)
            }
            WorkerEvent::Ended(end) => {
                stream.health.state = ReaderState::after_end(&end.reason, self.reconnect);
                stream.health.info = Some(end.info);
                stream.health.accounting = end.accounting;
                if end.counters.is_some() {
                    stream.health.counters = end.counters;
                }
                // The accounting asked before the end is older than the end's.
                stream.accounting = None;
                stream.stamper.finish()
            }
        };
        self.outgoing(device, released)
    }

    /// The items of every device whose wait for a clock estimate is over at host time `now_us`.
    pub fn release(&mut self, now_us: u64) -> Vec<Outgoing> {
        let mut outgoing = Vec::new();
        for device in 0..self.devices.len() {
            let released = self.devices[device].stamper.release(now_us);
            outgoing.extend(self.outgoing(device, released));
        }
        outgoing
    }

    /// Every item still waiting, stamped as well as possible now (the end of the run).
    pub fn finish(&mut self) -> Vec<Outgoing> {
        let mut outgoing = Vec::new();
        for device in 0..self.devices.len() {
            let released = self.devices[device].stamper.finish();
            outgoing.extend(self.outgoing(device, released));
        }
        outgoing
    }

    /// Asks every streaming device's thread for its session's accounting (it arrives in the
    /// health later, see [`Relay::poll_accounting`]).
    pub fn request_accounting<P: Read + Write + Send + 'static>(&mut self, worker: &Worker<P>) {
        for (worker_device, &device) in self.worker_devices.iter().enumerate() {
            let Some(stream) = self.devices.get_mut(device) else {
                continue;
            };
            if stream.health.state == ReaderState::Streaming && stream.accounting.is_none() {
                stream.accounting = worker
                    .run(worker_device, |session| session.accounting().clone())
                    .ok();
            }
        }
    }

    /// Takes the accountings that arrived.
    pub fn poll_accounting(&mut self) {
        for stream in &mut self.devices {
            if let Some(receiver) = &stream.accounting {
                match receiver.try_recv() {
                    Ok(accounting) => {
                        stream.health.accounting = accounting;
                        stream.accounting = None;
                    }
                    Err(std::sync::mpsc::TryRecvError::Empty) => {}
                    Err(std::sync::mpsc::TryRecvError::Disconnected) => stream.accounting = None,
                }
            }
        }
    }

    /// Every device's health now, with the sample sets the queue dropped.
    pub fn healths(&self, sets_dropped_by_bridge: u64) -> Vec<DeviceHealth> {
        self.devices
            .iter()
            .map(|stream| DeviceHealth {
                sets_dropped_by_bridge,
                ..stream.health.clone()
            })
            .collect()
    }

    fn outgoing(&mut self, device: usize, released: Vec<Stamped<Item>>) -> Vec<Outgoing> {
        let mut outgoing = Vec::with_capacity(released.len());
        for stamped in released {
            let stamp_ns = self.unix_ns(stamped.host_us);
            let arrival_ns = self.unix_ns(stamped.arrival_us);
            outgoing.push(match stamped.item {
                Item::Sample(sample) => Outgoing::Sample {
                    device,
                    sample,
                    stamp_ns,
                    arrival_ns,
                },
                Item::Contact { pad, started } => Outgoing::Contact {
                    device,
                    pad,
                    started,
                    stamp_ns,
                    arrival_ns,
                },
            });
        }
        if let Some(stream) = self.devices.get_mut(device) {
            stream.health.frames_published += outgoing
                .iter()
                .filter(|outgoing| matches!(outgoing, Outgoing::Sample { .. }))
                .count() as u64;
            stream.health.stamped_at_arrival = stream.stamper.stamped_at_arrival();
            stream.health.clock = stream.stamper.estimate();
        }
        outgoing
    }
}

impl DeviceStream {
    fn take(&mut self, event: SessionEvent, arrival_us: u64) {
        match event {
            SessionEvent::Set { set, .. } => {
                for sample in set.pads.into_iter().flatten() {
                    self.stamper.observe(sample.timestamp_us, arrival_us);
                    let pad = usize::from(sample.pad.get());
                    if self.health.temperature_sources.len() <= pad {
                        self.health.temperature_sources.resize(pad + 1, None);
                    }
                    self.health.temperature_sources[pad] = Some(sample.temperature_source);
                    let device_us = sample.timestamp_us;
                    self.stamper
                        .push(Item::Sample(sample), device_us, arrival_us);
                }
            }
            SessionEvent::Device(event) => {
                if let Some((pad, started)) = contact_change(&event) {
                    let item = Item::Contact {
                        pad: pad.get(),
                        started,
                    };
                    self.stamper.push(item, event.timestamp_us, arrival_us);
                }
            }
            SessionEvent::Info(info) => self.health.info = Some(info),
            SessionEvent::Counters(counters) => self.health.counters = Some(counters),
            SessionEvent::Baselines { .. }
            | SessionEvent::Refused { .. }
            | SessionEvent::BaselinesUnread { .. } => {}
        }
    }
}

/// The publisher with what it published: counts and the `--timing-log`.
pub struct Publication<'a> {
    publisher: &'a mut dyn FramePublisher,
    timing_log: Option<TimingLog>,
    counts: PublishCounts,
}

impl<'a> Publication<'a> {
    /// Publishes through `publisher`, writing a line per sample frame to `timing_log`.
    pub fn new(publisher: &'a mut dyn FramePublisher, timing_log: Option<TimingLog>) -> Self {
        Self {
            publisher,
            timing_log,
            counts: PublishCounts::default(),
        }
    }

    /// Publishes `messages` in order (the timing log's publication time is `relay`'s now).
    pub fn send(&mut self, messages: Vec<Outgoing>, relay: &Relay) -> anyhow::Result<()> {
        for outgoing in messages {
            self.publisher.publish(&outgoing)?;
            match &outgoing {
                Outgoing::Sample {
                    device,
                    sample,
                    arrival_ns,
                    ..
                } => {
                    self.counts.samples += 1;
                    if let Some(log) = self.timing_log.as_mut() {
                        writeln!(
                            log,
                            "{device},{},{},{arrival_ns},{}",
                            sample.pad.get(),
                            sample.sequence,
                            relay.now_ns()
                        )?;
                    }
                }
                Outgoing::Contact { .. } => self.counts.contacts += 1,
            }
        }
        Ok(())
    }

    /// Publishes every device's health, stamped now.
    pub fn health(&mut self, relay: &Relay, queue: &EventQueue) -> anyhow::Result<()> {
        self.publisher
            .publish_health(&relay.healths(queue.dropped_sets()), relay.now_ns())?;
        self.counts.diagnostics += 1;
        Ok(())
    }

    /// Flushes the timing log; returns what was published.
    pub fn finish(mut self) -> anyhow::Result<PublishCounts> {
        if let Some(log) = self.timing_log.as_mut() {
            log.flush()?;
        }
        Ok(self.counts)
    }
}

/// How often items waiting for a clock estimate are looked at when no event comes.
const RELEASE_PERIOD: Duration = Duration::from_millis(100);

/// What the relay loop calls between events to bring devices back ([`crate::reconnect`]).
pub type ReconnectHook<'a, P> = &'a mut dyn FnMut(&mut Worker<P>, &mut Relay);

/// Publishes the worker's events until `stop` is set, `deadline` passes or every device's
/// stream ended (and none is looked for again), and every device's health each
/// `health_period`; serves `commands`, if any, and calls `reconnect`, if any, between events.
#[allow(clippy::too_many_arguments)]
pub fn relay_events<P: Read + Write + Send + 'static>(
    worker: &mut Worker<P>,
    relay: &mut Relay,
    publication: &mut Publication<'_>,
    mut commands: Option<&mut DeviceCommands>,
    mut reconnect: Option<ReconnectHook<'_, P>>,
    stop: &AtomicBool,
    deadline: Option<Instant>,
    health_period: Duration,
) -> anyhow::Result<()> {
    let queue = Arc::clone(worker.queue());
    let mut last_health = Instant::now();
    let mut last_release = Instant::now();
    relay.request_accounting(worker);
    while !stop.load(Ordering::Relaxed)
        && relay.is_running()
        && deadline.is_none_or(|deadline| Instant::now() < deadline)
    {
        if let Some(arrived) = queue.pop_until(Instant::now() + Duration::from_millis(50)) {
            let messages = relay.take(arrived);
            publication.send(messages, relay)?;
        }
        if last_release.elapsed() >= RELEASE_PERIOD {
            let messages = relay.release(relay.clock().now_us());
            publication.send(messages, relay)?;
            last_release = Instant::now();
        }
        relay.poll_accounting();
        if let Some(commands) = commands.as_deref_mut() {
            commands.poll(worker, relay);
        }
        if let Some(reconnect) = reconnect.as_deref_mut() {
            reconnect(worker, relay);
        }
        if last_health.elapsed() >= health_period {
            publication.health(relay, &queue)?;
            relay.request_accounting(worker);
            last_health = Instant::now();
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use taxel_host::pad_set::PadSet;
    use taxel_host::stamping::MAX_WAIT_US;
    use wire::{DeviceEvent, EventFrame, PadIndex, TemperatureSource};

    fn frame(pad: u8, sequence: u32, timestamp_us: u64) -> SampleFrame {
        SampleFrame {
            sequence,
            timestamp_us,
            ..wire::testing::sample_frame(pad)
        }
    }

    fn set_event(device: usize, arrival_us: u64, sequence: u32, device_us: u64) -> ArrivedEvent {
        ArrivedEvent {
            device,
            arrival_us,
            event: WorkerEvent::Session(SessionEvent::Set {
                set: PadSet {
                    sequence,
                    pads: vec![
                        Some(frame(0, sequence, device_us)),
                        Some(frame(1, sequence, device_us + 400)),
                    ],
                },
                sets_missing_before: 0,
            }),
        }
    }

    fn relay_of_one_device() -> Relay {
        let health = DeviceHealth {
            state: ReaderState::Streaming,
            ..DeviceHealth::default()
        };
        // The worker's only device is the bridge's device 1 (device 0 could not be opened).
        Relay::new(
            UnixClock::new(),
            vec![DeviceHealth::default(), health],
            vec![1],
        )
    }

    #[test]
    fn every_frame_and_event_goes_out_in_order_stamped_never_after_its_arrival() {
        let mut relay = relay_of_one_device();
        let mut out = Vec::new();
        // The device clock runs 7 s ahead; sets arrive 0.1 to 2.1 ms after their last frame
        // (taken 0.4 ms after the first; the smallest latency below the mapper's assumed bound).
        for step in 0..300_u64 {
            let true_us = 1_000_000 + step * 10_000;
            let arrival_us = true_us + 500 + (step * 7919) % 2_000;
            out.extend(relay.take(set_event(0, arrival_us, step as u32, true_us + 7_000_000)));
            if step == 150 {
                out.extend(relay.take(ArrivedEvent {
                    device: 0,
                    arrival_us,
                    event: WorkerEvent::Session(SessionEvent::Device(EventFrame {
                        timestamp_us: true_us + 7_000_000,
                        event: DeviceEvent::ContactStarted {
                            pad: PadIndex::new(1).unwrap(),
                        },
                    })),
                }));
            }
        }
        out.extend(relay.finish());
        assert_eq!(out.len(), 601, "nothing dropped");
        let mut previous = None;
        for outgoing in &out {
            match outgoing {
                Outgoing::Sample {
                    device,
                    sample,
                    stamp_ns,
                    arrival_ns,
                } => {
                    assert_eq!(*device, 1);
                    assert!(stamp_ns <= arrival_ns);
                    let key = (sample.sequence, sample.pad.get());
                    assert!(previous < Some(key), "in order");
                    previous = Some(key);
                    let true_us = 1_000_000 + u64::from(sample.sequence) * 10_000;
                    let true_ns = relay.unix_ns(true_us + u64::from(sample.pad.get()) * 400);
                    // Early by at most the mapper's latency bound and fit error, never late.
                    let early_ns = true_ns as i64 - *stamp_ns as i64;
                    assert!((0..3_000_000).contains(&early_ns), "{early_ns} ns");
                }
                Outgoing::Contact {
                    device,
                    pad,
                    started,
                    stamp_ns,
                    arrival_ns,
                } => {
                    assert_eq!((*device, *pad, *started), (1, 1, true));
                    assert!(stamp_ns <= arrival_ns);
                    assert_eq!(previous.map(|(sequence, _)| sequence), Some(150));
                }
            }
        }
        let health = &relay.healths(0)[1];
        assert_eq!(health.frames_published, 600);
        assert_eq!(health.stamped_at_arrival, 0);
        assert!(health.clock.is_some());
        assert_eq!(
            health.temperature_sources,
            [Some(TemperatureSource::Tmp117); 2]
        );
    }

    #[test]
    fn without_a_clock_estimate_items_go_out_at_their_arrival_after_the_wait() {
        let mut relay = relay_of_one_device();
        let mut out = relay.take(set_event(0, 5_000, 1, 77));
        assert!(out.is_empty(), "waiting for the clock");
        assert!(relay.release(5_000 + MAX_WAIT_US - 1).is_empty());
        out.extend(relay.release(5_000 + MAX_WAIT_US));
        assert_eq!(out.len(), 2);
        for outgoing in &out {
            let Outgoing::Sample {
                stamp_ns,
                arrival_ns,
                ..
            } = outgoing
            else {
                panic!("not a sample");
            };
            assert_eq!(stamp_ns, arrival_ns);
            assert_eq!(*stamp_ns, relay.unix_ns(5_000));
        }
        assert_eq!(relay.healths(3)[1].stamped_at_arrival, 2);
        assert_eq!(relay.healths(3)[1].sets_dropped_by_bridge, 3);
        assert!(relay.is_running());
    }

    #[test]
    fn a_devices_end_releases_what_waits_and_stops_it() {
        let mut relay = relay_of_one_device();
        assert!(relay.take(set_event(0, 5_000, 1, 77)).is_empty());
        let info = wire::InfoFrame {
            protocol_version: wire::PROTOCOL_VERSION,
            firmware_version: wire::FirmwareVersion {
                major: 1,
                minor: 0,
                patch: 0,
            },
            board_serial: [1; 12],
            calibration_id: 7,
            calibration_source: wire::CalibrationSource::Defaults,
            rate: wire::SampleRate::Sps400,
            model_tier: wire::Tier::MonotoneCubic,
            streaming: false,
            text_mode: false,
            pad_count: 2,
            clock_us_per_s: 1_000_000,
        };
        let out = relay.take(ArrivedEvent {
            device: 0,
            arrival_us: 6_000,
            event: WorkerEvent::Ended(Box::new(taxel_host::worker::DeviceEnd {
                reason: taxel_host::worker::EndReason::Disconnected("unplugged".into()),
                info,
                accounting: StreamAccounting::new(),
                link: taxel_host::device_link::LinkStatistics::default(),
                counters: None,
                state: None,
            })),
        });
        assert_eq!(out.len(), 2, "the frames that waited go out at the end");
        assert!(!relay.is_running());
        let health = &relay.healths(0)[1];
        assert_eq!(
            health.state,
            ReaderState::Stopped("the device went away: unplugged".into())
        );
        assert_eq!(health.info.map(|info| info.calibration_id), Some(7));
    }

    #[test]
    fn a_device_that_went_away_is_looked_for_and_read_again_with_a_new_clock() {
        let mut relay = relay_of_one_device();
        relay.reconnect_devices();
        for step in 0..300_u64 {
            let true_us = 1_000_000 + step * 10_000;
            relay.take(set_event(0, true_us + 500, step as u32, true_us));
        }
        assert!(relay.healths(0)[1].clock.is_some());
        let info = wire::testing::info_frame(2);
        let ended = |reason| ArrivedEvent {
            device: 0,
            arrival_us: 4_000_000,
            event: WorkerEvent::Ended(Box::new(taxel_host::worker::DeviceEnd {
                reason,
                info,
                accounting: StreamAccounting::new(),
                link: taxel_host::device_link::LinkStatistics::default(),
                counters: None,
                state: None,
            })),
        };
        relay.take(ended(taxel_host::worker::EndReason::Disconnected(
            "unplugged".into(),
        )));
        assert!(
            relay.is_running(),
            "the run goes on while the board is looked for"
        );
        assert_eq!(relay.reconnecting(), vec![(1, 0)]);
        assert!(matches!(
            relay.healths(0)[1].state,
            ReaderState::Reconnecting(_)
        ));
        assert!(relay.command_target(1).is_err());
        // Back: streaming again, its clock estimated anew (the board may have restarted: its
        // first sets wait for the estimate instead of being stamped with the old one).
        relay.reattached(1, info, Vec::new()).unwrap();
        let health = &relay.healths(0)[1];
        assert_eq!(
            (health.state.clone(), health.reconnections),
            (ReaderState::Streaming, 1)
        );
        assert!(health.clock.is_none());
        assert!(relay.reconnecting().is_empty());
        assert!(
            relay.take(set_event(0, 9_000_000, 0, 5)).is_empty(),
            "waits for the clock"
        );
        // A board with other pads is refused.
        relay.take(ended(taxel_host::worker::EndReason::Disconnected(
            "unplugged".into(),
        )));
        let refused = relay
            .reattached(1, info, vec![wire::testing::pad_info_frame(0)])
            .unwrap_err();
        assert!(refused.contains("another board"), "{refused}");
        assert!(matches!(relay.healths(0)[1].state, ReaderState::Stopped(_)));
        assert!(!relay.is_running());
        // A device stopped on purpose is not looked for.
        let mut relay = relay_of_one_device();
        relay.reconnect_devices();
        relay.take(ended(taxel_host::worker::EndReason::Stopped));
        assert!(relay.reconnecting().is_empty() && !relay.is_running());
    }
}
