//! Recordings from Python: a file of the recording schema (what `taxel record` and the live
//! view write) read into arrays, as recorded or converted again by the host library's
//! conversion engine with each device's recorded state — the very code `taxel convert` runs.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use model_core::TAXEL_COUNT;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use taxel_host::convert::{
    convert_recording, ConversionEngine, ConvertSettings, RecordedStates, RowSink,
};
use taxel_host::csv_format::temperature_source_name;
use taxel_host::schema::{PadRow, RowReader, SchemaError};

use crate::calibration::Calibration;
use crate::errors::{anyhow_error, taxel_error, ErrorKind};
use crate::interrupt::SignalCheck;

/// A recording as arrays: one row per pad per sample set (the recording schema), every device
/// and pad of the file. Taxel arrays have shape ``(N, 4)`` (C11, C12, C21, C22); a pad whose
/// frame of a set never arrived has NaN readings, 0 flags and ``missing`` set.
#[pyclass(frozen, get_all, module = "taxel")]
pub struct Recording {
    /// When each set was sampled, Unix seconds on the host clock, ``(N,)``.
    pub host_time_s: Py<PyArray1<f64>>,
    /// The device of each row, ``(N,)`` ``int64``.
    pub device: Py<PyArray1<i64>>,
    /// The pad of each row, ``(N,)`` ``int64``.
    pub pad: Py<PyArray1<i64>>,
    /// The sample set's sequence number, ``(N,)`` ``int64``.
    pub sequence: Py<PyArray1<i64>>,
    /// The device clock, s since boot, ``(N,)``; NaN for a missing frame.
    pub device_time_s: Py<PyArray1<f64>>,
    /// Bound on host_time_s's error, ms, ``(N,)``; NaN without a clock estimate.
    pub sync_error_ms: Py<PyArray1<f64>>,
    /// The pad temperature, °C, ``(N,)``; NaN where there is none.
    pub temperature_c: Py<PyArray1<f64>>,
    /// Where each temperature came from (``tmp117``, ``mcu_internal``, ``last_known``,
    /// ``none``; empty for a missing frame).
    pub temperature_source: Vec<&'static str>,
    /// Capacitance per taxel, pF, ``(N, 4)``.
    pub capacitance_pf: Py<PyArray2<f64>>,
    /// Pressure per taxel, kPa, ``(N, 4)``; NaN where the model gives none (see the flags).
    pub pressure_kpa: Py<PyArray2<f64>>,
    /// Flags per taxel (bits of :class:`taxel.Flags`), ``(N, 4)`` ``uint16``.
    pub flags: Py<PyArray2<u16>>,
    /// Total normal force of the pad, N, ``(N,)``; NaN where there is none.
    pub force_n: Py<PyArray1<f64>>,
    /// Centre of pressure in the pad's frame, mm, ``(N, 2)``; NaN where there is none.
    pub cop_mm: Py<PyArray2<f64>>,
    /// Faulted taxels were left out of force and centre, ``(N,)`` ``bool``.
    pub partial: Py<PyArray1<bool>>,
    /// The pad is in contact, ``(N,)`` ``bool``.
    pub contact: Py<PyArray1<bool>>,
    /// The pad's frame of this set never arrived, ``(N,)`` ``bool``.
    pub missing: Py<PyArray1<bool>>,
    /// The markers, as ``(row, label)`` pairs.
    pub markers: Vec<(usize, String)>,
}

#[pymethods]
impl Recording {
    /// The number of rows.
    fn __len__(&self, py: Python<'_>) -> usize {
        self.device.bind(py).len().unwrap_or(0)
    }

    /// The recording as a pandas ``DataFrame`` of the recording schema: one row per pad per
    /// set, the schema's columns in its order (as :meth:`taxel.Buffer.to_pandas`: flags as
    /// integers, ``partial`` and ``contact`` booleans, empty cells NaN). Needs pandas.
    fn to_pandas(slf: &Bound<'_, Self>) -> PyResult<PyObject> {
        let py = slf.py();
        Ok(py
            .import("taxel._pandas")?
            .call_method1("recording_frame", (slf,))?
            .unbind())
    }

    /// A short description.
    fn __repr__(&self, py: Python<'_>) -> String {
        format!("Recording(rows={})", self.__len__(py))
    }
}

fn column<T: numpy::Element + Copy>(
    py: Python<'_>,
    rows: &[PadRow],
    value: impl Fn(&PadRow) -> T,
) -> Py<PyArray1<T>> {
    rows.iter()
        .map(value)
        .collect::<Vec<T>>()
        .into_pyarray(py)
        .unbind()
}

fn matrix<const N: usize>(
    py: Python<'_>,
    rows: &[PadRow],
    values: impl Fn(&PadRow) -> [f64; N],
) -> PyResult<Py<PyArray2<f64>>> {
    let flat: Vec<f64> = rows.iter().flat_map(&values).collect();
    Ok(Array2::from_shape_vec((rows.len(), N), flat)
        .map_err(|error| taxel_error(ErrorKind::Other, error.to_string()))?
        .into_pyarray(py)
        .unbind())
}

fn number(value: Option<f32>) -> f64 {
    value.map_or(f64::NAN, f64::from)
}

impl Recording {
    /// The arrays of `rows`.
    pub fn from_rows(py: Python<'_>, rows: &[PadRow]) -> PyResult<Self> {
        let flags: Vec<u16> = rows
            .iter()
            .flat_map(|row| {
                row.reading.map_or([0; TAXEL_COUNT], |reading| {
                    reading.flags.map(|flags| flags.bits())
                })
            })
            .collect();
        Ok(Self {
            host_time_s: column(py, rows, |row| row.host_time_us as f64 / 1e6),
            device: column(py, rows, |row| i64::from(row.device)),
            pad: column(py, rows, |row| i64::from(row.pad)),
            sequence: column(py, rows, |row| i64::from(row.sequence)),
            device_time_s: column(py, rows, |row| {
                row.reading
                    .map_or(f64::NAN, |reading| reading.device_time_us as f64 / 1e6)
            }),
            sync_error_ms: column(py, rows, |row| {
                row.sync_error_us
                    .map_or(f64::NAN, |error| error as f64 / 1e3)
            }),
            temperature_c: column(py, rows, |row| {
                number(row.reading.and_then(|reading| reading.temperature_c))
            }),
            temperature_source: rows
                .iter()
                .map(|row| {
                    row.reading.map_or("", |reading| {
                        temperature_source_name(reading.temperature_source)
                    })
                })
                .collect(),
            capacitance_pf: matrix(py, rows, |row| {
                row.reading.map_or([f64::NAN; TAXEL_COUNT], |reading| {
                    reading.capacitance_pf.map(number)
                })
            })?,
            pressure_kpa: matrix(py, rows, |row| {
                row.reading.map_or([f64::NAN; TAXEL_COUNT], |reading| {
                    reading.pressure_kpa.map(number)
                })
            })?,
            flags: Array2::from_shape_vec((rows.len(), TAXEL_COUNT), flags)
                .map_err(|error| taxel_error(ErrorKind::Other, error.to_string()))?
                .into_pyarray(py)
                .unbind(),
            force_n: column(py, rows, |row| {
                number(row.reading.and_then(|reading| reading.force_n))
            }),
            cop_mm: matrix(py, rows, |row| {
                row.reading
                    .and_then(|reading| reading.centre_of_pressure_mm)
                    .map_or([f64::NAN; 2], |[x_mm, y_mm]| {
                        [f64::from(x_mm), f64::from(y_mm)]
                    })
            })?,
            partial: column(py, rows, |row| {
                row.reading.is_some_and(|reading| reading.partial)
            }),
            contact: column(py, rows, |row| {
                row.reading.is_some_and(|reading| reading.contact)
            }),
            missing: column(py, rows, |row| row.reading.is_none()),
            markers: rows
                .iter()
                .enumerate()
                .filter(|(_, row)| !row.marker.is_empty())
                .map(|(index, row)| (index, row.marker.clone()))
                .collect(),
        })
    }
}

/// Collects converted rows, looking for Ctrl-C as it goes.
#[derive(Default)]
struct Collect {
    rows: Vec<PadRow>,
    signals: SignalCheck,
}

impl RowSink for Collect {
    fn write_row(&mut self, row: &PadRow) -> anyhow::Result<()> {
        self.signals.tick()?;
        self.rows.push(row.clone());
        Ok(())
    }

    fn finish(&mut self) -> anyhow::Result<()> {
        Ok(())
    }
}

fn open(path: &Path) -> PyResult<BufReader<File>> {
    File::open(path)
        .map(|file| BufReader::with_capacity(1 << 20, file))
        .map_err(|error| {
            taxel_error(
                ErrorKind::Convert,
                format!("opening {}: {error}", path.display()),
            )
        })
}

/// Reads a recording as recorded. Returns the recording and the reasons of rows that could
/// not be read (``line N: ...``; they are left out).
#[pyfunction]
pub fn read_recording_rows(py: Python<'_>, path: PathBuf) -> PyResult<(Recording, Vec<String>)> {
    let input = open(&path)?;
    let read = py.allow_threads(move || -> Result<(Vec<PadRow>, Vec<String>), PyErr> {
        let schema_error = |error: SchemaError| {
            taxel_error(
                ErrorKind::Convert,
                format!("reading {}: {error}", path.display()),
            )
        };
        let mut reader = RowReader::new(input).map_err(schema_error)?;
        let mut rows = Vec::new();
        let mut bad = Vec::new();
        let mut signals = SignalCheck::new();
        while let Some(row) = reader.next_row() {
            signals.tick()?;
            match row {
                Ok(row) => rows.push(row),
                Err(error @ SchemaError::Row { .. }) => bad.push(error.to_string()),
                Err(error) => return Err(schema_error(error)),
            }
        }
        Ok((rows, bad))
    });
    let (rows, bad) = read?;
    Ok((Recording::from_rows(py, &rows)?, bad))
}

/// Converts a recording again with the host library's conversion engine, as ``taxel
/// convert`` does: each device's recorded state beside the file unless ``use_device_state`` is
/// false; ``calibration``, ``tier`` and ``tare_rows`` replace its parts for every pad. Returns
/// the converted recording, the reasons of rows that could not be read, and the tares'
/// warnings.
#[pyfunction]
#[pyo3(signature = (path, calibration=None, tier=None, tare_rows=None, use_device_state=true))]
pub fn convert_recording_rows(
    py: Python<'_>,
    path: PathBuf,
    calibration: Option<PyRef<'_, Calibration>>,
    tier: Option<&str>,
    tare_rows: Option<u16>,
    use_device_state: bool,
) -> PyResult<(Recording, Vec<String>, Vec<String>)> {
    let tier = tier
        .map(taxel_host::convert::parse_tier)
        .transpose()
        .map_err(|message| taxel_error(ErrorKind::Convert, message))?;
    if tare_rows == Some(0) {
        return Err(taxel_error(
            ErrorKind::Convert,
            "tare_rows must be at least 1",
        ));
    }
    let settings = ConvertSettings {
        tare_rows,
        tier,
        calibration: calibration.map(|calibration| calibration.model().clone()),
        no_device_state: !use_device_state,
        pressures_only: false,
    };
    let states = if use_device_state {
        RecordedStates::beside(&path).map_err(|error| anyhow_error(&error, ErrorKind::Convert))?
    } else {
        RecordedStates::default()
    };
    let input = open(&path)?;
    let converted = py.allow_threads(move || {
        let mut rows = Collect::default();
        let summary = convert_recording(input, &mut rows, ConversionEngine::new(settings, states))?;
        Ok::<_, anyhow::Error>((rows.rows, summary))
    });
    let (rows, summary) = converted.map_err(|error| match error.downcast::<PyErr>() {
        // Ctrl-C (or another signal handler's exception) as it was raised.
        Ok(interrupted) => interrupted,
        Err(error) => anyhow_error(&error, ErrorKind::Convert),
    })?;
    let bad = summary
        .bad_rows
        .iter()
        .map(|bad| format!("line {}: {}", bad.line, bad.reason))
        .collect();
    // Asked to ignore the recorded states, the caller needs no word about pads without one.
    let without_state: &[(u32, u8)] = if use_device_state {
        &summary.pads_without_state
    } else {
        &[]
    };
    let mut warnings: Vec<String> = without_state
        .iter()
        .map(|(device, pad)| {
            format!(
                "device {device} pad {pad} has no recorded state: converted with the built-in calibration, the default tier and a tare on its first readable row unless options said otherwise"
            )
        })
        .collect();
    warnings.extend(summary.tare_warnings);
    Ok((Recording::from_rows(py, &rows)?, bad, warnings))
}
