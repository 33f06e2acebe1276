//! The view's engine, for any number of devices, with no terminal: [`LiveView`].
//!
//! Each device is opened as a [`taxel_host::session::DeviceSession`] on a thread of its own and
//! then read by a [`Worker`] of one session into a queue of its own that drops its oldest sample
//! sets when the view falls behind (counted, and shown). Every arrival is stamped on one
//! [`UnixClock`], so the devices share a timeline; the view takes every device's events each
//! tick in the order they arrived.
//!
//! Requests never make the view wait: the tare is sent and its reply looked for by jobs on the
//! device's thread whose results are polled; the accounting is read from each session every
//! half second the same way. The device's own counters arrive with its stream.
//!
//! Reconnection, one policy: a device that cannot be opened is tried again every 0.5 s, one
//! that went away is looked for again 0.2 s later (by its serial number when it has one, so a
//! replugged board is found under a new name); a path that is not a serial port is not tried
//! again. `--once` tries each device once.

use std::path::PathBuf;
use std::sync::mpsc::{Receiver, TryRecvError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use taxel_host::console::error_message;
use taxel_host::device_link::LinkError;
use taxel_host::device_state::RecordedDeviceState;
use taxel_host::host_clock::{HostClock, UnixClock};
use taxel_host::stream_accounting::StreamAccounting;
use taxel_host::worker::{ArrivedEvent, EndReason, EventQueue, Overflow, Worker, WorkerEvent};
use wire::{Command, ErrorCode, PadIndex, ReplyPayload};

use super::devices::DevicesView;
use super::record::{Stopping, ViewRecording};
use super::target::{open_in_background, Attempt, BoardTarget, OpenFailure, Opened, Port};
use super::ViewArgs;
use crate::layout::Layout;

/// Events a device's queue holds before the view drops its oldest sample sets: 40 s of one pad
/// at 100 sets/s, so only a view that stopped drawing falls that far behind.
const QUEUE_EVENTS: usize = 4096;
/// How often the view reads each session's accounting.
const ACCOUNTING_INTERVAL: Duration = Duration::from_millis(500);
/// How soon a device that went away is looked for again.
const REOPEN_AFTER_LOSS: Duration = Duration::from_millis(200);
/// How often a device that cannot be opened is tried again.
const RETRY_INTERVAL: Duration = Duration::from_millis(500);
/// How often the view looks for a tare's reply.
const TARE_POLL_INTERVAL: Duration = Duration::from_millis(100);

/// What a job on a device's thread gave, looked at without waiting.
enum Polled<T> {
    Ready(T),
    Waiting,
    Gone,
}

fn poll<T>(receiver: &Receiver<T>) -> Polled<T> {
    match receiver.try_recv() {
        Ok(value) => Polled::Ready(value),
        Err(TryRecvError::Empty) => Polled::Waiting,
        Err(TryRecvError::Disconnected) => Polled::Gone,
    }
}

/// The reply to an awaited request, if it came.
type ReplyLook = Result<Option<Result<ReplyPayload, ErrorCode>>, LinkError>;

/// A tare in flight: sent by a job on the device's thread, then its reply looked for.
enum Tare {
    Sending(Receiver<Result<u16, LinkError>>),
    Awaiting {
        request_id: u16,
        deadline: Instant,
        next_look: Instant,
        look: Option<Receiver<ReplyLook>>,
    },
}

/// A device being read.
struct Connection {
    worker: Worker<Port>,
    queue: Arc<EventQueue>,
}

/// One device of the view: how to find it, its connection, and the requests in flight.
struct DeviceSlot {
    target: BoardTarget,
    connection: Option<Connection>,
    opening: Option<Receiver<Attempt>>,
    /// When to try to open it (`None`: not again).
    next_attempt: Option<Instant>,
    /// The last attempt's failure.
    failure: Option<anyhow::Error>,
    accounting: Option<Receiver<(StreamAccounting, u64)>>,
    accounting_asked: Option<Instant>,
    tare: Option<Tare>,
    /// Sets skipped by the view on earlier connections.
    skipped_earlier: u64,
}

impl DeviceSlot {
    fn skipped(&self) -> u64 {
        self.skipped_earlier
            + self
                .connection
                .as_ref()
                .map_or(0, |connection| connection.queue.dropped_sets())
    }
}

/// The recording, if any.
enum RecordingPhase {
    Off,
    On(ViewRecording),
    Stopping(Stopping),
}

/// The live view of any number of devices without a terminal: [`LiveView::tick`] takes what
/// the devices sent, [`LiveView::press`] takes a key, [`LiveView::view`] is what to draw.
pub struct LiveView {
    view: DevicesView,
    slots: Vec<DeviceSlot>,
    clock: UnixClock,
    tare_sets: u16,
    record_dir: PathBuf,
    once: bool,
    /// How long the view's requests (identity, state, baselines) wait for their reply.
    request_timeout: Duration,
    recording: RecordingPhase,
    saved: Option<String>,
}

impl LiveView {
    /// The view of the devices `args` name (the PORTs, then the `--serial` boards; neither:
    /// the only attached board), laid out by `layout`; nothing is opened before the first
    /// [`LiveView::tick`]. A port or serial number given twice is refused.
    pub fn new(args: &ViewArgs, layout: Option<Layout>) -> anyhow::Result<Self> {
        let board = &args.board;
        board.refuse_repeats("shown")?;
        let by_port = board
            .ports
            .iter()
            .map(|port| BoardTarget::new(Some(port.clone()), None, board.usb.vid, board.usb.pid));
        let by_serial = board.serial.iter().map(|serial| {
            BoardTarget::new(None, Some(serial.clone()), board.usb.vid, board.usb.pid)
        });
        let mut targets: Vec<BoardTarget> = by_port.chain(by_serial).collect();
        if targets.is_empty() {
            targets.push(BoardTarget::new(None, None, board.usb.vid, board.usb.pid));
        }
        let mut view =
            DevicesView::new(targets.iter().map(BoardTarget::describe).collect(), layout);
        for device in &mut view.devices {
            device.state.full_scale_kpa = args.full_scale_kpa;
            device.state.history_s = args.history_s;
        }
        if args.pad.is_some() {
            view.show_pad(args.pad);
        }
        let now = Instant::now();
        let slots = targets
            .into_iter()
            .map(|target| DeviceSlot {
                target,
                connection: None,
                opening: None,
                next_attempt: Some(now),
                failure: None,
                accounting: None,
                accounting_asked: None,
                tare: None,
                skipped_earlier: 0,
            })
            .collect();
        Ok(Self {
            view,
            slots,
            clock: UnixClock::new(),
            tare_sets: args.tare_sets,
            record_dir: args.record_dir.clone(),
            once: args.once,
            request_timeout: args.link.timeout(),
            recording: RecordingPhase::Off,
            saved: None,
        })
    }

    /// What to draw.
    pub fn view(&self) -> &DevicesView {
        &self.view
    }

    /// Whether a device is being opened now.
    pub fn opening(&self) -> bool {
        self.slots.iter().any(|slot| slot.opening.is_some())
    }

    /// Whether any device is being read.
    pub fn any_connected(&self) -> bool {
        self.slots.iter().any(|slot| slot.connection.is_some())
    }

    /// The error of the first device whose last attempt to be opened failed, taken (`None`:
    /// none failed).
    pub fn take_failure(&mut self) -> Option<anyhow::Error> {
        self.slots.iter_mut().find_map(|slot| slot.failure.take())
    }

    /// Whether a recording is running (or being saved).
    pub fn is_recording(&self) -> bool {
        !matches!(self.recording, RecordingPhase::Off)
    }

    /// Opens the devices due, takes every device's events, and looks at the requests in
    /// flight and the recording.
    pub fn tick(&mut self) {
        let now = Instant::now();
        for device in 0..self.slots.len() {
            self.open_when_due(device, now);
            self.take_attempt(device, now);
        }
        for event in self.take_events() {
            self.apply(event);
        }
        for device in 0..self.slots.len() {
            self.poll_accounting(device, now);
            self.poll_tare(device, now);
        }
        self.poll_recording();
        self.view.refresh(self.clock.now_us());
    }

    /// Takes a key: t tare, p pause, r record, m marker, 0-7 a pad in detail, a every pad, d
    /// the next device; `false` for q (quit).
    pub fn press(&mut self, key: char) -> bool {
        match key {
            'q' => return false,
            'p' => self.view.set_paused(!self.view.paused),
            'a' => self.view.show_pad(None),
            'd' => self.view.select_next_device(),
            't' => self.tare(),
            'r' => self.toggle_recording(),
            'm' => self.mark(),
            digit @ '0'..='7' => self
                .view
                .show_pad(digit.to_digit(10).and_then(|pad| u8::try_from(pad).ok())),
            _ => {}
        }
        true
    }

    /// What the last recording saved said (the files, or why it failed).
    pub fn last_saved(&self) -> Option<&str> {
        self.saved.as_deref()
    }

    /// Stops every device (their last sets and ends are taken) and a recording in progress,
    /// which is saved; gives the view back, and what the last recording saved said.
    pub fn finish(mut self) -> (DevicesView, Option<String>) {
        let mut events = Vec::new();
        for (device, slot) in self.slots.iter_mut().enumerate() {
            if let Some(connection) = slot.connection.take() {
                slot.skipped_earlier += connection.queue.dropped_sets();
                let _ = connection.worker.finish();
                events.extend(connection.queue.drain().into_iter().map(|mut event| {
                    event.device = device;
                    event
                }));
            }
        }
        events.sort_by_key(|event| event.arrival_us);
        for event in events {
            self.apply(event);
        }
        match std::mem::replace(&mut self.recording, RecordingPhase::Off) {
            RecordingPhase::Off => {}
            RecordingPhase::On(recording) => {
                // The recorder took every device's end, with its state.
                let states = self.slots.iter().map(|_| None).collect();
                self.save(Stopping::new(recording, states));
            }
            RecordingPhase::Stopping(stopping) => self.save(stopping),
        }
        self.view.set_recording(None);
        self.view.refresh(self.clock.now_us());
        (self.view, self.saved)
    }

    fn open_when_due(&mut self, device: usize, now: Instant) {
        let Some(slot) = self.slots.get_mut(device) else {
            return;
        };
        if slot.connection.is_some()
            || slot.opening.is_some()
            || slot.next_attempt.is_none_or(|when| now < when)
        {
            return;
        }
        slot.next_attempt = None;
        slot.opening = Some(open_in_background(&slot.target, self.request_timeout));
    }

    fn take_attempt(&mut self, device: usize, now: Instant) {
        let (Some(slot), Some(shown)) = (
            self.slots.get_mut(device),
            self.view.devices.get_mut(device),
        ) else {
            return;
        };
        let Some(opening) = &slot.opening else {
            return;
        };
        let (target, result) = match poll(opening) {
            Polled::Waiting => return,
            Polled::Gone => {
                slot.opening = None;
                slot.next_attempt = (!self.once).then_some(now + RETRY_INTERVAL);
                return;
            }
            Polled::Ready(attempt) => attempt,
        };
        slot.opening = None;
        slot.target = target;
        match result {
            Ok(Opened { session, source }) => {
                shown.connected_to(source, *session.info());
                if let Some(state) = session.state() {
                    shown.state.set_geometries(state);
                }
                let queue = Arc::new(EventQueue::new(QUEUE_EVENTS, Overflow::DropOldestSet));
                let clock: Arc<dyn HostClock> = Arc::new(self.clock);
                match Worker::start(vec![session], Arc::clone(&queue), clock) {
                    Ok(worker) => {
                        slot.failure = None;
                        slot.accounting_asked = None;
                        slot.connection = Some(Connection { worker, queue });
                    }
                    Err(error) => {
                        let error = anyhow::Error::new(error).context("starting its reader");
                        shown.state.connection_lost(error_message(&error));
                        slot.failure = Some(error);
                        slot.next_attempt = (!self.once).then_some(now + RETRY_INTERVAL);
                    }
                }
            }
            Err(OpenFailure { error, permanent }) => {
                let message = error_message(&error);
                shown.state.connection_lost(if permanent && !self.once {
                    format!("{message}; press q to quit")
                } else if permanent || self.once {
                    message
                } else {
                    format!("waiting for {} ({message})", slot.target.describe())
                });
                slot.failure = Some(error);
                slot.next_attempt = (!permanent && !self.once).then_some(now + RETRY_INTERVAL);
            }
        }
    }

    /// Every device's events queued now, in the order they arrived.
    fn take_events(&mut self) -> Vec<ArrivedEvent> {
        let mut events = Vec::new();
        for (device, (slot, shown)) in self.slots.iter().zip(&mut self.view.devices).enumerate() {
            if let Some(connection) = &slot.connection {
                events.extend(connection.queue.drain().into_iter().map(|mut event| {
                    event.device = device;
                    event
                }));
                shown.state.view_dropped_sets = connection.queue.dropped_sets();
            }
        }
        // Stable: each device's events stay in their order.
        events.sort_by_key(|event| event.arrival_us);
        events
    }

    /// One event: to the view, to the recording, and a device's end.
    fn apply(&mut self, event: ArrivedEvent) {
        let device = event.device;
        let Some(shown) = self.view.devices.get_mut(device) else {
            return;
        };
        let ended = match &event.event {
            WorkerEvent::Session(session_event) => {
                shown.apply_event(session_event, event.arrival_us);
                None
            }
            WorkerEvent::Ended(end) => {
                shown
                    .state
                    .set_accounting(end.accounting.clone(), end.link.frames_rejected);
                if let RecordingPhase::Stopping(stopping) = &mut self.recording {
                    stopping.ended(device, end.state.as_ref());
                }
                Some(end.reason.clone())
            }
        };
        if let RecordingPhase::On(recording) = &mut self.recording {
            if let Err(error) = recording.take(event) {
                if let RecordingPhase::On(failed) =
                    std::mem::replace(&mut self.recording, RecordingPhase::Off)
                {
                    let words = failed.abandon(&error);
                    self.view.set_recording(None);
                    self.view.say(words);
                }
            }
        }
        if let Some(reason) = ended {
            self.ended(device, reason);
        }
    }

    /// A device's stream ended: unless the view stopped it, it is looked for again.
    fn ended(&mut self, device: usize, reason: EndReason) {
        let now = Instant::now();
        let Some(slot) = self.slots.get_mut(device) else {
            return;
        };
        if let Some(connection) = slot.connection.take() {
            slot.skipped_earlier += connection.queue.dropped_sets();
            // Its thread has ended: this only takes it back.
            let _ = connection.worker.finish();
        }
        slot.tare = None;
        slot.accounting = None;
        let message = match reason {
            EndReason::Stopped => return,
            EndReason::Disconnected(message) | EndReason::Failed(message) => message,
        };
        let waiting = if self.once {
            String::new()
        } else {
            format!("; waiting for {}", slot.target.describe())
        };
        slot.next_attempt = (!self.once).then_some(now + REOPEN_AFTER_LOSS);
        if let Some(shown) = self.view.devices.get_mut(device) {
            shown
                .state
                .connection_lost(format!("connection lost ({message}){waiting}"));
        }
        if matches!(self.recording, RecordingPhase::On(_)) {
            self.stop_recording(&format!("dev {device} went away"));
        }
    }

    fn poll_accounting(&mut self, device: usize, now: Instant) {
        let (Some(slot), Some(shown)) = (
            self.slots.get_mut(device),
            self.view.devices.get_mut(device),
        ) else {
            return;
        };
        let Some(connection) = &slot.connection else {
            return;
        };
        if let Some(receiver) = &slot.accounting {
            match poll(receiver) {
                Polled::Waiting => {}
                Polled::Gone => slot.accounting = None,
                Polled::Ready((accounting, frames_rejected)) => {
                    shown.state.set_accounting(accounting, frames_rejected);
                    slot.accounting = None;
                }
            }
            return;
        }
        if slot
            .accounting_asked
            .is_some_and(|asked| now.duration_since(asked) < ACCOUNTING_INTERVAL)
        {
            return;
        }
        slot.accounting_asked = Some(now);
        slot.accounting = connection
            .worker
            .run(0, |session| {
                (
                    session.accounting().clone(),
                    session.link_statistics().frames_rejected,
                )
            })
            .ok();
    }

    /// How long a tare's reply may take: the tare itself (its sets at the slowest rate, 25
    /// sets/s with eight pads on a 100 kHz bus) and a margin.
    fn tare_timeout(&self) -> Duration {
        Duration::from_secs(2) + Duration::from_millis(50) * u32::from(self.tare_sets)
    }

    /// Tares the pad shown in the detailed view, or every pad of every connected device.
    fn tare(&mut self) {
        let sample_sets = self.tare_sets;
        let only = self.view.pad_in_detail();
        let pad = only.and_then(|(_, pad)| PadIndex::new(pad));
        for (device, (slot, shown)) in self
            .slots
            .iter_mut()
            .zip(&mut self.view.devices)
            .enumerate()
        {
            if only.is_some_and(|(shown_device, _)| shown_device != device) {
                continue;
            }
            let Some(connection) = &slot.connection else {
                shown.state.status = "tare needs a connected device".to_owned();
                continue;
            };
            let sent = connection.worker.run(0, move |session| {
                session.send(Command::Tare { sample_sets, pad })
            });
            match sent {
                Ok(receiver) => {
                    slot.tare = Some(Tare::Sending(receiver));
                    shown.state.status = match pad {
                        Some(pad) => format!(
                            "tare of pad {} running over {sample_sets} sample sets: keep it unloaded",
                            pad.get()
                        ),
                        None => format!(
                            "tare running over {sample_sets} sample sets: keep the pad unloaded"
                        ),
                    };
                }
                Err(error) => shown.state.status = format!("tare not sent: {error}"),
            }
        }
        if self.view.shown_device().is_none() {
            self.view.say("tare sent to every connected device");
        }
    }

    fn poll_tare(&mut self, device: usize, now: Instant) {
        let timeout = self.tare_timeout();
        let (Some(slot), Some(shown)) = (
            self.slots.get_mut(device),
            self.view.devices.get_mut(device),
        ) else {
            return;
        };
        let (Some(connection), Some(tare)) = (&slot.connection, slot.tare.take()) else {
            return;
        };
        let status = &mut shown.state.status;
        slot.tare = match tare {
            Tare::Sending(receiver) => match poll(&receiver) {
                Polled::Waiting => Some(Tare::Sending(receiver)),
                Polled::Gone => None,
                Polled::Ready(Err(error)) => {
                    *status = format!("tare not sent: {error}");
                    None
                }
                Polled::Ready(Ok(request_id)) => Some(Tare::Awaiting {
                    request_id,
                    deadline: now + timeout,
                    next_look: now + TARE_POLL_INTERVAL,
                    look: None,
                }),
            },
            Tare::Awaiting {
                request_id,
                deadline,
                next_look,
                look: Some(receiver),
            } => match poll(&receiver) {
                Polled::Waiting => Some(Tare::Awaiting {
                    request_id,
                    deadline,
                    next_look,
                    look: Some(receiver),
                }),
                Polled::Gone => None,
                Polled::Ready(Ok(Some(Ok(_)))) => {
                    *status = "tare done".to_owned();
                    None
                }
                Polled::Ready(Ok(Some(Err(code)))) => {
                    *status = format!("tare refused: {code:?}");
                    None
                }
                Polled::Ready(Err(error)) => {
                    *status = format!("tare: {error}");
                    None
                }
                Polled::Ready(Ok(None)) if now >= deadline => {
                    *status = format!("tare: no reply within {} s", timeout.as_secs());
                    // Best effort: the reply, if it still comes, is then an ordinary frame.
                    let _ = connection.worker.run(0, move |session| {
                        let _ = session.no_reply_error(request_id, timeout);
                    });
                    None
                }
                Polled::Ready(Ok(None)) => Some(Tare::Awaiting {
                    request_id,
                    deadline,
                    next_look: now + TARE_POLL_INTERVAL,
                    look: None,
                }),
            },
            Tare::Awaiting {
                request_id,
                deadline,
                next_look,
                look: None,
            } => {
                let look = if now >= next_look {
                    connection
                        .worker
                        .run(0, move |session| {
                            session.wait_reply(request_id, Instant::now())
                        })
                        .ok()
                } else {
                    None
                };
                Some(Tare::Awaiting {
                    request_id,
                    deadline,
                    next_look,
                    look,
                })
            }
        };
    }

    /// Sets the view skipped so far, every device's.
    fn skipped(&self) -> u64 {
        self.slots.iter().map(DeviceSlot::skipped).sum()
    }

    fn toggle_recording(&mut self) {
        match &self.recording {
            RecordingPhase::On(_) => self.stop_recording("stopped"),
            RecordingPhase::Stopping(stopping) => {
                let words = format!("still saving {}", stopping.file());
                self.view.say(words);
            }
            RecordingPhase::Off if !self.any_connected() => {
                self.view.say("recording needs a connected device");
            }
            RecordingPhase::Off => {
                let clock_rates: Vec<u32> = self
                    .view
                    .devices
                    .iter()
                    .map(|device| {
                        device
                            .state
                            .info
                            .map_or(1_000_000, |info| info.clock_us_per_s)
                    })
                    .collect();
                let started = ViewRecording::start(
                    &self.record_dir,
                    &clock_rates,
                    self.clock,
                    self.skipped(),
                );
                match started {
                    Ok(recording) => {
                        let words = format!(
                            "recording every device to {} (no raw byte log: `taxel record` writes one)",
                            recording.file()
                        );
                        self.view.set_recording(Some(recording.status()));
                        self.recording = RecordingPhase::On(recording);
                        self.view.say(words);
                    }
                    Err(error) => {
                        self.view
                            .say(format!("cannot record: {}", error_message(&error)));
                    }
                }
            }
        }
    }

    /// Stops taking events into the recording and asks every device's session for its state;
    /// the recording is saved when they came ([`LiveView::tick`]).
    fn stop_recording(&mut self, why: &str) {
        let RecordingPhase::On(recording) =
            std::mem::replace(&mut self.recording, RecordingPhase::Off)
        else {
            return;
        };
        let states: Vec<Option<Receiver<Option<RecordedDeviceState>>>> = self
            .slots
            .iter()
            .map(|slot| {
                slot.connection.as_ref().and_then(|connection| {
                    connection
                        .worker
                        .run(0, |session| session.state().cloned())
                        .ok()
                })
            })
            .collect();
        let words = format!("recording {why}: saving {}", recording.file());
        self.recording = RecordingPhase::Stopping(Stopping::new(recording, states));
        self.view.set_recording(None);
        self.view.say(words);
    }

    fn poll_recording(&mut self) {
        match &mut self.recording {
            RecordingPhase::Off => {}
            RecordingPhase::On(recording) => {
                let status = recording.status();
                self.view.set_recording(Some(status));
            }
            RecordingPhase::Stopping(stopping) => {
                if stopping.ready() {
                    if let RecordingPhase::Stopping(stopping) =
                        std::mem::replace(&mut self.recording, RecordingPhase::Off)
                    {
                        self.save(stopping);
                    }
                }
            }
        }
    }

    fn save(&mut self, stopping: Stopping) {
        let words = stopping.finish(self.skipped());
        self.view.say(words.clone());
        self.saved = Some(words);
    }

    fn mark(&mut self) {
        match &mut self.recording {
            RecordingPhase::On(recording) => {
                let label = recording.mark();
                self.view.set_recording(Some(recording.status()));
                self.view.say(format!("{label} dropped"));
            }
            _ => self.view.say("markers go into a recording: press r first"),
        }
    }
}
