//! The `taxel` command line: argument parsing and presentation (the live view, plots, the
//! reports), on top of the host library `taxel-host`, which does the work.
//!
//! - [`cli`]: the subcommands; [`commands`]: record, convert, calibrate, calibration.
//! - [`view`] and [`layout`]: the live terminal view of one device or several, and where each
//!   pad's tile goes.
//! - [`plot`]: SVG/PNG pictures of recordings and calibrations; [`list`]: attached boards;
//!   [`sim`]: the simulated device on a pseudo-terminal, and the demo.
#![deny(missing_docs)]
// Output goes through `taxel_host::console`, which never panics on a closed stdout or stderr.
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod cli;
pub mod commands;
pub mod layout;
pub mod list;
pub mod plot;
pub mod sim;
pub mod view;
