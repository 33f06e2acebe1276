//! The pad's calibration kept in NOR flash, for the firmware (over embassy-stm32's flash) and for
//! the desktop simulator and tests (over `RamFlash`, with the `ram-flash` feature).
//!
//! Two layers:
//! - [`encode_record`] / [`decode_record`]: a [`CalibrationSpec`] as
//!   `[format version = 1][postcard body][CRC-32/ISO-HDLC little-endian]`, at most
//!   [`MAX_RECORD_LEN`] bytes. Decoding refuses anything that is not an intact record of a
//!   calibration that validates, with a typed [`RecordError`], and never panics.
//! - [`CalibrationStore`]: that record as the value of one key of a `sequential-storage` map over
//!   a flash range of at least two erase pages. Saving appends a new item and the previous one
//!   stays valid until the new one is completely written, so a power loss during a save leaves
//!   either the old or the new calibration, never something else. (That holds when an
//!   interrupted page erase has erased from the start of the page onwards, which is what
//!   sequential-storage assumes; if an erase is interrupted in another pattern, the outcome is a
//!   calibration saved at some earlier point, or none: never an unsaved one.)
//!
//! [`CalibrationSpec`]: model_core::CalibrationSpec
#![no_std]
#![deny(missing_docs)]

#[cfg(feature = "ram-flash")]
mod ram_flash;
mod record;
mod store;

#[cfg(feature = "ram-flash")]
pub use ram_flash::{
    OperationKind, PowerLossReport, RamFlash, RamFlashError, Tear, RAM_FLASH_WORD_SIZE,
};
pub use record::{
    decode_record, encode_record, RecordError, MAX_BODY_LEN, MAX_RECORD_LEN, RECORD_CRC_ALGORITHM,
    RECORD_FORMAT_VERSION,
};
pub use store::{
    CalibrationStore, CorruptReason, LoadOutcome, RegionError, StoreError, CALIBRATION_KEY,
    STM32F411_CALIBRATION_RANGE,
};
