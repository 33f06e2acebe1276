//! `taxel.convert`: capacitances and temperatures to pressures and flags with the pressure
//! model of `model-core`, exactly as `taxel convert` runs it on a CSV file: one model per pad,
//! its tier set, and a tare on the mean of the first `tare_rows` readable rows.

use model_core::{PadModel, SampleInput, TareStatus, TaxelReading, Tier, TAXEL_COUNT, TAXEL_NAMES};
use numpy::ndarray::{Array2, Ix1, Ix2};
use numpy::{IntoPyArray, PyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::arrays::{c_order_values, float64_c_array};
use crate::calibration::Calibration;
use crate::errors::{taxel_error, ErrorKind};

/// The input columns, checked: `capacitance_pf` (rows × pads × 4), `temperature_c`
/// (rows × pads), `time_s` (rows) when given.
struct Inputs<'a> {
    pads: usize,
    capacitance_pf: &'a [f64],
    temperature_c: &'a [f64],
    time_s: Option<&'a [f64]>,
}

/// The output columns: pressures and flags (rows × pads × 4).
struct Outputs {
    pressure_kpa: Vec<f64>,
    flags: Vec<u16>,
}

/// Runs pad `pad`'s model over every row, writing its columns of the outputs. The model's batch
/// path gives exactly what `PadModel::process` gives row by row (model-core tests it), which is
/// what `taxel convert` runs. With several pads, a row where the pad's four capacitances and its
/// temperature are all NaN is its frame missing from that set, as `taxel convert` reads a pad
/// whose cells are all empty: the model skips it, and its pressures are NaN and its flags 0.
fn run_pad(model: &mut PadModel, pad: usize, inputs: &Inputs<'_>, outputs: &mut Outputs) {
    let pads = inputs.pads;
    let taxels = pads * TAXEL_COUNT;
    let rows = inputs.temperature_c.len() / pads.max(1);
    let first_cell = |row: usize| row * taxels + pad * TAXEL_COUNT;
    let is_present = |row: usize| {
        pads == 1
            || !(inputs.temperature_c[row * pads + pad].is_nan()
                && inputs.capacitance_pf[first_cell(row)..first_cell(row) + TAXEL_COUNT]
                    .iter()
                    .all(|value| value.is_nan()))
    };
    let present_rows = || (0..rows).filter(move |&row| is_present(row));
    for row in (0..rows).filter(|&row| !is_present(row)) {
        outputs.pressure_kpa[first_cell(row)..first_cell(row) + TAXEL_COUNT].fill(f64::NAN);
    }
    let samples = present_rows().map(|row| {
        let first = first_cell(row);
        let readings: [TaxelReading; TAXEL_COUNT] = std::array::from_fn(|taxel| {
            let value = inputs.capacitance_pf[first + taxel];
            if value.is_nan() {
                TaxelReading::Unavailable
            } else {
                TaxelReading::CapacitancePf(value as f32)
            }
        });
        let temperature = inputs.temperature_c[row * pads + pad];
        let temperature = (!temperature.is_nan()).then_some(temperature as f32);
        let input = SampleInput::new(readings, temperature);
        match inputs.time_s.map(|time_s| time_s[row]) {
            // As `taxel convert` reads a time cell: a non-negative time in µs for the
            // temperature plausibility rule.
            Some(time_s) if time_s >= 0.0 => input.at_time_us((time_s * 1.0e6) as u64),
            _ => input,
        }
    });
    let mut output_rows = present_rows();
    model.process_all(samples, |output| {
        let Some(row) = output_rows.next() else {
            return;
        };
        let first = first_cell(row);
        for (taxel, result) in output.taxels.iter().enumerate() {
            outputs.pressure_kpa[first + taxel] = result.pressure_kpa().map_or(f64::NAN, f64::from);
            outputs.flags[first + taxel] = result.flags().bits();
        }
    });
}

/// The tare's problems, in `taxel convert`'s words.
fn tare_warnings(model: &PadModel, pad: usize, pads: usize) -> Vec<String> {
    let prefix = if pads > 1 {
        format!("pad {pad}: ")
    } else {
        String::new()
    };
    match model.tare_status() {
        TareStatus::Running { remaining } => vec![format!(
            "{prefix}the tare never finished ({remaining} more readable rows were needed); every pressure is empty (not_tared)"
        )],
        TareStatus::Finished { tared_mask } => {
            let errors = model.last_tare_errors();
            (0..TAXEL_COUNT)
                .filter(|taxel| tared_mask & (1 << taxel) == 0)
                .map(|taxel| {
                    format!(
                        "{prefix}taxel {} could not be tared ({}); it stays not_tared",
                        TAXEL_NAMES[taxel],
                        errors[taxel]
                            .map(|error| taxel_host::device_words::baseline_error_words(&error))
                            .unwrap_or_else(|| "no usable reading".to_owned())
                    )
                })
                .collect()
        }
        _ => Vec::new(),
    }
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
    let tier = match tier {
        Some(name) => taxel_host::convert::parse_tier(name)
            .map_err(|message| taxel_error(ErrorKind::Convert, message))?,
        None => Tier::default(),
    };
    let model_calibration = calibration
        .map(|calibration| calibration.model().clone())
        .unwrap_or_default();
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
            if let Some(row) = times.iter().position(|time| !time.is_finite()) {
                return Err(taxel_error(
                    ErrorKind::Convert,
                    format!("time_s[{row}]: the time must be a finite number of seconds"),
                ));
            }
            Some(times)
        }
        None => None,
    };
    let mut models = Vec::with_capacity(pads);
    for _ in 0..pads {
        let mut model = PadModel::new(model_calibration.clone());
        model.set_tier(tier).map_err(|_| {
            taxel_error(
                ErrorKind::Convert,
                format!(
                    "tier {} is not available for this calibration (the saturating fit needs a concave curve on every taxel)",
                    tier.name()
                ),
            )
        })?;
        model.start_tare(tare_rows);
        models.push(model);
    }
    let inputs = Inputs {
        pads,
        capacitance_pf: capacitances,
        temperature_c: temperatures,
        time_s: times,
    };
    let (outputs, warnings) = py.allow_threads(|| {
        let mut outputs = Outputs {
            // Zeroed memory comes from the system untouched; `run_pad` writes every cell.
            pressure_kpa: vec![0.0; rows * taxels],
            flags: vec![0u16; rows * taxels],
        };
        let mut warnings = Vec::new();
        for (pad, model) in models.iter_mut().enumerate() {
            run_pad(model, pad, &inputs, &mut outputs);
            warnings.extend(tare_warnings(model, pad, pads));
        }
        (outputs, warnings)
    });
    let Outputs {
        pressure_kpa,
        flags,
    } = outputs;
    // The vectors become the arrays' memory (no copy).
    let pressure_kpa = Array2::from_shape_vec((rows, taxels), pressure_kpa)
        .map_err(|error| taxel_error(ErrorKind::Convert, error.to_string()))?
        .into_pyarray(py);
    let flags = Array2::from_shape_vec((rows, taxels), flags)
        .map_err(|error| taxel_error(ErrorKind::Convert, error.to_string()))?
        .into_pyarray(py);
    Ok((pressure_kpa, flags, warnings))
}
