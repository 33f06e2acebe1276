//! One sample set as numbers ([`SetRecord`], built from the frames the host library gathered)
//! and as the Python `SampleSet`, whose arrays are flat over the taxels: taxel `4 * pad + k`
//! is taxel `k` (C11, C12, C21, C22) of pad `pad`.

use model_core::TAXEL_COUNT;
use numpy::{PyArray1, ToPyArray};
use pyo3::prelude::*;
use taxel_host::csv_format::temperature_source_name;
use taxel_host::pad_set::PadSet;

/// The numbers of one sample set, every pad's.
#[derive(Debug, Clone, PartialEq)]
pub struct SetRecord {
    /// The set's sequence number.
    pub sequence: u32,
    /// The device clock at pad 0's conversion (the first pad present when pad 0's frame is
    /// missing), µs since the device booted.
    pub device_time_us: u64,
    /// The host clock (seconds since the Unix epoch) when the set's last frame arrived.
    pub host_time_s: f64,
    /// Each pad's temperature, °C (NaN: none).
    pub temperature_c: Vec<f64>,
    /// Where each pad's temperature came from.
    pub temperature_source: Vec<&'static str>,
    /// Each taxel's pressure, kPa (NaN: none, see the flags).
    pub pressure_kpa: Vec<f64>,
    /// Each taxel's capacitance, pF (NaN: the pad's frame is missing).
    pub capacitance_pf: Vec<f64>,
    /// Each taxel's flags (the documented bits of `taxel.Flags`).
    pub flags: Vec<u16>,
    /// Each pad's total normal force, N (NaN: none).
    pub force_n: Vec<f64>,
    /// Pads whose frame of this set never arrived.
    pub missing_pads: Vec<usize>,
    /// Sample sets missing just before this one in the sequence numbers (0 normally).
    pub sets_missing_before: u64,
}

impl SetRecord {
    /// The numbers of a gathered set that arrived at `host_time_s` after `sets_missing_before`
    /// missing sets.
    pub fn from_pad_set(set: &PadSet, host_time_s: f64, sets_missing_before: u64) -> Self {
        let pads = set.pads.len();
        let mut record = SetRecord {
            sequence: set.sequence,
            device_time_us: 0,
            host_time_s,
            temperature_c: vec![f64::NAN; pads],
            temperature_source: vec!["none"; pads],
            pressure_kpa: vec![f64::NAN; pads * TAXEL_COUNT],
            capacitance_pf: vec![f64::NAN; pads * TAXEL_COUNT],
            flags: vec![0; pads * TAXEL_COUNT],
            force_n: vec![f64::NAN; pads],
            missing_pads: set.missing_pads().collect(),
            sets_missing_before,
        };
        let mut time_known = false;
        for (pad, frame) in set.pads.iter().enumerate() {
            let Some(frame) = frame else { continue };
            if !time_known {
                record.device_time_us = frame.timestamp_us;
                time_known = true;
            }
            record.temperature_c[pad] = frame.temperature_c.map_or(f64::NAN, f64::from);
            record.temperature_source[pad] = temperature_source_name(frame.temperature_source);
            record.force_n[pad] = frame.summary.force_n.map_or(f64::NAN, f64::from);
            for (taxel, sample) in frame.taxels.iter().enumerate() {
                let index = pad * TAXEL_COUNT + taxel;
                record.pressure_kpa[index] = sample.pressure_kpa.map_or(f64::NAN, f64::from);
                record.capacitance_pf[index] = f64::from(sample.capacitance_pf);
                record.flags[index] = sample.flags;
            }
        }
        record
    }

    /// The number of pads.
    pub fn pad_count(&self) -> usize {
        self.temperature_c.len()
    }
}

/// One sample set of every pad of a device: sequence number, device and host time,
/// temperature, and per taxel pressure, capacitance and flags.
///
/// Arrays over the taxels have shape ``(taxels,)`` with ``taxels = 4 * pads``: taxel
/// ``4 * pad + k`` is taxel ``k`` (C11, C12, C21, C22) of pad ``pad``; ``reshape(pads, 4)`` gives
/// one row per pad. Arrays over the pads have shape ``(pads,)``.
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
    /// The set's sequence number (one more per set the device acquires; wraps at 2**32).
    #[getter]
    fn sequence(&self) -> u32 {
        self.record.sequence
    }

    /// The device clock at the conversion, µs since the device booted (pad 0's frame).
    #[getter]
    fn device_time_us(&self) -> u64 {
        self.record.device_time_us
    }

    /// The device clock at the conversion, seconds since the device booted.
    #[getter]
    fn device_time_s(&self) -> f64 {
        self.record.device_time_us as f64 / 1e6
    }

    /// The host clock when the set arrived, seconds since the Unix epoch (as ``time.time()``).
    #[getter]
    fn host_time_s(&self) -> f64 {
        self.record.host_time_s
    }

    /// The number of pads.
    #[getter]
    fn pads(&self) -> usize {
        self.record.pad_count()
    }

    /// Each pad's temperature, °C, shape ``(pads,)``; NaN where there is none.
    #[getter]
    fn temperature_c<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.record.temperature_c.to_pyarray(py)
    }

    /// Where each pad's temperature came from: ``"tmp117"``, ``"mcu_internal"``,
    /// ``"last_known"`` or ``"none"``.
    #[getter]
    fn temperature_source(&self) -> Vec<&'static str> {
        self.record.temperature_source.clone()
    }

    /// Pressure per taxel, kPa, shape ``(taxels,)``; NaN where the model gives none (the flags
    /// say why).
    #[getter]
    fn pressure_kpa<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.record.pressure_kpa.to_pyarray(py)
    }

    /// Capacitance per taxel, pF, shape ``(taxels,)``; NaN for a pad whose frame is missing.
    #[getter]
    fn capacitance_pf<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.record.capacitance_pf.to_pyarray(py)
    }

    /// Flags per taxel (bits of :class:`taxel.Flags`), shape ``(taxels,)``, ``uint16``.
    #[getter]
    fn flags<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u16>> {
        self.record.flags.to_pyarray(py)
    }

    /// Each pad's total normal force, N, shape ``(pads,)``; NaN where there is none.
    #[getter]
    fn force_n<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.record.force_n.to_pyarray(py)
    }

    /// Pads whose frame of this set never arrived (their cells are NaN and 0).
    #[getter]
    fn missing_pads(&self) -> Vec<usize> {
        self.record.missing_pads.clone()
    }

    /// Sample sets missing just before this one in the sequence numbers: 0 unless sets were
    /// lost (dropped by the device or on the link).
    #[getter]
    fn sets_missing_before(&self) -> u64 {
        self.record.sets_missing_before
    }

    /// A short description.
    fn __repr__(&self) -> String {
        format!(
            "SampleSet(sequence={}, device_time_s={:.6}, pads={}, pressure_kpa={:?})",
            self.record.sequence,
            self.record.device_time_us as f64 / 1e6,
            self.record.pad_count(),
            self.record.pressure_kpa
        )
    }
}
