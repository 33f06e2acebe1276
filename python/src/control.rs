//! What `taxel.Device` and `taxel.Devices` share: the host library's worker (one thread per
//! device, carrying out requests between reads), the simulated devices behind it, the
//! background buffer, and closing all of them from any thread. Every wait releases the GIL and
//! looks for Ctrl-C every [`SLICE`].

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use pyo3::prelude::*;
use taxel_host::device_link::RequestError;
use taxel_host::session::DeviceSession;
use taxel_host::worker::Worker;
use wire::{Command, ReplyPayload};

use crate::buffering::{Buffering, Collected};
use crate::connect::wait_interruptibly;
use crate::errors::{anyhow_error, taxel_error, ErrorKind};
use crate::locking::lock;
use crate::stream::SetSource;

/// A byte stream to a device.
pub trait Transport: std::io::Read + std::io::Write + Send {}

impl<T: std::io::Read + std::io::Write + Send> Transport for T {}

/// The link a device is read over.
pub type Link = Box<dyn Transport>;

/// How long a blocking call waits with the GIL released before it looks for Ctrl-C.
pub const SLICE: Duration = Duration::from_millis(50);

/// What stops the thing behind a device when it closes (the simulated device's thread).
pub trait Backend: Send + Sync {
    /// Stops it and waits.
    fn stop(&mut self);
}

/// The worker, the backends and the buffer of one or several devices.
pub struct Control {
    // Behind locks of their own so that every method takes `&self`: a method holding a mutable
    // borrow of the object would make `close()` from another thread fail with "Already
    // borrowed" while a `read()` waits.
    worker: Mutex<Option<Worker<Link>>>,
    buffering: Mutex<Option<Buffering>>,
    backends: Mutex<Vec<Box<dyn Backend>>>,
    /// Every request's timeout, and every read's by default.
    pub timeout: Duration,
}

/// The error of a closed device.
pub fn closed_error() -> PyErr {
    taxel_error(ErrorKind::Link, "the device is closed")
}

impl Control {
    /// The control of a started worker and the backends behind its devices.
    pub fn new(worker: Worker<Link>, backends: Vec<Box<dyn Backend>>, timeout: Duration) -> Self {
        Self {
            worker: Mutex::new(Some(worker)),
            buffering: Mutex::new(None),
            backends: Mutex::new(backends),
            timeout,
        }
    }

    /// Whether it was closed.
    pub fn is_closed(&self, py: Python<'_>) -> bool {
        py.allow_threads(|| lock(&self.worker).is_none())
    }

    /// Runs `job` on device `device`'s session (on the worker's thread, between reads) and
    /// waits for its result with the GIL released, looking for Ctrl-C, for `timeout` and a
    /// little more (the job bounds itself; this only guards against a worker that stopped).
    /// `ended` is the error when the device can no longer be asked.
    pub fn on_session<T: Send + 'static>(
        &self,
        py: Python<'_>,
        device: usize,
        timeout: Duration,
        ended: &dyn Fn() -> PyErr,
        job: impl FnOnce(&mut DeviceSession<Link>) -> T + Send + 'static,
    ) -> PyResult<T> {
        let receiver = py
            .allow_threads(|| {
                lock(&self.worker)
                    .as_ref()
                    .map(|worker| worker.run(device, job))
            })
            .ok_or_else(closed_error)?
            .map_err(|_| ended())?;
        wait_interruptibly(
            py,
            receiver,
            Instant::now() + timeout + Duration::from_secs(1),
        )?
        .ok_or_else(ended)
    }

    /// Sends a request to device `device` and waits (interruptibly) for a successful reply;
    /// `what` names it in errors, as the CLI does.
    pub fn request(
        &self,
        py: Python<'_>,
        device: usize,
        command: Command,
        what: &str,
        timeout: Duration,
        ended: &dyn Fn() -> PyErr,
    ) -> PyResult<ReplyPayload> {
        // The device's thread sends it and goes on reading while the reply is awaited, so the
        // sets arriving meanwhile keep their arrival times (a tare takes a second or more).
        let receiver = py
            .allow_threads(|| {
                lock(&self.worker)
                    .as_ref()
                    .map(|worker| worker.send(device, command, timeout))
            })
            .ok_or_else(closed_error)?
            .map_err(|_| ended())?;
        let deadline = Instant::now()
            .checked_add(timeout + Duration::from_secs(1))
            .unwrap_or_else(Instant::now);
        let result = wait_interruptibly(py, receiver, deadline)?.ok_or_else(ended)?;
        result.map_err(|error| {
            let kind = match &error {
                RequestError::Refused(_) => ErrorKind::Refused,
                RequestError::Timeout { .. } => ErrorKind::Timeout,
                _ => ErrorKind::Other,
            };
            anyhow_error(&anyhow::Error::new(error).context(what.to_owned()), kind)
        })
    }

    /// Whether sets are being collected in the background.
    pub fn is_buffering(&self, py: Python<'_>) -> bool {
        py.allow_threads(|| lock(&self.buffering).is_some())
    }

    /// Refuses `what` while buffering.
    pub fn refuse_while_buffering(&self, py: Python<'_>, what: &str) -> PyResult<()> {
        if self.is_buffering(py) {
            return Err(taxel_error(
                ErrorKind::Other,
                format!("{what} while buffering: take the sets with read_buffer(), or call stop_buffering() first"),
            ));
        }
        Ok(())
    }

    /// Starts collecting from `source` in the background.
    pub fn start_buffering(
        &self,
        py: Python<'_>,
        source: Arc<dyn SetSource>,
        capacity_sets: usize,
    ) -> PyResult<()> {
        if capacity_sets == 0 {
            return Err(pyo3::exceptions::PyValueError::new_err(
                "capacity_sets must be at least 1",
            ));
        }
        if self.is_closed(py) {
            return Err(closed_error());
        }
        let started = py.allow_threads(|| -> std::io::Result<bool> {
            let mut buffering = lock(&self.buffering);
            if buffering.is_some() {
                return Ok(false);
            }
            *buffering = Some(Buffering::start(source, capacity_sets)?);
            Ok(true)
        });
        match started {
            Ok(true) => Ok(()),
            Ok(false) => self.refuse_while_buffering(py, "start_buffering()"),
            Err(error) => Err(taxel_error(
                ErrorKind::Other,
                format!("starting the buffer thread: {error}"),
            )),
        }
    }

    /// What was collected since the last call, with the store's capacity; an error when no
    /// collection runs.
    pub fn take_buffer(&self, py: Python<'_>) -> PyResult<(Collected, usize)> {
        py.allow_threads(|| {
            lock(&self.buffering)
                .as_ref()
                .map(|buffering| (buffering.take(), buffering.capacity_sets))
        })
        .ok_or_else(|| {
            taxel_error(
                ErrorKind::Other,
                "read_buffer() needs start_buffering() first",
            )
        })
    }

    /// Stops collecting; returns what was collected and not yet read (nothing when no
    /// collection ran).
    pub fn stop_buffering(&self, py: Python<'_>) -> Collected {
        py.allow_threads(|| {
            let buffering = lock(&self.buffering).take();
            buffering.map(|mut buffering| {
                buffering.stop();
                buffering.take()
            })
        })
        .unwrap_or_default()
    }

    /// Closes everything with the GIL released (no lock is ever held while Python code may
    /// run, so a signal handler may call this while another call of this thread waits).
    pub fn close(&self, py: Python<'_>) {
        py.allow_threads(|| self.close_blocking());
    }

    /// Stops the buffer, the worker (every device's stream; their ends reach the queue, so a
    /// read waiting now ends) and the backends.
    pub fn close_blocking(&self) {
        let buffering = lock(&self.buffering).take();
        if let Some(mut buffering) = buffering {
            buffering.stop();
        }
        let worker = lock(&self.worker).take();
        if let Some(worker) = worker {
            worker.finish();
        }
        let backends = std::mem::take(&mut *lock(&self.backends));
        for mut backend in backends {
            backend.stop();
        }
    }
}

impl Drop for Control {
    fn drop(&mut self) {
        self.close_blocking();
    }
}

/// The message of `DataLossError`: sets lost to a full buffer or to gaps.
pub fn data_loss_message(
    overflowed_sets: u64,
    sequence_gap_sets: u64,
    capacity_sets: usize,
) -> String {
    format!(
        "{} sample set(s) lost: {} arrived while the buffer of {} sets was full (call read_buffer() more often or give a larger capacity_sets), {} missing from the sequence numbers",
        overflowed_sets + sequence_gap_sets,
        overflowed_sets,
        capacity_sets,
        sequence_gap_sets
    )
}
