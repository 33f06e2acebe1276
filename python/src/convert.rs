//! `taxel.convert`: capacitances and temperatures to pressures and flags through the host
//! library's conversion engine, the one `taxel convert` runs on a recording: one pipeline per
//! pad with the calibration and tier given, and a tare on the mean of each pad's first
//! `tare_rows` readable rows.

use model_core::TAXEL_COUNT;
use model_core::{PadContact, PadOutput, SampleInput, TaxelReading};
use numpy::ndarray::{Ix1, Ix2};
use numpy::{PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use taxel_host::console::error_message;
use taxel_host::convert::{ConversionEngine, ConvertSettings, PadSets, RecordedStates};
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

/// One pad's sets among a block of rows, as the conversion engine reads and writes them: read
/// from the input arrays, the results written into the output arrays (no rows made).
struct PadColumns<'a, 'b> {
    inputs: &'a Inputs<'a>,
    outputs: &'b mut Outputs<'a>,
    pad: usize,
    /// The rows whose frame of the pad is present, in order: with several pads, a row whose
    /// four capacitances and temperature are all NaN has none (its frame missing from the
    /// set, as `taxel convert` reads a pad whose cells are all empty).
    rows: &'b [u32],
}

impl PadColumns<'_, '_> {
    /// The first cell of set `index` (in the capacitance, pressure and flags arrays).
    fn first_cell(&self, index: usize) -> Option<(usize, usize)> {
        let row = *self.rows.get(index)? as usize;
        Some((row, (row * self.inputs.pads + self.pad) * TAXEL_COUNT))
    }
}

impl PadSets for PadColumns<'_, '_> {
    fn len(&self) -> usize {
        self.rows.len()
    }

    fn identity(&self, index: usize) -> (u32, TemperatureSource) {
        (
            self.rows.get(index).copied().unwrap_or_default(),
            TemperatureSource::None,
        )
    }

    fn input(&self, index: usize, timed: bool) -> SampleInput {
        let empty = SampleInput::new([TaxelReading::Unavailable; TAXEL_COUNT], None);
        let Some((row, first)) = self.first_cell(index) else {
            return empty;
        };
        let (Some(capacitances), Some(temperature)) = (
            self.inputs.capacitance_pf.get(first..first + TAXEL_COUNT),
            self.inputs
                .temperature_c
                .get(row * self.inputs.pads + self.pad),
        ) else {
            return empty;
        };
        // An empty (NaN) cell is no reading, as an empty cell of a recording.
        let readings = std::array::from_fn(|taxel| match capacitances.get(taxel) {
            Some(value) if !value.is_nan() => TaxelReading::CapacitancePf(*value as f32),
            _ => TaxelReading::Unavailable,
        });
        let temperature_c = (!temperature.is_nan()).then_some(*temperature as f32);
        // A time given is non-negative (checked): the time cell of a recording, in µs.
        let time_us = self
            .inputs
            .time_s
            .filter(|_| timed)
            .and_then(|times| times.get(row))
            .map(|time_s| (time_s * 1.0e6) as u64);
        SampleInput {
            time_us,
            ..SampleInput::new(readings, temperature_c)
        }
    }

    fn recorded_contact(&self, _: usize) -> bool {
        false
    }

    fn write(&mut self, index: usize, output: &PadOutput, _: Option<&PadContact>) {
        let Some((_, first)) = self.first_cell(index) else {
            return;
        };
        let cells = first..first + TAXEL_COUNT;
        let (Some(pressures), Some(flags)) = (
            self.outputs.pressure_kpa.get_mut(cells.clone()),
            self.outputs.flags.get_mut(cells),
        ) else {
            return;
        };
        for ((pressure, flag_bits), taxel) in pressures.iter_mut().zip(flags).zip(&output.taxels) {
            *pressure = taxel.pressure_kpa().map_or(f64::NAN, f64::from);
            *flag_bits = taxel.flags().bits();
        }
    }
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
const SETS_PER_BLOCK: usize = 4096;

/// Runs every row of every pad through `engine`, in set order, into `outputs` (a missing
/// frame's pressures NaN and flags 0), looking for Ctrl-C as it goes.
// Inlined into each instruction set's caller.
#[inline(always)]
fn run_rows<'a>(
    engine: &mut ConversionEngine,
    inputs: &'a Inputs<'a>,
    outputs: &mut Outputs<'a>,
) -> Result<(), Stopped> {
    let rows = inputs.temperature_c.len() / inputs.pads.max(1);
    let mut signals = SignalCheck::new();
    let mut present: Vec<u32> = Vec::with_capacity(SETS_PER_BLOCK);
    for first_row in (0..rows).step_by(SETS_PER_BLOCK) {
        let end_row = (first_row + SETS_PER_BLOCK).min(rows);
        signals
            .tick_rows((end_row - first_row) as u32)
            .map_err(Stopped::Interrupted)?;
        for pad in 0..inputs.pads {
            present.clear();
            for row in first_row..end_row {
                if inputs.pads > 1 && frame_missing(inputs, row, pad) {
                    let first = (row * inputs.pads + pad) * TAXEL_COUNT;
                    let cells = first..first + TAXEL_COUNT;
                    if let (Some(pressures), Some(flags)) = (
                        outputs.pressure_kpa.get_mut(cells.clone()),
                        outputs.flags.get_mut(cells),
                    ) {
                        pressures.fill(f64::NAN);
                        flags.fill(0);
                    }
                } else {
                    present.push(row as u32);
                }
            }
            let mut sets = PadColumns {
                inputs,
                outputs: &mut *outputs,
                pad,
                rows: &present,
            };
            engine
                .convert_sets(0, pad as u8, &mut sets, inputs.time_s.is_some())
                .map_err(Stopped::Engine)?;
        }
    }
    Ok(())
}

/// [`run_rows`], compiled for AVX2 where the CPU has it: the engine and the model inlined into
/// it then use the wider instructions (1M rows: about 2 ms of 47 less).
fn run_rows_for_this_cpu<'a>(
    engine: &mut ConversionEngine,
    inputs: &'a Inputs<'a>,
    outputs: &mut Outputs<'a>,
) -> Result<(), Stopped> {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // The package's one unsafe operation: calling a function compiled for an instruction
        // set extension, which Rust cannot prove the CPU has, after asking the CPU.
        #[allow(unsafe_code)]
        // SAFETY: the CPU has AVX2 (asked just above), the only feature the function enables.
        return unsafe { run_rows_avx2(engine, inputs, outputs) };
    }
    run_rows(engine, inputs, outputs)
}

/// [`run_rows`] with AVX2 (callable only where the CPU has it).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn run_rows_avx2<'a>(
    engine: &mut ConversionEngine,
    inputs: &'a Inputs<'a>,
    outputs: &mut Outputs<'a>,
) -> Result<(), Stopped> {
    run_rows(engine, inputs, outputs)
}

/// With several pads, whether pad `pad`'s frame of row `row` is missing: its four capacitances
/// and its temperature all NaN.
fn frame_missing(inputs: &Inputs<'_>, row: usize, pad: usize) -> bool {
    let first = (row * inputs.pads + pad) * TAXEL_COUNT;
    let temperature = inputs
        .temperature_c
        .get(row * inputs.pads + pad)
        .copied()
        .unwrap_or(f64::NAN);
    temperature.is_nan()
        && inputs
            .capacitance_pf
            .get(first..first + TAXEL_COUNT)
            .is_none_or(|values| values.iter().all(|value| value.is_nan()))
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

/// `array`, given as `out`'s `name`, when it can take the results: a writable, C-ordered array
/// of `dtype` and `shape`.
fn output_array<'py, T: numpy::Element>(
    array: Bound<'py, PyAny>,
    shape: [usize; 2],
    name: &str,
    dtype: &str,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let wrong = |what: String| {
        taxel_error(
            ErrorKind::Convert,
            format!("out's {name} array {what}: it must be a writable, C-ordered {dtype} array of shape ({}, {})", shape[0], shape[1]),
        )
    };
    let Ok(array) = array.downcast_into::<numpy::PyUntypedArray>() else {
        return Err(wrong("is not a numpy array".to_owned()));
    };
    if array.shape() != shape {
        return Err(wrong(format!("has shape {:?}", array.shape())));
    }
    let found = array.dtype().to_string();
    let Ok(array) = array.into_any().downcast_into::<PyArray2<T>>() else {
        return Err(wrong(format!("has dtype {found}")));
    };
    if !array.is_c_contiguous() {
        return Err(wrong("is not C-ordered".to_owned()));
    }
    let writeable: bool = array.getattr("flags")?.getattr("writeable")?.extract()?;
    if !writeable {
        return Err(wrong("is read-only".to_owned()));
    }
    Ok(array)
}

/// Converts checked, contiguous arrays (the Python wrapper `taxel.convert` checks and shapes
/// them): `capacitance_pf` (N, 4 × pads), `temp_c` (N, pads), `time_s` (N,) or None. Returns
/// pressures (N, taxels) float64, flags (N, taxels) uint16 and the tare's warnings; the
/// pressures and flags are written into `out` (pressure, flags) when given (checked: their
/// dtypes, shape, C order, writable, not overlapping the inputs), else into new arrays.
#[pyfunction]
#[pyo3(signature = (capacitance_pf, temp_c, time_s, calibration, tier, tare_rows, out=None))]
// Python's keyword arguments, each a parameter.
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
pub fn convert_arrays<'py>(
    py: Python<'py>,
    capacitance_pf: &Bound<'py, PyAny>,
    temp_c: &Bound<'py, PyAny>,
    time_s: Option<&Bound<'py, PyAny>>,
    calibration: Option<PyRef<'py, Calibration>>,
    tier: Option<&str>,
    tare_rows: u16,
    out: Option<(Bound<'py, PyAny>, Bound<'py, PyAny>)>,
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
    let (pressure_kpa, flags) = match out {
        Some((pressure_kpa, flags)) => (
            output_array::<f64>(pressure_kpa, [rows, taxels], "pressure", "float64")?,
            output_array::<u16>(flags, [rows, taxels], "flags", "uint16")?,
        ),
        None => (
            empty_array::<f64>(py, [rows, taxels], "float64")?,
            empty_array::<u16>(py, [rows, taxels], "uint16")?,
        ),
    };
    for (output, name) in [
        (pressure_kpa.as_any(), "pressure"),
        (flags.as_any(), "flags"),
    ] {
        for (input, input_name) in [
            (capacitance_pf.as_any(), "capacitance_pf"),
            (temp_c.as_any(), "temp_c"),
        ]
        .into_iter()
        .chain(time_s.as_ref().map(|times| (times.as_any(), "time_s")))
        {
            let shared: bool = py
                .import("numpy")?
                .call_method1("may_share_memory", (output, input))?
                .extract()?;
            if shared {
                return Err(taxel_error(
                    ErrorKind::Convert,
                    format!("out's {name} array shares memory with {input_name}: the results would overwrite the inputs being read"),
                ));
            }
        }
    }
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
            run_rows_for_this_cpu(&mut engine, &inputs, &mut outputs)?;
            Ok(engine.finish())
        })
        .map_err(|stopped| match stopped {
            Stopped::Engine(error) => taxel_error(ErrorKind::Convert, error_message(&error)),
            Stopped::Interrupted(error) => error,
        })?;
    Ok((pressure_kpa, flags, warnings))
}
