//! The pads' calibrations kept in NOR flash, for the firmware (over embassy-stm32's flash) and for
//! the desktop simulator and tests (over `RamFlash`, with the `ram-flash` feature).
//!
//! Three layers:
//! - [`encode_body`] / [`decode_body`]: what a pad's record holds, a [`PadRecord`] (its
//!   calibration, role and geometry) as `[body format version = 2][postcard]`, at most
//!   [`MAX_BODY_LEN`] bytes. Decoding refuses anything that is not a calibration and a geometry
//!   that validate, with a typed [`RecordError`], and never panics. This is the only place that
//!   knows what a body is.
//! - the on-flash format ([`format`] documents it): two erase pages, each with a header
//!   (magic "TXCS", format version [`STORE_FORMAT_VERSION`], generation, CRC-32) and a commit
//!   word, then records `[body length][its complement][save counter][pads][CRC-32][body]`, one
//!   per pad or one for every pad ([`RecordScope`]).
//! - [`CalibrationStore`]: loading gives a pad its newest record (highest save counter) in the
//!   current page (the complete page with the highest generation); saving appends to that page,
//!   or moves every record still in use and the new one into the other page, makes it current
//!   only once it reads back, and only then erases the old one. So a power loss in the middle of
//!   a save leaves every pad its previous calibration or, for the pads the save is for, the new
//!   one: never an older calibration, never an unsaved one, whichever way an interrupted page
//!   erase leaves the page (from its start, from its end, or random bits). A damaged record is
//!   skipped (its pad falls back to its previous record, if the page still holds it) and a pad
//!   with nothing intact left loads the defaults with the corrupt flag
//!   ([`LoadOutcome::Corrupt`]). The `store` module's documentation gives the power-loss
//!   argument.

#![no_std]
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

mod erase_hook;
pub mod format;
mod page;
#[cfg(feature = "ram-flash")]
mod ram_flash;
mod record;
mod store;

pub use erase_hook::EraseHook;
pub use format::{
    RecordScope, MAX_PADS, MAX_RECORD_LEN, RECORD_CRC_ALGORITHM, STORE_FORMAT_VERSION,
};
#[cfg(feature = "ram-flash")]
pub use ram_flash::{
    OperationKind, PowerLossReport, RamFlash, RamFlashError, Tear, RAM_FLASH_WORD_SIZE,
};
pub use record::{
    decode_body, encode_body, PadRecord, RecordError, BODY_FORMAT_VERSION, MAX_BODY_LEN,
};
pub use store::{
    CalibrationStore, CorruptReason, LoadOutcome, RegionError, StoreError,
    STM32F411_CALIBRATION_RANGE,
};
