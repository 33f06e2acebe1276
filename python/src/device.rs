//! `taxel.Device`: one board (or, through `taxel.Simulator`, the simulated device) as a Python
//! object: its identity, sample sets one at a time or collected in the background, its events,
//! and its commands. The host library's worker reads the device on a thread of its own (the one stream
//! loop, `taxel_host::session`); every wait here releases the GIL and looks for Ctrl-C every
//! [`SLICE`].

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use pyo3::exceptions::{PyStopIteration, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use taxel_host::device_link::{
    open_serial, select_port, LinkStatistics, RequestError, DEFAULT_PID, DEFAULT_VID,
};
use taxel_host::device_state::RecordedDeviceState;
use taxel_host::session::DeviceSession;
use taxel_host::stream_accounting::StreamAccounting;
use wire::{Command, InfoFrame, PadIndex, ReplyPayload, SampleRate};

use crate::buffering::Buffer;
use crate::calibration::Calibration;
use crate::connect::start_interruptibly;
use crate::control::{closed_error, data_loss_message, Backend, Control, Link, Transport, SLICE};
use crate::errors::{anyhow_error, taxel_error, ErrorKind};
use crate::events::DeviceEvent;
use crate::sample_set::{SampleSet, SetRecord};
use crate::stream::{SetSource, Stream, QUEUE_SETS};

/// How long the device's thread may take to hand over the device's state (it does between two
/// reads of the link, every 20 ms).
pub const STATE_WAIT: Duration = Duration::from_millis(500);

/// The read timeout of a serial port: one poll of the link waits at most this.
pub const PORT_READ_TIMEOUT: Duration = Duration::from_millis(20);

/// A board or the simulated device, with its sample sets, events and commands (see the
/// package's documentation). Use it as a context manager, or call :meth:`close`.
///
/// Every method may be called from any thread: :meth:`close` from another thread or from a
/// signal handler ends a :meth:`read` blocked in this one (it raises :class:`taxel.LinkError`
/// within about 50 ms).
#[pyclass(frozen, subclass, module = "taxel")]
pub struct Device {
    control: Control,
    stream: Arc<Stream>,
    pads: usize,
    port_name: String,
}

/// A queue size given by the caller, checked.
pub fn queue_sets_checked(queue_sets: usize) -> PyResult<usize> {
    if queue_sets == 0 {
        return Err(PyValueError::new_err("queue_sets must be at least 1"));
    }
    Ok(queue_sets)
}

/// The longest timeout taken, s (11.6 days): longer ones would overflow the clock's arithmetic.
const MAX_TIMEOUT_S: f64 = 1.0e6;

/// A timeout given in seconds, checked.
pub fn timeout_from_s(timeout_s: f64) -> PyResult<Duration> {
    if !(timeout_s.is_finite() && timeout_s > 0.0 && timeout_s <= MAX_TIMEOUT_S) {
        return Err(PyValueError::new_err(format!(
            "timeout must be a positive number of seconds up to {MAX_TIMEOUT_S} (got {timeout_s})"
        )));
    }
    Ok(Duration::from_secs_f64(timeout_s))
}

/// A device's identity as a dict.
pub fn info_dict<'py>(
    py: Python<'py>,
    info: &InfoFrame,
    port: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    let version = info.firmware_version;
    dict.set_item("protocol_version", info.protocol_version)?;
    dict.set_item(
        "firmware_version",
        format!("{}.{}.{}", version.major, version.minor, version.patch),
    )?;
    dict.set_item(
        "board_serial",
        taxel_host::device_words::board_serial_hex(info),
    )?;
    dict.set_item("calibration_id", info.calibration_id)?;
    dict.set_item(
        "calibration_source",
        format!("{:?}", info.calibration_source).to_lowercase(),
    )?;
    dict.set_item("rate_sps", info.rate.sps())?;
    dict.set_item("tier", info.model_tier.name())?;
    dict.set_item("pad_count", info.pad_count)?;
    dict.set_item("streaming", info.streaming)?;
    dict.set_item("port", port)?;
    Ok(dict)
}

/// A pad's PadInfo as a dict (see `Device.pad_info`).
pub fn pad_info_dict<'py>(
    py: Python<'py>,
    info: &wire::PadInfoFrame,
) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item("pad", info.pad.get())?;
    dict.set_item("channel", info.channel)?;
    dict.set_item("calibration_id", info.calibration_id)?;
    dict.set_item(
        "calibration_source",
        format!("{:?}", info.calibration_source).to_lowercase(),
    )?;
    dict.set_item("tier", info.model_tier.name())?;
    dict.set_item("role", info.role.name())?;
    let taxels: Vec<[f64; 3]> = info
        .taxels
        .iter()
        .map(|taxel| {
            [
                f64::from(taxel.x_mm),
                f64::from(taxel.y_mm),
                f64::from(taxel.area_mm2),
            ]
        })
        .collect();
    let taxels = numpy::ndarray::Array2::from_shape_vec(
        (taxels.len(), 3),
        taxels.into_iter().flatten().collect(),
    )
    .map_err(|error| taxel_error(ErrorKind::Link, error.to_string()))?;
    dict.set_item("taxels", numpy::IntoPyArray::into_pyarray(taxels, py))?;
    Ok(dict)
}

/// How long a tare of `sample_sets` sets may take at `rate_sps`, beyond the request timeout.
pub fn tare_duration(sample_sets: u16, rate_sps: u16) -> Duration {
    // A set takes about four conversions; allow twice that.
    Duration::from_secs_f64(f64::from(sample_sets) * 8.0 / f64::from(rate_sps.max(1)))
}

/// The payload of a request that answers with an acknowledgement.
pub fn expect_ack(payload: ReplyPayload, what: &str) -> PyResult<()> {
    match payload {
        ReplyPayload::Ack => Ok(()),
        _ => Err(taxel_error(
            ErrorKind::Other,
            format!(
                "{what}: {}",
                RequestError::UnexpectedReply("an acknowledgement")
            ),
        )),
    }
}

impl Device {
    /// A device on an open byte stream: the session starts (identity, stream) with the GIL
    /// released, within `timeout` in all (`slow_hint` is added to the message when it does
    /// not).
    pub fn connect(
        py: Python<'_>,
        port: Box<dyn Transport>,
        port_name: String,
        timeout: Duration,
        backend: Option<Box<dyn Backend>>,
        queue_sets: usize,
        slow_hint: &str,
    ) -> PyResult<Self> {
        let started = start_interruptibly(py, port, timeout, queue_sets, slow_hint);
        let (worker, stream) = match started {
            Ok(started) => started,
            Err(error) => {
                if let Some(mut backend) = backend {
                    py.allow_threads(|| backend.stop());
                }
                return Err(error);
            }
        };
        let pads = usize::from(stream.state().info.pad_count.max(1));
        Ok(Self {
            control: Control::new(worker, backend.into_iter().collect(), timeout),
            stream,
            pads,
            port_name,
        })
    }

    fn on_session<T: Send + 'static>(
        &self,
        py: Python<'_>,
        timeout: Duration,
        job: impl FnOnce(&mut DeviceSession<Link>) -> T + Send + 'static,
    ) -> PyResult<T> {
        self.control
            .on_session(py, 0, timeout, &|| self.ended_error(), job)
    }

    fn request(
        &self,
        py: Python<'_>,
        command: Command,
        what: &str,
        timeout: Duration,
    ) -> PyResult<ReplyPayload> {
        self.control
            .request(py, 0, command, what, timeout, &|| self.ended_error())
    }

    /// What the device computes with now (its state as its session follows it), or as it was
    /// when its stream ended; `None` when it never said.
    fn device_state(&self, py: Python<'_>) -> Option<RecordedDeviceState> {
        let now = self
            .on_session(py, STATE_WAIT, |session| session.state().cloned())
            .ok()
            .flatten();
        now.or_else(|| {
            self.stream
                .state()
                .ended
                .as_ref()
                .and_then(|end| end.state.clone())
        })
    }

    /// Why the device can no longer be asked anything: closed, or its stream ended.
    fn ended_error(&self) -> PyErr {
        match self.stream.is_ended() {
            Some(ended) => taxel_error(ErrorKind::Link, ended.0),
            None => closed_error(),
        }
    }

    /// After a request that may have changed them: the device's identity, and the state its
    /// session follows (what a saved buffer carries), asked again.
    fn refresh_info(&self, py: Python<'_>) -> PyResult<()> {
        let timeout = self.control.timeout;
        // The identity, then per pad its info and calibration (four requests per taxel).
        let requests = 1 + self.pads as u32 * 18;
        let info = self
            .on_session(py, timeout * requests, |session| {
                session.refresh_state().map(|()| *session.info())
            })?
            .map_err(|error| anyhow_error(&error, ErrorKind::Other))?;
        self.stream.state().info = info;
        Ok(())
    }
}

fn no_set_error(timeout: Duration) -> PyErr {
    taxel_error(
        ErrorKind::Timeout,
        format!("no sample set within {} ms", timeout.as_millis()),
    )
}

/// The device's counters as a dict.
pub fn counters_dict<'py>(
    py: Python<'py>,
    counters: &wire::CountersFrame,
) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item("dropped_sample_frames", counters.dropped_sample_frames)?;
    dict.set_item("converter_reinits", counters.converter_reinits)?;
    dict.set_item("i2c_errors", counters.i2c_errors)?;
    dict.set_item(
        "temperature_sensor_errors",
        counters.temperature_sensor_errors,
    )?;
    dict.set_item("frames_dropped_no_host", counters.frames_dropped_no_host)?;
    dict.set_item("host_frames_rejected", counters.host_frames_rejected)?;
    Ok(dict)
}

/// One device's accounting, for `stats`.
pub struct StatsCounts {
    /// Where every sample set went.
    pub accounting: StreamAccounting,
    /// The link's decoding counters.
    pub link: LinkStatistics,
    /// Sets handed to the caller.
    pub sets_delivered: u64,
    /// Sets closed with a pad's frame missing.
    pub incomplete_sets: u64,
    /// Sets dropped because nobody read them.
    pub sets_dropped_unread: u64,
    /// Device events dropped because nobody took them.
    pub events_dropped: u64,
}

/// The dict of `stats`.
pub fn stats_dict<'py>(py: Python<'py>, counts: &StatsCounts) -> PyResult<Bound<'py, PyDict>> {
    let accounting = &counts.accounting;
    let dict = PyDict::new(py);
    dict.set_item("sets_delivered", counts.sets_delivered)?;
    dict.set_item("frames_received", accounting.received())?;
    dict.set_item("sequence_gap_frames", accounting.sequence_gap_sets())?;
    dict.set_item("device_dropped_frames", accounting.device_dropped())?;
    dict.set_item("lost_on_link_frames", accounting.lost_on_link())?;
    dict.set_item("stale_frames", accounting.stale_frames())?;
    dict.set_item("incomplete_sets", counts.incomplete_sets)?;
    dict.set_item("sets_dropped_unread", counts.sets_dropped_unread)?;
    dict.set_item("events_dropped", counts.events_dropped)?;
    dict.set_item("frames_rejected", counts.link.frames_rejected)?;
    Ok(dict)
}

/// The next set from `source` by `deadline`, in slices with the GIL released, raising on
/// Ctrl-C, on a closed control and at the end of the stream.
pub fn next_set_until(
    py: Python<'_>,
    control: &Control,
    source: &Arc<dyn SetSource>,
    deadline: Instant,
) -> PyResult<Option<SetRecord>> {
    loop {
        if control.is_closed(py) {
            return Err(closed_error());
        }
        let slice_end = deadline.min(Instant::now() + SLICE);
        let source = Arc::clone(source);
        match py.allow_threads(move || source.next_set(slice_end)) {
            Ok(Some(set)) => return Ok(Some(set)),
            Ok(None) => {}
            Err(ended) => return Err(taxel_error(ErrorKind::Link, ended.0)),
        }
        py.check_signals()?;
        if Instant::now() >= deadline {
            return Ok(None);
        }
    }
}

#[pymethods]
impl Device {
    /// Opens a board: the one on ``port``, else the attached board with USB serial number
    /// ``serial``, else the only attached board. ``timeout`` (seconds) bounds the connection,
    /// every request and every :meth:`read`. ``queue_sets``: the sample sets kept for
    /// :meth:`read` while nobody reads (the oldest are dropped beyond, and counted).
    #[new]
    #[pyo3(signature = (port=None, serial=None, timeout=2.0, queue_sets=QUEUE_SETS))]
    fn new(
        py: Python<'_>,
        port: Option<String>,
        serial: Option<String>,
        timeout: f64,
        queue_sets: usize,
    ) -> PyResult<Self> {
        let timeout = timeout_from_s(timeout)?;
        let queue_sets = queue_sets_checked(queue_sets)?;
        if port.is_some() && serial.is_some() {
            return Err(PyValueError::new_err("give port or serial, not both"));
        }
        let opened = py.allow_threads(|| {
            let path = select_port(port.as_deref(), serial.as_deref(), DEFAULT_VID, DEFAULT_PID)?;
            let opened = open_serial(&path, PORT_READ_TIMEOUT)?;
            Ok::<_, taxel_host::device_link::LinkError>((path, opened.port))
        });
        let (path, port) = opened.map_err(crate::errors::link_error)?;
        Device::connect(py, Box::new(port), path, timeout, None, queue_sets, "")
    }

    /// The device's identity: protocol and firmware version, board serial, calibration id and
    /// source, converter rate, model tier, pad count, streaming.
    #[getter]
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        if self.control.is_closed(py) {
            return Err(closed_error());
        }
        let info = self.stream.state().info;
        info_dict(py, &info, &self.port_name)
    }

    /// Pad ``pad``'s description as the device reports it (its PadInfo): multiplexer
    /// ``channel`` (None on the bus itself), ``calibration_id`` and ``calibration_source``,
    /// ``tier``, ``role`` (``"fingertip"``, ``"palm"``, ...) and ``taxels``, a (4, 3) array of
    /// each taxel's electrode centre x, y (mm, in the pad's frame) and area (mm²), in pad order:
    /// what the device computes the pad's force and centre of pressure with. Raises
    /// :class:`taxel.LinkError` for a pad the device does not have.
    fn pad_info<'py>(&self, py: Python<'py>, pad: u8) -> PyResult<Bound<'py, PyDict>> {
        let index = PadIndex::new(pad)
            .filter(|_| usize::from(pad) < self.pads)
            .ok_or_else(|| {
                taxel_error(
                    ErrorKind::Link,
                    format!("the device has {} pads: there is no pad {pad}", self.pads),
                )
            })?;
        let reply = self.request(
            py,
            Command::PadInfo { pad: index },
            "PadInfo",
            self.control.timeout,
        )?;
        let ReplyPayload::PadInfo(info) = reply else {
            return Err(taxel_error(
                ErrorKind::Link,
                "the device answered PadInfo with a reply of another kind",
            ));
        };
        pad_info_dict(py, &info)
    }

    /// The number of pads of each sample set.
    #[getter]
    fn pads(&self) -> usize {
        self.pads
    }

    /// The number of taxels of each sample set: 4 per pad.
    #[getter]
    fn taxels(&self) -> usize {
        self.pads * model_core::TAXEL_COUNT
    }

    /// The oldest sample set not yet read: sets queue up (in arrival order, each stamped
    /// with its arrival in ``host_time_s``) while nobody reads, up to 65,536, beyond which the
    /// oldest are dropped and counted in :attr:`stats`. Waits up to ``timeout`` seconds
    /// (default: the device's timeout) and raises :class:`taxel.DeviceTimeoutError` if none
    /// arrives. A control loop that wants the newest set uses :meth:`latest`.
    #[pyo3(signature = (timeout=None))]
    fn read(&self, py: Python<'_>, timeout: Option<f64>) -> PyResult<SampleSet> {
        self.control.refuse_while_buffering(py, "read()")?;
        let timeout = self.timeout_or_default(timeout)?;
        self.next_set_until(py, Instant::now() + timeout)?
            .map(SampleSet::new)
            .ok_or_else(|| no_set_error(timeout))
    }

    /// The newest complete sample set: the sets queued before it are discarded (they stay
    /// counted in :attr:`stats` as delivered), and when none is queued, the next to arrive
    /// (waiting up to ``timeout`` seconds). What a control loop reads each cycle.
    #[pyo3(signature = (timeout=None))]
    fn latest(&self, py: Python<'_>, timeout: Option<f64>) -> PyResult<SampleSet> {
        self.control.refuse_while_buffering(py, "latest()")?;
        let timeout = self.timeout_or_default(timeout)?;
        if self.is_closed(py) {
            return Err(closed_error());
        }
        let stream = Arc::clone(&self.stream);
        let queued = py.allow_threads(|| stream.drain_sets());
        match queued.into_iter().rev().find(SetRecord::is_complete) {
            Some(newest) => Ok(SampleSet::new(newest)),
            None => self
                .next_set_until(py, Instant::now() + timeout)?
                .map(SampleSet::new)
                .ok_or_else(|| no_set_error(timeout)),
        }
    }

    /// The device itself: iterating reads sample sets until it is closed.
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// The next sample set (:meth:`read`); stops when the device is closed.
    fn __next__(&self, py: Python<'_>) -> PyResult<SampleSet> {
        if self.is_closed(py) {
            return Err(PyStopIteration::new_err(()));
        }
        self.read(py, None)
    }

    /// Starts collecting every sample set in the background, up to ``capacity_sets`` sets
    /// between two :meth:`read_buffer` calls; sets beyond are counted as overflowed.
    #[pyo3(signature = (capacity_sets=1_000_000))]
    fn start_buffering(&self, py: Python<'_>, capacity_sets: usize) -> PyResult<()> {
        let source: Arc<dyn SetSource> = self.stream.clone();
        self.control.start_buffering(py, source, capacity_sets)
    }

    /// The sets collected since the last call, as a :class:`taxel.Buffer`. With ``strict``
    /// (the default), sets lost meanwhile (the buffer was full, or sequence numbers have gaps)
    /// raise :class:`taxel.DataLossError`, whose ``buffer`` holds what was collected. When the
    /// link failed (the board was unplugged), :class:`taxel.LinkError` is raised, with the sets
    /// collected before the failure in its ``buffer``; so is every later call.
    #[pyo3(signature = (strict=true))]
    fn read_buffer(&self, py: Python<'_>, strict: bool) -> PyResult<Buffer> {
        let (collected, capacity_sets) = self.control.take_buffer(py)?;
        let state = self.device_state(py);
        let buffer = Buffer::new(
            py,
            0,
            &collected.sets,
            self.pads,
            collected.overflowed_sets,
            state,
        )?;
        if let Some(error) = &collected.error {
            let error = anyhow_error(error, ErrorKind::Link);
            error.value(py).setattr("buffer", Py::new(py, buffer)?)?;
            return Err(error);
        }
        if strict && (buffer.overflowed_sets > 0 || buffer.sequence_gap_sets > 0) {
            let message = data_loss_message(
                buffer.overflowed_sets,
                buffer.sequence_gap_sets,
                capacity_sets,
            );
            let error = taxel_error(ErrorKind::DataLoss, message);
            error.value(py).setattr("buffer", Py::new(py, buffer)?)?;
            return Err(error);
        }
        Ok(buffer)
    }

    /// Stops collecting in the background and returns the sets collected since the last
    /// :meth:`read_buffer` (as ``read_buffer(strict=False)``: losses are in its counters; an
    /// empty buffer when none was running). Sets arriving afterwards are for :meth:`read`.
    fn stop_buffering(&self, py: Python<'_>) -> PyResult<Buffer> {
        let collected = self.control.stop_buffering(py);
        let state = self.device_state(py);
        Buffer::new(
            py,
            0,
            &collected.sets,
            self.pads,
            collected.overflowed_sets,
            state,
        )
    }

    /// Whether sets are being collected in the background.
    #[getter]
    fn buffering(&self, py: Python<'_>) -> bool {
        self.control.is_buffering(py)
    }

    /// The device events (contact started or ended, tare finished, temperature source
    /// changed, converter re-initialised, ...) that arrived since the last call, oldest first,
    /// as :class:`taxel.DeviceEvent` objects. Events are kept whether or not sets are read (a
    /// full set queue drops sets, never events), up to 100,000 (beyond, the oldest are
    /// dropped and counted in :attr:`stats`). After :meth:`close`, the events that arrived
    /// before it.
    fn events(&self, py: Python<'_>) -> Vec<DeviceEvent> {
        let stream = Arc::clone(&self.stream);
        py.allow_threads(move || stream.take_events())
            .into_iter()
            .map(DeviceEvent::new)
            .collect()
    }

    /// Tares every pad, or pad ``pad`` only: the unloaded reference of each of its taxels
    /// becomes the mean of the next ``sample_sets`` sets (keep the pads unloaded); the other
    /// pads keep theirs. Returns when the device says it is done.
    #[pyo3(signature = (sample_sets=64, pad=None))]
    fn tare(&self, py: Python<'_>, sample_sets: u16, pad: Option<u8>) -> PyResult<()> {
        if sample_sets == 0 {
            return Err(PyValueError::new_err("sample_sets must be at least 1"));
        }
        let pad = pad.map(|pad| self.pad_index(pad)).transpose()?;
        let rate_sps = self.stream.state().info.rate.sps();
        let payload = self.request(
            py,
            Command::Tare { sample_sets, pad },
            "Tare",
            self.control.timeout + tare_duration(sample_sets, rate_sps),
        )?;
        expect_ack(payload, "Tare")
    }

    /// Sets the converter rate: 100, 200 or 400 conversions per second (a sample set arrives
    /// at about a quarter of it).
    fn set_rate(&self, py: Python<'_>, rate_sps: u16) -> PyResult<()> {
        let rate = SampleRate::from_sps(rate_sps).ok_or_else(|| {
            PyValueError::new_err(format!(
                "rate {rate_sps} S/s is not supported; valid rates: 100, 200, 400"
            ))
        })?;
        let payload = self.request(
            py,
            Command::SetRate { rate },
            "SetRate",
            self.control.timeout,
        )?;
        expect_ack(payload, "SetRate")?;
        self.refresh_info(py)
    }

    /// Selects the pressure-model tier by name (see :data:`taxel.TIERS`).
    fn set_tier(&self, py: Python<'_>, tier: &str) -> PyResult<()> {
        let tier = taxel_host::convert::parse_tier(tier).map_err(PyValueError::new_err)?;
        let payload = self.request(
            py,
            Command::SetModelTier { tier },
            "SetModelTier",
            self.control.timeout,
        )?;
        expect_ack(payload, "SetModelTier")?;
        self.refresh_info(py)
    }

    /// Lets the device choose the tier for a use case: ``"light_touch"``, ``"gripper"``,
    /// ``"glove"``, or a dict with ``pressure_max_kpa``, ``temperature_min_c``,
    /// ``temperature_max_c`` and ``error_budget_kpa``. Returns the tier chosen.
    fn set_use_case(&self, py: Python<'_>, use_case: &Bound<'_, PyAny>) -> PyResult<String> {
        let use_case = crate::use_case::use_case_from_python(use_case)?;
        match self.request(
            py,
            Command::SetUseCase(use_case),
            "SetUseCase",
            self.control.timeout,
        )? {
            ReplyPayload::ModelTier(tier) => {
                self.refresh_info(py)?;
                Ok(tier.name().to_owned())
            }
            _ => Err(taxel_error(
                ErrorKind::Other,
                format!(
                    "SetUseCase: {}",
                    RequestError::UnexpectedReply("SetUseCase")
                ),
            )),
        }
    }

    /// The calibration pad ``pad`` uses, read from the device.
    #[pyo3(signature = (pad=0))]
    fn read_calibration(&self, py: Python<'_>, pad: u8) -> PyResult<Calibration> {
        let pad_index = self.pad_index(pad)?;
        let timeout = self.control.timeout;
        // Four requests per taxel and the pad's info, each bounded by the timeout.
        let calibration = self
            .on_session(py, timeout * 6, move |session| {
                let link = session.link_mut();
                let pad_info =
                    taxel_host::calibration_transfer::pad_info(link, pad_index, timeout)?;
                taxel_host::calibration_transfer::pull(
                    link,
                    pad_index,
                    pad_info.calibration_id,
                    timeout,
                )
                .with_context(|| format!("reading pad {pad}'s calibration"))
            })?
            .map_err(|error| anyhow_error(&error, ErrorKind::Other))?;
        Ok(Calibration::from_model(calibration))
    }

    /// Writes a calibration to every pad, or to ``pad`` only, in the device's RAM; with
    /// ``save`` also to its flash (see :meth:`save_calibration`).
    #[pyo3(signature = (calibration, pad=None, save=false))]
    fn write_calibration(
        &self,
        py: Python<'_>,
        calibration: PyRef<'_, Calibration>,
        pad: Option<u8>,
        save: bool,
    ) -> PyResult<()> {
        let only_pad = pad.map(|pad| self.pad_index(pad)).transpose()?;
        let model = calibration.model().clone();
        let timeout = self.control.timeout;
        // Every pad's curve and its save: a few dozen requests, each bounded by the timeout.
        self.on_session(py, timeout * 64, move |session| {
            taxel_host::calibration_transfer::upload_to_pads(
                session.link_mut(),
                &model,
                only_pad,
                save,
                timeout,
                &mut |_| {},
            )
        })?
        .map_err(|error| anyhow_error(&error, ErrorKind::Other))?;
        self.refresh_info(py)
    }

    /// Saves the calibration in use to the device's flash, which every pad boots with.
    fn save_calibration(&self, py: Python<'_>) -> PyResult<()> {
        let payload = self.request(
            py,
            Command::SaveCalibration,
            "SaveCalibration",
            self.control.timeout,
        )?;
        expect_ack(payload, "SaveCalibration")
    }

    /// Replaces every pad's calibration in RAM by the built-in default (flash untouched).
    fn restore_defaults(&self, py: Python<'_>) -> PyResult<()> {
        let payload = self.request(
            py,
            Command::RestoreDefaults,
            "RestoreDefaults",
            self.control.timeout,
        )?;
        expect_ack(payload, "RestoreDefaults")?;
        self.refresh_info(py)
    }

    /// The device's health counters since it booted.
    fn read_counters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        match self.request(
            py,
            Command::ReadCounters,
            "ReadCounters",
            self.control.timeout,
        )? {
            ReplyPayload::Counters(counters) => counters_dict(py, &counters),
            _ => Err(taxel_error(
                ErrorKind::Other,
                format!(
                    "ReadCounters: {}",
                    RequestError::UnexpectedReply("ReadCounters")
                ),
            )),
        }
    }

    /// This connection's accounting: sets delivered, frames received, sets missing from the
    /// sequence numbers, dropped by the device (as of its last counters), lost on the link,
    /// incomplete sets, stale frames discarded at connection, sets dropped unread, device
    /// events dropped untaken.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let ended = self.stream.state().ended.clone();
        let (accounting, link) = match ended {
            Some(end) => (end.accounting, end.link),
            None => self.on_session(py, self.control.timeout, |session| {
                (
                    session.accounting().clone(),
                    session.link_statistics().clone(),
                )
            })?,
        };
        let (sets_delivered, incomplete_sets, events_dropped) = {
            let state = self.stream.state();
            (
                state.sets_delivered,
                state.incomplete_sets,
                state.events.dropped,
            )
        };
        stats_dict(
            py,
            &StatsCounts {
                accounting,
                link,
                sets_delivered,
                incomplete_sets,
                sets_dropped_unread: self.stream.sets_dropped_unread(),
                events_dropped,
            },
        )
    }

    /// Stops the stream and closes the port (and stops the simulated device). Idempotent, and
    /// safe from any thread or a signal handler: a :meth:`read` or request waiting meanwhile
    /// raises :class:`taxel.LinkError` ("the device is closed").
    fn close(&self, py: Python<'_>) {
        self.close_now(py);
    }

    /// Whether :meth:`close` was called.
    #[getter]
    fn closed(&self, py: Python<'_>) -> bool {
        self.is_closed(py)
    }

    /// The device, for ``with``.
    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// Closes the device at the end of ``with``; exceptions propagate.
    #[pyo3(signature = (*_exception))]
    fn __exit__(&self, py: Python<'_>, _exception: &Bound<'_, pyo3::types::PyTuple>) -> bool {
        self.close_now(py);
        false
    }

    /// A short description.
    fn __repr__(&self) -> String {
        format!("Device(port={:?}, pads={})", self.port_name, self.pads)
    }
}

impl Device {
    fn is_closed(&self, py: Python<'_>) -> bool {
        self.control.is_closed(py)
    }

    fn close_now(&self, py: Python<'_>) {
        self.control.close(py);
    }

    fn timeout_or_default(&self, timeout: Option<f64>) -> PyResult<Duration> {
        match timeout {
            Some(timeout_s) => timeout_from_s(timeout_s),
            None => Ok(self.control.timeout),
        }
    }

    fn next_set_until(&self, py: Python<'_>, deadline: Instant) -> PyResult<Option<SetRecord>> {
        let source: Arc<dyn SetSource> = self.stream.clone();
        next_set_until(py, &self.control, &source, deadline)
    }

    fn pad_index(&self, pad: u8) -> PyResult<PadIndex> {
        if usize::from(pad) >= self.pads {
            return Err(PyValueError::new_err(format!(
                "the device reads {} pad{}: there is no pad {pad}",
                self.pads,
                if self.pads == 1 { "" } else { "s" }
            )));
        }
        PadIndex::new(pad).ok_or_else(|| PyValueError::new_err(format!("no pad {pad}")))
    }
}
