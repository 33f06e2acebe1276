//! [`CalibrationStore`]: the calibration record in a flash range of two erase pages, with the load
//! outcomes the firmware turns into a calibration source.
//!
//! # On flash
//!
//! The layout is the one sequential-storage 8.0.2's map wrote for the earlier firmware (a map
//! whose only key is the zero-length [`CalibrationKey`]), so that firmware's flash loads with the
//! same reader; this module reads and writes it itself. With `W` the flash word (the larger of
//! its read and write sizes, at most 32 bytes):
//! - a page in use starts with a marker word of zeros; its last word is kept free (for
//!   sequential-storage's end marker). The reader ignores both markers;
//! - from the second word on, items follow one another: an 8-byte header (the data CRC, u32 LE;
//!   the data length, u16 LE; the length CRC, u16 LE) padded to `W`, then the data padded to `W`;
//! - the data CRC is CRC-32C (reflected polynomial 0x82F6_3B78) from 0xEEEE_EEEE, inverted, then
//!   written as 1 if it is 0, and with its lowest bit flipped if its first byte is 0x00 or 0xFF;
//!   the length CRC is CRC-16 with reflected polynomial 0x1A2E from 0xFFFF, inverted, and written
//!   as 0xFFFE if it is 0xFFFF (both as sequential-storage computes them);
//! - the data of every item is one calibration record ([`crate::encode_record`]), which carries
//!   its save counter and its own CRC-32.
//!
//! An item is intact when both its CRCs match. Reading a page goes from item to item and stops at
//! a header slot that reads erased; a header whose length CRC fails (torn, damaged) hides where the
//! next item starts, so the reader tries again one word further on. The item CRC is what tells a
//! torn or damaged item (skipped) from an intact item whose record this firmware refuses
//! (reported).
//!
//! # Loading
//!
//! [`CalibrationStore::load`] reads page 0 then page 1, each from its start, and returns the valid
//! record with the highest save counter (of equal counters, the later). It returns
//! [`CorruptReason::Record`] (or [`CorruptReason::Storage`] for an intact item longer than any
//! record) instead when an intact item it cannot use may be newer than that record: one after it
//! in its page (a page is appended to in order), or one in the other page when that page holds
//! no valid record to date it (a move erases the page it writes to, so a page with valid records
//! of lower counters is older as a whole). Damage to the newest record (not a power loss) brings
//! back the record before it when that one is still in flash, which is the case when the newest
//! was appended.
//!
//! # Saving
//!
//! [`CalibrationStore::save`] gives the new record the highest save counter plus one, then:
//! - if the other page is erased and the new item fits in erased space after the last item of
//!   the page holding the newest record, appends it there; appending keeps sector erases rare (an
//!   F411 128 KiB sector takes 1 to 2 s to erase, and wears out after 10 000 erases);
//! - otherwise, or if the appended record does not read back, moves: erases the other page unless
//!   it reads erased, writes the marker and the new item there, reads the new record back, and
//!   only then erases the page it came from.
//!
//! So outside a save one page at most holds items; when both do (a save that did not complete, or
//! damage), the next save moves, which cleans up.
//!
//! # Power loss
//!
//! Each flash operation of a save, interrupted, leaves the previous record intact (and still the
//! highest counter) or the new record intact (with a higher counter):
//! - an append writes only erased space after the newest record: a torn item there is skipped;
//! - a move erases and writes only the page without the newest record, whatever an interrupted
//!   erase leaves in it (erased from its start, from its end, or random bits), and a torn item
//!   there is skipped;
//! - the old page is erased only once the new record reads back: what an interrupted erase leaves
//!   of it are records with lower counters, or items that are not intact.
//!
//! A torn item can pass for intact only by matching the length CRC, the data CRC and the record's
//! CRC-32. A load never writes, so a power loss during a boot changes nothing.

use core::fmt;
use core::ops::Range;

use crc::{Algorithm, Crc};

use embedded_storage_async::nor_flash::NorFlash;
use model_core::CalibrationSpec;
use sequential_storage::map::{Key, SerializationError};

use crate::record::{
    decode_record, decode_saved_record, encode_record, RecordError, MAX_RECORD_LEN,
};

/// The key of the earlier firmware's sequential-storage map, whose items are the ones this store
/// reads and writes: with it, a sequential-storage map over the region writes items this store
/// reads (the tests place arbitrary items that way).
///
/// It serialises to no bytes. sequential-storage 8.0.2 slices an item's data by the key length
/// without checking it against the item's (`data[..len][key_len..]` while iterating,
/// `len - key_len` when fetching), so a one-byte key panics on a zero-length item that corrupt
/// flash can hold (found by the `flash_record` fuzz target). A key of no bytes can never be
/// longer than an item.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CalibrationKey;

impl Key for CalibrationKey {
    fn serialize_into(&self, _buffer: &mut [u8]) -> Result<usize, SerializationError> {
        Ok(0)
    }

    fn deserialize_from(_buffer: &[u8]) -> Result<(Self, usize), SerializationError> {
        Ok((CalibrationKey, 0))
    }
}

/// The key of the calibration record.
pub const CALIBRATION_KEY: CalibrationKey = CalibrationKey;

/// The region the STM32F411CE firmware uses: sectors 6 and 7 (2 x 128 KiB, 0x0804_0000 to
/// 0x0807_FFFF) as offsets from the start of flash, which is how embassy-stm32's `Flash`
/// addresses them. The firmware's `memory.x` must then end FLASH at 0x0804_0000 (256 KiB).
pub const STM32F411_CALIBRATION_RANGE: Range<u32> = 0x0004_0000..0x0008_0000;

/// The store works on exactly two pages: one holds the records, the other is erased, ready for
/// the next move.
const PAGE_COUNT: u32 = 2;

/// The largest flash word the header and marker buffers hold (sequential-storage's limit too).
const LARGEST_WORD_SIZE: usize = 32;
/// Data CRC, length and length CRC, before padding to the flash word.
const ITEM_HEADER_LEN: usize = 8;
/// A whole number of words of every supported size that holds the longest record.
const ITEM_BUFFER_LEN: usize = MAX_RECORD_LEN.next_multiple_of(LARGEST_WORD_SIZE);

/// Flash drivers may need word-aligned source buffers.
#[repr(align(4))]
struct ItemBuffer([u8; ITEM_BUFFER_LEN]);

/// Header and marker words, written straight from here (see [`ItemBuffer`]).
#[repr(align(4))]
struct WordBuffer([u8; LARGEST_WORD_SIZE]);

/// Why a flash range cannot hold the calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RegionError {
    /// The range does not start and end on erase-page boundaries.
    NotPageAligned,
    /// The range has fewer than two erase pages (one is always kept erased for the next move).
    TooFewPages,
    /// The range has more than two erase pages: the store's power-loss guarantees are worked out
    /// and tested for two.
    TooManyPages,
    /// An erase page cannot hold its marker words and two items of [`MAX_RECORD_LEN`], the
    /// minimum the earlier firmware's store required, so that both accept the same regions.
    PagesTooSmall,
    /// The flash's write or read size is above 32 bytes.
    WordSizeTooLarge,
    /// The range ends beyond the flash's capacity.
    BeyondFlash,
}

impl fmt::Display for RegionError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = match self {
            RegionError::NotPageAligned => "range not aligned to erase pages",
            RegionError::TooFewPages => "range has fewer than two erase pages",
            RegionError::TooManyPages => "range has more than two erase pages",
            RegionError::PagesTooSmall => "erase page cannot hold two calibration records",
            RegionError::WordSizeTooLarge => "flash word size above 32 bytes",
            RegionError::BeyondFlash => "range ends beyond the flash",
        };
        formatter.write_str(text)
    }
}

impl core::error::Error for RegionError {}

/// Why a save or an erase failed.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreError<E> {
    /// The calibration does not validate (nothing was written).
    Record(RecordError),
    /// The flash driver reported an error.
    Flash(E),
    /// The record read back after writing is missing or differs from what was written.
    VerifyFailed,
}

impl<E: fmt::Debug> fmt::Display for StoreError<E> {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StoreError::Record(error) => write!(formatter, "calibration record: {error}"),
            StoreError::Flash(error) => write!(formatter, "flash: {error:?}"),
            StoreError::VerifyFailed => write!(formatter, "read-back verification failed"),
        }
    }
}

impl<E: fmt::Debug> core::error::Error for StoreError<E> {}

/// Why [`CalibrationStore::load`] found no usable calibration in a region that holds something.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CorruptReason<E> {
    /// An intact item holds no acceptable record (unknown version, CRC, does not parse, does not
    /// validate) and no valid record follows it.
    Record(RecordError),
    /// The region holds written bytes but no intact record: a save torn before its record was
    /// complete, or the only record damaged.
    NoIntactRecord,
    /// Reading the flash failed.
    Flash(E),
    /// An intact item longer than any record, with no valid record after it.
    Storage,
}

/// What [`CalibrationStore::load`] found. Whatever it is, the caller carries on: with the stored
/// calibration, or with the defaults (flagging the hello frame when the flash was corrupt).
#[derive(Debug, Clone, PartialEq)]
#[allow(
    clippy::large_enum_variant,
    reason = "no allocation: the spec is returned by value, once per boot"
)]
pub enum LoadOutcome<E> {
    /// The valid record with the highest save counter.
    Stored(CalibrationSpec),
    /// The region is entirely erased: nothing was ever saved, or it was erased on purpose.
    Absent,
    /// The region holds something, but no calibration that can be used.
    Corrupt(CorruptReason<E>),
}

impl<E> LoadOutcome<E> {
    /// The stored calibration, if there is one.
    pub fn stored(&self) -> Option<&CalibrationSpec> {
        match self {
            LoadOutcome::Stored(spec) => Some(spec),
            LoadOutcome::Absent | LoadOutcome::Corrupt(_) => None,
        }
    }

    /// Whether the flash held something unusable (the hello frame's "defaults after corrupt
    /// flash").
    pub fn is_corrupt(&self) -> bool {
        matches!(self, LoadOutcome::Corrupt(_))
    }
}

#[cfg(feature = "defmt")]
impl<E: defmt::Format> defmt::Format for LoadOutcome<E> {
    fn format(&self, formatter: defmt::Formatter) {
        match self {
            LoadOutcome::Stored(spec) => defmt::write!(formatter, "Stored(id {=u32})", spec.id),
            LoadOutcome::Absent => defmt::write!(formatter, "Absent"),
            LoadOutcome::Corrupt(reason) => defmt::write!(formatter, "Corrupt({})", reason),
        }
    }
}

/// The newest valid record a scan found; its bytes are in the store's `newest` buffer.
#[derive(Debug, Clone, Copy)]
struct NewestRecord {
    save_counter: u32,
    length: usize,
    page: u32,
}

/// What one pass over both pages (page 0 first, each from its start) found.
struct Scan<E> {
    newest: Option<NewestRecord>,
    /// Why an intact item that may be newer than the newest record is unusable: one after it
    /// in its page, or anywhere in a page without a valid record (whose age is unknown).
    /// Set when the scan ends, from the per-page fields below.
    refused_after_newest: Option<CorruptReason<E>>,
    /// Per page, the highest save counter of a valid record in it.
    page_newest: [Option<u32>; PAGE_COUNT as usize],
    /// Per page, why an intact item after the page's highest valid record (or anywhere in a
    /// page without one) is unusable.
    page_refused: [Option<CorruptReason<E>>; PAGE_COUNT as usize],
    /// Per page, where the next item would go: after the last item, or after damage.
    free_start: [u32; PAGE_COUNT as usize],
}

/// The calibration in a flash range of two erase pages.
///
/// `F` is any async NOR flash: embassy-stm32's `Flash` (directly, or blocking through
/// `embassy_embedded_hal::adapter::BlockingAsync`), a `&mut` to one, or `RamFlash`.
pub struct CalibrationStore<F: NorFlash> {
    flash: F,
    range: Range<u32>,
    buffer: ItemBuffer,
    /// The newest record the last scan found.
    newest: ItemBuffer,
}

impl<F: NorFlash> CalibrationStore<F> {
    const WORD_LEN: u32 = if F::WRITE_SIZE > F::READ_SIZE {
        F::WRITE_SIZE
    } else {
        F::READ_SIZE
    } as u32;
    const PAGE_LEN: u32 = F::ERASE_SIZE as u32;
    const HEADER_LEN: u32 = (ITEM_HEADER_LEN as u32).next_multiple_of(Self::WORD_LEN);

    /// A store over `range` (offsets in `flash`'s own address space), checked: page-aligned,
    /// exactly two pages, pages large enough for two records, inside the flash.
    pub fn new(flash: F, range: Range<u32>) -> Result<Self, RegionError> {
        if !range.start.is_multiple_of(Self::PAGE_LEN) || !range.end.is_multiple_of(Self::PAGE_LEN)
        {
            return Err(RegionError::NotPageAligned);
        }
        // Two pages of an erase size near 4 GiB overflow u32: no region can hold them.
        let Some(region_len) = PAGE_COUNT.checked_mul(Self::PAGE_LEN) else {
            return Err(RegionError::BeyondFlash);
        };
        if range.end.saturating_sub(range.start) < region_len {
            return Err(RegionError::TooFewPages);
        }
        if range.end as usize > flash.capacity() {
            return Err(RegionError::BeyondFlash);
        }
        if range.end - range.start > region_len {
            return Err(RegionError::TooManyPages);
        }
        if Self::WORD_LEN as usize > LARGEST_WORD_SIZE {
            return Err(RegionError::WordSizeTooLarge);
        }
        if Self::PAGE_LEN < 2 * Self::WORD_LEN + 2 * Self::item_len(MAX_RECORD_LEN) {
            return Err(RegionError::PagesTooSmall);
        }
        Ok(Self {
            flash,
            range,
            buffer: ItemBuffer([0; ITEM_BUFFER_LEN]),
            newest: ItemBuffer([0; ITEM_BUFFER_LEN]),
        })
    }

    /// The valid record with the highest save counter, or why there is none. Never fails: every
    /// problem is an outcome. Never writes: the next save cleans up whatever a power loss left,
    /// so a power loss during a boot cannot change anything.
    ///
    /// Corrupt rather than a valid record when an intact item after the newest valid record holds
    /// something this firmware refuses (it may be newer); Corrupt rather than Absent when the
    /// region holds anything at all without an intact record (a torn save, a damaged record).
    pub async fn load(&mut self) -> LoadOutcome<F::Error> {
        let scan = match self.scan().await {
            Ok(scan) => scan,
            Err(error) => return LoadOutcome::Corrupt(CorruptReason::Flash(error)),
        };
        if let Some(reason) = scan.refused_after_newest {
            return LoadOutcome::Corrupt(reason);
        }
        if let Some(newest) = scan.newest {
            let bytes = self.newest.0.get(..newest.length).unwrap_or_default();
            return match decode_record(bytes) {
                Ok(spec) => LoadOutcome::Stored(spec),
                Err(error) => LoadOutcome::Corrupt(CorruptReason::Record(error)),
            };
        }
        let mut blank = true;
        for page in 0..PAGE_COUNT {
            match self.is_erased(self.page_range(page)).await {
                Ok(erased) => blank &= erased,
                Err(error) => return LoadOutcome::Corrupt(CorruptReason::Flash(error)),
            }
        }
        if blank {
            LoadOutcome::Absent
        } else {
            LoadOutcome::Corrupt(CorruptReason::NoIntactRecord)
        }
    }

    /// Saves `spec` with the next save counter (the highest in the region plus one, from 0; it
    /// saturates at `u32::MAX`, where the later of equal counters in a page wins) and reads it
    /// back: appended after the newest record when the other page is erased and it fits,
    /// otherwise (or if the appended record does not read back) moved into the other page, the
    /// page of the older records being erased only once the new one reads back. A power loss at
    /// any point leaves the previous or the new calibration.
    pub async fn save(&mut self, spec: &CalibrationSpec) -> Result<(), StoreError<F::Error>> {
        // Scanning writes nothing, so a calibration the model refuses leaves the flash untouched.
        let scan = self.scan().await.map_err(StoreError::Flash)?;
        let save_counter = scan
            .newest
            .map_or(0, |newest| newest.save_counter.saturating_add(1));
        let mut record = [0u8; MAX_RECORD_LEN];
        let record_len =
            encode_record(spec, save_counter, &mut record).map_err(StoreError::Record)?;
        let record = record
            .get(..record_len)
            .ok_or(StoreError::Record(RecordError::BufferTooSmall))?;
        if let Some(newest) = scan.newest {
            let page = newest.page;
            let start = scan
                .free_start
                .get(page as usize)
                .copied()
                .unwrap_or(u32::MAX);
            let end = start.saturating_add(Self::item_len(record_len));
            if end <= self.items_end(page)
                && self
                    .is_erased(self.page_range(other_page(page)))
                    .await
                    .map_err(StoreError::Flash)?
                && self
                    .is_erased(start..end)
                    .await
                    .map_err(StoreError::Flash)?
            {
                self.write_item(start, record).await?;
                if self.reads_back(record, save_counter).await? {
                    return Ok(());
                }
            }
        }
        let target = scan.newest.map_or(0, |newest| other_page(newest.page));
        self.erase_if_written(target).await?;
        let marker = WordBuffer([0; LARGEST_WORD_SIZE]);
        let target_start = self.page_range(target).start;
        write(&mut self.flash, target_start, &marker.0, Self::WORD_LEN).await?;
        self.write_item(target_start + Self::WORD_LEN, record)
            .await?;
        if !self.reads_back(record, save_counter).await? {
            return Err(StoreError::VerifyFailed);
        }
        self.erase_if_written(other_page(target)).await
    }

    /// Erases the whole region: the next [`Self::load`] gives [`LoadOutcome::Absent`].
    pub async fn erase_all(&mut self) -> Result<(), StoreError<F::Error>> {
        self.flash
            .erase(self.range.start, self.range.end)
            .await
            .map_err(StoreError::Flash)
    }

    /// The flash range in use.
    pub fn range(&self) -> Range<u32> {
        self.range.clone()
    }

    /// The flash, for inspection. Changing its content under the store is allowed: the store
    /// keeps no cache.
    pub fn flash(&mut self) -> &mut F {
        &mut self.flash
    }

    /// Gives the flash back.
    pub fn into_flash(self) -> F {
        self.flash
    }

    /// Header and data of an item of `data_len` bytes, in bytes of flash.
    const fn item_len(data_len: usize) -> u32 {
        Self::HEADER_LEN + (data_len as u32).next_multiple_of(Self::WORD_LEN)
    }

    fn page_range(&self, page: u32) -> Range<u32> {
        let start = self.range.start + page * Self::PAGE_LEN;
        start..start + Self::PAGE_LEN
    }

    /// Where items of `page` must end: before its last word (sequential-storage's end marker).
    fn items_end(&self, page: u32) -> u32 {
        self.page_range(page).end - Self::WORD_LEN
    }

    /// Reads every item of both pages, without writing.
    async fn scan(&mut self) -> Result<Scan<F::Error>, F::Error> {
        let mut scan = Scan {
            newest: None,
            refused_after_newest: None,
            page_newest: [None; PAGE_COUNT as usize],
            page_refused: [const { None }; PAGE_COUNT as usize],
            free_start: [0; PAGE_COUNT as usize],
        };
        for page in 0..PAGE_COUNT {
            let end = self.items_end(page);
            let mut address = self.page_range(page).start + Self::WORD_LEN;
            let mut header_buffer = WordBuffer([0; LARGEST_WORD_SIZE]);
            while address.saturating_add(Self::HEADER_LEN) <= end {
                let Some(header) = header_buffer.0.get_mut(..Self::HEADER_LEN as usize) else {
                    break;
                };
                self.flash.read(address, header).await?;
                if header.iter().all(|&byte| byte == 0xFF) {
                    break;
                }
                let [c0, c1, c2, c3, l0, l1, k0, k1, ..] = *header else {
                    break;
                };
                let length = u16::from_le_bytes([l0, l1]);
                let data_address = address + Self::HEADER_LEN;
                // A length read from flash must not wrap the address (a range near 4 GiB).
                let next = address.saturating_add(Self::item_len(length.into()));
                if length_crc(u16::from_le_bytes([l0, l1])) != u16::from_le_bytes([k0, k1])
                    || next > end
                {
                    // A torn or damaged header hides where the next item starts.
                    address += Self::WORD_LEN;
                    continue;
                }
                let data_crc = u32::from_le_bytes([c0, c1, c2, c3]);
                if self
                    .data_intact(data_address, length.into(), data_crc)
                    .await?
                {
                    self.add_item(&mut scan, page, length.into());
                }
                address = next;
            }
            if let Some(free_start) = scan.free_start.get_mut(page as usize) {
                *free_start = address;
            }
        }
        // A page is appended to in order, and the other page holds only older records (a move
        // erases it before writing): so only a refused item after the newest record in its
        // page, or in a page with no valid record to date it, may be newer than the newest.
        scan.refused_after_newest = match scan.newest {
            Some(newest) => {
                let other = other_page(newest.page) as usize;
                let other_undated = scan.page_newest.get(other).is_some_and(Option::is_none);
                let undated = if other_undated {
                    scan.page_refused.get_mut(other).and_then(Option::take)
                } else {
                    None
                };
                let after_newest = scan
                    .page_refused
                    .get_mut(newest.page as usize)
                    .and_then(Option::take);
                after_newest.or(undated)
            }
            None => scan.page_refused.iter_mut().find_map(Option::take),
        };
        Ok(scan)
    }

    /// Whether the `length` bytes at `address` match `expected` (a header's data CRC); they stay
    /// in `self.buffer` when they fit.
    async fn data_intact(
        &mut self,
        address: u32,
        length: usize,
        expected: u32,
    ) -> Result<bool, F::Error> {
        let mut digest = ITEM_DATA_CRC.digest();
        let mut done = 0;
        while done < length {
            let chunk_len = (length - done).min(ITEM_BUFFER_LEN);
            let read_len = chunk_len.next_multiple_of(Self::WORD_LEN as usize);
            let Some(chunk) = self.buffer.0.get_mut(..read_len) else {
                return Ok(false);
            };
            self.flash.read(address + done as u32, chunk).await?;
            digest.update(chunk.get(..chunk_len).unwrap_or_default());
            done += chunk_len;
        }
        Ok(adapted_crc32(digest.finalize()) == expected)
    }

    /// Takes the intact item of `length` bytes in `self.buffer` into account.
    fn add_item(&mut self, scan: &mut Scan<F::Error>, page: u32, length: usize) {
        let Some(value) = self
            .buffer
            .0
            .get(..length)
            .filter(|_| length <= MAX_RECORD_LEN)
        else {
            if let Some(refused) = scan.page_refused.get_mut(page as usize) {
                *refused = Some(CorruptReason::Storage);
            }
            return;
        };
        let record = match decode_saved_record(value) {
            Ok(record) => record,
            Err(error) => {
                if let Some(refused) = scan.page_refused.get_mut(page as usize) {
                    *refused = Some(CorruptReason::Record(error));
                }
                return;
            }
        };
        if let (Some(page_newest), Some(refused)) = (
            scan.page_newest.get_mut(page as usize),
            scan.page_refused.get_mut(page as usize),
        ) {
            if page_newest.is_none_or(|counter| record.save_counter >= counter) {
                *page_newest = Some(record.save_counter);
                *refused = None;
            }
        }
        if scan
            .newest
            .is_none_or(|newest| record.save_counter >= newest.save_counter)
        {
            if let Some(newest) = self.newest.0.get_mut(..length) {
                newest.copy_from_slice(value);
            }
            scan.newest = Some(NewestRecord {
                save_counter: record.save_counter,
                length,
                page,
            });
        }
    }

    /// Whether the whole region now reads `record` (with `save_counter`) as the newest record.
    async fn reads_back(
        &mut self,
        record: &[u8],
        save_counter: u32,
    ) -> Result<bool, StoreError<F::Error>> {
        let scan = self.scan().await.map_err(StoreError::Flash)?;
        Ok(scan.newest.is_some_and(|newest| {
            newest.save_counter == save_counter
                && self.newest.0.get(..newest.length) == Some(record)
        }))
    }

    /// Writes `record` as an item at `address`: header first, then the data.
    async fn write_item(
        &mut self,
        address: u32,
        record: &[u8],
    ) -> Result<(), StoreError<F::Error>> {
        let length = record.len() as u16;
        let mut header = WordBuffer([0xFF; LARGEST_WORD_SIZE]);
        for (byte, value) in header.0.iter_mut().zip(
            adapted_crc32(ITEM_DATA_CRC.checksum(record))
                .to_le_bytes()
                .into_iter()
                .chain(length.to_le_bytes())
                .chain(length_crc(length).to_le_bytes()),
        ) {
            *byte = value;
        }
        write(&mut self.flash, address, &header.0, Self::HEADER_LEN).await?;
        self.buffer.0.fill(0xFF);
        if let Some(data) = self.buffer.0.get_mut(..record.len()) {
            data.copy_from_slice(record);
        }
        let data_len = (record.len() as u32).next_multiple_of(Self::WORD_LEN);
        write(
            &mut self.flash,
            address + Self::HEADER_LEN,
            &self.buffer.0,
            data_len,
        )
        .await
    }

    async fn erase_if_written(&mut self, page: u32) -> Result<(), StoreError<F::Error>> {
        let range = self.page_range(page);
        if self
            .is_erased(range.clone())
            .await
            .map_err(StoreError::Flash)?
        {
            return Ok(());
        }
        self.flash
            .erase(range.start, range.end)
            .await
            .map_err(StoreError::Flash)
    }

    /// Whether every byte of `range` reads erased (0xFF).
    async fn is_erased(&mut self, range: Range<u32>) -> Result<bool, F::Error> {
        let mut address = range.start;
        while address < range.end {
            let length = ITEM_BUFFER_LEN.min((range.end - address) as usize);
            // `length` fits the buffer; were it not, the range would count as written, which
            // costs only an erase or a move.
            let Some(chunk) = self.buffer.0.get_mut(..length) else {
                return Ok(false);
            };
            self.flash.read(address, chunk).await?;
            if chunk.iter().any(|&byte| byte != 0xFF) {
                return Ok(false);
            }
            address += length as u32;
        }
        Ok(true)
    }
}

/// Writes the first `length` bytes of `bytes` at `address`.
async fn write<F: NorFlash>(
    flash: &mut F,
    address: u32,
    bytes: &[u8],
    length: u32,
) -> Result<(), StoreError<F::Error>> {
    let bytes = bytes
        .get(..length as usize)
        .ok_or(StoreError::Record(RecordError::BufferTooSmall))?;
    flash.write(address, bytes).await.map_err(StoreError::Flash)
}

fn other_page(page: u32) -> u32 {
    PAGE_COUNT - 1 - page
}

/// sequential-storage's data CRC: CRC-32C (Castagnoli, reflected) from 0xEEEE_EEEE, inverted.
/// The `crc` crate takes a reflected algorithm's initial value bit-reversed.
const ITEM_DATA_CRC: Crc<u32> = Crc::<u32>::new(&Algorithm {
    width: 32,
    poly: 0x1EDC_6F41,
    init: 0xEEEE_EEEE_u32.reverse_bits(),
    refin: true,
    refout: true,
    xorout: 0xFFFF_FFFF,
    check: 0,
    residue: 0,
});

/// sequential-storage's length CRC: polynomial 0x7458 (0x1A2E reflected) from 0xFFFF, inverted.
const ITEM_LENGTH_CRC: Crc<u16> = Crc::<u16>::new(&Algorithm {
    width: 16,
    poly: 0x7458,
    init: 0xFFFF,
    refin: true,
    refout: true,
    xorout: 0xFFFF,
    check: 0,
    residue: 0,
});

/// The data CRC as sequential-storage writes it: never 0 (an item erased in place), and a first
/// byte that is neither erased nor fully programmed, so a torn header cannot pass for one.
fn adapted_crc32(crc: u32) -> u32 {
    match crc {
        0 => 1,
        value if matches!(value.to_le_bytes(), [0x00 | 0xFF, ..]) => value ^ 1,
        value => value,
    }
}

/// The length CRC as sequential-storage writes it: never 0xFFFF (erased).
fn length_crc(length: u16) -> u16 {
    match ITEM_LENGTH_CRC.checksum(&length.to_le_bytes()) {
        0xFFFF => 0xFFFE,
        value => value,
    }
}
