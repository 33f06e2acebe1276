//! The subcommands that drive the host library: each holds its arguments and its `run`.

pub mod calibrate;
pub mod calibration;
pub mod convert;
pub mod record;
