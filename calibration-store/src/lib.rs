//! The pads' calibrations kept in NOR flash, for the firmware (over embassy-stm32's flash) and for
//! the desktop simulator and tests (over `RamFlash`, with the `ram-flash` feature).
//!
//! Two layers:
//! - [`encode_scoped_record`] / [`decode_saved_record`]: a [`CalibrationSpec`], the pads it is
//!   for and its save counter as `[format version = 3][save counter u32 LE][postcard body]
//!   [CRC-32/ISO-HDLC little-endian]` for every pad, or `[4][pad][save counter]...` for one pad,
//!   at most [`MAX_RECORD_LEN`] bytes. Decoding also reads version 2 (written by earlier firmware:
//!   the body without the taxels' calibrated C0, which loads as none), refuses anything that is
//!   not an intact record of a calibration that validates, with a typed [`RecordError`], and
//!   never panics.
//! - [`CalibrationStore`]: those records as items in a flash range of two erase pages, in the
//!   on-flash format of the `sequential-storage` 8.0.2 map the earlier firmware used (read and
//!   written by this crate: no sequential-storage code runs). Loading returns a pad's valid
//!   record with the highest save counter (its own or one for every pad), wherever it is; saving
//!   appends beside an erased page or moves to the other page with every record a pad still
//!   loads, and erases nothing those records need until they and the new one read back. So bit
//!   flips, truncation or a power loss in the middle of a save leave the previous or the
//!   new calibration, or the defaults with the corrupt flag ([`LoadOutcome::Corrupt`]): never an
//!   older calibration, never an unsaved one, whichever way an interrupted page erase leaves the
//!   page (from its start, from its end, or random bits). The `store` module's documentation
//!   gives the format and the power-loss argument.
//!
//! [`CalibrationSpec`]: model_core::CalibrationSpec
#![no_std]
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

mod erase_hook;
#[cfg(feature = "ram-flash")]
mod ram_flash;
mod record;
mod store;

pub use erase_hook::EraseHook;
#[cfg(feature = "ram-flash")]
pub use ram_flash::{
    OperationKind, PowerLossReport, RamFlash, RamFlashError, Tear, RAM_FLASH_WORD_SIZE,
};
pub use record::{
    decode_record, decode_saved_record, encode_record, encode_scoped_record, RecordError,
    RecordScope, SavedRecord, MAX_BODY_LEN, MAX_PADS, MAX_RECORD_LEN, PAD_RECORD_FORMAT_VERSION,
    RECORD_CRC_ALGORITHM, RECORD_FORMAT_VERSION,
};
pub use store::{
    CalibrationKey, CalibrationStore, CorruptReason, LoadOutcome, RegionError, StoreError,
    CALIBRATION_KEY, STM32F411_CALIBRATION_RANGE,
};
