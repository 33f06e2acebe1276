//! Rust errors as Python exceptions. The exception classes live in `taxel._errors` (Python, so
//! that each can also derive from the built-in exception it resembles); the messages are the
//! command-line tool's, cause chain included.

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use taxel_host::device_link::{LinkError, RequestError};

/// The Python exception classes, by their name in `taxel._errors`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// `DeviceNotFoundError`.
    DeviceNotFound,
    /// `LinkError`.
    Link,
    /// `DeviceTimeoutError`.
    Timeout,
    /// `DeviceRefusedError`.
    Refused,
    /// `ProtocolVersionError`.
    ProtocolVersion,
    /// `CalibrationError`.
    Calibration,
    /// `ConvertError`.
    Convert,
    /// `DataLossError`.
    DataLoss,
    /// `TaxelError`, the base class.
    Other,
}

impl ErrorKind {
    fn class_name(self) -> &'static str {
        match self {
            ErrorKind::DeviceNotFound => "DeviceNotFoundError",
            ErrorKind::Link => "LinkError",
            ErrorKind::Timeout => "DeviceTimeoutError",
            ErrorKind::Refused => "DeviceRefusedError",
            ErrorKind::ProtocolVersion => "ProtocolVersionError",
            ErrorKind::Calibration => "CalibrationError",
            ErrorKind::Convert => "ConvertError",
            ErrorKind::DataLoss => "DataLossError",
            ErrorKind::Other => "TaxelError",
        }
    }
}

/// A Python exception of `kind` with `message` (and, for a refusal, the device's error code).
pub fn taxel_error(kind: ErrorKind, message: impl Into<String>) -> PyErr {
    let message = message.into();
    Python::with_gil(|py| {
        let class = py
            .import("taxel._errors")
            .and_then(|module| module.getattr(kind.class_name()));
        match class {
            Ok(class) => match class.call1((message.clone(),)) {
                Ok(instance) => PyErr::from_value(instance),
                Err(error) => error,
            },
            // Only when the package is broken: still say what went wrong.
            Err(_) => PyRuntimeError::new_err(message),
        }
    })
}

/// A refusal by the device, with its error code as `code`.
pub fn refused_error(message: String, code: String) -> PyErr {
    Python::with_gil(|py| {
        let class = py
            .import("taxel._errors")
            .and_then(|module| module.getattr("DeviceRefusedError"));
        match class.and_then(|class| class.call1((message.clone(), code))) {
            Ok(instance) => PyErr::from_value(instance),
            Err(_) => PyRuntimeError::new_err(message),
        }
    })
}

/// The exception class a link failure belongs to.
pub fn link_error_kind(error: &LinkError) -> ErrorKind {
    match error {
        LinkError::NoBoard { .. }
        | LinkError::SerialNumberNotFound { .. }
        | LinkError::SeveralBoards { .. } => ErrorKind::DeviceNotFound,
        _ => ErrorKind::Link,
    }
}

/// A link failure as a Python exception.
pub fn link_error(error: LinkError) -> PyErr {
    taxel_error(link_error_kind(&error), error.to_string())
}

/// An error of the host library (an `anyhow` chain) as a Python exception: the class from the
/// innermost typed cause, the message as the CLI prints it.
pub fn anyhow_error(error: &anyhow::Error, default_kind: ErrorKind) -> PyErr {
    let message = taxel_host::console::error_message(error);
    let mut kind = default_kind;
    for cause in error.chain() {
        if let Some(request) = cause.downcast_ref::<RequestError>() {
            kind = match request {
                RequestError::Link(link) => link_error_kind(link),
                RequestError::Timeout { .. } => ErrorKind::Timeout,
                RequestError::Refused(code) => {
                    return refused_error(message, format!("{code:?}"));
                }
                RequestError::UnexpectedReply(_) => ErrorKind::Other,
                RequestError::OtherProtocolVersion { .. } => ErrorKind::ProtocolVersion,
            };
            break;
        }
        if let Some(link) = cause.downcast_ref::<LinkError>() {
            kind = link_error_kind(link);
            break;
        }
    }
    taxel_error(kind, message)
}
