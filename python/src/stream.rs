//! One device's stream as the Python side takes it: the host library's worker reads the device
//! on a thread of its own (so a set's `host_time_s` is its arrival, whenever Python asks), and
//! its events arrive in a bounded queue that drops its oldest sets (counted) if nobody reads.
//! [`Stream`] turns those events into [`SetRecord`]s and keeps the rest: the device's identity,
//! its events, and its end.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use taxel_host::session::SessionEvent;
use taxel_host::stream_accounting::sequence_gap;
use taxel_host::worker::{ArrivedEvent, DeviceEnd, EndReason, EventQueue, WorkerEvent};
use wire::{EventFrame, InfoFrame};

use crate::locking::lock;
use crate::sample_set::SetRecord;

/// Sample sets the queue holds by default for a caller that does not read; older ones are
/// dropped and counted beyond this (and the next set read says how many are missing before it).
pub const QUEUE_SETS: usize = 65_536;

/// Device events kept for `Device.events()`; older ones are dropped beyond this.
const EVENT_CAPACITY: usize = 10_000;

/// What the stream has said besides its sets.
#[derive(Debug)]
pub struct StreamState {
    /// The device's identity as last said.
    pub info: InfoFrame,
    /// Device events not yet taken, with their arrival (Unix seconds).
    pub events: VecDeque<(EventFrame, f64)>,
    /// Events dropped because nobody took them.
    pub events_dropped: u64,
    /// The end of the stream, once it ended.
    pub ended: Option<DeviceEnd>,
    /// Sets handed to the caller.
    pub sets_delivered: u64,
    /// Sets closed with at least one pad's frame missing.
    pub incomplete_sets: u64,
    /// The sequence number of the last set taken from the queue.
    last_sequence: Option<u32>,
}

/// Why no more sets will come.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ended(pub String);

/// One device's stream (see the module documentation).
#[derive(Debug)]
pub struct Stream {
    queue: Arc<EventQueue>,
    origin_unix_s: f64,
    state: Mutex<StreamState>,
}

impl Stream {
    /// The stream of a worker whose queue is `queue` and whose host clock started at
    /// `origin_unix_s` (Unix seconds).
    pub fn new(queue: Arc<EventQueue>, origin_unix_s: f64, info: InfoFrame) -> Self {
        Self {
            queue,
            origin_unix_s,
            state: Mutex::new(StreamState {
                info,
                events: VecDeque::new(),
                events_dropped: 0,
                ended: None,
                sets_delivered: 0,
                incomplete_sets: 0,
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
        self.queue.dropped_sets()
    }

    /// Takes one event: a sample set becomes a record (stamped with its arrival); the others
    /// update the state.
    fn take(&self, arrived: ArrivedEvent) -> Option<SetRecord> {
        let arrival_unix_s = self.origin_unix_s + arrived.arrival_us as f64 * 1e-6;
        let mut state = self.state();
        match arrived.event {
            WorkerEvent::Session(SessionEvent::Set {
                set,
                sets_missing_before,
            }) => {
                if !set.is_complete() {
                    state.incomplete_sets += 1;
                }
                state.sets_delivered += 1;
                // Sets the queue dropped unread are missing too, as the caller sees it.
                let dropped_unread = state
                    .last_sequence
                    .map_or(0, |previous| sequence_gap(previous, set.sequence));
                state.last_sequence = Some(set.sequence);
                return Some(SetRecord::from_pad_set(
                    &set,
                    arrival_unix_s,
                    sets_missing_before.max(dropped_unread),
                ));
            }
            WorkerEvent::Session(SessionEvent::Device(event)) => {
                if state.events.len() >= EVENT_CAPACITY {
                    state.events.pop_front();
                    state.events_dropped += 1;
                }
                state.events.push_back((event, arrival_unix_s));
            }
            WorkerEvent::Session(SessionEvent::Info(info)) => state.info = info,
            WorkerEvent::Session(_) => {}
            WorkerEvent::Ended(end) => state.ended = Some(*end),
        }
        None
    }

    fn ended(&self) -> Option<Ended> {
        self.state().ended.as_ref().map(|end| {
            Ended(match &end.reason {
                EndReason::Stopped => "the device is closed".to_owned(),
                EndReason::Disconnected(message) => format!("the device went away: {message}"),
                EndReason::Failed(message) => message.clone(),
            })
        })
    }

    /// The oldest set not yet taken, waiting until `until` at most; the end of the stream
    /// once every set before it was taken.
    pub fn next_set(&self, until: Instant) -> Result<Option<SetRecord>, Ended> {
        loop {
            if let Some(ended) = self.ended() {
                return Err(ended);
            }
            let Some(arrived) = self.queue.pop_until(until) else {
                return Ok(None);
            };
            if let Some(set) = self.take(arrived) {
                return Ok(Some(set));
            }
        }
    }

    /// Every set queued now, oldest first (the events among them are taken too).
    pub fn drain_sets(&self) -> Vec<SetRecord> {
        self.queue
            .drain()
            .into_iter()
            .filter_map(|arrived| self.take(arrived))
            .collect()
    }

    /// Whether the stream ended (every set before the end taken).
    pub fn is_ended(&self) -> Option<Ended> {
        self.ended()
    }
}
