//! A use case from Python: a preset's name or a dict of its four numbers.

use model_core::UseCase;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The presets by name.
pub const PRESETS: [(&str, UseCase); 3] = [
    ("light_touch", UseCase::LIGHT_TOUCH),
    ("gripper", UseCase::GRIPPER),
    ("glove", UseCase::GLOVE),
];

/// A preset's name or a dict with `pressure_max_kpa`, `temperature_min_c`,
/// `temperature_max_c` and `error_budget_kpa`, checked.
pub fn use_case_from_python(value: &Bound<'_, PyAny>) -> PyResult<UseCase> {
    let names = || {
        PRESETS
            .iter()
            .map(|(name, _)| *name)
            .collect::<Vec<_>>()
            .join(", ")
    };
    let use_case = if let Ok(name) = value.extract::<String>() {
        PRESETS
            .iter()
            .find(|(preset, _)| *preset == name)
            .map(|(_, use_case)| *use_case)
            .ok_or_else(|| {
                PyValueError::new_err(format!(
                    "unknown use case '{name}'; valid use cases: {}, or a dict",
                    names()
                ))
            })?
    } else if let Ok(dict) = value.downcast::<PyDict>() {
        let number = |key: &str| -> PyResult<f32> {
            dict.get_item(key)?
                .ok_or_else(|| PyValueError::new_err(format!("the use case lacks '{key}'")))?
                .extract::<f32>()
        };
        UseCase {
            pressure_max_kpa: number("pressure_max_kpa")?,
            temperature_min_c: number("temperature_min_c")?,
            temperature_max_c: number("temperature_max_c")?,
            error_budget_kpa: number("error_budget_kpa")?,
        }
    } else {
        return Err(PyTypeError::new_err(format!(
            "a use case is a name ({}) or a dict",
            names()
        )));
    };
    if !use_case.is_valid() {
        return Err(PyValueError::new_err(
            "the use case needs a positive pressure range and error budget and the lowest temperature below the highest",
        ));
    }
    Ok(use_case)
}
