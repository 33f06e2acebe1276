//! `taxel.convert`: capacitances and temperatures to pressures and flags through the host
//! library's conversion engine, the one `taxel convert` runs on a recording: one pipeline per
//! pad with the calibration and tier given, and a tare on the mean of each pad's first
//! `tare_rows` readable rows.

use model_core::TAXEL_COUNT;
use numpy::ndarray::{Ix1, Ix2};
use numpy::{PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use taxel_host::console::error_message;
use taxel_host::convert::{ConversionEngine, ConvertSettings, RecordedStates};
use taxel_host::schema::{PadReading, PadRow};
use wire::TemperatureSource;

use crate::arrays::{c_order_values, float64_c_array};
use crate::calibration::Calibration;
use crate::errors::{taxel_error, ErrorKind};
use crate::interrupt::SignalCheck;

/// The input columns, checked: `capacitance_pf` (rows × pads × 4), `temperature_c`
/// (rows × pads), `time_s` (rows) when given.
struct Inputs<'a> {
    pads: usize,
    capacitance_pf: &'a [f64],
    temperature_c: &'a [f64],
    time_s: Option<&'a [f64]>,
}

/// The output columns: pressures and flags (rows × pads × 4), the memory of the arrays returned.
struct Outputs<'a> {
    pressure_kpa: &'a mut [f64],
    flags: &'a mut [u16],
}

/// Pad `pad`'s row of set `row` as the schema holds it: `None` when, with several pads, its
/// four capacitances and its temperature are all NaN (its frame missing from the set, as
/// `taxel convert` reads a pad whose cells are all empty).
fn pad_row(inputs: &Inputs<'_>, row: usize, pad: usize) -> PadRow {
    let mut pad_row = PadRow {
        host_time_us: 0,
        device: 0,
        pad: 0,
        sequence: 0,
        sync_error_us: None,
        reading: None,
        marker: String::new(),
    };
    set_pad_row(&mut pad_row, inputs, row, pad);
    pad_row
}

/// Makes `pad_row` (a row of device 0 without host time or marker, as [`pad_row`] makes) pad
/// `pad`'s row of set `row`: a block's rows are used again for the next block's.
fn set_pad_row(pad_row: &mut PadRow, inputs: &Inputs<'_>, row: usize, pad: usize) {
    let first = (row * inputs.pads + pad) * TAXEL_COUNT;
    let capacitances = &inputs.capacitance_pf[first..first + TAXEL_COUNT];
    let temperature = inputs.temperature_c[row * inputs.pads + pad];
    let missing =
        inputs.pads > 1 && temperature.is_nan() && capacitances.iter().all(|value| value.is_nan());
    // A time given is non-negative (checked): the time cell of a recording, in µs.
    let device_time_us = inputs.time_s.map_or(0, |times| (times[row] * 1.0e6) as u64);
    pad_row.pad = pad as u8;
    pad_row.sequence = row as u32;
    pad_row.reading = (!missing).then(|| {
        PadReading::unconverted(
            device_time_us,
            (!temperature.is_nan()).then_some(temperature as f32),
            TemperatureSource::None,
            std::array::from_fn(|taxel| {
                let value = capacitances[taxel];
                (!value.is_nan()).then_some(value as f32)
            }),
        )
    });
}

/// Why a conversion stopped.
enum Stopped {
    /// The engine refused a row.
    Engine(anyhow::Error),
    /// A signal handler raised (Ctrl-C: `KeyboardInterrupt`).
    Interrupted(PyErr),
}

/// Sample sets converted together: enough for the pipelines' batch path, few enough to look for
/// Ctrl-C often.
const SETS_PER_BLOCK: usize = 256;

/// Runs every row of every pad through `engine`, in set order, into `outputs` (a missing frame's
/// pressures NaN and flags 0), looking for Ctrl-C as it goes.
fn run_rows(
    engine: &mut ConversionEngine,
    inputs: &Inputs<'_>,
    outputs: &mut Outputs<'_>,
) -> Result<(), Stopped> {
    let rows = inputs.temperature_c.len() / inputs.pads.max(1);
    let mut signals = SignalCheck::new();
    let mut block: Vec<PadRow> = Vec::with_capacity(SETS_PER_BLOCK * inputs.pads);
    for first_row in (0..rows).step_by(SETS_PER_BLOCK) {
        let end_row = (first_row + SETS_PER_BLOCK).min(rows);
        signals
            .tick_rows((end_row - first_row) as u32)
            .map_err(Stopped::Interrupted)?;
        // The last block's rows are made this block's in place: only what differs is written.
        let mut pad_rows =
            (first_row..end_row).flat_map(|row| (0..inputs.pads).map(move |pad| (row, pad)));
        block.truncate((end_row - first_row) * inputs.pads);
        for (slot, (row, pad)) in block.iter_mut().zip(pad_rows.by_ref()) {
            set_pad_row(slot, inputs, row, pad);
        }
        block.extend(pad_rows.map(|(row, pad)| pad_row(inputs, row, pad)));
        engine
            .convert_rows(&mut block, inputs.time_s.is_some())
            .map_err(Stopped::Engine)?;
        let first_cell = first_row * inputs.pads * TAXEL_COUNT;
        let cells = first_cell..first_cell + block.len() * TAXEL_COUNT;
        let (Some(pressures), Some(flags)) = (
            outputs.pressure_kpa.get_mut(cells.clone()),
            outputs.flags.get_mut(cells),
        ) else {
            // Never: the outputs have a cell for every input's (shapes checked). The arrays are
            // not zeroed, so no block may be skipped without an error.
            return Err(Stopped::Engine(anyhow::anyhow!(
                "the output arrays have fewer cells than the input"
            )));
        };
        let cells = block.iter().zip(
            pressures
                .chunks_exact_mut(TAXEL_COUNT)
                .zip(flags.chunks_exact_mut(TAXEL_COUNT)),
        );
        for (pad_row, (pressures, flags)) in cells {
            match &pad_row.reading {
                Some(reading) => {
                    let taxels = pressures
                        .iter_mut()
                        .zip(flags.iter_mut())
                        .zip(reading.pressure_kpa.iter().zip(&reading.flags));
                    for ((pressure, flag_bits), (pressure_kpa, taxel_flags)) in taxels {
                        *pressure = pressure_kpa.map_or(f64::NAN, f64::from);
                        *flag_bits = taxel_flags.bits();
                    }
                }
                None => {
                    pressures.fill(f64::NAN);
                    flags.fill(0);
                }
            }
        }
    }
    Ok(())
}

/// A new C-ordered array of `shape` whose values are not set (numpy's `empty`: its memory is
/// not written before the caller writes it).
fn empty_array<'py, T: numpy::Element>(
    py: Python<'py>,
    shape: [usize; 2],
    dtype: &str,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let array = py
        .import("numpy")?
        .call_method1("empty", (shape, dtype))?
        .downcast_into::<PyArray2<T>>()?;
    Ok(array)
}

/// Converts checked, contiguous arrays (the Python wrapper `taxel.convert` checks and shapes
/// them): `capacitance_pf` (N, 4 × pads), `temp_c` (N, pads), `time_s` (N,) or None. Returns
/// pressures (N, taxels) float64, flags (N, taxels) uint16 and the tare's warnings.
#[pyfunction]
#[pyo3(signature = (capacitance_pf, temp_c, time_s, calibration, tier, tare_rows))]
#[allow(clippy::type_complexity)]
pub fn convert_arrays<'py>(
    py: Python<'py>,
    capacitance_pf: &Bound<'py, PyAny>,
    temp_c: &Bound<'py, PyAny>,
    time_s: Option<&Bound<'py, PyAny>>,
    calibration: Option<PyRef<'py, Calibration>>,
    tier: Option<&str>,
    tare_rows: u16,
) -> PyResult<(
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<u16>>,
    Vec<String>,
)> {
    let kind = ErrorKind::Convert;
    let capacitance_pf = float64_c_array::<Ix2>(capacitance_pf, "capacitance_pf", kind)?;
    let temp_c = float64_c_array::<Ix2>(temp_c, "temp_c", kind)?;
    let time_s = time_s
        .map(|values| float64_c_array::<Ix1>(values, "time_s", kind))
        .transpose()?;
    let [rows, taxels] = [capacitance_pf.shape()[0], capacitance_pf.shape()[1]];
    if taxels == 0 || taxels % TAXEL_COUNT != 0 {
        return Err(taxel_error(
            ErrorKind::Convert,
            format!("capacitance_pf has {taxels} columns: it needs 4 per pad (C11, C12, C21, C22)"),
        ));
    }
    let pads = taxels / TAXEL_COUNT;
    if temp_c.shape() != [rows, pads] {
        return Err(taxel_error(
            ErrorKind::Convert,
            format!(
                "temp_c has shape {:?}; it must be ({rows},) or ({rows}, {pads})",
                temp_c.shape()
            ),
        ));
    }
    if tare_rows == 0 {
        return Err(taxel_error(
            ErrorKind::Convert,
            "tare_rows must be at least 1",
        ));
    }
    let tier = tier
        .map(|name| {
            taxel_host::convert::parse_tier(name)
                .map_err(|message| taxel_error(ErrorKind::Convert, message))
        })
        .transpose()?;
    let calibration = calibration.map(|calibration| calibration.model().clone());
    let capacitances = c_order_values(&capacitance_pf, "capacitance_pf", kind)?;
    let temperatures = c_order_values(&temp_c, "temp_c", kind)?;
    let times = match &time_s {
        Some(times) => {
            let times = c_order_values(times, "time_s", kind)?;
            if times.len() != rows {
                return Err(taxel_error(
                    ErrorKind::Convert,
                    format!("time_s has {} values for {rows} rows", times.len()),
                ));
            }
            if let Some(row) = times
                .iter()
                .position(|time| !time.is_finite() || *time < 0.0)
            {
                return Err(taxel_error(
                    ErrorKind::Convert,
                    format!(
                        "time_s[{row}] is {}: a time is a finite, non-negative number of seconds",
                        times[row]
                    ),
                ));
            }
            Some(times)
        }
        None => None,
    };
    let settings = ConvertSettings {
        tare_rows: Some(tare_rows),
        tier,
        calibration,
        no_device_state: true,
        // `convert` returns pressures and flags only.
        pressures_only: true,
    };
    let inputs = Inputs {
        pads,
        capacitance_pf: capacitances,
        temperature_c: temperatures,
        time_s: times,
    };
    // numpy's allocator gives memory this large transparent huge pages, which a vector's does
    // not: a fifth of the conversion's time went to first touching 4 KiB pages. Empty, not
    // zeros: every cell is written below (or the arrays are dropped with the error), and
    // zeroing 40 MB first cost about 4 ms of a million rows' conversion.
    let pressure_kpa = empty_array::<f64>(py, [rows, taxels], "float64")?;
    let flags = empty_array::<u16>(py, [rows, taxels], "uint16")?;
    let (mut pressure_memory, mut flags_memory) = (pressure_kpa.readwrite(), flags.readwrite());
    let (Ok(pressure_slice), Ok(flags_slice)) =
        (pressure_memory.as_slice_mut(), flags_memory.as_slice_mut())
    else {
        return Err(taxel_error(
            ErrorKind::Convert,
            "the output arrays are not contiguous",
        ));
    };
    let warnings = py
        .allow_threads(|| {
            let mut engine = ConversionEngine::new(settings, RecordedStates::default());
            let mut outputs = Outputs {
                pressure_kpa: pressure_slice,
                flags: flags_slice,
            };
            run_rows(&mut engine, &inputs, &mut outputs)?;
            Ok(engine.finish())
        })
        .map_err(|stopped| match stopped {
            Stopped::Engine(error) => taxel_error(ErrorKind::Convert, error_message(&error)),
            Stopped::Interrupted(error) => error,
        })?;
    Ok((pressure_kpa, flags, warnings))
}
