//! The `taxel` Python package's native module (`taxel._taxel`): devices, the simulated device,
//! several devices on one timeline, device events, conversion, recordings and calibrations,
//! built on the host crates (`taxel-host`, `taxel-sim-device`, `model-core`): the protocol,
//! the stamping and the model are theirs, this crate only turns their values into Python
//! objects and numpy arrays. The Python side (`taxel/__init__.py`, `_errors.py`, `_pandas.py`)
//! adds the argument checks of `taxel.convert`, the `Flags` enumeration, the exception and
//! warning classes and the pandas tables.
#![deny(missing_docs)]

mod arrays;
mod buffering;
mod calibration;
mod connect;
mod control;
mod convert;
mod device;
mod devices;
mod errors;
mod events;
mod interrupt;
mod locking;
mod memory_link;
mod recording;
mod sample_set;
mod simulator;
mod stream;
mod timeline;
mod use_case;

use model_core::{TaxelFlags, Tier};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use taxel_host::device_link::{attached_boards, DEFAULT_PID, DEFAULT_VID};

/// The boards attached by USB with the pad's VID:PID, sorted by port: one dict per board with
/// ``port``, ``serial_number``, ``manufacturer``, ``product``, ``vid`` and ``pid``.
#[pyfunction]
fn list_devices(py: Python<'_>) -> PyResult<Vec<Bound<'_, PyDict>>> {
    let boards = py
        .allow_threads(|| attached_boards(DEFAULT_VID, DEFAULT_PID))
        .map_err(errors::link_error)?;
    boards
        .into_iter()
        .map(|board| {
            let dict = PyDict::new(py);
            dict.set_item("port", board.port_name)?;
            dict.set_item("serial_number", board.serial_number)?;
            dict.set_item("manufacturer", board.manufacturer)?;
            dict.set_item("product", board.product)?;
            dict.set_item("vid", board.vid)?;
            dict.set_item("pid", board.pid)?;
            Ok(dict)
        })
        .collect()
}

/// The documented flag names and their bits, in bit order (the source of ``taxel.Flags``).
#[pyfunction]
fn flag_bits() -> Vec<(&'static str, u16)> {
    TaxelFlags::NAMES
        .iter()
        .map(|(flag, name)| (*name, flag.bits()))
        .collect()
}

/// The inversion tiers' names, in id order (the default is ``monotone-cubic``).
#[pyfunction]
fn tier_names() -> Vec<&'static str> {
    Tier::ALL.iter().map(|tier| tier.name()).collect()
}

/// The recording schema's columns, in order (the header ``taxel record`` writes).
#[pyfunction]
fn recording_columns() -> Vec<&'static str> {
    taxel_host::schema::header()
}

/// The native module.
#[pymodule]
fn _taxel(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_function(wrap_pyfunction!(list_devices, module)?)?;
    module.add_function(wrap_pyfunction!(flag_bits, module)?)?;
    module.add_function(wrap_pyfunction!(tier_names, module)?)?;
    module.add_function(wrap_pyfunction!(recording_columns, module)?)?;
    module.add_function(wrap_pyfunction!(convert::convert_arrays, module)?)?;
    module.add_function(wrap_pyfunction!(recording::read_recording_rows, module)?)?;
    module.add_function(wrap_pyfunction!(recording::convert_recording_rows, module)?)?;
    module.add_class::<recording::Recording>()?;
    module.add_class::<device::Device>()?;
    module.add_class::<simulator::Simulator>()?;
    module.add_class::<simulator::SimulatedBoard>()?;
    module.add_class::<devices::Devices>()?;
    module.add_class::<sample_set::SampleSet>()?;
    module.add_class::<buffering::Buffer>()?;
    module.add_class::<events::DeviceEvent>()?;
    module.add_class::<calibration::Calibration>()?;
    Ok(())
}
