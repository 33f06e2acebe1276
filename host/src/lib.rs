//! The taxel host library: everything between a device's bytes and a consumer (the `taxel`
//! command line, the Zenoh bridge, the Python package), with no terminal, plotting or
//! argument-parsing dependency.
//!
//! - The device: [`device_link`] (board discovery, the serial link, frames, requests matched
//!   with their replies), [`session`] (one device's stream, the host's only stream loop),
//!   [`worker`] (sessions on threads, their events down one queue with their arrival on the
//!   [`host_clock`]), [`stream_accounting`] (gaps, drops), [`pad_set`] (every pad's frame of a
//!   sample set), [`clock_sync`] (device clocks mapped onto the host's) and [`stamping`] (the
//!   one stamping policy).
//! - Its state: [`device_state`], [`device_words`] (what a device says, in words),
//!   [`calibration_file`], [`calibration_transfer`], [`calibrate`] and [`calibrate_report`]
//!   (fitting a calibration from reference loads).
//! - Files: [`schema`] (the one recording schema), [`recorder`] (worker events into the schema
//!   and MCAP, with raw logs and device states), [`convert`] (the conversion engine),
//!   [`csv_format`], [`output_file`] (written under a temporary name, renamed when complete).
//! - [`console`]: notes to the user on stderr that never panic on a closed stream.
#![deny(missing_docs)]
// Output goes through `console`, which never panics on a closed stdout or stderr.
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod calibrate;
pub mod calibrate_report;
pub mod calibration_file;
pub mod calibration_transfer;
pub mod clock_sync;
pub mod console;
pub mod convert;
pub mod csv_format;
pub mod device_link;
pub mod device_state;
pub mod device_words;
pub mod frame_receiver;
pub mod host_clock;
pub mod output_file;
pub mod pad_set;
pub mod recorder;
pub mod schema;
pub mod session;
pub mod stamping;
pub mod stream_accounting;
pub mod worker;
