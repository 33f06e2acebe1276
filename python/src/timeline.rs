//! Several devices on one host timeline: one host-library worker reads every device (a thread
//! each, one queue, arrivals on one host clock), each device's sets are stamped by the host
//! library's stamping policy ([`taxel_host::stamping::Stamper`], the recorder's: the device
//! clock mapped onto the host's, never later than the arrival, with an error bound), and the
//! stamped sets of every device come out merged in host-time order.
//!
//! A set is handed out once no other device can still produce one stamped before it: every
//! other device has a later set stamped already, has ended, or has nothing waiting for its
//! clock estimate and has been silent for [`LATENESS_US`]. The stamper holds a device's sets
//! until its first clock estimate (about 1.5 s of sets, at most
//! [`taxel_host::stamping::MAX_WAIT_US`]), so the first sets come out that late; later ones
//! within a few milliseconds of the slowest device's next set.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use taxel_host::host_clock::{HostClock, UnixClock};
use taxel_host::session::SessionEvent;
use taxel_host::stamping::Stamper;
use taxel_host::stream_accounting::sequence_gap;
use taxel_host::worker::{ArrivedEvent, DeviceEnd, EventQueue, WorkerEvent};
use wire::InfoFrame;

use crate::events::EventRecord;
use crate::locking::lock;
use crate::sample_set::SetRecord;
use crate::stream::{end_words, Ended, EventStore, SetSource};

/// How long a stamped set waits for a silent device (one with nothing stamped after it and
/// nothing waiting for its clock estimate) before it is handed out anyway, µs: more than a
/// set's transit and the mapping's error, so that a set the silent device sends later is
/// stamped after it.
pub const LATENESS_US: u64 = 250_000;

/// How long one wait on the queue lasts before the held sets are looked at again.
const POLL: Duration = Duration::from_millis(10);

/// One device's part of the timeline.
struct Track {
    info: InfoFrame,
    name: String,
    stamper: Stamper<SetRecord>,
    /// Sets in the stamper, waiting for the clock estimate.
    waiting: usize,
    /// Sets stamped and not yet handed out, in stamp order: (host µs, set).
    stamped: VecDeque<(u64, SetRecord)>,
    last_stamp_us: Option<u64>,
    last_sequence: Option<u32>,
    ended: Option<DeviceEnd>,
    sets_delivered: u64,
    incomplete_sets: u64,
    sets_dropped_unread: u64,
}

/// A device's counts for `stats`.
#[derive(Debug, Clone)]
pub struct TrackCounts {
    /// Sets handed to the caller.
    pub sets_delivered: u64,
    /// Sets closed with a pad's frame missing.
    pub incomplete_sets: u64,
    /// Sets dropped because nobody read them (seen as gaps between the sets handed out).
    pub sets_dropped_unread: u64,
    /// The stream's end, once it ended.
    pub ended: Option<DeviceEnd>,
}

struct TimelineState {
    tracks: Vec<Track>,
    events: EventStore,
}

/// Several devices' sets merged on one host timeline (see the module documentation).
pub struct Timeline {
    queue: Arc<EventQueue>,
    clock: UnixClock,
    queue_sets: usize,
    state: Mutex<TimelineState>,
}

fn unix_s(clock: &UnixClock, host_us: u64) -> f64 {
    clock.unix_us(host_us) as f64 / 1e6
}

impl Timeline {
    /// The timeline of the devices whose identities are `infos` (named `names`), read by a
    /// worker into `queue`, their arrivals on `clock`.
    pub fn new(
        queue: Arc<EventQueue>,
        clock: UnixClock,
        infos: Vec<InfoFrame>,
        names: Vec<String>,
    ) -> Self {
        let tracks = infos
            .into_iter()
            .zip(names)
            .map(|(info, name)| {
                let mut stamper = Stamper::default();
                stamper.set_clock_us_per_s(info.clock_us_per_s);
                Track {
                    info,
                    name,
                    stamper,
                    waiting: 0,
                    stamped: VecDeque::new(),
                    last_stamp_us: None,
                    last_sequence: None,
                    ended: None,
                    sets_delivered: 0,
                    incomplete_sets: 0,
                    sets_dropped_unread: 0,
                }
            })
            .collect();
        Self {
            queue_sets: 65_536,
            queue,
            clock,
            state: Mutex::new(TimelineState {
                tracks,
                events: EventStore::default(),
            }),
        }
    }

    /// The timeline with a bound of `queue_sets` sets held for a caller who does not read
    /// (beyond it the oldest are dropped, as the queue does).
    pub fn with_queue_sets(mut self, queue_sets: usize) -> Self {
        self.queue_sets = queue_sets.max(1);
        self
    }

    fn state(&self) -> MutexGuard<'_, TimelineState> {
        lock(&self.state)
    }

    /// Each device's identity as last said.
    pub fn infos(&self) -> Vec<InfoFrame> {
        self.state().tracks.iter().map(|track| track.info).collect()
    }

    /// Each device's counts.
    pub fn counts(&self) -> Vec<TrackCounts> {
        self.state()
            .tracks
            .iter()
            .map(|track| TrackCounts {
                sets_delivered: track.sets_delivered,
                incomplete_sets: track.incomplete_sets,
                sets_dropped_unread: track.sets_dropped_unread,
                ended: track.ended.clone(),
            })
            .collect()
    }

    /// Device events dropped because nobody took them.
    pub fn events_dropped(&self) -> u64 {
        self.state().events.dropped
    }

    /// Why device `device` can no longer be asked anything, if its stream ended.
    pub fn device_ended(&self, device: usize) -> Option<Ended> {
        self.state().tracks.get(device).and_then(|track| {
            track.ended.as_ref().map(|end| {
                Ended(format!(
                    "device {device} ({}): {}",
                    track.name,
                    end_words(end)
                ))
            })
        })
    }

    /// Takes one event of the worker.
    fn ingest(&self, state: &mut TimelineState, arrived: ArrivedEvent) {
        let ArrivedEvent {
            device,
            arrival_us,
            event,
        } = arrived;
        let arrival_unix_s = unix_s(&self.clock, arrival_us);
        let Some(track) = state.tracks.get_mut(device) else {
            return;
        };
        match event {
            WorkerEvent::Session(SessionEvent::Set {
                set,
                sets_missing_before,
            }) => {
                let record =
                    SetRecord::from_pad_set(device, &set, arrival_unix_s, sets_missing_before);
                for frame in set.pads.iter().flatten() {
                    track.stamper.observe(frame.timestamp_us, arrival_us);
                }
                let device_us = record.device_time_us();
                track.stamper.push(record, device_us, arrival_us);
                track.waiting += 1;
            }
            WorkerEvent::Session(SessionEvent::Device(frame)) => {
                state.events.push(EventRecord {
                    device,
                    frame,
                    arrival_unix_s,
                });
            }
            WorkerEvent::Session(SessionEvent::Info(info)) => {
                track.stamper.set_clock_us_per_s(info.clock_us_per_s);
                track.info = info;
            }
            WorkerEvent::Session(_) => {}
            WorkerEvent::Ended(end) => {
                track.ended = Some(*end);
                let finished = track.stamper.finish();
                Self::take_stamped(&self.clock, track, finished);
            }
        }
    }

    fn take_stamped(
        clock: &UnixClock,
        track: &mut Track,
        stamped: Vec<taxel_host::stamping::Stamped<SetRecord>>,
    ) {
        for stamped in stamped {
            track.waiting = track.waiting.saturating_sub(1);
            let mut record = stamped.item;
            record.host_time_s = unix_s(clock, stamped.host_us);
            record.sync_error_ms = stamped
                .error_us
                .map_or(f64::NAN, |error_us| error_us as f64 / 1e3);
            track.last_stamp_us = Some(stamped.host_us);
            track.stamped.push_back((stamped.host_us, record));
        }
    }

    /// Stamps what can be stamped now, and drops the oldest stamped sets beyond the bound.
    fn release(&self, state: &mut TimelineState, now_us: u64) {
        for track in &mut state.tracks {
            let released = track.stamper.release(now_us);
            Self::take_stamped(&self.clock, track, released);
        }
        let held = |tracks: &[Track]| -> usize {
            tracks
                .iter()
                .map(|track| track.stamped.len() + track.waiting)
                .sum()
        };
        while held(&state.tracks) > self.queue_sets {
            let Some(oldest) = Self::earliest(&state.tracks) else {
                break;
            };
            let track = &mut state.tracks[oldest];
            track.stamped.pop_front();
            track.sets_dropped_unread += 1;
        }
    }

    /// The device whose next stamped set is the earliest (the first device on a tie).
    fn earliest(tracks: &[Track]) -> Option<usize> {
        tracks
            .iter()
            .enumerate()
            .filter_map(|(device, track)| {
                track.stamped.front().map(|(host_us, _)| (*host_us, device))
            })
            .min()
            .map(|(_, device)| device)
    }

    /// The next set in host-time order, if no device can still produce an earlier one.
    fn next_ready(state: &mut TimelineState, now_us: u64) -> Option<SetRecord> {
        let first = Self::earliest(&state.tracks)?;
        let host_us = state.tracks[first].stamped.front()?.0;
        let blocked = state.tracks.iter().enumerate().any(|(device, track)| {
            if device == first || track.ended.is_some() || !track.stamped.is_empty() {
                return false;
            }
            if track.waiting > 0 {
                return true;
            }
            let stamped_later = track
                .last_stamp_us
                .is_some_and(|last_us| last_us >= host_us);
            !stamped_later && now_us < host_us.saturating_add(LATENESS_US)
        });
        if blocked {
            return None;
        }
        let track = &mut state.tracks[first];
        let (_, mut set) = track.stamped.pop_front()?;
        if !set.is_complete() {
            track.incomplete_sets += 1;
        }
        track.sets_delivered += 1;
        let gap = track
            .last_sequence
            .map_or(0, |previous| sequence_gap(previous, set.sequence));
        track.last_sequence = Some(set.sequence);
        if gap > set.sets_missing_before {
            track.sets_dropped_unread += gap - set.sets_missing_before;
            set.sets_missing_before = gap;
        }
        Some(set)
    }

    /// The end of the timeline: a device whose stream ended and whose sets were all handed out.
    fn ended(state: &TimelineState) -> Option<Ended> {
        state
            .tracks
            .iter()
            .enumerate()
            .find_map(|(device, track)| match &track.ended {
                Some(end) if track.stamped.is_empty() && track.waiting == 0 => Some(Ended(
                    format!("device {device} ({}): {}", track.name, end_words(end)),
                )),
                _ => None,
            })
    }

    /// The device events that arrived since the last call, oldest first (the sets that came
    /// with them are stamped and held for the next read).
    pub fn take_events(&self) -> Vec<EventRecord> {
        let arrived = self.queue.drain();
        let mut state = self.state();
        for arrived in arrived {
            self.ingest(&mut state, arrived);
        }
        self.release(&mut state, self.clock.now_us());
        state.events.take()
    }
}

impl SetSource for Timeline {
    fn next_set(&self, until: Instant) -> Result<Option<SetRecord>, Ended> {
        loop {
            {
                let mut state = self.state();
                let now_us = self.clock.now_us();
                self.release(&mut state, now_us);
                if let Some(set) = Self::next_ready(&mut state, now_us) {
                    return Ok(Some(set));
                }
                if let Some(ended) = Self::ended(&state) {
                    return Err(ended);
                }
            }
            let now = Instant::now();
            if now >= until {
                return Ok(None);
            }
            if let Some(arrived) = self.queue.pop_until(until.min(now + POLL)) {
                let mut state = self.state();
                self.ingest(&mut state, arrived);
                // Everything else already queued too, so that the stamps see every arrival.
                for arrived in self.queue.drain() {
                    self.ingest(&mut state, arrived);
                }
            }
        }
    }
}
