//! Arrays from Python: whatever a researcher passes (lists, numpy arrays of any numeric type and
//! any memory layout, pandas Series and DataFrames) becomes a C-ordered float64 array through
//! numpy's own conversion, or the call is refused with a message naming the argument.
//!
//! rust-numpy's `as_slice` also accepts a Fortran-ordered array and returns its memory in that
//! order, so a `(N, 4)` array from `DataFrame.to_numpy()` would be read column by column as if
//! it were row by row. Every array the package reads goes through [`float64_c_array`], which
//! makes the layout C order first, and [`c_order_values`], which refuses anything else.

use numpy::ndarray::Dimension;
use numpy::{PyArray, PyArrayMethods, PyReadonlyArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{taxel_error, ErrorKind};

/// `value` as a C-ordered float64 array of dimension `D` (numpy's `ascontiguousarray` with
/// `dtype=float64`: a copy only when the layout or type differs). Values that are not numbers,
/// or another number of dimensions, raise `kind`'s exception naming `name`.
pub fn float64_c_array<'py, D: Dimension>(
    value: &Bound<'py, PyAny>,
    name: &str,
    kind: ErrorKind,
) -> PyResult<PyReadonlyArray<'py, f64, D>> {
    let py = value.py();
    let keywords = PyDict::new(py);
    keywords.set_item("dtype", "float64")?;
    let converted = py
        .import("numpy")?
        .call_method("ascontiguousarray", (value,), Some(&keywords))
        .map_err(|error| {
            taxel_error(
                kind,
                format!("{name} cannot be read as an array of numbers: {error}"),
            )
        })?;
    let dimensions = D::NDIM.unwrap_or(0);
    let array = converted
        .downcast_into::<PyArray<f64, D>>()
        .map_err(|error| {
            let found = error
                .into_inner()
                .getattr("shape")
                .map_or_else(|_| "?".to_owned(), |shape| shape.to_string());
            taxel_error(
                kind,
                format!("{name} must have {dimensions} dimension(s); got shape {found}"),
            )
        })?;
    Ok(array.readonly())
}

/// The values of a C-ordered array in row-major order; any other layout is refused (never read
/// in memory order).
pub fn c_order_values<'a, D: Dimension>(
    array: &'a PyReadonlyArray<'_, f64, D>,
    name: &str,
    kind: ErrorKind,
) -> PyResult<&'a [f64]> {
    let refused = || {
        taxel_error(
            kind,
            format!("{name} must be a C-ordered (row-major) array"),
        )
    };
    if !array.is_c_contiguous() {
        return Err(refused());
    }
    array.as_slice().map_err(|_| refused())
}
