//! Sessions on threads: each device's [`DeviceSession`] is read by a thread of its own, and
//! every event goes down one [`EventQueue`] with its device and its arrival on the shared
//! [`HostClock`]. Requests for a device (tare, rate, anything) are carried out by its thread
//! between reads, so a consumer never touches a link. One device is a worker of one session.
//!
//! The queue's [`Overflow`] policy says what happens when the consumer falls behind: a
//! recorder waits (the device's own buffers then fill, and its drops are counted by the
//! accounting, never hidden), a live consumer drops its oldest sample sets and counts them.
//! Device events and ends are never dropped.

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread;
use std::time::{Duration, Instant};

use wire::{Command, CountersFrame, InfoFrame, ReplyPayload};

use crate::device_link::{LinkError, LinkStatistics, RequestError};
use crate::device_state::RecordedDeviceState;
use crate::host_clock::HostClock;
use crate::session::{DeviceSession, SessionEvent};
use crate::stream_accounting::StreamAccounting;

/// How long a device's thread reads before it looks at its requests and the stop flag.
const READ_SLICE: Duration = Duration::from_millis(20);

/// Why a device's stream ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum EndReason {
    /// The consumer stopped the worker.
    Stopped,
    /// The device went away; the message says how.
    Disconnected(String),
    /// Something on the host failed (the raw log could not be written); the message says what.
    Failed(String),
}

/// A device's last word: why it ended and its final accounting.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceEnd {
    /// Why the stream ended.
    pub reason: EndReason,
    /// The device's identity as last said.
    pub info: InfoFrame,
    /// Where every sample set went.
    pub accounting: StreamAccounting,
    /// The link's decoding counters.
    pub link: LinkStatistics,
    /// The device's counters read at the stop (not when it went away).
    pub counters: Option<CountersFrame>,
    /// The device's state with every baseline change (when the session followed it).
    pub state: Option<RecordedDeviceState>,
}

/// What a device's thread sends.
#[derive(Debug, Clone, PartialEq)]
pub enum WorkerEvent {
    /// An event of the device's stream.
    Session(SessionEvent),
    /// The stream ended; nothing follows from this device.
    Ended(Box<DeviceEnd>),
}

/// An event with its device (the index of its session) and its arrival on the host clock.
#[derive(Debug, Clone, PartialEq)]
pub struct ArrivedEvent {
    /// The device, numbered in the order the sessions were given.
    pub device: usize,
    /// When the event was read, µs on the worker's host clock.
    pub arrival_us: u64,
    /// What happened.
    pub event: WorkerEvent,
}

/// What a full [`EventQueue`] does with the next event.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overflow {
    /// The device's thread waits until the consumer takes events (or the worker stops).
    Wait,
    /// The oldest sample set in the queue is dropped and counted
    /// ([`EventQueue::dropped_sets`]); other events are always kept.
    DropOldestSet,
}

#[derive(Debug, Default)]
struct QueueState {
    events: VecDeque<ArrivedEvent>,
    dropped_sets: u64,
}

/// The bounded queue between the devices' threads and the consumer.
#[derive(Debug)]
pub struct EventQueue {
    state: Mutex<QueueState>,
    changed: Condvar,
    capacity: usize,
    overflow: Overflow,
}

impl EventQueue {
    /// A queue of `capacity` events (at least 1).
    pub fn new(capacity: usize, overflow: Overflow) -> Self {
        Self {
            state: Mutex::new(QueueState::default()),
            changed: Condvar::new(),
            capacity: capacity.max(1),
            overflow,
        }
    }

    fn lock(&self) -> MutexGuard<'_, QueueState> {
        self.state
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Adds an event (see [`Overflow`]); with [`Overflow::Wait`] gives up when `stop` is set.
    pub fn push(&self, event: ArrivedEvent, stop: &AtomicBool) {
        let mut state = self.lock();
        while state.events.len() >= self.capacity {
            match self.overflow {
                Overflow::Wait => {
                    if stop.load(Ordering::Relaxed) {
                        break;
                    }
                    state = self
                        .changed
                        .wait_timeout(state, READ_SLICE)
                        .unwrap_or_else(|poisoned| poisoned.into_inner())
                        .0;
                }
                Overflow::DropOldestSet => {
                    let oldest_set = state.events.iter().position(|queued| {
                        matches!(queued.event, WorkerEvent::Session(SessionEvent::Set { .. }))
                    });
                    match oldest_set {
                        Some(position) => {
                            state.events.remove(position);
                            state.dropped_sets += 1;
                        }
                        // Only events that are never dropped: keep them all.
                        None => break,
                    }
                }
            }
        }
        state.events.push_back(event);
        drop(state);
        self.changed.notify_all();
    }

    /// The oldest event, waiting until `deadline` at most.
    pub fn pop_until(&self, deadline: Instant) -> Option<ArrivedEvent> {
        let mut state = self.lock();
        loop {
            if let Some(event) = state.events.pop_front() {
                drop(state);
                self.changed.notify_all();
                return Some(event);
            }
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return None;
            }
            state = self
                .changed
                .wait_timeout(state, remaining)
                .unwrap_or_else(|poisoned| poisoned.into_inner())
                .0;
        }
    }

    /// Every event queued now, oldest first.
    pub fn drain(&self) -> Vec<ArrivedEvent> {
        let events: Vec<ArrivedEvent> = self.lock().events.drain(..).collect();
        self.changed.notify_all();
        events
    }

    /// Sample sets dropped because the queue was full ([`Overflow::DropOldestSet`]).
    pub fn dropped_sets(&self) -> u64 {
        self.lock().dropped_sets
    }
}

/// Something to run on a device's session.
type SessionJob<P> = Box<dyn FnOnce(&mut DeviceSession<P>) + Send>;

/// Work for a device's thread, carried out between reads.
enum Job<P> {
    /// Runs on the session.
    Run(SessionJob<P>),
    /// A request whose reply the thread watches for while it goes on reading.
    Request {
        command: Command,
        timeout: Duration,
        reply: Sender<Result<ReplyPayload, RequestError>>,
    },
}

/// A request sent and not yet answered.
struct Pending {
    request_id: u16,
    deadline: Instant,
    timeout: Duration,
    reply: Sender<Result<ReplyPayload, RequestError>>,
}

/// A request the worker could not carry out.
#[derive(Debug, thiserror::Error)]
pub enum WorkerRequestError {
    /// There is no such device.
    #[error("there is no device {0}")]
    NoDevice(usize),
    /// The device's stream has ended.
    #[error("device {0}'s stream has ended")]
    Ended(usize),
    /// The device answered with an error, or not in time.
    #[error(transparent)]
    Request(#[from] RequestError),
}

/// Devices read by threads of their own into one queue (see the module documentation).
pub struct Worker<P> {
    threads: Vec<Option<thread::JoinHandle<DeviceSession<P>>>>,
    jobs: Vec<Sender<Job<P>>>,
    stop: Arc<AtomicBool>,
    queue: Arc<EventQueue>,
    clock: Arc<dyn HostClock>,
    // Per device: its thread has sent its end (and returns at once).
    ended: Vec<Arc<AtomicBool>>,
}

impl<P: Read + Write + Send + 'static> Worker<P> {
    /// Reads every session (already started, see [`DeviceSession::start`]) on a thread of its
    /// own; device `n` is `sessions[n]`. Arrivals are stamped with `clock`.
    pub fn start(
        sessions: Vec<DeviceSession<P>>,
        queue: Arc<EventQueue>,
        clock: Arc<dyn HostClock>,
    ) -> std::io::Result<Self> {
        let mut worker = Self {
            threads: Vec::new(),
            jobs: Vec::new(),
            stop: Arc::new(AtomicBool::new(false)),
            queue,
            clock,
            ended: Vec::new(),
        };
        for (device, session) in sessions.into_iter().enumerate() {
            let ended = Arc::new(AtomicBool::new(false));
            match worker.spawn(device, session, Arc::clone(&ended)) {
                Ok((handle, sender)) => {
                    worker.threads.push(Some(handle));
                    worker.jobs.push(sender);
                    worker.ended.push(ended);
                }
                Err(error) => {
                    worker.stop_threads();
                    return Err(error);
                }
            }
        }
        Ok(worker)
    }

    /// Device `device`'s thread, reading `session`.
    #[allow(clippy::type_complexity)]
    fn spawn(
        &self,
        device: usize,
        session: DeviceSession<P>,
        ended: Arc<AtomicBool>,
    ) -> std::io::Result<(thread::JoinHandle<DeviceSession<P>>, Sender<Job<P>>)> {
        let (sender, jobs) = mpsc::channel();
        let context = ThreadContext {
            device,
            ended,
            queue: Arc::clone(&self.queue),
            clock: Arc::clone(&self.clock),
            stop: Arc::clone(&self.stop),
            jobs,
        };
        let handle = thread::Builder::new()
            .name(format!("taxel-device-{device}"))
            .spawn(move || read_device(session, &context))?;
        Ok((handle, sender))
    }

    /// Reads `session` (started) as device `device` again, after that device's stream ended
    /// (it was unplugged and is back): its events come with the same device number, after its
    /// end. Fails when there is no such device or its stream has not ended (its end is not
    /// in the queue yet).
    pub fn reattach(&mut self, device: usize, session: DeviceSession<P>) -> anyhow::Result<()> {
        let (Some(slot), Some(ended)) = (self.threads.get_mut(device), self.ended.get(device))
        else {
            anyhow::bail!("there is no device {device}");
        };
        if !ended.load(Ordering::Acquire) {
            anyhow::bail!("device {device}'s stream has not ended");
        }
        if let Some(handle) = slot.take() {
            // The old session is over (its thread returns right after its end); its link goes
            // with it.
            let _ = handle.join();
        }
        let ended = Arc::new(AtomicBool::new(false));
        let (handle, sender) = self
            .spawn(device, session, Arc::clone(&ended))
            .map_err(|error| anyhow::anyhow!("starting a thread for device {device}: {error}"))?;
        if let Some(flag) = self.ended.get_mut(device) {
            *flag = ended;
        }
        if let (Some(slot), Some(jobs)) = (self.threads.get_mut(device), self.jobs.get_mut(device))
        {
            *slot = Some(handle);
            *jobs = sender;
        }
        Ok(())
    }

    /// The queue the events arrive in.
    pub fn queue(&self) -> &Arc<EventQueue> {
        &self.queue
    }

    /// The number of devices.
    pub fn device_count(&self) -> usize {
        self.jobs.len()
    }

    /// Runs `job` on `device`'s session, on its thread between reads (a calibration transfer,
    /// a look at its accounting); returns where its result will arrive. Frames that arrive
    /// meanwhile become events afterwards, in order.
    pub fn run<R: Send + 'static>(
        &self,
        device: usize,
        job: impl FnOnce(&mut DeviceSession<P>) -> R + Send + 'static,
    ) -> Result<Receiver<R>, WorkerRequestError> {
        let sender = self
            .jobs
            .get(device)
            .ok_or(WorkerRequestError::NoDevice(device))?;
        let (result, receiver) = mpsc::channel();
        sender
            .send(Job::Run(Box::new(move |session: &mut DeviceSession<P>| {
                // The caller may have given up; the result is then nobody's.
                let _ = result.send(job(session));
            })))
            .map_err(|_| WorkerRequestError::Ended(device))?;
        Ok(receiver)
    }

    /// Sends `command` to `device` and returns where its reply will arrive, within `timeout`.
    /// The device's thread sends it and goes on reading while it waits (a tare's reply comes
    /// when the tare is done, and the sets keep arriving meanwhile). A reply carrying a new
    /// Info becomes the session's.
    pub fn send(
        &self,
        device: usize,
        command: Command,
        timeout: Duration,
    ) -> Result<Receiver<Result<ReplyPayload, RequestError>>, WorkerRequestError> {
        let sender = self
            .jobs
            .get(device)
            .ok_or(WorkerRequestError::NoDevice(device))?;
        let (reply, receiver) = mpsc::channel();
        sender
            .send(Job::Request {
                command,
                timeout,
                reply,
            })
            .map_err(|_| WorkerRequestError::Ended(device))?;
        Ok(receiver)
    }

    /// Sends `command` to `device` and waits for its reply.
    pub fn request(
        &self,
        device: usize,
        command: Command,
        timeout: Duration,
    ) -> Result<ReplyPayload, WorkerRequestError> {
        let receiver = self.send(device, command, timeout)?;
        // The device's thread answers within the timeout; the margin covers its read slice. A
        // thread that cannot answer (it waits for a full queue nobody empties) is an end.
        match receiver.recv_timeout(timeout + 4 * READ_SLICE) {
            Ok(result) => Ok(result?),
            Err(_) => Err(WorkerRequestError::Ended(device)),
        }
    }

    /// Stops every device (each sends its last set and its [`WorkerEvent::Ended`]) and gives
    /// the sessions back, in device order (`None` for a thread that panicked).
    pub fn finish(mut self) -> Vec<Option<DeviceSession<P>>> {
        self.stop_threads()
    }

    fn stop_threads(&mut self) -> Vec<Option<DeviceSession<P>>> {
        self.stop.store(true, Ordering::Relaxed);
        self.threads
            .iter_mut()
            .map(|handle| handle.take().and_then(|handle| handle.join().ok()))
            .collect()
    }
}

impl<P> Drop for Worker<P> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for handle in self.threads.iter_mut().filter_map(Option::take) {
            let _ = handle.join();
        }
    }
}

struct ThreadContext<P> {
    device: usize,
    ended: Arc<AtomicBool>,
    queue: Arc<EventQueue>,
    clock: Arc<dyn HostClock>,
    stop: Arc<AtomicBool>,
    jobs: Receiver<Job<P>>,
}

impl<P> ThreadContext<P> {
    fn deliver(&self, event: WorkerEvent) {
        self.queue.push(
            ArrivedEvent {
                device: self.device,
                arrival_us: self.clock.now_us(),
                event,
            },
            &self.stop,
        );
    }
}

/// Hands out the replies that arrived, and the timeouts of those that did not (a request's
/// reply is kept by the link for it, whoever reads the stream).
fn answer_pending<P: Read + Write>(session: &mut DeviceSession<P>, pending: &mut Vec<Pending>) {
    let now = Instant::now();
    pending.retain(|request| {
        let answer = match session.wait_reply(request.request_id, now) {
            Ok(Some(result)) => Some(result.map_err(RequestError::Refused)),
            Ok(None) if now >= request.deadline => Some(Err(
                session.no_reply_error(request.request_id, request.timeout)
            )),
            // A link error ends the stream; the requester sees the worker end.
            Ok(None) | Err(_) => None,
        };
        match answer {
            Some(result) => {
                if let Ok(ReplyPayload::Info(info)) = &result {
                    session.set_info(*info);
                }
                // The requester may have given up; the reply is then nobody's.
                let _ = request.reply.send(result);
                false
            }
            None => true,
        }
    });
}

/// A device's thread: reads its session until the worker stops or the device goes away,
/// carrying out requests between reads; then its last set, the stop and its end.
fn read_device<P: Read + Write>(
    mut session: DeviceSession<P>,
    context: &ThreadContext<P>,
) -> DeviceSession<P> {
    let mut pending: Vec<Pending> = Vec::new();
    let reason = loop {
        if context.stop.load(Ordering::Relaxed) {
            break EndReason::Stopped;
        }
        while let Ok(job) = context.jobs.try_recv() {
            match job {
                Job::Run(job) => job(&mut session),
                Job::Request {
                    command,
                    timeout,
                    reply,
                } => match session.send(command) {
                    Ok(request_id) => pending.push(Pending {
                        request_id,
                        deadline: Instant::now() + timeout,
                        timeout,
                        reply,
                    }),
                    Err(error) => {
                        let _ = reply.send(Err(RequestError::Link(error)));
                    }
                },
            }
        }
        answer_pending(&mut session, &mut pending);
        match session.next_event(Instant::now() + READ_SLICE) {
            Ok(Some(event)) => context.deliver(WorkerEvent::Session(event)),
            Ok(None) => {}
            Err(LinkError::RawLog(error)) => {
                break EndReason::Failed(format!("writing the raw log: {error}"))
            }
            Err(error) => break EndReason::Disconnected(error.to_string()),
        }
    };
    if reason == EndReason::Stopped {
        // What the session already holds (events of a frame taken, frames decoded and not yet
        // taken) goes out before the last set is closed, so no pad is called missing that came.
        let until = Instant::now() + READ_SLICE;
        while let Ok(Some(event)) = session.next_event(until) {
            context.deliver(WorkerEvent::Session(event));
        }
    }
    if let Some(event) = session.close_open_set() {
        context.deliver(WorkerEvent::Session(event));
    }
    let counters = match reason {
        EndReason::Disconnected(_) => None,
        _ => session.stop(),
    };
    let mut reason = reason;
    if let Err(error) = session.link_mut().flush_raw_log() {
        if reason == EndReason::Stopped {
            reason = EndReason::Failed(format!("writing the raw log: {error}"));
        }
    }
    context.deliver(WorkerEvent::Ended(Box::new(DeviceEnd {
        reason,
        info: *session.info(),
        accounting: session.accounting().clone(),
        link: session.link_statistics().clone(),
        counters,
        state: session.state().cloned(),
    })));
    // After the end is in the queue (delivering may wait for room): from here the thread only
    // returns, so `reattach` can join it.
    context.ended.store(true, Ordering::Release);
    session
}
