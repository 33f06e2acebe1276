//! Collecting sample sets in the background: a thread takes every set from a device's stream
//! (or several devices' timeline) into a bounded store; when the store is full, further sets
//! are counted as overflowed (never silently lost), and `read_buffer` hands the collected sets
//! to Python as arrays with the counts of what was lost. A [`Buffer`] also becomes a pandas
//! table of the recording schema, or a recording file of it.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use model_core::{TaxelFlags, TAXEL_COUNT};
use numpy::ndarray::{Array2, Array3, ArrayView1, ArrayView2, ArrayView3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use taxel_host::console::error_message;
use taxel_host::device_state::RecordedDeviceState;
use taxel_host::output_file::OutputFile;
use taxel_host::recorder::device_file;
use taxel_host::schema::{PadReading, PadRow, RowWriter};
use wire::TemperatureSource;

use crate::errors::{taxel_error, ErrorKind};
use crate::locking::lock;
use crate::sample_set::SetRecord;
use crate::stream::SetSource;

/// How long the collecting thread waits for a set before it looks at its stop flag.
const SLICE: Duration = Duration::from_millis(20);

/// The temperature sources by their code (`TemperatureSource::code`), as the recording names
/// them.
const SOURCES: [TemperatureSource; 4] = [
    TemperatureSource::None,
    TemperatureSource::Tmp117,
    TemperatureSource::McuInternal,
    TemperatureSource::LastKnown,
];

/// What the collecting thread gathered since the last read.
#[derive(Debug, Default)]
pub struct Collected {
    /// The sets, oldest first.
    pub sets: Vec<SetRecord>,
    /// Sets that arrived while the store was full, discarded.
    pub overflowed_sets: u64,
    /// The error that ended the collection (the link failed), as the exception to raise; it
    /// stays for every later read.
    pub error: Option<Arc<anyhow::Error>>,
}

/// A running collection.
pub struct Buffering {
    collected: Arc<Mutex<Collected>>,
    stop: Arc<AtomicBool>,
    handle: Option<thread::JoinHandle<()>>,
    /// The most sets the store holds.
    pub capacity_sets: usize,
}

impl Buffering {
    /// Starts collecting from `source` into a store of `capacity_sets`.
    pub fn start(source: Arc<dyn SetSource>, capacity_sets: usize) -> std::io::Result<Self> {
        let collected = Arc::new(Mutex::new(Collected::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let thread_collected = Arc::clone(&collected);
        let thread_stop = Arc::clone(&stop);
        let handle = thread::Builder::new()
            .name("taxel-buffer".into())
            .spawn(move || {
                collect(
                    source.as_ref(),
                    &thread_collected,
                    &thread_stop,
                    capacity_sets,
                )
            })?;
        Ok(Self {
            collected,
            stop,
            handle: Some(handle),
            capacity_sets,
        })
    }

    /// Takes what was collected so far (the store is empty afterwards; an error that ended the
    /// collection stays).
    pub fn take(&self) -> Collected {
        let mut store = lock(&self.collected);
        Collected {
            sets: std::mem::take(&mut store.sets),
            overflowed_sets: std::mem::take(&mut store.overflowed_sets),
            error: store.error.clone(),
        }
    }

    /// Stops the thread and waits for it.
    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(handle) = self.handle.take() {
            let _ = handle.join();
        }
    }
}

impl Drop for Buffering {
    fn drop(&mut self) {
        self.stop();
    }
}

fn collect(
    source: &dyn SetSource,
    collected: &Mutex<Collected>,
    stop: &AtomicBool,
    capacity_sets: usize,
) {
    while !stop.load(Ordering::Relaxed) {
        let result = source.next_set(Instant::now() + SLICE);
        let mut store = lock(collected);
        match result {
            Ok(Some(set)) => {
                if store.sets.len() < capacity_sets {
                    store.sets.push(set);
                } else {
                    store.overflowed_sets += 1;
                }
            }
            Ok(None) => {}
            Err(ended) => {
                store.error = Some(Arc::new(anyhow::anyhow!(ended.0)));
                return;
            }
        }
    }
}

/// Sample sets of one device collected in the background, as arrays of one row per set.
///
/// Arrays over the taxels have shape ``(N, taxels)`` with ``taxels = 4 * pads`` (taxel
/// ``4 * pad + k`` is taxel ``k`` of pad ``pad``; ``reshape(N, pads, 4)`` separates the pads);
/// arrays over the pads have shape ``(N, pads)`` (``cop_mm`` ``(N, pads, 2)``); the others
/// ``(N,)``. :meth:`to_pandas` gives the long table of the recording schema, :meth:`save` its
/// file.
#[pyclass(frozen, module = "taxel")]
pub struct Buffer {
    /// The device (0 for :class:`taxel.Device`; its index for :class:`taxel.Devices`).
    #[pyo3(get)]
    pub device: usize,
    /// Sequence numbers, ``(N,)`` ``int64``.
    #[pyo3(get)]
    pub sequence: Py<PyArray1<i64>>,
    /// Device clock at each set (pad 0's conversion), µs since boot, ``(N,)`` ``int64``.
    #[pyo3(get)]
    pub device_time_us: Py<PyArray1<i64>>,
    /// Device clock at each pad's conversion, µs since boot, ``(N, pads)`` ``int64``; -1 for a
    /// missing frame.
    #[pyo3(get)]
    pub pad_device_time_us: Py<PyArray2<i64>>,
    /// Host clock of each set, seconds since the Unix epoch, ``(N,)``: its arrival
    /// (:class:`taxel.Device`), or its device time mapped onto the host clock
    /// (:class:`taxel.Devices`).
    #[pyo3(get)]
    pub host_time_s: Py<PyArray1<f64>>,
    /// Bound on ``host_time_s``'s error, ms, ``(N,)``; NaN where it is the arrival.
    #[pyo3(get)]
    pub sync_error_ms: Py<PyArray1<f64>>,
    /// Temperature per pad, °C, ``(N, pads)``; NaN where there is none.
    #[pyo3(get)]
    pub temperature_c: Py<PyArray2<f64>>,
    /// Where each temperature came from, ``(N, pads)`` strings (``tmp117``, ``mcu_internal``,
    /// ``last_known``, ``none``).
    #[pyo3(get)]
    pub temperature_source: PyObject,
    /// Pressure per taxel, kPa, ``(N, taxels)``; NaN where there is none.
    #[pyo3(get)]
    pub pressure_kpa: Py<PyArray2<f64>>,
    /// Capacitance per taxel, pF, ``(N, taxels)``; NaN for a missing pad frame.
    #[pyo3(get)]
    pub capacitance_pf: Py<PyArray2<f64>>,
    /// Flags per taxel (bits of :class:`taxel.Flags`), ``(N, taxels)`` ``uint16``.
    #[pyo3(get)]
    pub flags: Py<PyArray2<u16>>,
    /// Total normal force per pad, N, ``(N, pads)``; NaN where there is none.
    #[pyo3(get)]
    pub force_n: Py<PyArray2<f64>>,
    /// Centre of pressure per pad in the pad's frame, mm, ``(N, pads, 2)`` (x, y); NaN where
    /// there is none.
    #[pyo3(get)]
    pub cop_mm: Py<PyArray3<f64>>,
    /// Whether each pad is in contact (the device's detector), ``(N, pads)`` ``bool``.
    #[pyo3(get)]
    pub contact: Py<PyArray2<bool>>,
    /// Whether faulted taxels were left out of a pad's force and centre, ``(N, pads)`` ``bool``.
    #[pyo3(get)]
    pub partial: Py<PyArray2<bool>>,
    /// Whether a pad's frame of the set never arrived, ``(N, pads)`` ``bool``.
    #[pyo3(get)]
    pub missing: Py<PyArray2<bool>>,
    /// Sets missing just before each one in the sequence numbers, ``(N,)`` ``int64``.
    #[pyo3(get)]
    pub sets_missing_before: Py<PyArray1<i64>>,
    /// The number of pads.
    #[pyo3(get)]
    pub pads: usize,
    /// Sets that arrived while the buffer was full and were discarded (since the last read).
    #[pyo3(get)]
    pub overflowed_sets: u64,
    /// Sets missing from the sequence numbers among these (dropped by the device or on the
    /// link): the sum of ``sets_missing_before``.
    #[pyo3(get)]
    pub sequence_gap_sets: u64,
    /// What the device computed these sets with (identity, and per pad calibration, tier,
    /// geometry and baselines), when it could say: saved beside the recording.
    state: Option<RecordedDeviceState>,
}

#[pymethods]
impl Buffer {
    /// The number of sample sets.
    fn __len__(&self, py: Python<'_>) -> usize {
        self.sequence.bind(py).len()
    }

    /// Sets lost since the last read: overflowed plus missing from the sequence numbers.
    #[getter]
    fn lost_sets(&self) -> u64 {
        self.overflowed_sets + self.sequence_gap_sets
    }

    /// The sets as a pandas ``DataFrame`` of the recording schema (what ``taxel record``
    /// writes): one row per pad per set, the schema's columns in its order. Flags are integers
    /// (bits of :class:`taxel.Flags`) where the file has their names; ``partial`` and
    /// ``contact`` are booleans; empty cells are NaN. Needs pandas (``ImportError`` otherwise).
    fn to_pandas(slf: &Bound<'_, Self>) -> PyResult<PyObject> {
        let py = slf.py();
        Ok(py
            .import("taxel._pandas")?
            .call_method1("buffer_frame", (slf,))?
            .unbind())
    }

    /// Writes the sets as a recording of the schema (the CSV file ``taxel record`` writes,
    /// without its raw log), which :func:`taxel.read_recording`, :func:`taxel.convert_recording`,
    /// ``taxel convert`` and ``taxel plot`` read, and beside it, as ``taxel record`` does,
    /// ``PATH.dev<device>.device.json``: what the device computed the sets with (its calibration,
    /// tier, geometry and baselines per pad), so that :func:`taxel.convert_recording` and
    /// ``taxel convert`` reproduce the device's pressures rather than use the defaults. When the
    /// device could not say (it went away before its state was read), only the recording is
    /// written, with a :class:`taxel.TaxelWarning`. Each file is written under a temporary name
    /// and renamed once complete: a failed save leaves an existing file as it was.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let rows = self.rows(py)?;
        let state_path = device_file(&path, self.device, "device.json");
        py.allow_threads(|| -> anyhow::Result<()> {
            let mut writer = RowWriter::new(OutputFile::create(&path)?)?;
            for row in &rows {
                writer.write(row)?;
            }
            writer.flush()?;
            writer.into_inner().commit()?;
            if let Some(state) = &self.state {
                state.write(&state_path)?;
            }
            Ok(())
        })
        .map_err(|error| {
            taxel_error(
                ErrorKind::Other,
                format!("writing {}: {}", path.display(), error_message(&error)),
            )
        })?;
        let message = match &self.state {
            None => Some(format!(
                "{}: saved without the device's state ({} not written): the device could not \
                 say what it computed these sets with, so converting the recording again uses \
                 the default calibration and a tare on its first rows",
                path.display(),
                state_path.display()
            )),
            Some(state) => {
                let sequences = self.sequence.bind(py).to_vec()?;
                let changed: Vec<String> = state
                    .pads
                    .iter()
                    .filter(|pad| {
                        sequences
                            .iter()
                            .any(|sequence| *sequence < i64::from(pad.state_from_sequence))
                    })
                    .map(|pad| format!("pad {} before set {}", pad.pad, pad.state_from_sequence))
                    .collect();
                (!changed.is_empty()).then(|| {
                    format!(
                        "{}: the device's calibration, tier or geometry changed while these sets \
                         were read ({}): the state saved is the one after, so converting the \
                         recording again gives other values for the sets before it",
                        path.display(),
                        changed.join(", ")
                    )
                })
            }
        };
        if let Some(message) = message {
            let warning = py.import("taxel")?.getattr("TaxelWarning")?;
            py.import("warnings")?
                .call_method1("warn", (message, warning, 2))?;
        }
        Ok(())
    }

    /// A short description.
    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "Buffer(device={}, sets={}, pads={}, overflowed_sets={}, sequence_gap_sets={})",
            self.device,
            self.sequence.bind(py).len(),
            self.pads,
            self.overflowed_sets,
            self.sequence_gap_sets
        )
    }
}

/// A table of `columns` values per set (rows padded with `missing`, never needed: every set of
/// a device has its pad count).
fn matrix<T: Copy + numpy::Element>(
    py: Python<'_>,
    sets: &[SetRecord],
    columns: usize,
    values: impl Fn(&SetRecord) -> Vec<T>,
    missing: T,
) -> Py<PyArray2<T>> {
    let mut flat = Vec::with_capacity(sets.len() * columns);
    for set in sets {
        let row = values(set);
        let taken = row.len().min(columns);
        flat.extend_from_slice(&row[..taken]);
        flat.extend(std::iter::repeat_n(missing, columns - taken));
    }
    match Array2::from_shape_vec((sets.len(), columns), flat) {
        Ok(array) => array.into_pyarray(py).unbind(),
        // The rows were padded to `columns`: the shape always matches.
        Err(_) => Array2::from_elem((sets.len(), columns), missing)
            .into_pyarray(py)
            .unbind(),
    }
}

impl Buffer {
    /// The arrays of `sets` of device `device` of `pads` pads, with the overflow count and what
    /// the device computed them with.
    pub fn new(
        py: Python<'_>,
        device: usize,
        sets: &[SetRecord],
        pads: usize,
        overflowed_sets: u64,
        state: Option<RecordedDeviceState>,
    ) -> PyResult<Self> {
        let taxels = pads * TAXEL_COUNT;
        let column = |value: &dyn Fn(&SetRecord) -> i64| -> Py<PyArray1<i64>> {
            sets.iter()
                .map(value)
                .collect::<Vec<i64>>()
                .into_pyarray(py)
                .unbind()
        };
        let floats = |value: &dyn Fn(&SetRecord) -> f64| -> Py<PyArray1<f64>> {
            sets.iter()
                .map(value)
                .collect::<Vec<f64>>()
                .into_pyarray(py)
                .unbind()
        };
        let mut cop = Vec::with_capacity(sets.len() * pads * 2);
        for set in sets {
            let centres = set.cop_mm();
            for pad in 0..pads {
                cop.extend(centres.get(pad).copied().unwrap_or([f64::NAN; 2]));
            }
        }
        let cop_mm = Array3::from_shape_vec((sets.len(), pads, 2), cop)
            .map_err(|error| taxel_error(ErrorKind::Other, error.to_string()))?
            .into_pyarray(py)
            .unbind();
        let source_codes = matrix(
            py,
            sets,
            pads,
            |set| set.per_pad(|reading| reading.temperature_source.code(), 0),
            0u8,
        );
        let names: Vec<&str> = SOURCES
            .iter()
            .map(|source| taxel_host::csv_format::temperature_source_name(*source))
            .collect();
        let temperature_source = py
            .import("numpy")?
            .call_method1("array", (names,))?
            .get_item(source_codes)?
            .unbind();
        Ok(Buffer {
            device,
            sequence: column(&|set| i64::from(set.sequence)),
            device_time_us: column(&|set| i64::try_from(set.device_time_us()).unwrap_or(i64::MAX)),
            pad_device_time_us: matrix(
                py,
                sets,
                pads,
                |set| {
                    set.per_pad(
                        |reading| i64::try_from(reading.device_time_us).unwrap_or(i64::MAX),
                        -1,
                    )
                },
                -1,
            ),
            host_time_s: floats(&|set| set.host_time_s),
            sync_error_ms: floats(&|set| set.sync_error_ms),
            temperature_c: matrix(py, sets, pads, SetRecord::temperature_c, f64::NAN),
            temperature_source,
            pressure_kpa: matrix(py, sets, taxels, SetRecord::pressure_kpa, f64::NAN),
            capacitance_pf: matrix(py, sets, taxels, SetRecord::capacitance_pf, f64::NAN),
            flags: matrix(py, sets, taxels, SetRecord::flags, 0u16),
            force_n: matrix(py, sets, pads, SetRecord::force_n, f64::NAN),
            cop_mm,
            contact: matrix(
                py,
                sets,
                pads,
                |set| set.per_pad(|reading| reading.contact, false),
                false,
            ),
            partial: matrix(
                py,
                sets,
                pads,
                |set| set.per_pad(|reading| reading.partial, false),
                false,
            ),
            missing: matrix(
                py,
                sets,
                pads,
                |set| set.readings.iter().map(Option::is_none).collect(),
                true,
            ),
            sets_missing_before: column(&|set| {
                i64::try_from(set.sets_missing_before).unwrap_or(i64::MAX)
            }),
            pads,
            overflowed_sets,
            sequence_gap_sets: sets.iter().map(|set| set.sets_missing_before).sum(),
            state,
        })
    }

    /// The rows of the recording schema, read back from the arrays (their values came from
    /// the device's `f32`s, so they convert back exactly).
    fn rows(&self, py: Python<'_>) -> PyResult<Vec<PadRow>> {
        let sequence = self.sequence.bind(py).readonly();
        let pad_time = self.pad_device_time_us.bind(py).readonly();
        let host_time = self.host_time_s.bind(py).readonly();
        let sync_error = self.sync_error_ms.bind(py).readonly();
        let temperature = self.temperature_c.bind(py).readonly();
        let pressure = self.pressure_kpa.bind(py).readonly();
        let capacitance = self.capacitance_pf.bind(py).readonly();
        let flags = self.flags.bind(py).readonly();
        let force = self.force_n.bind(py).readonly();
        let cop = self.cop_mm.bind(py).readonly();
        let contact = self.contact.bind(py).readonly();
        let partial = self.partial.bind(py).readonly();
        let missing = self.missing.bind(py).readonly();
        let names: Vec<String> = self
            .temperature_source
            .bind(py)
            .call_method0("ravel")?
            .call_method0("tolist")?
            .extract()?;
        let arrays = Arrays {
            sequence: sequence.as_array(),
            pad_time: pad_time.as_array(),
            host_time: host_time.as_array(),
            sync_error: sync_error.as_array(),
            temperature: temperature.as_array(),
            pressure: pressure.as_array(),
            capacitance: capacitance.as_array(),
            flags: flags.as_array(),
            force: force.as_array(),
            cop: cop.as_array(),
            contact: contact.as_array(),
            partial: partial.as_array(),
            missing: missing.as_array(),
            sources: &names,
        };
        Ok(arrays.rows(self.device, self.pads))
    }
}

/// Views of a buffer's arrays.
struct Arrays<'a> {
    sequence: ArrayView1<'a, i64>,
    pad_time: ArrayView2<'a, i64>,
    host_time: ArrayView1<'a, f64>,
    sync_error: ArrayView1<'a, f64>,
    temperature: ArrayView2<'a, f64>,
    pressure: ArrayView2<'a, f64>,
    capacitance: ArrayView2<'a, f64>,
    flags: ArrayView2<'a, u16>,
    force: ArrayView2<'a, f64>,
    cop: ArrayView3<'a, f64>,
    contact: ArrayView2<'a, bool>,
    partial: ArrayView2<'a, bool>,
    missing: ArrayView2<'a, bool>,
    sources: &'a [String],
}

fn single(value: f64) -> Option<f32> {
    (!value.is_nan()).then_some(value as f32)
}

impl Arrays<'_> {
    fn rows(&self, device: usize, pads: usize) -> Vec<PadRow> {
        let sets = self.sequence.len();
        let mut rows = Vec::with_capacity(sets * pads);
        for set in 0..sets {
            let sync_error_ms = self.sync_error[set];
            for pad in 0..pads {
                let reading = (!self.missing[[set, pad]]).then(|| {
                    let taxel = |column: usize| [set, pad * TAXEL_COUNT + column];
                    let source = self
                        .sources
                        .get(set * pads + pad)
                        .and_then(|name| {
                            SOURCES.into_iter().find(|source| {
                                taxel_host::csv_format::temperature_source_name(*source) == name
                            })
                        })
                        .unwrap_or(TemperatureSource::None);
                    let cop = [self.cop[[set, pad, 0]], self.cop[[set, pad, 1]]];
                    PadReading {
                        device_time_us: u64::try_from(self.pad_time[[set, pad]]).unwrap_or(0),
                        temperature_c: single(self.temperature[[set, pad]]),
                        temperature_source: source,
                        capacitance_pf: std::array::from_fn(|k| single(self.capacitance[taxel(k)])),
                        pressure_kpa: std::array::from_fn(|k| single(self.pressure[taxel(k)])),
                        flags: std::array::from_fn(|k| {
                            TaxelFlags::from_bits_retain(self.flags[taxel(k)])
                        }),
                        force_n: single(self.force[[set, pad]]),
                        centre_of_pressure_mm: (!cop[0].is_nan() && !cop[1].is_nan())
                            .then(|| cop.map(|value| value as f32)),
                        partial: self.partial[[set, pad]],
                        contact: self.contact[[set, pad]],
                    }
                });
                rows.push(PadRow {
                    host_time_us: (self.host_time[set] * 1e6).round().max(0.0) as u64,
                    device: u32::try_from(device).unwrap_or(u32::MAX),
                    pad: u8::try_from(pad).unwrap_or(u8::MAX),
                    sequence: u32::try_from(self.sequence[set]).unwrap_or(u32::MAX),
                    sync_error_us: (!sync_error_ms.is_nan())
                        .then(|| (sync_error_ms * 1e3).round().max(0.0) as u64),
                    reading,
                    marker: String::new(),
                });
            }
        }
        rows
    }
}

/// Splits collected sets by device into one [`Buffer`] per device (of `pads[device]` pads, with
/// `states[device]`); the overflow count goes to every buffer (the store is shared).
pub fn buffers_by_device(
    py: Python<'_>,
    sets: Vec<SetRecord>,
    pads: &[usize],
    overflowed_sets: u64,
    states: Vec<Option<RecordedDeviceState>>,
) -> PyResult<Vec<Buffer>> {
    let mut by_device: Vec<Vec<SetRecord>> = pads.iter().map(|_| Vec::new()).collect();
    for set in sets {
        if let Some(device_sets) = by_device.get_mut(set.device) {
            device_sets.push(set);
        }
    }
    let mut states = states.into_iter();
    by_device
        .iter()
        .enumerate()
        .map(|(device, device_sets)| {
            let state = states.next().flatten();
            Buffer::new(
                py,
                device,
                device_sets,
                pads[device],
                overflowed_sets,
                state,
            )
        })
        .collect()
}
