//! `taxel.Calibration`: a pad's calibration (curve points per taxel, parasitic and unloaded
//! capacitances, temperature law, thresholds) read from and written to the calibration files of
//! `taxel calibrate`, or fitted from reference loads with the same code and report.

use std::ffi::CString;
use std::path::PathBuf;

use model_core::{Calibration as ModelCalibration, TAXEL_COUNT, TAXEL_NAMES};
use numpy::ndarray::{Ix1, Ix2};
use numpy::PyUntypedArrayMethods;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use taxel_host::calibrate::{
    cross_validate, curve_points, fit_calibration, reference_data, LoadRow, ReferenceData,
    TierFitError,
};
use taxel_host::calibration_file;

use crate::arrays::{c_order_values, float64_c_array};
use crate::errors::{anyhow_error, taxel_error, ErrorKind};

/// One tier's leave-one-out result on one taxel.
#[derive(Debug, Clone)]
struct LeaveOneOut {
    taxel: &'static str,
    result: TierFitError,
}

/// The report of a fit as `taxel calibrate` prints it on stdout, and its warnings without their
/// "warning: " (Python shows them through `warnings`): the host library's report.
fn fit_report(
    data: &ReferenceData,
    calibration: &ModelCalibration,
    budget_kpa: f32,
) -> (String, Vec<String>) {
    let (text, warnings) = taxel_host::calibrate_report::fit_report(data, calibration, budget_kpa);
    let warnings = warnings
        .into_iter()
        .map(|warning| {
            warning
                .strip_prefix("warning: ")
                .map_or(warning.clone(), str::to_owned)
        })
        .collect();
    (text, warnings)
}

/// A calibration: per taxel the curve of dC/C0 against pressure, the parasitic and unloaded
/// capacitances; the temperature law; the fault thresholds. Files are the JSON files
/// ``taxel calibrate`` writes and ``taxel convert --calibration`` reads.
#[pyclass(frozen, module = "taxel")]
pub struct Calibration {
    model: ModelCalibration,
    report: Option<String>,
    leave_one_out: Vec<LeaveOneOut>,
    warnings: Vec<String>,
}

impl Calibration {
    /// A calibration without a fit report.
    pub fn from_model(model: ModelCalibration) -> Self {
        Self {
            model,
            report: None,
            leave_one_out: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// The model's calibration.
    pub fn model(&self) -> &ModelCalibration {
        &self.model
    }
}

#[pymethods]
impl Calibration {
    /// The built-in default calibration (the article's curve), which a device without a
    /// calibration of its own uses.
    #[staticmethod]
    fn default() -> Self {
        Self::from_model(ModelCalibration::default())
    }

    /// Reads a calibration file.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        calibration_file::read(&path)
            .map(Self::from_model)
            .map_err(|error| {
                taxel_error(
                    ErrorKind::Calibration,
                    format!("reading {}: {error}", path.display()),
                )
            })
    }

    /// Reads a calibration from the file's JSON text.
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        calibration_file::from_json(text)
            .map(Self::from_model)
            .map_err(|error| taxel_error(ErrorKind::Calibration, error.to_string()))
    }

    /// Writes the calibration file (under a temporary name, renamed when complete).
    fn save(&self, path: PathBuf) -> PyResult<()> {
        calibration_file::write(&path, &self.model)
            .map_err(|error| anyhow_error(&error, ErrorKind::Calibration))
    }

    /// The calibration file's JSON text.
    fn to_json(&self) -> PyResult<String> {
        calibration_file::to_json(&self.model)
            .map_err(|error| taxel_error(ErrorKind::Calibration, error.to_string()))
    }

    /// Fits a calibration from reference loads, as ``taxel calibrate`` does: ``pressure_kpa``
    /// (N,) applied pressures (several rows at 0 kPa give C0), ``capacitance_pf`` (N, 4)
    /// measured capacitances, ``temp_c`` (N,) pad temperatures (NaN or omitted: none). Any
    /// array-like is accepted (lists, numpy arrays of any numeric type and memory layout,
    /// pandas Series and DataFrames) and read as float64 in row order. The result's
    /// :attr:`fit_report` is the command's report and :attr:`leave_one_out` its
    /// cross-validation of every tier; what the command prints as warnings (rows outside the
    /// temperature law's range, intervals where converter noise exceeds ``budget_kpa``) is
    /// issued as :class:`taxel.TaxelWarning` warnings and kept in :attr:`fit_warnings`.
    #[staticmethod]
    #[pyo3(signature = (pressure_kpa, capacitance_pf, temp_c=None, id=1, parasitic_pf=0.0, budget_kpa=model_core::UseCase::GRIPPER.error_budget_kpa))]
    fn fit(
        py: Python<'_>,
        pressure_kpa: &Bound<'_, PyAny>,
        capacitance_pf: &Bound<'_, PyAny>,
        temp_c: Option<&Bound<'_, PyAny>>,
        id: u32,
        parasitic_pf: f32,
        budget_kpa: f32,
    ) -> PyResult<Self> {
        let kind = ErrorKind::Calibration;
        let pressure_kpa = float64_c_array::<Ix1>(pressure_kpa, "pressure_kpa", kind)?;
        let capacitance_pf = float64_c_array::<Ix2>(capacitance_pf, "capacitance_pf", kind)?;
        let temp_c = temp_c
            .map(|values| float64_c_array::<Ix1>(values, "temp_c", kind))
            .transpose()?;
        let pressures = c_order_values(&pressure_kpa, "pressure_kpa", kind)?;
        let rows = pressures.len();
        let shape = capacitance_pf.shape();
        if shape != [rows, TAXEL_COUNT] {
            return Err(taxel_error(
                ErrorKind::Calibration,
                format!(
                    "capacitance_pf has shape {shape:?}; with {rows} pressures it must be ({rows}, {TAXEL_COUNT}): one row per load, one column per taxel of one pad"
                ),
            ));
        }
        let capacitances = c_order_values(&capacitance_pf, "capacitance_pf", kind)?;
        let temperatures = match &temp_c {
            Some(values) => {
                let values = c_order_values(values, "temp_c", kind)?;
                if values.len() != rows {
                    return Err(taxel_error(
                        ErrorKind::Calibration,
                        format!("temp_c has {} values for {rows} pressures", values.len()),
                    ));
                }
                Some(values)
            }
            None => None,
        };
        let mut loads = Vec::with_capacity(rows);
        for (row, &pressure) in pressures.iter().enumerate() {
            let capacitances_pf: [f64; TAXEL_COUNT] =
                std::array::from_fn(|taxel| capacitances[row * TAXEL_COUNT + taxel]);
            if !pressure.is_finite() || capacitances_pf.iter().any(|value| !value.is_finite()) {
                return Err(taxel_error(
                    ErrorKind::Calibration,
                    format!("row {row}: a pressure or capacitance is NaN or infinite"),
                ));
            }
            if pressure < 0.0 {
                return Err(taxel_error(
                    ErrorKind::Calibration,
                    format!("row {row}: negative pressure {pressure} kPa"),
                ));
            }
            loads.push(LoadRow {
                line: row as u64,
                pressure_kpa: pressure,
                capacitances_pf,
                temperature_c: temperatures
                    .and_then(|values| values.get(row).copied())
                    .filter(|value| value.is_finite()),
            });
        }
        let fitted = py.allow_threads(|| -> anyhow::Result<(Self, Vec<String>)> {
            let law = ModelCalibration::default().temperature_law().clone();
            let data = reference_data(&loads, [f64::from(parasitic_pf); TAXEL_COUNT], &law)?;
            let mut warnings = Vec::new();
            if data.rows_temperature_clamped > 0 {
                warnings.push(format!(
                    "{} row(s) outside the characterised {}..{} °C were corrected as if at the nearest end",
                    data.rows_temperature_clamped,
                    law.characterised_min_c(),
                    law.characterised_max_c()
                ));
            }
            let model = fit_calibration(&data, id, parasitic_pf)?;
            let (report, conditioning_warnings) = fit_report(&data, &model, budget_kpa);
            warnings.extend(conditioning_warnings);
            let leave_one_out = (0..TAXEL_COUNT)
                .flat_map(|taxel| {
                    cross_validate(&curve_points(&data, taxel))
                        .into_iter()
                        .map(move |result| LeaveOneOut {
                            taxel: TAXEL_NAMES[taxel],
                            result,
                        })
                })
                .collect();
            Ok((
                Self {
                    model,
                    report: Some(report),
                    leave_one_out,
                    warnings: warnings.clone(),
                },
                warnings,
            ))
        });
        let (fitted, warnings) =
            fitted.map_err(|error| anyhow_error(&error, ErrorKind::Calibration))?;
        let category = py.import("taxel._errors")?.getattr("TaxelWarning")?;
        for warning in warnings {
            let message = CString::new(warning)
                .map_err(|error| taxel_error(ErrorKind::Calibration, error.to_string()))?;
            PyErr::warn(py, &category, &message, 1)?;
        }
        Ok(fitted)
    }

    /// The warnings of :meth:`fit` (also issued as :class:`taxel.TaxelWarning` warnings when it
    /// ran): rows whose temperature was outside the characterised range, and calibration
    /// intervals where the converter's noise moves the pressure by more than the budget.
    /// Empty for a calibration that was not fitted here.
    #[getter]
    fn fit_warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    /// The calibration id (reported by a device that uses it).
    #[getter]
    fn id(&self) -> u32 {
        self.model.id()
    }

    /// The report of :meth:`fit` (levels, cross-validation, conditioning), as ``taxel
    /// calibrate`` prints it; ``None`` for a calibration that was not fitted here.
    #[getter]
    fn fit_report(&self) -> Option<String> {
        self.report.clone()
    }

    /// The cross-validation of :meth:`fit`: one dict per taxel and tier with ``taxel``,
    /// ``tier``, ``fit_max_kpa`` (largest error at the points with the full curve),
    /// ``leave_one_out_kpa`` (the error of each interior level predicted without it),
    /// ``leave_one_out_max_kpa`` and ``leave_one_out_rms_kpa``; ``None`` where the tier is not
    /// available. Empty for a calibration that was not fitted here.
    #[getter]
    fn leave_one_out<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.leave_one_out
            .iter()
            .map(|entry| {
                let dict = PyDict::new(py);
                dict.set_item("taxel", entry.taxel)?;
                dict.set_item("tier", entry.result.tier.name())?;
                dict.set_item("fit_max_kpa", entry.result.fit_max_kpa)?;
                dict.set_item("leave_one_out_kpa", entry.result.leave_one_out_kpa.clone())?;
                dict.set_item(
                    "leave_one_out_max_kpa",
                    entry.result.leave_one_out_max_kpa(),
                )?;
                dict.set_item(
                    "leave_one_out_rms_kpa",
                    entry.result.leave_one_out_rms_kpa(),
                )?;
                Ok(dict)
            })
            .collect()
    }

    /// Whether both hold the same calibration.
    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other
            .downcast::<Calibration>()
            .is_ok_and(|other| other.get().model == self.model)
    }

    /// A short description.
    fn __repr__(&self) -> String {
        format!("Calibration(id={})", self.model.id())
    }
}
