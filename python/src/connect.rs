//! Connecting to a device from Python without ever blocking Ctrl-C: the session is opened
//! and the worker started on a thread of their own, waited for in slices with the GIL
//! released, within one overall timeout.

use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context;
use pyo3::prelude::*;
use taxel_host::device_link::DeviceLink;
use taxel_host::host_clock::{MonotonicClock, UnixClock};
use taxel_host::session::{DeviceSession, SessionConfig};
use taxel_host::worker::{EventQueue, Overflow, Worker};

use crate::control::{Link, SLICE};
use crate::errors::{anyhow_error, taxel_error, ErrorKind};
use crate::stream::Stream;
use crate::timeline::Timeline;

/// Waits for `receiver` until `deadline` in slices with the GIL released, raising on Ctrl-C;
/// `None` when nothing came (or the sender went away).
pub fn wait_interruptibly<T: Send>(
    py: Python<'_>,
    receiver: Receiver<T>,
    deadline: Instant,
) -> PyResult<Option<T>> {
    let mut receiver = receiver;
    loop {
        let slice = deadline
            .saturating_duration_since(Instant::now())
            .min(SLICE);
        // Moved in and out: a receiver may not be shared between threads, only sent.
        let (received, returned) = py.allow_threads(move || {
            let received = receiver.recv_timeout(slice);
            (received, receiver)
        });
        receiver = returned;
        match received {
            Ok(value) => return Ok(Some(value)),
            Err(RecvTimeoutError::Disconnected) => return Ok(None),
            Err(RecvTimeoutError::Timeout) => {
                py.check_signals()?;
                if Instant::now() >= deadline {
                    return Ok(None);
                }
            }
        }
    }
}

/// The host clock now, Unix seconds.
pub fn unix_now_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |elapsed| elapsed.as_secs_f64())
}

/// Runs `start` on a thread of its own, waited for in slices with the GIL released so that
/// Ctrl-C interrupts it, until `deadline`; `what` says what did not finish in time. An abandoned
/// start ends by itself within its own timeouts.
fn run_interruptibly<T: Send + 'static>(
    py: Python<'_>,
    deadline: Instant,
    what: String,
    start: impl FnOnce() -> anyhow::Result<T> + Send + 'static,
) -> PyResult<T> {
    let (sender, receiver) = mpsc::channel();
    thread::Builder::new()
        .name("taxel-connect".into())
        .spawn(move || {
            let _ = sender.send(start());
        })
        .map_err(|error| {
            taxel_error(
                ErrorKind::Other,
                format!("starting the connection: {error}"),
            )
        })?;
    match wait_interruptibly(py, receiver, deadline)? {
        Some(started) => started.map_err(|error| anyhow_error(&error, ErrorKind::Other)),
        None => Err(taxel_error(ErrorKind::Timeout, what)),
    }
}

/// Opens every link's session and starts its stream (`names` name the devices in errors).
fn open_and_start(
    links: Vec<Link>,
    names: &[String],
    timeout: Duration,
) -> anyhow::Result<Vec<DeviceSession<Link>>> {
    let config = SessionConfig {
        request_timeout: timeout,
        follow_state: false,
    };
    let mut sessions = Vec::new();
    for (link, name) in links.into_iter().zip(names) {
        let session = DeviceSession::open(DeviceLink::new(link), config)
            .with_context(|| format!("the device {name}"))?;
        sessions.push(session);
    }
    for (session, name) in sessions.iter_mut().zip(names) {
        session
            .start()
            .with_context(|| format!("starting the stream of {name}"))?;
        // The device's state (per pad calibration, tier, geometry, baselines) is followed so
        // that a saved buffer carries it, as `taxel record` writes it beside a recording; read
        // once the stream runs, so that no event of the device is discarded.
        session
            .start_following_state()
            .with_context(|| format!("reading the state of {name}"))?;
    }
    Ok(sessions)
}

/// Opens the session, starts its stream and the worker reading it (see [`run_interruptibly`]),
/// for `timeout` in all (the start makes several requests, each bounded by `timeout`).
pub fn start_interruptibly(
    py: Python<'_>,
    port: Link,
    timeout: Duration,
    queue_sets: usize,
    slow_hint: &str,
) -> PyResult<(Worker<Link>, Arc<Stream>)> {
    // A little over the timeout, so that a first request that times out reports itself (with
    // the request it was) rather than this overall bound.
    let deadline = Instant::now() + timeout + 2 * SLICE;
    let what = format!(
        "the device did not finish connecting (identity and stream start) within {} ms{slow_hint}",
        timeout.as_millis()
    );
    run_interruptibly(py, deadline, what, move || {
        let sessions = open_and_start(vec![port], &["on its port".to_owned()], timeout)?;
        let info = sessions
            .first()
            .map(|session| *session.info())
            .context("the device's session")?;
        let queue = Arc::new(EventQueue::new(queue_sets, Overflow::DropOldestSet));
        let origin_unix_s = unix_now_s();
        let worker = Worker::start(
            sessions,
            Arc::clone(&queue),
            Arc::new(MonotonicClock::new()),
        )
        .context("starting the device's reader thread")?;
        Ok((
            worker,
            Arc::new(Stream::new(queue, queue_sets, origin_unix_s, info)),
        ))
    })
}

/// Opens every device's session, starts their streams and one worker reading them all (see
/// [`run_interruptibly`]), `timeout` per device. Each device's arrivals are stamped with
/// `clock`, which must have started before the links were opened. `names` name the devices in
/// errors.
pub fn start_many_interruptibly(
    py: Python<'_>,
    links: Vec<Link>,
    names: Vec<String>,
    timeout: Duration,
    queue_sets: usize,
    clock: UnixClock,
    slow_hint: &str,
) -> PyResult<(Worker<Link>, Arc<Timeline>)> {
    let count = u32::try_from(links.len().max(1)).unwrap_or(u32::MAX);
    let deadline = Instant::now() + timeout * count + 2 * SLICE;
    let what = format!(
        "the devices did not finish connecting (identity and stream start) within {} ms{slow_hint}",
        (timeout * count).as_millis()
    );
    run_interruptibly(py, deadline, what, move || {
        let sessions = open_and_start(links, &names, timeout)?;
        let infos = sessions.iter().map(|session| *session.info()).collect();
        let queue = Arc::new(EventQueue::new(queue_sets, Overflow::DropOldestSet));
        let worker = Worker::start(sessions, Arc::clone(&queue), Arc::new(clock))
            .context("starting the devices' reader threads")?;
        Ok((
            worker,
            Arc::new(Timeline::new(queue, clock, infos, names).with_queue_sets(queue_sets)),
        ))
    })
}
