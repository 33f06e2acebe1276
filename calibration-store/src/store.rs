//! [`CalibrationStore`]: the pads' calibration records in a flash range of two erase pages, with
//! the load outcomes the firmware turns into a calibration source.
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
//! - the data of every item is one calibration record ([`crate::encode_scoped_record`]), which
//!   carries its pad (or none: every pad), its save counter and its own CRC-32.
//!
//! An item is intact when both its CRCs match. Reading a page goes from item to item and stops at
//! a header slot that reads erased; a header whose length CRC fails (torn, damaged) hides where the
//! next item starts, so the reader tries again one word further on. The item CRC is what tells a
//! torn or damaged item (skipped) from an intact item whose record this firmware refuses
//! (reported).
//!
//! # Loading
//!
//! Records are for one pad (version 4) or for every pad (version 3, the only kind the
//! single-pad firmware wrote). [`CalibrationStore::load`] reads page 0 then page 1, each from
//! its start, and returns for a pad the valid record with the highest save counter among its
//! own and those for every pad. The current page is the one holding the highest counter (of
//! equal ones, the one with more intact items: a move torn after its last copy leaves copies
//! in the page it was writing and everything in the page it came from). A page is appended to
//! in increasing counters, and the other page holds only older records or copies (a move
//! erases the page it writes to), so an intact item this firmware refuses (unknown version,
//! does not parse or validate) may be newer than a pad's record, and the pad loads
//! [`CorruptReason::Record`] (or [`CorruptReason::Storage`] for an item longer than any
//! record) rather than that record, when it is in the current page, or in a page with no valid
//! record to date it, and no valid record at most as new as the pad's follows it in its page.
//! Its scope cannot be known, so every pad it may be newer than is flagged. A pad with no
//! record loads [`LoadOutcome::Absent`] when other records are intact. Damage to a pad's newest
//! record (not a power loss) brings back the record before it when that one is still in flash,
//! which is the case when the newest was appended.
//!
//! # Saving
//!
//! [`CalibrationStore::save_for`] gives the new record the highest save counter plus one, then:
//! - if the other page is erased and the new item fits in erased space after the last item of
//!   the current page, appends it there; appending keeps sector erases rare (an F411 128 KiB
//!   sector takes 1 to 2 s to erase, and wears out after 10 000 erases);
//! - otherwise, or if the appended record does not read back, moves: erases the other page
//!   unless it reads erased, writes the marker, copies in page order every record a pad still
//!   loads once the new one is in (at most one per pad and one for every pad), writes the new
//!   item, checks that every pad loads from the new page what it should, and only then erases
//!   the page it came from (if the check fails, it erases the new page instead and reports
//!   [`StoreError::VerifyFailed`]). Before erasing anything it refuses the save when those
//!   records do not fit a page ([`StoreError::Full`]; with the firmware's 128 KiB pages it
//!   cannot happen: ten records take under 7 KiB), and when an item this firmware refuses may
//!   be newer than the record of a pad the save is not for ([`StoreError::Unreadable`]): a move
//!   copies only records it reads, so that pad would lose its flag and load an older
//!   calibration. A save for every pad, newer than anything, always may move.
//!
//! So outside a save one page at most holds items; when both do (a save that did not complete, or
//! damage), the next save moves, which cleans up. A move drops records no pad loads any more.
//!
//! # Power loss
//!
//! Each flash operation of a save, interrupted, leaves every pad the save is not for with the
//! record it loaded, and the saved pads with their previous record intact (and still the newest
//! for them) or the new record intact (with a higher counter):
//! - an append writes only erased space after the current page's last item: a torn item there
//!   is skipped;
//! - a move erases and writes only the page that is not current, whatever an interrupted erase
//!   leaves in it (erased from its start, from its end, or random bits); a torn item there is
//!   skipped, and its copies are of the same records with the same counters;
//! - the old page is erased only once every pad reads its record back from the new one: what
//!   an interrupted erase leaves of it are records with lower counters, or copies, or items
//!   that are not intact. One exception: an item this firmware refuses that a move left behind
//!   (it was older than every pad's record) and that an erase torn from the page's end or in
//!   random bits leaves intact alone in its page can no longer be dated, so the pads load the
//!   defaults flagged corrupt until a save for every pad.
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
    decode_record, decode_saved_record, encode_scoped_record, RecordError, RecordScope, MAX_PADS,
    MAX_RECORD_LEN,
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
    /// The records other pads still load and the new one do not fit in an erase page (nothing
    /// was written).
    Full,
    /// The save needs a move, and flash holds a record this firmware cannot read that may be
    /// newer than the calibration of a pad the save is not for: the move would drop it and that
    /// pad would load an older calibration. Nothing was written; a save for every pad, which
    /// is newer than anything, replaces it.
    Unreadable,
}

impl<E: fmt::Debug> fmt::Display for StoreError<E> {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StoreError::Record(error) => write!(formatter, "calibration record: {error}"),
            StoreError::Flash(error) => write!(formatter, "flash: {error:?}"),
            StoreError::VerifyFailed => write!(formatter, "read-back verification failed"),
            StoreError::Full => write!(formatter, "the records do not fit in an erase page"),
            StoreError::Unreadable => write!(
                formatter,
                "flash holds a record this firmware cannot read; save every pad's calibration at once"
            ),
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

/// Scope slots a scan keeps: one per pad, then one for every pad.
const SCOPE_SLOTS: usize = MAX_PADS as usize + 1;
/// The slot of the records for every pad.
const EVERY_PAD_SLOT: usize = MAX_PADS as usize;

/// The scan slot of a record's scope (decoding keeps pad indices below [`MAX_PADS`]).
fn slot(scope: RecordScope) -> usize {
    match scope {
        RecordScope::EveryPad => EVERY_PAD_SLOT,
        RecordScope::Pad(pad) => usize::from(pad).min(EVERY_PAD_SLOT),
    }
}

/// A valid record a scan found.
#[derive(Debug, Clone, Copy)]
struct Located {
    save_counter: u32,
    page: u32,
    /// Where its item (the header) starts.
    address: u32,
    /// The record's length.
    length: usize,
}

/// The last intact item of a page whose record this firmware refuses.
#[derive(Debug)]
struct Refused<E> {
    reason: CorruptReason<E>,
    /// The save counter of the first valid record after it in its page, which is newer than it
    /// (a page is appended to in order); none if no valid record follows it.
    counter_after: Option<u32>,
}

/// What one pass over both pages (page 0 first, each from its start) found.
struct Scan<E> {
    /// Per scope (pads 0 to 7, then every pad) and page, the valid record with the highest save
    /// counter in that page (of equal counters, the later).
    records: [[Option<Located>; PAGE_COUNT as usize]; SCOPE_SLOTS],
    /// The current page: the one with the highest save counter. The other page holds only older
    /// records, or copies of the current page's (a move erases the page it writes to, copies
    /// in page order, and erases the page it came from once everything reads back). Of pages
    /// with equal highest counters (a move torn after its last copy), the one with more intact
    /// items: the page copied from holds everything the copies do.
    current: Option<u32>,
    /// Per page, the highest save counter of a valid record in it.
    page_newest: [Option<u32>; PAGE_COUNT as usize],
    /// Per page, its intact items.
    page_items: [u32; PAGE_COUNT as usize],
    /// Per page, its last intact item that holds no usable record.
    page_refused: [Option<Refused<E>>; PAGE_COUNT as usize],
    /// Per page, where the next item would go: after the last item, or after damage.
    free_start: [u32; PAGE_COUNT as usize],
}

impl<E> Scan<E> {
    /// The highest save counter in the region.
    fn highest_counter(&self) -> Option<u32> {
        self.page_newest.iter().flatten().copied().max()
    }

    /// Chooses the current page once both pages are read.
    fn choose_current_page(&mut self) {
        let [first, second] = self.page_newest;
        let [first_items, second_items] = self.page_items;
        self.current = match (first, second) {
            (None, None) => None,
            (Some(_), None) => Some(0),
            (None, Some(_)) => Some(1),
            (Some(first), Some(second)) if first > second => Some(0),
            (Some(first), Some(second)) if first == second && first_items > second_items => Some(0),
            (Some(_), Some(_)) => Some(1),
        };
    }

    /// The newest record of scope slot `slot`, in `page` only if given (of equal counters in
    /// both pages, the current page's).
    fn newest(&self, slot: usize, page: Option<u32>) -> Option<Located> {
        let [first, second] = self.records.get(slot).copied().unwrap_or_default();
        match page {
            Some(0) => first,
            Some(_) => second,
            None => match (first, second) {
                (Some(first), Some(second)) => Some(
                    if first.save_counter > second.save_counter
                        || (first.save_counter == second.save_counter && self.current == Some(0))
                    {
                        first
                    } else {
                        second
                    },
                ),
                (first, second) => first.or(second),
            },
        }
    }

    /// The record `pad` loads (from `page` only if given): the newer of its own newest record
    /// and the newest record for every pad (its own when the counters are equal). Only records
    /// for every pad apply to pads of index [`MAX_PADS`] or more.
    fn answer(&self, pad: u8, page: Option<u32>) -> Option<Located> {
        let own = if pad < MAX_PADS {
            self.newest(usize::from(pad), page)
        } else {
            None
        };
        let every = self.newest(EVERY_PAD_SLOT, page);
        match (own, every) {
            (Some(own), Some(every)) if every.save_counter > own.save_counter => Some(every),
            (own, every) => own.or(every),
        }
    }

    /// The page of a refused item that may be newer than a pad's record of save counter
    /// `answer` (or than no record): one in the current page, or in a page with no valid record
    /// to date it, unless a valid record no newer than the answer follows it in its page.
    fn refusal_page(&self, answer: Option<u32>) -> Option<usize> {
        (0..PAGE_COUNT as usize).find(|&page| {
            let dated_other = self.current.is_some_and(|current| current as usize != page)
                && self.page_newest.get(page).is_some_and(Option::is_some);
            let refused = self.page_refused.get(page).and_then(Option::as_ref);
            !dated_other
                && refused.is_some_and(|refused| match (answer, refused.counter_after) {
                    (Some(answer), Some(after)) => after > answer,
                    _ => true,
                })
        })
    }
}

/// One step of a walk through a page.
enum ItemStep {
    /// The header slot reads erased: no item here or after.
    End,
    /// The header is torn or damaged: where the next item starts is unknown.
    Damaged,
    /// An item of `length` bytes of data, intact or not, whose data (when intact and no longer
    /// than the buffer) is in the store's buffer; the next item starts at `next`.
    Item {
        length: usize,
        intact: bool,
        next: u32,
    },
}

/// The calibration in a flash range of two erase pages.
///
/// `F` is any async NOR flash: embassy-stm32's `Flash` (directly, or blocking through
/// `embassy_embedded_hal::adapter::BlockingAsync`), a `&mut` to one, or `RamFlash`.
pub struct CalibrationStore<F: NorFlash> {
    flash: F,
    range: Range<u32>,
    buffer: ItemBuffer,
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
        })
    }

    /// The calibration of pad `pad`: the valid record with the highest save counter among its
    /// own records and the records for every pad, or why there is none. Never fails: every
    /// problem is an outcome. Never writes: the next save cleans up whatever a power loss left,
    /// so a power loss during a boot cannot change anything.
    ///
    /// Corrupt rather than a valid record when an intact item that may be newer holds something
    /// this firmware refuses (see the module documentation); Corrupt rather than Absent when the
    /// region holds anything at all without an intact record (a torn save, a damaged record).
    /// A single-pad device loads pad 0.
    pub async fn load(&mut self, pad: u8) -> LoadOutcome<F::Error> {
        let mut scan = match self.scan().await {
            Ok(scan) => scan,
            Err(error) => return LoadOutcome::Corrupt(CorruptReason::Flash(error)),
        };
        let answer = scan.answer(pad, None);
        if let Some(page) = scan.refusal_page(answer.map(|record| record.save_counter)) {
            if let Some(refused) = scan.page_refused.get_mut(page).and_then(Option::take) {
                return LoadOutcome::Corrupt(refused.reason);
            }
        }
        if let Some(record) = answer {
            return match self.read_item(record.address, u32::MAX).await {
                Err(error) => LoadOutcome::Corrupt(CorruptReason::Flash(error)),
                Ok(ItemStep::Item {
                    length,
                    intact: true,
                    ..
                }) => match decode_record(self.buffer.0.get(..length).unwrap_or_default()) {
                    Ok(spec) => LoadOutcome::Stored(spec),
                    Err(error) => LoadOutcome::Corrupt(CorruptReason::Record(error)),
                },
                // The flash changed between the scan and this read.
                Ok(_) => LoadOutcome::Corrupt(CorruptReason::NoIntactRecord),
            };
        }
        if scan.current.is_some() {
            // Other pads' records are intact: nothing was saved for this one (what else the
            // region holds is a save torn before its record was complete, or damage).
            return LoadOutcome::Absent;
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

    /// Saves `spec` for every pad (a version-3 record: every pad loads it until it gets a newer
    /// record of its own); see [`Self::save_for`].
    pub async fn save(&mut self, spec: &CalibrationSpec) -> Result<(), StoreError<F::Error>> {
        self.save_for(RecordScope::EveryPad, spec).await
    }

    /// Saves `spec` for `scope` with the next save counter (the highest in the region plus one,
    /// from 0; it saturates at `u32::MAX`, where the later of equal counters in a page wins) and
    /// reads it back: appended after the newest record when the other page is erased and it
    /// fits, otherwise (or if the appended record does not read back) moved into the other page
    /// with every record another pad still loads, the page they came from being erased only once
    /// all of them read back. A power loss at any point leaves every pad with its previous
    /// calibration, or the saved pads with the new one.
    pub async fn save_for(
        &mut self,
        scope: RecordScope,
        spec: &CalibrationSpec,
    ) -> Result<(), StoreError<F::Error>> {
        // Scanning writes nothing, so a calibration the model refuses leaves the flash untouched.
        let scan = self.scan().await.map_err(StoreError::Flash)?;
        let save_counter = scan
            .highest_counter()
            .map_or(0, |highest| highest.saturating_add(1));
        let mut record = [0u8; MAX_RECORD_LEN];
        let record_len = encode_scoped_record(scope, spec, save_counter, &mut record)
            .map_err(StoreError::Record)?;
        let record = record
            .get(..record_len)
            .ok_or(StoreError::Record(RecordError::BufferTooSmall))?;
        let expected = Expected::after_save(&scan, scope, save_counter);
        if let Some(page) = scan.current {
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
                if self.reads_back(record, scope, &expected, None).await? {
                    return Ok(());
                }
            }
        }
        // A move keeps only records this firmware reads: refused items go with the pages it
        // erases. So it must not move while one may be newer than the record of a pad the
        // save is not for (that pad would silently load an older calibration).
        let keeps_flag = (0..MAX_PADS).any(|pad| {
            !scope.covers(pad)
                && scan
                    .refusal_page(scan.answer(pad, None).map(|record| record.save_counter))
                    .is_some()
        });
        if keeps_flag {
            return Err(StoreError::Unreadable);
        }
        let target = scan.current.map_or(0, other_page);
        let (copies, copy_count) = copies(&scan, &expected);
        let copies = copies.get(..copy_count).unwrap_or_default();
        let target_start = self.page_range(target).start;
        let needed = copies
            .iter()
            .flatten()
            .fold(Self::item_len(record_len), |total, record| {
                total.saturating_add(Self::item_len(record.length))
            });
        if (target_start + Self::WORD_LEN).saturating_add(needed) > self.items_end(target) {
            return Err(StoreError::Full);
        }
        self.erase_if_written(target).await?;
        let marker = WordBuffer([0; LARGEST_WORD_SIZE]);
        write(&mut self.flash, target_start, &marker.0, Self::WORD_LEN).await?;
        let mut address = target_start + Self::WORD_LEN;
        let mut copied = true;
        for record in copies.iter().flatten() {
            let step = self
                .read_item(record.address, u32::MAX)
                .await
                .map_err(StoreError::Flash)?;
            let ItemStep::Item {
                length,
                intact: true,
                ..
            } = step
            else {
                // Changed since the scan.
                copied = false;
                break;
            };
            self.write_buffered_item(address, length).await?;
            address = address.saturating_add(Self::item_len(length));
        }
        if copied {
            self.write_item(address, record).await?;
        }
        if !copied
            || !self
                .reads_back(record, scope, &expected, Some(target))
                .await?
        {
            // Undone, so that the page with every record stays the current one.
            self.erase_if_written(target).await?;
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
            records: [[None; PAGE_COUNT as usize]; SCOPE_SLOTS],
            current: None,
            page_newest: [None; PAGE_COUNT as usize],
            page_items: [0; PAGE_COUNT as usize],
            page_refused: [const { None }; PAGE_COUNT as usize],
            free_start: [0; PAGE_COUNT as usize],
        };
        for page in 0..PAGE_COUNT {
            let end = self.items_end(page);
            let mut address = self.page_range(page).start + Self::WORD_LEN;
            while address.saturating_add(Self::HEADER_LEN) <= end {
                match self.read_item(address, end).await? {
                    ItemStep::End => break,
                    // A torn or damaged header hides where the next item starts.
                    ItemStep::Damaged => address += Self::WORD_LEN,
                    ItemStep::Item {
                        length,
                        intact,
                        next,
                    } => {
                        if intact {
                            self.add_item(&mut scan, page, address, length);
                        }
                        address = next;
                    }
                }
            }
            if let Some(free_start) = scan.free_start.get_mut(page as usize) {
                *free_start = address;
            }
        }
        scan.choose_current_page();
        Ok(scan)
    }

    /// Reads the item whose header is at `address` and which must end by `end`: its data goes
    /// into `self.buffer` when it fits.
    async fn read_item(&mut self, address: u32, end: u32) -> Result<ItemStep, F::Error> {
        let mut header_buffer = WordBuffer([0; LARGEST_WORD_SIZE]);
        let Some(header) = header_buffer.0.get_mut(..Self::HEADER_LEN as usize) else {
            return Ok(ItemStep::End);
        };
        self.flash.read(address, header).await?;
        if header.iter().all(|&byte| byte == 0xFF) {
            return Ok(ItemStep::End);
        }
        let [c0, c1, c2, c3, l0, l1, k0, k1, ..] = *header else {
            return Ok(ItemStep::End);
        };
        let length = u16::from_le_bytes([l0, l1]);
        // A length read from flash must not wrap the address (a range near 4 GiB).
        let next = address.saturating_add(Self::item_len(length.into()));
        if length_crc(length) != u16::from_le_bytes([k0, k1]) || next > end {
            return Ok(ItemStep::Damaged);
        }
        let data_crc = u32::from_le_bytes([c0, c1, c2, c3]);
        let intact = self
            .data_intact(address + Self::HEADER_LEN, length.into(), data_crc)
            .await?;
        Ok(ItemStep::Item {
            length: length.into(),
            intact,
            next,
        })
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

    /// Takes the intact item at `address` of `length` bytes in `self.buffer` into account.
    fn add_item(&mut self, scan: &mut Scan<F::Error>, page: u32, address: u32, length: usize) {
        if let Some(items) = scan.page_items.get_mut(page as usize) {
            *items += 1;
        }
        let decoded = match self
            .buffer
            .0
            .get(..length)
            .filter(|_| length <= MAX_RECORD_LEN)
        {
            Some(value) => decode_saved_record(value).map_err(CorruptReason::Record),
            None => Err(CorruptReason::Storage),
        };
        let record = match decoded {
            Ok(record) => record,
            Err(reason) => {
                if let Some(refused) = scan.page_refused.get_mut(page as usize) {
                    *refused = Some(Refused {
                        reason,
                        counter_after: None,
                    });
                }
                return;
            }
        };
        let located = Located {
            save_counter: record.save_counter,
            page,
            address,
            length,
        };
        if let Some(Some(refused)) = scan.page_refused.get_mut(page as usize) {
            refused.counter_after.get_or_insert(record.save_counter);
        }
        if let Some(page_newest) = scan.page_newest.get_mut(page as usize) {
            *page_newest = Some(page_newest.map_or(record.save_counter, |counter| {
                counter.max(record.save_counter)
            }));
        }
        let kept = scan
            .records
            .get_mut(slot(record.scope))
            .and_then(|pages| pages.get_mut(page as usize));
        if let Some(kept) = kept {
            if kept.is_none_or(|kept| record.save_counter >= kept.save_counter) {
                *kept = Some(located);
            }
        }
    }

    /// Whether the region now reads as `expected` after saving `record` for `scope`: every pad
    /// loads the record it should, `record` is the newest for its scope, and, after a move into
    /// `moved_to`, every record a pad loads is there.
    async fn reads_back(
        &mut self,
        record: &[u8],
        scope: RecordScope,
        expected: &Expected,
        moved_to: Option<u32>,
    ) -> Result<bool, StoreError<F::Error>> {
        let scan = self.scan().await.map_err(StoreError::Flash)?;
        for pad in 0..MAX_PADS {
            let answer = scan.answer(pad, moved_to);
            if !expected.holds(pad, answer.map(|record| record.save_counter)) {
                return Ok(false);
            }
        }
        let Some(saved) = scan.newest(slot(scope), moved_to) else {
            return Ok(false);
        };
        match self
            .read_item(saved.address, u32::MAX)
            .await
            .map_err(StoreError::Flash)?
        {
            ItemStep::Item {
                length,
                intact: true,
                ..
            } => Ok(self.buffer.0.get(..length) == Some(record)),
            _ => Ok(false),
        }
    }

    /// Writes `record` as an item at `address`: header first, then the data.
    async fn write_item(
        &mut self,
        address: u32,
        record: &[u8],
    ) -> Result<(), StoreError<F::Error>> {
        self.buffer
            .0
            .get_mut(..record.len())
            .ok_or(StoreError::Record(RecordError::BufferTooSmall))?
            .copy_from_slice(record);
        self.write_buffered_item(address, record.len()).await
    }

    /// Writes the first `length` bytes of `self.buffer` as an item at `address`: header first,
    /// then the data padded with erased bytes to the flash word.
    async fn write_buffered_item(
        &mut self,
        address: u32,
        length: usize,
    ) -> Result<(), StoreError<F::Error>> {
        let data = self
            .buffer
            .0
            .get(..length)
            .ok_or(StoreError::Record(RecordError::BufferTooSmall))?;
        let length16 = length as u16;
        let mut header = WordBuffer([0xFF; LARGEST_WORD_SIZE]);
        for (byte, value) in header.0.iter_mut().zip(
            adapted_crc32(ITEM_DATA_CRC.checksum(data))
                .to_le_bytes()
                .into_iter()
                .chain(length16.to_le_bytes())
                .chain(length_crc(length16).to_le_bytes()),
        ) {
            *byte = value;
        }
        write(&mut self.flash, address, &header.0, Self::HEADER_LEN).await?;
        if let Some(padding) = self.buffer.0.get_mut(length..) {
            padding.fill(0xFF);
        }
        let data_len = (length as u32).next_multiple_of(Self::WORD_LEN);
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

/// The save counter of the record every pad must load after a save.
struct Expected {
    /// Per pad, the counter it must load (none: no record), or `None` outside when it is not
    /// checked: a pad whose record was only in the page a move erases (flash damaged in its
    /// newer copy) loads what is left.
    counters: [Option<Option<u32>>; MAX_PADS as usize],
}

impl Expected {
    /// What every pad loads once the record of `save_counter` for `scope` is in.
    fn after_save<E>(scan: &Scan<E>, scope: RecordScope, save_counter: u32) -> Self {
        let current_page = scan.current;
        let mut counters = [None; MAX_PADS as usize];
        for (pad, counter) in (0..MAX_PADS).zip(counters.iter_mut()) {
            *counter = if scope.covers(pad) {
                Some(Some(save_counter))
            } else {
                match scan.answer(pad, None) {
                    None => Some(None),
                    Some(answer) if Some(answer.page) == current_page => {
                        Some(Some(answer.save_counter))
                    }
                    Some(_) => None,
                }
            };
        }
        Self { counters }
    }

    /// Whether `pad` loading the record of `counter` (or none) is as expected.
    fn holds(&self, pad: u8, counter: Option<u32>) -> bool {
        match self.counters.get(usize::from(pad)) {
            Some(Some(expected)) => *expected == counter,
            Some(None) | None => true,
        }
    }

    /// Whether some pad must load the record of `counter`.
    fn loads(&self, counter: u32) -> bool {
        self.counters.contains(&Some(Some(counter)))
    }
}

/// The records of the current page a move copies, in page order: every record some pad still
/// loads after the save.
fn copies<E>(scan: &Scan<E>, expected: &Expected) -> ([Option<Located>; SCOPE_SLOTS], usize) {
    let mut copies = [None; SCOPE_SLOTS];
    let mut count = 0;
    let Some(current) = scan.current else {
        return (copies, 0);
    };
    for record in (0..SCOPE_SLOTS).filter_map(|slot| scan.newest(slot, None)) {
        if record.page == current && expected.loads(record.save_counter) {
            if let Some(copy) = copies.get_mut(count) {
                *copy = Some(record);
                count += 1;
            }
        }
    }
    copies
        .get_mut(..count)
        .unwrap_or_default()
        .sort_unstable_by_key(|record| record.map(|record| record.address));
    (copies, count)
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
