//! The `taxel` host tool as a library: every subcommand's logic, testable without the binary.
//!
//! - [`convert`]: re-process recorded capacitances with another calibration or tier.
//! - [`calibrate`]: fit a calibration from reference loads, cross-validate the tiers, upload.
//! - [`plot`]: SVG/PNG pictures of recordings and calibrations.
//! - [`list`], [`record`], [`view`]: attached boards, recording, the live terminal view.
//! - [`device_link`]: the serial link: board discovery, frame decoding, requests and replies.
//! - [`calibration_file`], [`csv_format`], [`device_state`]: the file formats.
#![deny(missing_docs)]
// Output goes through `console`, which never panics on a closed stdout or stderr.
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod calibrate;
pub mod calibrate_report;
pub mod calibration_file;
pub mod calibration_transfer;
pub mod cli;
pub mod clock_sync;
pub mod console;
pub mod convert;
pub mod csv_format;
pub mod device_link;
pub mod device_state;
pub mod device_words;
pub mod frame_receiver;
pub mod host_timeline;
pub mod layout;
pub mod list;
pub mod mcap_record;
pub mod multi_record;
pub mod output_file;
pub mod pad_set;
pub mod plot;
pub mod record;
pub mod record_rows;
pub mod recording;
pub mod sim;
pub mod stream_accounting;
pub mod timeline_files;
pub mod view;
