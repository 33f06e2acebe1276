//! `taxel.Devices`: several boards and simulated boards read through one host-library worker,
//! their sample sets stamped by the host library's stamping policy and merged on one host
//! timeline (see [`crate::timeline`]) — what `taxel record` of several devices does, as a
//! Python object with the interface of `taxel.Device` where it makes sense.

use std::sync::Arc;
use std::time::{Duration, Instant};

use pyo3::exceptions::{PyStopIteration, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use taxel_host::device_link::open_serial;
use taxel_host::device_state::RecordedDeviceState;
use taxel_host::host_clock::UnixClock;
use taxel_host::stamping::MAX_WAIT_US;
use wire::{Command, PadIndex};

use crate::buffering::{buffers_by_device, Buffer};
use crate::connect::start_many_interruptibly;
use crate::control::{closed_error, data_loss_message, Backend, Control, Link};
use crate::device::{
    expect_ack, info_dict, next_set_until, queue_sets_checked, stats_dict, tare_duration,
    timeout_from_s, StatsCounts, PORT_READ_TIMEOUT, STATE_WAIT,
};
use crate::errors::{anyhow_error, link_error, taxel_error, ErrorKind};
use crate::events::DeviceEvent;
use crate::sample_set::SampleSet;
use crate::simulator::SimulatedBoard;
use crate::stream::{SetSource, QUEUE_SETS};
use crate::timeline::Timeline;

/// Several devices on one host timeline: boards (by port) and simulated boards
/// (:class:`taxel.SimulatedBoard`), read through one host-library worker. Each set is stamped
/// as ``taxel record`` stamps it (its device time mapped onto the host clock, with
/// ``sync_error_ms``) and the sets of every device come out in host-time order, each saying
/// its ``device`` (its index in ``sources``).
///
/// The first sets come out once each device's clock mapping has formed (about 1.5 s, at most
/// 3 s; a simulator at ``speed=None`` is never mapped and every set waits the 3 s), then a few
/// milliseconds after the slowest device's next set. A context manager and an iterator of
/// :class:`taxel.SampleSet`.
#[pyclass(frozen, module = "taxel")]
pub struct Devices {
    control: Control,
    timeline: Arc<Timeline>,
    pads: Vec<usize>,
    names: Vec<String>,
}

/// A device to open, as given.
enum Source {
    Port(String),
    Simulated(SimulatedBoard),
}

fn sources_from_python(sources: &Bound<'_, PyAny>) -> PyResult<Vec<Source>> {
    let mut found = Vec::new();
    for item in sources.try_iter()? {
        let item = item?;
        if let Ok(board) = item.downcast::<SimulatedBoard>() {
            found.push(Source::Simulated(board.get().clone()));
        } else if let Ok(path) = item.extract::<std::path::PathBuf>() {
            found.push(Source::Port(path.to_string_lossy().into_owned()));
        } else {
            return Err(PyValueError::new_err(format!(
                "each source is a serial port's path or a taxel.SimulatedBoard (got {})",
                item.repr()?
            )));
        }
    }
    if found.is_empty() {
        return Err(PyValueError::new_err("give at least one device"));
    }
    Ok(found)
}

fn stop_all(py: Python<'_>, backends: Vec<Box<dyn Backend>>) {
    py.allow_threads(|| {
        for mut backend in backends {
            backend.stop();
        }
    });
}

#[pymethods]
impl Devices {
    /// Opens every device of ``sources`` (serial ports' paths and
    /// :class:`taxel.SimulatedBoard` objects) and starts their streams. ``timeout`` (seconds)
    /// bounds each connection and request; ``queue_sets``: the sets (of every device) kept for
    /// :meth:`read` while nobody reads.
    #[new]
    #[pyo3(signature = (sources, timeout=2.0, queue_sets=QUEUE_SETS))]
    fn new(
        py: Python<'_>,
        sources: &Bound<'_, PyAny>,
        timeout: f64,
        queue_sets: usize,
    ) -> PyResult<Self> {
        let timeout = timeout_from_s(timeout)?;
        let queue_sets = queue_sets_checked(queue_sets)?;
        let sources = sources_from_python(sources)?;
        // The host clock starts before any device is opened (as `taxel record`'s): a
        // device's first sets must not map before its origin.
        let clock = UnixClock::new();
        let mut links: Vec<Link> = Vec::new();
        let mut names = Vec::new();
        let mut backends: Vec<Box<dyn Backend>> = Vec::new();
        let mut hints = String::new();
        for source in &sources {
            let opened = match source {
                Source::Simulated(board) => board.start(py).map(|(run, host_end, scene)| {
                    hints.push_str(&board.slow_hint());
                    backends.push(Box::new(run));
                    (
                        Box::new(host_end) as Link,
                        format!(
                            "simulated {}",
                            if scene.is_empty() { "board" } else { &scene }
                        ),
                    )
                }),
                Source::Port(path) => py
                    .allow_threads(|| open_serial(path, PORT_READ_TIMEOUT))
                    .map(|opened| (Box::new(opened.port) as Link, path.clone()))
                    .map_err(link_error),
            };
            match opened {
                Ok((link, name)) => {
                    links.push(link);
                    names.push(name);
                }
                Err(error) => {
                    stop_all(py, backends);
                    return Err(error);
                }
            }
        }
        let started =
            start_many_interruptibly(py, links, names.clone(), timeout, queue_sets, clock, &hints);
        let (worker, timeline) = match started {
            Ok(started) => started,
            Err(error) => {
                stop_all(py, backends);
                return Err(error);
            }
        };
        let pads = timeline
            .infos()
            .iter()
            .map(|info| usize::from(info.pad_count.max(1)))
            .collect();
        Ok(Self {
            control: Control::new(worker, backends, timeout),
            timeline,
            pads,
            names,
        })
    }

    /// The number of devices.
    fn __len__(&self) -> usize {
        self.pads.len()
    }

    /// Each device's identity (as :attr:`taxel.Device.info`), in the order given.
    #[getter]
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        if self.control.is_closed(py) {
            return Err(closed_error());
        }
        self.timeline
            .infos()
            .iter()
            .zip(&self.names)
            .map(|(info, name)| info_dict(py, info, name))
            .collect()
    }

    /// Each device's number of pads.
    #[getter]
    fn pads(&self) -> Vec<usize> {
        self.pads.clone()
    }

    /// Each device's number of taxels (4 per pad).
    #[getter]
    fn taxels(&self) -> Vec<usize> {
        self.pads
            .iter()
            .map(|pads| pads * model_core::TAXEL_COUNT)
            .collect()
    }

    /// The next sample set in host-time order, of any device (its ``device`` says which).
    /// Waits up to ``timeout`` seconds (default: the timeout given plus the 3 s a set may wait
    /// for its device's clock mapping) and raises :class:`taxel.DeviceTimeoutError` if none
    /// comes; :class:`taxel.LinkError` once a device's stream ended (unplugged, or closed).
    #[pyo3(signature = (timeout=None))]
    fn read(&self, py: Python<'_>, timeout: Option<f64>) -> PyResult<SampleSet> {
        self.control.refuse_while_buffering(py, "read()")?;
        let timeout = match timeout {
            Some(timeout_s) => timeout_from_s(timeout_s)?,
            None => self.control.timeout + Duration::from_micros(MAX_WAIT_US),
        };
        let source: Arc<dyn SetSource> = self.timeline.clone();
        next_set_until(py, &self.control, &source, Instant::now() + timeout)?
            .map(SampleSet::new)
            .ok_or_else(|| {
                taxel_error(
                    ErrorKind::Timeout,
                    format!("no sample set within {} ms", timeout.as_millis()),
                )
            })
    }

    /// The devices themselves: iterating reads sample sets until they are closed.
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// The next sample set (:meth:`read`); stops when the devices are closed.
    fn __next__(&self, py: Python<'_>) -> PyResult<SampleSet> {
        if self.control.is_closed(py) {
            return Err(PyStopIteration::new_err(()));
        }
        self.read(py, None)
    }

    /// The device events of every device that arrived since the last call, in arrival order
    /// (each says its ``device``).
    fn events(&self, py: Python<'_>) -> Vec<DeviceEvent> {
        let timeline = Arc::clone(&self.timeline);
        py.allow_threads(move || timeline.take_events())
            .into_iter()
            .map(DeviceEvent::new)
            .collect()
    }

    /// Starts collecting every device's sets in the background, up to ``capacity_sets`` sets
    /// (of all devices) between two :meth:`read_buffer` calls.
    #[pyo3(signature = (capacity_sets=1_000_000))]
    fn start_buffering(&self, py: Python<'_>, capacity_sets: usize) -> PyResult<()> {
        let source: Arc<dyn SetSource> = self.timeline.clone();
        self.control.start_buffering(py, source, capacity_sets)
    }

    /// The sets collected since the last call: one :class:`taxel.Buffer` per device, in the
    /// order given (each on the shared timeline: ``host_time_s`` stamped, ``sync_error_ms``).
    /// Losses and a failed link raise as :meth:`taxel.Device.read_buffer` does, with the list
    /// of buffers as the exception's ``buffer``.
    #[pyo3(signature = (strict=true))]
    fn read_buffer<'py>(&self, py: Python<'py>, strict: bool) -> PyResult<Bound<'py, PyList>> {
        let (collected, capacity_sets) = self.control.take_buffer(py)?;
        let states = self.device_states(py);
        let buffers = buffers_by_device(
            py,
            collected.sets,
            &self.pads,
            collected.overflowed_sets,
            states,
        )?;
        let gaps: u64 = buffers.iter().map(|buffer| buffer.sequence_gap_sets).sum();
        let list = PyList::empty(py);
        for buffer in buffers {
            list.append(Py::new(py, buffer)?)?;
        }
        if let Some(error) = &collected.error {
            let error = anyhow_error(error, ErrorKind::Link);
            error.value(py).setattr("buffer", &list)?;
            return Err(error);
        }
        if strict && (collected.overflowed_sets > 0 || gaps > 0) {
            let message = data_loss_message(collected.overflowed_sets, gaps, capacity_sets);
            let error = taxel_error(ErrorKind::DataLoss, message);
            error.value(py).setattr("buffer", &list)?;
            return Err(error);
        }
        Ok(list)
    }

    /// Stops collecting in the background; returns the sets not yet read, one
    /// :class:`taxel.Buffer` per device.
    fn stop_buffering(&self, py: Python<'_>) -> PyResult<Vec<Buffer>> {
        let collected = self.control.stop_buffering(py);
        let states = self.device_states(py);
        buffers_by_device(
            py,
            collected.sets,
            &self.pads,
            collected.overflowed_sets,
            states,
        )
    }

    /// Whether sets are being collected in the background.
    #[getter]
    fn buffering(&self, py: Python<'_>) -> bool {
        self.control.is_buffering(py)
    }

    /// Tares every pad of every device (or of device ``device`` only, or only its pad ``pad``)
    /// on the mean of its next ``sample_sets`` sets (keep the pads unloaded; the other pads keep
    /// their references); returns when every device said it is done.
    #[pyo3(signature = (sample_sets=64, device=None, pad=None))]
    fn tare(
        &self,
        py: Python<'_>,
        sample_sets: u16,
        device: Option<usize>,
        pad: Option<u8>,
    ) -> PyResult<()> {
        if sample_sets == 0 {
            return Err(PyValueError::new_err("sample_sets must be at least 1"));
        }
        let pad = match (pad, device) {
            (None, _) => None,
            (Some(pad), None) => {
                return Err(PyValueError::new_err(format!(
                    "pad {pad} of which device? give device= too"
                )))
            }
            (Some(pad), Some(device)) => {
                let pads = self.pads.get(device).copied().unwrap_or(0);
                match PadIndex::new(pad).filter(|_| usize::from(pad) < pads) {
                    Some(index) => Some(index),
                    None => {
                        return Err(PyValueError::new_err(format!(
                            "device {device} reads {pads} pads: there is no pad {pad}"
                        )))
                    }
                }
            }
        };
        let devices: Vec<usize> = match device {
            Some(device) if device < self.pads.len() => vec![device],
            Some(device) => {
                return Err(PyValueError::new_err(format!(
                    "there is no device {device} (there are {})",
                    self.pads.len()
                )))
            }
            None => (0..self.pads.len()).collect(),
        };
        let infos = self.timeline.infos();
        for device in devices {
            let rate_sps = infos.get(device).map_or(100, |info| info.rate.sps());
            let payload = self.control.request(
                py,
                device,
                Command::Tare { sample_sets, pad },
                &format!("Tare (device {device})"),
                self.control.timeout + tare_duration(sample_sets, rate_sps),
                &|| self.ended_error(device),
            )?;
            expect_ack(payload, "Tare")?;
        }
        Ok(())
    }

    /// Each device's accounting (as :attr:`taxel.Device.stats`), in the order given.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let counts = self.timeline.counts();
        let events_dropped = self.timeline.events_dropped();
        let mut dicts = Vec::new();
        for (device, count) in counts.into_iter().enumerate() {
            let (accounting, link) = match count.ended {
                Some(end) => (end.accounting, end.link),
                None => self.control.on_session(
                    py,
                    device,
                    self.control.timeout,
                    &|| self.ended_error(device),
                    |session| {
                        (
                            session.accounting().clone(),
                            session.link_statistics().clone(),
                        )
                    },
                )?,
            };
            dicts.push(stats_dict(
                py,
                &StatsCounts {
                    accounting,
                    link,
                    sets_delivered: count.sets_delivered,
                    incomplete_sets: count.incomplete_sets,
                    sets_dropped_unread: count.sets_dropped_unread,
                    events_dropped,
                },
            )?);
        }
        Ok(dicts)
    }

    /// Stops every stream, closes the ports and stops the simulated boards. Idempotent, and
    /// safe from any thread or a signal handler.
    fn close(&self, py: Python<'_>) {
        self.control.close(py);
    }

    /// Whether :meth:`close` was called.
    #[getter]
    fn closed(&self, py: Python<'_>) -> bool {
        self.control.is_closed(py)
    }

    /// The devices, for ``with``.
    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// Closes the devices at the end of ``with``; exceptions propagate.
    #[pyo3(signature = (*_exception))]
    fn __exit__(&self, py: Python<'_>, _exception: &Bound<'_, pyo3::types::PyTuple>) -> bool {
        self.control.close(py);
        false
    }

    /// A short description.
    fn __repr__(&self) -> String {
        format!("Devices({:?}, pads={:?})", self.names, self.pads)
    }
}

impl Devices {
    /// What each device computes with now, or as it was when its stream ended (`None` for a
    /// device that never said); see `Device`'s.
    fn device_states(&self, py: Python<'_>) -> Vec<Option<RecordedDeviceState>> {
        let counts = self.timeline.counts();
        (0..self.pads.len())
            .map(|device| {
                let now = self
                    .control
                    .on_session(
                        py,
                        device,
                        STATE_WAIT,
                        &|| self.ended_error(device),
                        |session| session.state().cloned(),
                    )
                    .ok()
                    .flatten();
                now.or_else(|| {
                    counts
                        .get(device)
                        .and_then(|track| track.ended.as_ref())
                        .and_then(|end| end.state.clone())
                })
            })
            .collect()
    }

    fn ended_error(&self, device: usize) -> PyErr {
        match self.timeline.device_ended(device) {
            Some(ended) => taxel_error(ErrorKind::Link, ended.0),
            None => closed_error(),
        }
    }
}
