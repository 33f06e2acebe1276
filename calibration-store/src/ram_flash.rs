//! [`RamFlash`]: an in-memory NOR flash shaped like the STM32F4's, with injectable faults, for
//! host tests and the desktop simulator.
//!
//! NOR rules as on the chip: erased bytes read 0xFF, erasing works on whole pages, a write can
//! only clear bits (asking for a 0 bit to become 1 without an erase is an error here, where the
//! chip would silently keep the 0), and writes are word-aligned: embassy-stm32 programs the F4 in
//! x32 parallelism and declares `WRITE_SIZE = 4` for every F411 flash region, reads are byte-wise
//! (`READ_SIZE = 1`).
//!
//! Faults:
//! - power loss after N more write/erase operations ([`RamFlash::schedule_power_loss`]): the
//!   interrupted operation is torn as its [`Tear`] says, it and every later operation (reads
//!   included) fail with [`RamFlashError::PowerLoss`] until [`RamFlash::power_cycle`];
//! - bit flips at chosen addresses ([`RamFlash::flip_bit`]), or any byte edit through
//!   [`RamFlash::as_bytes_mut`];
//! - snapshots ([`RamFlash::snapshot`], [`RamFlash::restore`], or `Clone`) for "reboot" tests.

use core::fmt;

use embedded_storage_async::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// The programming unit of [`RamFlash`], as embassy-stm32's F4 flash `WRITE_SIZE`.
pub const RAM_FLASH_WORD_SIZE: usize = 4;

const ERASED_BYTE: u8 = 0xFF;

/// Which operation a power loss interrupted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum OperationKind {
    /// A write (programming).
    Write,
    /// An erase.
    Erase,
}

/// How much of the interrupted operation reaches the array. The operation proceeds word by word
/// from its lowest address, as a sector erase or a programming sequence does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Tear {
    /// Words completed, clamped to one fewer than the operation has: an interrupted operation
    /// never completes.
    pub whole_words: usize,
    /// Bits of the next word that change anyway: a write clears those of them it was going to
    /// clear, an erase sets them.
    pub partial_word_mask: u32,
}

impl Tear {
    /// Nothing of the interrupted operation reaches the array.
    pub const NOTHING: Tear = Tear {
        whole_words: 0,
        partial_word_mask: 0,
    };

    /// `whole_words` words complete, the next one is untouched.
    pub const fn words(whole_words: usize) -> Self {
        Tear {
            whole_words,
            partial_word_mask: 0,
        }
    }
}

/// The last power loss: what was interrupted and how much of it was done.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PowerLossReport {
    /// The interrupted operation.
    pub kind: OperationKind,
    /// Its first address.
    pub address: u32,
    /// Its length in words.
    pub words: usize,
    /// Words it completed before the power went.
    pub whole_words_done: usize,
}

/// What [`RamFlash`] refuses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RamFlashError {
    /// The operation reaches beyond the flash.
    OutOfBounds,
    /// A write not on word boundaries, or an erase not on page boundaries.
    NotAligned,
    /// A write asked for a 0 bit to become 1 (the first such byte's address); nothing was written.
    NotErased {
        /// Address of the first byte that needed an erase.
        address: u32,
    },
    /// The power is off: a scheduled power loss happened and [`RamFlash::power_cycle`] was not
    /// called yet.
    PowerLoss,
}

impl fmt::Display for RamFlashError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RamFlashError::OutOfBounds => write!(formatter, "out of bounds"),
            RamFlashError::NotAligned => write!(formatter, "not aligned"),
            RamFlashError::NotErased { address } => {
                write!(formatter, "write over non-erased bits at {address:#x}")
            }
            RamFlashError::PowerLoss => write!(formatter, "power lost"),
        }
    }
}

impl core::error::Error for RamFlashError {}

impl NorFlashError for RamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            RamFlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            RamFlashError::NotAligned => NorFlashErrorKind::NotAligned,
            RamFlashError::NotErased { .. } | RamFlashError::PowerLoss => NorFlashErrorKind::Other,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Power {
    On,
    LossAfter { operations: u32, tear: Tear },
    Off,
}

/// `SIZE` bytes of NOR flash erased in pages of `PAGE` bytes (both multiples of the 4-byte word),
/// initially erased.
#[derive(Debug, Clone)]
pub struct RamFlash<const SIZE: usize, const PAGE: usize> {
    bytes: [u8; SIZE],
    power: Power,
    writes: u32,
    erases: u32,
    last_power_loss: Option<PowerLossReport>,
}

impl<const SIZE: usize, const PAGE: usize> Default for RamFlash<SIZE, PAGE> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const SIZE: usize, const PAGE: usize> RamFlash<SIZE, PAGE> {
    const GEOMETRY_IS_VALID: () = assert!(
        PAGE > 0
            && PAGE.is_multiple_of(RAM_FLASH_WORD_SIZE)
            && SIZE.is_multiple_of(PAGE)
            && SIZE <= u32::MAX as usize,
        "RamFlash: PAGE must be a non-zero multiple of 4 dividing SIZE, SIZE must fit in u32"
    );

    /// A fully erased flash with the power on.
    pub const fn new() -> Self {
        Self::from_bytes([ERASED_BYTE; SIZE])
    }

    /// A flash holding `bytes`, with the power on.
    pub const fn from_bytes(bytes: [u8; SIZE]) -> Self {
        let () = Self::GEOMETRY_IS_VALID;
        Self {
            bytes,
            power: Power::On,
            writes: 0,
            erases: 0,
            last_power_loss: None,
        }
    }

    /// The content.
    pub fn as_bytes(&self) -> &[u8; SIZE] {
        &self.bytes
    }

    /// The content, for direct corruption (no NOR rule applies).
    pub fn as_bytes_mut(&mut self) -> &mut [u8; SIZE] {
        &mut self.bytes
    }

    /// A copy of the content.
    pub fn snapshot(&self) -> [u8; SIZE] {
        self.bytes
    }

    /// Puts back a copy of the content (power state and counters are kept).
    pub fn restore(&mut self, bytes: &[u8; SIZE]) {
        self.bytes = *bytes;
    }

    /// Toggles bit `bit` (0 = least significant, taken modulo 8) of the byte at `address`;
    /// refuses an address beyond the flash.
    pub fn flip_bit(&mut self, address: u32, bit: u8) -> Result<(), RamFlashError> {
        let byte = self
            .bytes
            .get_mut(address as usize)
            .ok_or(RamFlashError::OutOfBounds)?;
        *byte ^= 1 << (bit % 8);
        Ok(())
    }

    /// After `operations` more writes or erases complete, the next one is torn as `tear` says
    /// and the power stays off until [`Self::power_cycle`]. Replaces any earlier schedule.
    pub fn schedule_power_loss(&mut self, operations: u32, tear: Tear) {
        self.power = Power::LossAfter { operations, tear };
    }

    /// Power back on (a reboot): the content is kept, any pending power loss is cancelled.
    pub fn power_cycle(&mut self) {
        self.power = Power::On;
    }

    /// Whether a scheduled power loss has happened and the power is still off.
    pub fn is_powered_off(&self) -> bool {
        self.power == Power::Off
    }

    /// The most recent power loss, if any happened.
    pub fn last_power_loss(&self) -> Option<PowerLossReport> {
        self.last_power_loss
    }

    /// Writes completed since creation (non-empty, torn ones excluded).
    pub fn write_count(&self) -> u32 {
        self.writes
    }

    /// Erases completed since creation (non-empty, torn ones excluded).
    pub fn erase_count(&self) -> u32 {
        self.erases
    }

    fn check_power(&self) -> Result<(), RamFlashError> {
        if self.power == Power::Off {
            Err(RamFlashError::PowerLoss)
        } else {
            Ok(())
        }
    }

    fn range(&self, offset: u32, length: usize) -> Result<core::ops::Range<usize>, RamFlashError> {
        let start = offset as usize;
        let end = start
            .checked_add(length)
            .ok_or(RamFlashError::OutOfBounds)?;
        if end > SIZE {
            return Err(RamFlashError::OutOfBounds);
        }
        Ok(start..end)
    }

    /// The bytes of a range [`Self::range`] accepted.
    fn area(&self, range: core::ops::Range<usize>) -> Result<&[u8], RamFlashError> {
        self.bytes.get(range).ok_or(RamFlashError::OutOfBounds)
    }

    /// The bytes of a range [`Self::range`] accepted, to change.
    fn area_mut(&mut self, range: core::ops::Range<usize>) -> Result<&mut [u8], RamFlashError> {
        self.bytes.get_mut(range).ok_or(RamFlashError::OutOfBounds)
    }

    /// Counts a write/erase against the power-loss schedule: `Some(tear)` if this one is torn.
    fn consume_operation(&mut self) -> Option<Tear> {
        match self.power {
            Power::LossAfter {
                operations: 0,
                tear,
            } => {
                self.power = Power::Off;
                Some(tear)
            }
            Power::LossAfter { operations, tear } => {
                self.power = Power::LossAfter {
                    operations: operations - 1,
                    tear,
                };
                None
            }
            Power::On | Power::Off => None,
        }
    }

    fn record_power_loss(
        &mut self,
        kind: OperationKind,
        address: u32,
        words: usize,
        tear: Tear,
    ) -> usize {
        let whole_words_done = tear.whole_words.min(words.saturating_sub(1));
        self.last_power_loss = Some(PowerLossReport {
            kind,
            address,
            words,
            whole_words_done,
        });
        whole_words_done
    }
}

impl<const SIZE: usize, const PAGE: usize> ErrorType for RamFlash<SIZE, PAGE> {
    type Error = RamFlashError;
}

impl<const SIZE: usize, const PAGE: usize> ReadNorFlash for RamFlash<SIZE, PAGE> {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.check_power()?;
        let range = self.range(offset, bytes.len())?;
        bytes.copy_from_slice(self.area(range)?);
        Ok(())
    }

    fn capacity(&self) -> usize {
        SIZE
    }
}

impl<const SIZE: usize, const PAGE: usize> NorFlash for RamFlash<SIZE, PAGE> {
    const WRITE_SIZE: usize = RAM_FLASH_WORD_SIZE;
    const ERASE_SIZE: usize = PAGE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.check_power()?;
        if from > to {
            return Err(RamFlashError::OutOfBounds);
        }
        let range = self.range(from, (to - from) as usize)?;
        if !range.start.is_multiple_of(PAGE) || !range.end.is_multiple_of(PAGE) {
            return Err(RamFlashError::NotAligned);
        }
        if range.is_empty() {
            return Ok(());
        }
        let Some(tear) = self.consume_operation() else {
            self.area_mut(range)?.fill(ERASED_BYTE);
            self.erases += 1;
            return Ok(());
        };
        let words = range.len() / RAM_FLASH_WORD_SIZE;
        let done = self.record_power_loss(OperationKind::Erase, from, words, tear);
        let (erased, rest) = self
            .area_mut(range)?
            .split_at_mut_checked(done * RAM_FLASH_WORD_SIZE)
            .ok_or(RamFlashError::OutOfBounds)?;
        erased.fill(ERASED_BYTE);
        if let Some(partial) = rest.first_chunk_mut::<RAM_FLASH_WORD_SIZE>() {
            let value = u32::from_le_bytes(*partial) | tear.partial_word_mask;
            *partial = value.to_le_bytes();
        }
        Err(RamFlashError::PowerLoss)
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.check_power()?;
        let range = self.range(offset, bytes.len())?;
        if !range.start.is_multiple_of(RAM_FLASH_WORD_SIZE)
            || !bytes.len().is_multiple_of(RAM_FLASH_WORD_SIZE)
        {
            return Err(RamFlashError::NotAligned);
        }
        if bytes.is_empty() {
            return Ok(());
        }
        if let Some(index) = self
            .area(range.clone())?
            .iter()
            .zip(bytes)
            .position(|(&stored, &new)| stored & new != new)
        {
            return Err(RamFlashError::NotErased {
                address: offset + index as u32,
            });
        }
        let Some(tear) = self.consume_operation() else {
            for (stored, new) in self.area_mut(range)?.iter_mut().zip(bytes) {
                *stored &= new;
            }
            self.writes += 1;
            return Ok(());
        };
        let words = bytes.len() / RAM_FLASH_WORD_SIZE;
        let done = self.record_power_loss(OperationKind::Write, offset, words, tear);
        let done_len = done * RAM_FLASH_WORD_SIZE;
        let area = self.area_mut(range)?;
        for (stored, new) in area.iter_mut().zip(bytes).take(done_len) {
            *stored &= new;
        }
        let partial_source = bytes
            .get(done_len..)
            .and_then(<[u8]>::first_chunk::<RAM_FLASH_WORD_SIZE>);
        let partial_target = area
            .get_mut(done_len..)
            .and_then(<[u8]>::first_chunk_mut::<RAM_FLASH_WORD_SIZE>);
        if let (Some(source), Some(target)) = (partial_source, partial_target) {
            let new = u32::from_le_bytes(*source);
            let value = u32::from_le_bytes(*target) & (new | !tear.partial_word_mask);
            *target = value.to_le_bytes();
        }
        Err(RamFlashError::PowerLoss)
    }
}

/// Re-writing a written word is allowed as long as it only clears bits, as the F4 reference
/// manuals allow. The calibration store itself never re-writes a word.
impl<const SIZE: usize, const PAGE: usize> MultiwriteNorFlash for RamFlash<SIZE, PAGE> {}
