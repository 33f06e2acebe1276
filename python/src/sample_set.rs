//! One sample set as numbers ([`SetRecord`]: every pad's reading as the recording schema holds
//! it, built from the frames the host library gathered) and as the Python `SampleSet`, whose
//! arrays are flat over the taxels: taxel `4 * pad + k` is taxel `k` (C11, C12, C21, C22) of pad
//! `pad`.

use model_core::TAXEL_COUNT;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, ToPyArray};
use pyo3::prelude::*;
use taxel_host::csv_format::temperature_source_name;
use taxel_host::pad_set::PadSet;
use taxel_host::schema::PadReading;

/// The numbers of one sample set of one device, every pad's.
#[derive(Debug, Clone, PartialEq)]
pub struct SetRecord {
    /// The device, numbered in the order the devices were given (0 for a single device).
    pub device: usize,
    /// The set's sequence number.
    pub sequence: u32,
    /// The host clock (seconds since the Unix epoch) of the set: its arrival, or (several
    /// devices on one timeline) its device time mapped onto the host clock.
    pub host_time_s: f64,
    /// Bound on `host_time_s`'s distance from the sampling instant, ms; NaN when it is the
    /// arrival (no clock mapping).
    pub sync_error_ms: f64,
    /// Each pad's reading (`None`: its frame of this set never arrived).
    pub readings: Vec<Option<PadReading>>,
    /// Sample sets missing just before this one in the sequence numbers (0 normally).
    pub sets_missing_before: u64,
}

fn number(value: Option<f32>) -> f64 {
    value.map_or(f64::NAN, f64::from)
}

impl SetRecord {
    /// The numbers of a gathered set of device `device` that arrived at `host_time_s` after
    /// `sets_missing_before` missing sets.
    pub fn from_pad_set(
        device: usize,
        set: &PadSet,
        host_time_s: f64,
        sets_missing_before: u64,
    ) -> Self {
        SetRecord {
            device,
            sequence: set.sequence,
            host_time_s,
            sync_error_ms: f64::NAN,
            readings: set
                .pads
                .iter()
                .map(|frame| frame.as_ref().map(PadReading::from_frame))
                .collect(),
            sets_missing_before,
        }
    }

    /// The number of pads.
    pub fn pad_count(&self) -> usize {
        self.readings.len()
    }

    /// Whether every pad's frame arrived.
    pub fn is_complete(&self) -> bool {
        self.readings.iter().all(Option::is_some)
    }

    /// The device clock at pad 0's conversion (the first pad present when pad 0's frame is
    /// missing), µs since the device booted.
    pub fn device_time_us(&self) -> u64 {
        self.readings
            .iter()
            .flatten()
            .map(|reading| reading.device_time_us)
            .next()
            .unwrap_or(0)
    }

    /// Pads whose frame never arrived.
    pub fn missing_pads(&self) -> Vec<usize> {
        self.readings
            .iter()
            .enumerate()
            .filter(|(_, reading)| reading.is_none())
            .map(|(pad, _)| pad)
            .collect()
    }

    /// One value per pad (`missing` for a missing frame).
    pub fn per_pad<T: Copy>(&self, value: impl Fn(&PadReading) -> T, missing: T) -> Vec<T> {
        self.readings
            .iter()
            .map(|reading| reading.as_ref().map_or(missing, &value))
            .collect()
    }

    /// Four values per pad, flat over the taxels (`missing` for a missing frame).
    pub fn per_taxel<T: Copy>(
        &self,
        value: impl Fn(&PadReading, usize) -> T,
        missing: T,
    ) -> Vec<T> {
        let mut values = Vec::with_capacity(self.readings.len() * TAXEL_COUNT);
        for reading in &self.readings {
            for taxel in 0..TAXEL_COUNT {
                values.push(
                    reading
                        .as_ref()
                        .map_or(missing, |reading| value(reading, taxel)),
                );
            }
        }
        values
    }

    /// Each taxel's pressure, kPa (NaN: none).
    pub fn pressure_kpa(&self) -> Vec<f64> {
        self.per_taxel(
            |reading, taxel| number(reading.pressure_kpa[taxel]),
            f64::NAN,
        )
    }

    /// Each taxel's capacitance, pF (NaN: none).
    pub fn capacitance_pf(&self) -> Vec<f64> {
        self.per_taxel(
            |reading, taxel| number(reading.capacitance_pf[taxel]),
            f64::NAN,
        )
    }

    /// Each taxel's flags.
    pub fn flags(&self) -> Vec<u16> {
        self.per_taxel(|reading, taxel| reading.flags[taxel].bits(), 0)
    }

    /// Each pad's temperature, °C (NaN: none).
    pub fn temperature_c(&self) -> Vec<f64> {
        self.per_pad(|reading| number(reading.temperature_c), f64::NAN)
    }

    /// Each pad's total normal force, N (NaN: none).
    pub fn force_n(&self) -> Vec<f64> {
        self.per_pad(|reading| number(reading.force_n), f64::NAN)
    }

    /// Each pad's centre of pressure, mm (NaN: none).
    pub fn cop_mm(&self) -> Vec<[f64; 2]> {
        self.per_pad(
            |reading| {
                reading
                    .centre_of_pressure_mm
                    .map_or([f64::NAN; 2], |centre| centre.map(f64::from))
            },
            [f64::NAN; 2],
        )
    }
}

/// One sample set of every pad of a device: sequence number, device and host time,
/// temperature, per taxel pressure, capacitance and flags, and per pad force, centre of
/// pressure and contact.
///
/// Arrays over the taxels have shape ``(taxels,)`` with ``taxels = 4 * pads``: taxel
/// ``4 * pad + k`` is taxel ``k`` (C11, C12, C21, C22) of pad ``pad``; ``reshape(pads, 4)`` gives
/// one row per pad. Arrays over the pads have shape ``(pads,)``; ``cop_mm`` ``(pads, 2)``.
#[pyclass(frozen, module = "taxel")]
pub struct SampleSet {
    record: SetRecord,
}

impl SampleSet {
    /// The Python object of a set's numbers.
    pub fn new(record: SetRecord) -> Self {
        Self { record }
    }
}

#[pymethods]
impl SampleSet {
    /// The device (0 for :class:`taxel.Device`; its index for :class:`taxel.Devices`).
    #[getter]
    fn device(&self) -> usize {
        self.record.device
    }

    /// The set's sequence number (one more per set the device acquires; wraps at 2**32).
    #[getter]
    fn sequence(&self) -> u32 {
        self.record.sequence
    }

    /// The device clock at the conversion, µs since the device booted (pad 0's frame).
    #[getter]
    fn device_time_us(&self) -> u64 {
        self.record.device_time_us()
    }

    /// The device clock at the conversion, seconds since the device booted.
    #[getter]
    fn device_time_s(&self) -> f64 {
        self.record.device_time_us() as f64 / 1e6
    }

    /// The host clock of the set, seconds since the Unix epoch (as ``time.time()``): for
    /// :class:`taxel.Device` its arrival; for :class:`taxel.Devices` its device time mapped
    /// onto the host clock (``sync_error_ms`` bounds the error), or its arrival without a
    /// clock estimate.
    #[getter]
    fn host_time_s(&self) -> f64 {
        self.record.host_time_s
    }

    /// Bound on ``host_time_s``'s distance from the sampling instant, ms; NaN when
    /// ``host_time_s`` is the arrival.
    #[getter]
    fn sync_error_ms(&self) -> f64 {
        self.record.sync_error_ms
    }

    /// The number of pads.
    #[getter]
    fn pads(&self) -> usize {
        self.record.pad_count()
    }

    /// Each pad's temperature, °C, shape ``(pads,)``; NaN where there is none.
    #[getter]
    fn temperature_c<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.record.temperature_c().into_pyarray(py)
    }

    /// Where each pad's temperature came from: ``"tmp117"``, ``"mcu_internal"``,
    /// ``"last_known"`` or ``"none"`` (also for a missing frame).
    #[getter]
    fn temperature_source(&self) -> Vec<&'static str> {
        self.record.per_pad(
            |reading| temperature_source_name(reading.temperature_source),
            "none",
        )
    }

    /// Pressure per taxel, kPa, shape ``(taxels,)``; NaN where the model gives none (the flags
    /// say why).
    #[getter]
    fn pressure_kpa<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.record.pressure_kpa().into_pyarray(py)
    }

    /// Capacitance per taxel, pF, shape ``(taxels,)``; NaN for a pad whose frame is missing.
    #[getter]
    fn capacitance_pf<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.record.capacitance_pf().into_pyarray(py)
    }

    /// Flags per taxel (bits of :class:`taxel.Flags`), shape ``(taxels,)``, ``uint16``.
    #[getter]
    fn flags<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u16>> {
        self.record.flags().into_pyarray(py)
    }

    /// Each pad's total normal force, N, shape ``(pads,)``; NaN where there is none.
    #[getter]
    fn force_n<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.record.force_n().into_pyarray(py)
    }

    /// Each pad's centre of pressure in the pad's frame, mm, shape ``(pads, 2)`` (x, y); NaN
    /// where the device gives none (too little force to place it, or a missing frame).
    #[getter]
    fn cop_mm<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let flat: Vec<f64> = self.record.cop_mm().into_iter().flatten().collect();
        Array2::from_shape_vec((self.record.pad_count(), 2), flat)
            .map(|array| array.into_pyarray(py))
            .map_err(|error| pyo3::exceptions::PyRuntimeError::new_err(error.to_string()))
    }

    /// Whether each pad is in contact (the device's detector, with hysteresis and debounce),
    /// shape ``(pads,)`` ``bool``; False for a missing frame.
    #[getter]
    fn contact<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        self.record
            .per_pad(|reading| reading.contact, false)
            .to_pyarray(py)
    }

    /// Whether faulted taxels were left out of each pad's force and centre of pressure, shape
    /// ``(pads,)`` ``bool``.
    #[getter]
    fn partial<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        self.record
            .per_pad(|reading| reading.partial, false)
            .to_pyarray(py)
    }

    /// Pads whose frame of this set never arrived (their cells are NaN and 0).
    #[getter]
    fn missing_pads(&self) -> Vec<usize> {
        self.record.missing_pads()
    }

    /// Sample sets missing just before this one in the sequence numbers: 0 unless sets were
    /// lost (dropped by the device, on the link, or unread from a full queue).
    #[getter]
    fn sets_missing_before(&self) -> u64 {
        self.record.sets_missing_before
    }

    /// A short description.
    fn __repr__(&self) -> String {
        format!(
            "SampleSet(device={}, sequence={}, device_time_s={:.6}, pads={}, pressure_kpa={:?}, force_n={:?})",
            self.record.device,
            self.record.sequence,
            self.record.device_time_us() as f64 / 1e6,
            self.record.pad_count(),
            self.record.pressure_kpa(),
            self.record.force_n()
        )
    }
}
