//! One device's stream as the Python side takes it: the host library's worker reads the device
//! on a thread of its own (so a set's `host_time_s` is its arrival, whenever Python asks), and
//! its events arrive in a bounded queue that drops its oldest sets (counted) if nobody reads,
//! and never drops a device event. [`Stream`] turns those events into [`SetRecord`]s and keeps
//! the rest: the device's identity, its device events (for `Device.events()`), and its end.
//!
//! Taking the device events out of the queue (`events()`) takes the sets queued with them too:
//! they wait in the stream's own queue of the same size, with the same drop-the-oldest rule,
//! so that a caller who asks only for events still gets every one of them.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use taxel_host::session::SessionEvent;
use taxel_host::stream_accounting::sequence_gap;
use taxel_host::worker::{ArrivedEvent, DeviceEnd, EndReason, EventQueue, WorkerEvent};
use wire::InfoFrame;

use crate::events::EventRecord;
use crate::locking::lock;
use crate::sample_set::SetRecord;

/// Sample sets the queue holds by default for a caller that does not read; older ones are
/// dropped and counted beyond this (and the next set read says how many are missing before it).
pub const QUEUE_SETS: usize = 65_536;

/// Device events kept for `events()`; older ones are dropped (and counted) beyond this. A
/// device reports a few events per contact: this is hours of them.
pub const EVENT_CAPACITY: usize = 100_000;

/// How long one wait on the queue lasts before the stream's own queue is looked at again.
const WAITING_POLL: Duration = Duration::from_millis(10);

/// Why no more sets will come.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ended(pub String);

/// The words of a stream's end.
pub fn end_words(end: &DeviceEnd) -> String {
    match &end.reason {
        EndReason::Stopped => "the device is closed".to_owned(),
        EndReason::Disconnected(message) => format!("the device went away: {message}"),
        EndReason::Failed(message) => message.clone(),
    }
}

/// Something sets are read from: one device's stream, or several devices' timeline.
pub trait SetSource: Send + Sync {
    /// The oldest set not yet taken, waiting until `until` at most; the end once every set
    /// before it was taken.
    fn next_set(&self, until: Instant) -> Result<Option<SetRecord>, Ended>;
}

/// Device events taken out of a queue and not yet handed to the caller, bounded.
#[derive(Debug, Default)]
pub struct EventStore {
    events: VecDeque<EventRecord>,
    /// Events dropped because nobody took them.
    pub dropped: u64,
}

impl EventStore {
    /// Keeps an event (dropping the oldest beyond [`EVENT_CAPACITY`]).
    pub fn push(&mut self, event: EventRecord) {
        if self.events.len() >= EVENT_CAPACITY {
            self.events.pop_front();
            self.dropped += 1;
        }
        self.events.push_back(event);
    }

    /// Every event kept, oldest first; the store is empty afterwards.
    pub fn take(&mut self) -> Vec<EventRecord> {
        self.events.drain(..).collect()
    }
}

/// What the stream has said besides its sets.
#[derive(Debug)]
pub struct StreamState {
    /// The device's identity as last said.
    pub info: InfoFrame,
    /// Device events not yet taken.
    pub events: EventStore,
    /// The end of the stream, once it ended.
    pub ended: Option<DeviceEnd>,
    /// Sets handed to the caller.
    pub sets_delivered: u64,
    /// Sets closed with at least one pad's frame missing.
    pub incomplete_sets: u64,
    /// Sets taken out of the queue with the events and not yet handed out.
    waiting: VecDeque<SetRecord>,
    /// Sets dropped from `waiting` because nobody read them.
    waiting_dropped: u64,
    /// The sequence number of the last set handed out.
    last_sequence: Option<u32>,
}

/// One device's stream (see the module documentation).
#[derive(Debug)]
pub struct Stream {
    queue: Arc<EventQueue>,
    queue_sets: usize,
    origin_unix_s: f64,
    state: Mutex<StreamState>,
}

impl Stream {
    /// The stream of a worker whose queue is `queue` (of `queue_sets` sets) and whose host
    /// clock started at `origin_unix_s` (Unix seconds).
    pub fn new(
        queue: Arc<EventQueue>,
        queue_sets: usize,
        origin_unix_s: f64,
        info: InfoFrame,
    ) -> Self {
        Self {
            queue,
            queue_sets: queue_sets.max(1),
            origin_unix_s,
            state: Mutex::new(StreamState {
                info,
                events: EventStore::default(),
                ended: None,
                sets_delivered: 0,
                incomplete_sets: 0,
                waiting: VecDeque::new(),
                waiting_dropped: 0,
                last_sequence: None,
            }),
        }
    }

    /// The stream's state.
    pub fn state(&self) -> std::sync::MutexGuard<'_, StreamState> {
        lock(&self.state)
    }

    /// Sets dropped because nobody read them.
    pub fn sets_dropped_unread(&self) -> u64 {
        self.queue.dropped_sets() + self.state().waiting_dropped
    }

    /// Takes one event: a sample set becomes a record (stamped with its arrival); the others
    /// update the state.
    fn take(&self, state: &mut StreamState, arrived: ArrivedEvent) -> Option<SetRecord> {
        let arrival_unix_s = self.origin_unix_s + arrived.arrival_us as f64 * 1e-6;
        match arrived.event {
            WorkerEvent::Session(SessionEvent::Set {
                set,
                sets_missing_before,
            }) => {
                return Some(SetRecord::from_pad_set(
                    0,
                    &set,
                    arrival_unix_s,
                    sets_missing_before,
                ));
            }
            WorkerEvent::Session(SessionEvent::Device(frame)) => state.events.push(EventRecord {
                device: 0,
                frame,
                arrival_unix_s,
            }),
            WorkerEvent::Session(SessionEvent::Info(info)) => state.info = info,
            WorkerEvent::Session(_) => {}
            WorkerEvent::Ended(end) => state.ended = Some(*end),
        }
        None
    }

    /// Hands a set to the caller: the sets dropped unread before it (the queue's or this
    /// stream's) count as missing before it, as the caller sees it.
    fn deliver(state: &mut StreamState, mut set: SetRecord) -> SetRecord {
        if !set.is_complete() {
            state.incomplete_sets += 1;
        }
        state.sets_delivered += 1;
        let dropped_unread = state
            .last_sequence
            .map_or(0, |previous| sequence_gap(previous, set.sequence));
        state.last_sequence = Some(set.sequence);
        set.sets_missing_before = set.sets_missing_before.max(dropped_unread);
        set
    }

    fn ended(state: &StreamState) -> Option<Ended> {
        state.ended.as_ref().map(|end| Ended(end_words(end)))
    }

    /// Every set queued now, oldest first (the events among them are taken too).
    pub fn drain_sets(&self) -> Vec<SetRecord> {
        let arrived = self.queue.drain();
        let mut state = self.state();
        let mut sets: Vec<SetRecord> = state.waiting.drain(..).collect();
        for arrived in arrived {
            sets.extend(self.take(&mut state, arrived));
        }
        sets.into_iter()
            .map(|set| Self::deliver(&mut state, set))
            .collect()
    }

    /// The device events that arrived since the last call, oldest first. The sets queued with
    /// them wait for the next read (see the module documentation).
    pub fn take_events(&self) -> Vec<EventRecord> {
        let arrived = self.queue.drain();
        let mut state = self.state();
        for arrived in arrived {
            if let Some(set) = self.take(&mut state, arrived) {
                if state.waiting.len() >= self.queue_sets {
                    state.waiting.pop_front();
                    state.waiting_dropped += 1;
                }
                state.waiting.push_back(set);
            }
        }
        state.events.take()
    }

    /// Whether the stream ended (every set before the end taken).
    pub fn is_ended(&self) -> Option<Ended> {
        let state = self.state();
        if state.waiting.is_empty() {
            Self::ended(&state)
        } else {
            None
        }
    }
}

impl SetSource for Stream {
    fn next_set(&self, until: Instant) -> Result<Option<SetRecord>, Ended> {
        loop {
            {
                let mut state = self.state();
                if let Some(set) = state.waiting.pop_front() {
                    return Ok(Some(Self::deliver(&mut state, set)));
                }
                if let Some(ended) = Self::ended(&state) {
                    return Err(ended);
                }
            }
            // In short waits: `take_events` on another thread may move the sets into
            // `waiting` meanwhile, and nothing in the queue would say so.
            let now = Instant::now();
            let Some(arrived) = self.queue.pop_until(until.min(now + WAITING_POLL)) else {
                if Instant::now() >= until {
                    return Ok(None);
                }
                continue;
            };
            let mut state = self.state();
            if let Some(set) = self.take(&mut state, arrived) {
                return Ok(Some(Self::deliver(&mut state, set)));
            }
        }
    }
}
