//! Collecting sample sets in the background: a thread takes every set from the session into a
//! bounded store; when the store is full, further sets are counted as overflowed (never
//! silently lost), and `read_buffer` hands the collected sets to Python as arrays with the
//! counts of what was lost.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyUntypedArrayMethods, ToPyArray};
use pyo3::prelude::*;

use crate::locking::lock;
use crate::sample_set::SetRecord;
use crate::stream::Stream;

/// How long the collecting thread waits for a set before it looks at its stop flag.
const SLICE: Duration = Duration::from_millis(20);

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
    /// Starts collecting from `stream` into a store of `capacity_sets`.
    pub fn start(stream: Arc<Stream>, capacity_sets: usize) -> std::io::Result<Self> {
        let collected = Arc::new(Mutex::new(Collected::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let thread_collected = Arc::clone(&collected);
        let thread_stop = Arc::clone(&stop);
        let handle = thread::Builder::new()
            .name("taxel-buffer".into())
            .spawn(move || collect(&stream, &thread_collected, &thread_stop, capacity_sets))?;
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

fn collect(stream: &Stream, collected: &Mutex<Collected>, stop: &AtomicBool, capacity_sets: usize) {
    while !stop.load(Ordering::Relaxed) {
        let result = stream.next_set(Instant::now() + SLICE);
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

/// Sample sets collected in the background, as arrays of one row per set.
///
/// Arrays over the taxels have shape ``(N, taxels)`` with ``taxels = 4 * pads`` (taxel
/// ``4 * pad + k`` is taxel ``k`` of pad ``pad``; ``reshape(N, pads, 4)`` separates the pads);
/// arrays over the pads have shape ``(N, pads)``; the others ``(N,)``.
#[pyclass(frozen, get_all, module = "taxel")]
pub struct Buffer {
    /// Sequence numbers, ``(N,)`` ``int64``.
    pub sequence: Py<PyArray1<i64>>,
    /// Device clock at each set, µs since boot, ``(N,)`` ``int64``.
    pub device_time_us: Py<PyArray1<i64>>,
    /// Host clock when each set arrived, seconds since the Unix epoch, ``(N,)``.
    pub host_time_s: Py<PyArray1<f64>>,
    /// Temperature per pad, °C, ``(N, pads)``; NaN where there is none.
    pub temperature_c: Py<PyArray2<f64>>,
    /// Pressure per taxel, kPa, ``(N, taxels)``; NaN where there is none.
    pub pressure_kpa: Py<PyArray2<f64>>,
    /// Capacitance per taxel, pF, ``(N, taxels)``; NaN for a missing pad frame.
    pub capacitance_pf: Py<PyArray2<f64>>,
    /// Flags per taxel (bits of :class:`taxel.Flags`), ``(N, taxels)`` ``uint16``.
    pub flags: Py<PyArray2<u16>>,
    /// Total normal force per pad, N, ``(N, pads)``; NaN where there is none.
    pub force_n: Py<PyArray2<f64>>,
    /// Sets missing just before each one in the sequence numbers, ``(N,)`` ``int64``.
    pub sets_missing_before: Py<PyArray1<i64>>,
    /// The number of pads.
    pub pads: usize,
    /// Sets that arrived while the buffer was full and were discarded (since the last read).
    pub overflowed_sets: u64,
    /// Sets missing from the sequence numbers among these (dropped by the device or on the
    /// link): the sum of ``sets_missing_before``.
    pub sequence_gap_sets: u64,
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

    /// A short description.
    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "Buffer(sets={}, pads={}, overflowed_sets={}, sequence_gap_sets={})",
            self.sequence.bind(py).len(),
            self.pads,
            self.overflowed_sets,
            self.sequence_gap_sets
        )
    }
}

fn matrix<T: Copy + numpy::Element>(
    py: Python<'_>,
    sets: &[SetRecord],
    columns: usize,
    values: impl Fn(&SetRecord) -> &[T],
    missing: T,
) -> Py<PyArray2<T>> {
    let mut flat = Vec::with_capacity(sets.len() * columns);
    for set in sets {
        let row = values(set);
        flat.extend(row.iter().copied().take(columns));
        flat.extend(std::iter::repeat_n(
            missing,
            columns.saturating_sub(row.len()),
        ));
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
    /// The arrays of `sets` of `pads` pads, with the overflow count.
    pub fn new(py: Python<'_>, sets: &[SetRecord], pads: usize, overflowed_sets: u64) -> Self {
        let taxels = pads * model_core::TAXEL_COUNT;
        let column = |value: &dyn Fn(&SetRecord) -> i64| -> Py<PyArray1<i64>> {
            sets.iter()
                .map(value)
                .collect::<Vec<i64>>()
                .to_pyarray(py)
                .unbind()
        };
        Buffer {
            sequence: column(&|set| i64::from(set.sequence)),
            device_time_us: column(&|set| i64::try_from(set.device_time_us).unwrap_or(i64::MAX)),
            host_time_s: sets
                .iter()
                .map(|set| set.host_time_s)
                .collect::<Vec<f64>>()
                .to_pyarray(py)
                .unbind(),
            temperature_c: matrix(py, sets, pads, |set| &set.temperature_c, f64::NAN),
            pressure_kpa: matrix(py, sets, taxels, |set| &set.pressure_kpa, f64::NAN),
            capacitance_pf: matrix(py, sets, taxels, |set| &set.capacitance_pf, f64::NAN),
            flags: matrix(py, sets, taxels, |set| &set.flags, 0u16),
            force_n: matrix(py, sets, pads, |set| &set.force_n, f64::NAN),
            sets_missing_before: column(&|set| {
                i64::try_from(set.sets_missing_before).unwrap_or(i64::MAX)
            }),
            pads,
            overflowed_sets,
            sequence_gap_sets: sets.iter().map(|set| set.sets_missing_before).sum(),
        }
    }
}
