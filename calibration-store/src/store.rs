//! [`CalibrationStore`]: the calibration record as one key of a `sequential-storage` map over two
//! flash pages, with the load outcomes the firmware turns into a calibration source.
//!
//! sequential-storage appends every save as a new item (header with a CRC-protected length and a
//! CRC-32 of the data, then the data) and erases a page only after copying the newest item out of
//! it. Its idea of "newest" is positional, and its page states come from marker bytes at both ends
//! of each page, which it expects an interrupted erase to clear from the start of the page. An
//! erase interrupted in another pattern (from the end, or random bits) can leave the half-erased
//! page looking open, partially open or closed, with some older items intact; sequential-storage
//! then takes an older item for the newest, and its repair may erase the page that holds the only
//! copy of the newest record.
//!
//! The store therefore does not rely on position:
//! - every record carries a save counter; [`CalibrationStore::load`] reads, without writing,
//!   every item sequential-storage can see and returns the valid record with the highest counter;
//! - [`CalibrationStore::save`] lets sequential-storage append only from a clean layout: one page
//!   that, read alone, shows the newest record as its last item, and one erased page. Any other
//!   layout is first cleaned by erasing the page that is not needed, which it tells by asking
//!   sequential-storage what the other page alone shows (through `PageView`); if a clean layout
//!   cannot be reached, or appending fails, the new record is written into an erased page on its
//!   own and the other page is erased only once the new record reads back.
//!
//! So at every step of a save some page holds the newest record (or the new one) in a state that
//! sequential-storage reads, and a power loss anywhere leaves the old or the new calibration. The
//! tests tear every operation of a save, with the interrupted erase leaving the page erased from
//! its start, from its end or in random bits, and tear a second save after such a one. Only a
//! layout that damage (not an interrupted operation of this store) produces can leave no page
//! that shows the newest record alone; the save then still succeeds, but a power loss during it
//! may bring back an older record.

use core::fmt;
use core::ops::Range;

use embedded_storage_async::nor_flash::{ErrorType, NorFlash};
use model_core::CalibrationSpec;
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{Key, MapConfig, MapConfigError, MapStorage, SerializationError};

use crate::page_view::{PageView, View, ViewError};
use crate::record::{
    decode_record, decode_saved_record, encode_record, RecordError, MAX_RECORD_LEN,
};

/// The map key of the calibration record, the only kind of item this store writes.
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
/// the next page change.
const PAGE_COUNT: u32 = 2;

const KEY_LEN: usize = 0;
/// sequential-storage supports flash words of up to 32 bytes and reads whole words into the
/// buffer, so key + record rounded up to 32 fits every flash.
const LARGEST_WORD_SIZE: usize = 32;
const ITEM_BUFFER_LEN: usize = (KEY_LEN + MAX_RECORD_LEN).next_multiple_of(LARGEST_WORD_SIZE);

/// Item data is written to flash straight from this buffer; some flash drivers need word-aligned
/// source buffers.
#[repr(align(4))]
struct ItemBuffer([u8; ITEM_BUFFER_LEN]);

type Map<F> =
    MapStorage<CalibrationKey, PageView<F>, Cache<Uncached, Uncached, Uncached, CalibrationKey>>;
type MapError<F> = sequential_storage::Error<ViewError<<F as ErrorType>::Error>>;

/// Why a flash range cannot hold the calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RegionError {
    /// The range does not start and end on erase-page boundaries.
    NotPageAligned,
    /// The range has fewer than two erase pages (one is always kept erased for the next copy).
    TooFewPages,
    /// The range has more than two erase pages: the store's power-loss guarantees are worked out
    /// and tested for two.
    TooManyPages,
    /// An erase page cannot hold two records of [`MAX_RECORD_LEN`] with their headers (the newest
    /// record is copied into a fresh page before the next one is appended).
    PagesTooSmall,
    /// The flash's write or read size is above the 32 bytes sequential-storage supports.
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

impl From<MapConfigError> for RegionError {
    fn from(error: MapConfigError) -> Self {
        match error {
            MapConfigError::StartRangeNotAtPageBoundary
            | MapConfigError::EndRangeNotAtPageBoundary => RegionError::NotPageAligned,
            MapConfigError::RangeTooSmall => RegionError::TooFewPages,
            MapConfigError::PagesTooSmall => RegionError::PagesTooSmall,
            MapConfigError::WordSizeTooLarge => RegionError::WordSizeTooLarge,
        }
    }
}

/// Why a save or an erase failed.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreError<E> {
    /// The calibration does not validate (nothing was written).
    Record(RecordError),
    /// The flash driver reported an error.
    Flash(E),
    /// sequential-storage found the region inconsistent and its repair did not help.
    Layout,
    /// The region cannot hold the record (cannot happen for a range [`CalibrationStore::new`]
    /// accepted).
    NoSpace,
    /// The record read back after writing is missing or differs from what was written.
    VerifyFailed,
    /// sequential-storage failed for another reason (an internal error of that crate).
    Storage,
}

impl<E: fmt::Debug> fmt::Display for StoreError<E> {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StoreError::Record(error) => write!(formatter, "calibration record: {error}"),
            StoreError::Flash(error) => write!(formatter, "flash: {error:?}"),
            StoreError::Layout => write!(formatter, "flash layout corrupt beyond repair"),
            StoreError::NoSpace => write!(formatter, "flash region too small"),
            StoreError::VerifyFailed => write!(formatter, "read-back verification failed"),
            StoreError::Storage => write!(formatter, "sequential-storage internal error"),
        }
    }
}

impl<E: fmt::Debug> core::error::Error for StoreError<E> {}

impl<E> StoreError<E> {
    fn from_map(error: sequential_storage::Error<ViewError<E>>) -> Self {
        match error {
            sequential_storage::Error::Storage {
                value: ViewError::Flash(value),
                ..
            } => StoreError::Flash(value),
            sequential_storage::Error::Corrupted { .. } => StoreError::Layout,
            sequential_storage::Error::FullStorage | sequential_storage::Error::ItemTooBig => {
                StoreError::NoSpace
            }
            _ => StoreError::Storage,
        }
    }
}

/// Why [`CalibrationStore::load`] found no usable calibration in a region that holds something.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CorruptReason<E> {
    /// An intact item holds no acceptable record (unknown version, CRC, does not parse, does not
    /// validate) and no valid record is newer than it.
    Record(RecordError),
    /// The region holds written bytes but no intact record: a save torn before its record was
    /// complete, or the only record damaged.
    NoIntactRecord,
    /// The region's layout is inconsistent and sequential-storage's repair did not fix it; the
    /// next [`CalibrationStore::save`] rewrites the region.
    Layout,
    /// Reading (or repairing) the flash failed.
    Flash(E),
    /// sequential-storage refused the region for another reason (for example an item longer than
    /// any record).
    Storage,
}

impl<E> CorruptReason<E> {
    fn from_map(error: sequential_storage::Error<ViewError<E>>) -> Self {
        match error {
            sequential_storage::Error::Storage {
                value: ViewError::Flash(value),
                ..
            } => CorruptReason::Flash(value),
            // A refused write is sequential-storage trying to repair through the read-only view.
            sequential_storage::Error::Corrupted { .. }
            | sequential_storage::Error::Storage {
                value: ViewError::Refused,
                ..
            } => CorruptReason::Layout,
            _ => CorruptReason::Storage,
        }
    }
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
}

/// What one pass over every calibration item sequential-storage can see found, in its order
/// (oldest page first, each page from its start).
#[derive(Debug, Default)]
struct Scan {
    newest: Option<NewestRecord>,
    /// No calibration item comes after the newest record: sequential-storage's own "latest item"
    /// is that record, so the copy it makes when it changes pages is the newest record.
    newest_is_last: bool,
    /// Why an intact item after the newest record (or anywhere, without one) holds no acceptable
    /// record: something newer than anything readable may be there.
    refused_after_newest: Option<RecordError>,
}

impl Scan {
    fn newest_counter(&self) -> Option<u32> {
        self.newest.map(|newest| newest.save_counter)
    }

    /// Takes one item's value into account; a new newest record is copied into `newest_bytes`.
    fn add(&mut self, value: &[u8], newest_bytes: &mut [u8; ITEM_BUFFER_LEN]) {
        let decoded = decode_saved_record(value);
        let slot = newest_bytes.get_mut(..value.len());
        match (decoded, slot) {
            (Ok(record), Some(slot))
                if self
                    .newest
                    .is_none_or(|newest| record.save_counter >= newest.save_counter) =>
            {
                slot.copy_from_slice(value);
                self.newest = Some(NewestRecord {
                    save_counter: record.save_counter,
                    length: value.len(),
                });
                self.newest_is_last = true;
                self.refused_after_newest = None;
            }
            (Ok(_), _) => self.newest_is_last = false,
            (Err(error), _) => {
                self.newest_is_last = false;
                self.refused_after_newest = Some(error);
            }
        }
    }
}

/// The region after [`CalibrationStore::prune`].
struct Pruned {
    /// An erased page, if there is one.
    erased_page: Option<u32>,
    /// sequential-storage can append from here: both pages erased, or one erased and the other
    /// showing, alone, the newest record as its last item.
    clean: bool,
}

/// The calibration in a flash range of two erase pages.
///
/// `F` is any async NOR flash: embassy-stm32's `Flash` (directly, or blocking through
/// `embassy_embedded_hal::adapter::BlockingAsync`), a `&mut` to one, or `RamFlash`.
pub struct CalibrationStore<F: NorFlash> {
    map: Map<F>,
    item_buffer: ItemBuffer,
    /// The newest record the last scan found.
    newest: ItemBuffer,
}

impl<F: NorFlash> CalibrationStore<F> {
    /// A store over `range` (offsets in `flash`'s own address space), checked: page-aligned,
    /// exactly two pages, pages large enough for two records, inside the flash.
    pub fn new(flash: F, range: Range<u32>) -> Result<Self, RegionError> {
        let config = MapConfig::<PageView<F>>::try_new(range.clone())?;
        if range.end as usize > flash.capacity() {
            return Err(RegionError::BeyondFlash);
        }
        if range.end - range.start > PAGE_COUNT * F::ERASE_SIZE as u32 {
            return Err(RegionError::TooManyPages);
        }
        let word_size = F::WRITE_SIZE.max(F::READ_SIZE);
        let item_len = Map::<F>::item_overhead_size() as usize
            + (KEY_LEN + MAX_RECORD_LEN).next_multiple_of(word_size);
        let page_markers_len = 2 * word_size;
        if F::ERASE_SIZE < page_markers_len + 2 * item_len {
            return Err(RegionError::PagesTooSmall);
        }
        Ok(Self {
            map: MapStorage::new(
                PageView::new(flash, range.start),
                config,
                Cache::new_uncached(),
            ),
            item_buffer: ItemBuffer([0; ITEM_BUFFER_LEN]),
            newest: ItemBuffer([0; ITEM_BUFFER_LEN]),
        })
    }

    /// The valid record with the highest save counter, or why there is none. Never fails: every
    /// problem is an outcome. Never writes: a layout a power loss left behind is cleaned up by the
    /// next save, so a power loss during a boot cannot change anything.
    ///
    /// Corrupt rather than a valid record when an intact item after the newest valid record holds
    /// a record this firmware refuses (it may be newer); Corrupt rather than Absent when the
    /// region holds anything at all without an intact record (a torn save, a damaged record).
    pub async fn load(&mut self) -> LoadOutcome<F::Error> {
        let scan = match self.scan_region().await {
            Ok(scan) => scan,
            Err(error) => return LoadOutcome::Corrupt(CorruptReason::from_map(error)),
        };
        if let Some(error) = scan.refused_after_newest {
            return LoadOutcome::Corrupt(CorruptReason::Record(error));
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
            match self.page_is_erased(page).await {
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

    /// Saves `spec` with the next save counter (the highest in the region plus one, from 0;
    /// it saturates at `u32::MAX`, where equal counters fall back to sequential-storage's order)
    /// and reads it back.
    ///
    /// The page that does not hold the newest record is erased first if it is not erased yet.
    /// From the clean layout (one page showing the newest record as its last item, one erased
    /// page) sequential-storage appends the record. Otherwise, or if appending or the read-back
    /// fails, the record is written alone into the erased page, and the page holding the previous
    /// record is erased only after the new one reads back. A power loss at any point leaves the
    /// previous or the new calibration.
    pub async fn save(&mut self, spec: &CalibrationSpec) -> Result<(), StoreError<F::Error>> {
        let mut record = [0u8; MAX_RECORD_LEN];
        // Reading the newest counter writes nothing, so a calibration the model refuses leaves
        // the flash untouched.
        let newest = self.newest_counter().await?;
        let save_counter = newest.map_or(0, |counter| counter.saturating_add(1));
        let record_len =
            encode_record(spec, save_counter, &mut record).map_err(StoreError::Record)?;
        let record = record
            .get(..record_len)
            .ok_or(StoreError::Record(RecordError::BufferTooSmall))?;
        let pruned = self.prune(newest).await?;
        if pruned.clean && self.append(record, save_counter).await {
            return Ok(());
        }
        self.write_into_erased_page(record, save_counter).await
    }

    /// Erases the whole region: the next [`Self::load`] gives [`LoadOutcome::Absent`].
    pub async fn erase_all(&mut self) -> Result<(), StoreError<F::Error>> {
        self.set_view(View::Whole);
        self.map.erase_all().await.map_err(StoreError::from_map)
    }

    /// The flash range in use.
    pub fn range(&self) -> Range<u32> {
        self.map.flash_range()
    }

    /// The flash, for inspection. Changing its content under the store is allowed: the store
    /// keeps no cache.
    pub fn flash(&mut self) -> &mut F {
        &mut self.map.flash().flash
    }

    /// Gives the flash back.
    pub fn into_flash(self) -> F {
        self.map.destroy().0.flash
    }

    fn set_view(&mut self, view: View) {
        self.map.flash().view = view;
    }

    /// Reads the region without writing: as a whole or, if sequential-storage cannot read it as a
    /// whole (it would first repair a half-erased page), the page that shows the newest record
    /// alone; the error if no page shows a valid record alone either. The newest record's bytes
    /// are then in `self.newest`.
    async fn scan_region(&mut self) -> Result<Scan, MapError<F>> {
        self.set_view(View::ReadOnly);
        let whole = self.scan().await;
        self.set_view(View::Whole);
        let error = match whole {
            Ok(scan) => return Ok(scan),
            Err(
                error @ sequential_storage::Error::Storage {
                    value: ViewError::Flash(_),
                    ..
                },
            ) => return Err(error),
            Err(error) => error,
        };
        let mut best: Option<(u32, Scan)> = None;
        for page in 0..PAGE_COUNT {
            if let Some(scan) = self.scan_one_page(page, 1).await {
                if scan.newest.is_some()
                    && best
                        .as_ref()
                        .is_none_or(|(_, best)| scan.newest_counter() > best.newest_counter())
                {
                    best = Some((page, scan));
                }
            }
        }
        match best {
            // The later scan of the other page may have replaced the record bytes.
            Some((page, _)) if page + 1 < PAGE_COUNT => {
                self.scan_one_page(page, 1).await.ok_or(error)
            }
            Some((_, scan)) => Ok(scan),
            None => Err(error),
        }
    }

    /// Reads every calibration item sequential-storage sees through the current view.
    async fn scan(&mut self) -> Result<Scan, MapError<F>> {
        let mut scan = Scan::default();
        let mut items = self.map.fetch_all_items(&mut self.item_buffer.0).await?;
        while let Some((key, value)) = items.next::<&[u8]>(&mut self.item_buffer.0).await? {
            if key == CALIBRATION_KEY {
                scan.add(value, &mut self.newest.0);
            }
        }
        Ok(scan)
    }

    /// What sequential-storage would see if page `kept` were alone at position `shown_as`, the
    /// other page erased; nothing is written. None if it could not read it (or would have
    /// repaired it).
    async fn scan_one_page(&mut self, kept: u32, shown_as: u32) -> Option<Scan> {
        self.set_view(View::OnePage {
            kept,
            shown_as,
            writable: false,
        });
        let scan = self.scan().await;
        self.set_view(View::Whole);
        scan.ok()
    }

    /// The highest save counter of a valid record in the region; None also when nothing in it can
    /// be read (then every page gets erased before the save).
    async fn newest_counter(&mut self) -> Result<Option<u32>, StoreError<F::Error>> {
        match self.scan_region().await.map_err(StoreError::from_map) {
            Ok(scan) => Ok(scan.newest_counter()),
            Err(StoreError::Flash(error)) => Err(StoreError::Flash(error)),
            Err(_) => Ok(None),
        }
    }

    /// Erases every page the newest record (save counter `newest`) does not need: a page is
    /// erased only if the other page alone still shows a record at least that new. Without a
    /// valid record, every written page is erased.
    async fn prune(&mut self, newest: Option<u32>) -> Result<Pruned, StoreError<F::Error>> {
        let mut erased = [false; PAGE_COUNT as usize];
        for (page, page_erased) in (0..PAGE_COUNT).zip(erased.iter_mut()) {
            *page_erased = self.page_is_erased(page).await.map_err(StoreError::Flash)?;
        }
        for (page, page_erased) in (0..PAGE_COUNT).zip(erased.iter_mut()) {
            if *page_erased {
                continue;
            }
            let other_keeps_newest = match newest {
                None => true,
                Some(counter) => self
                    .scan_one_page(other_page(page), 1)
                    .await
                    .and_then(|scan| scan.newest_counter())
                    .is_some_and(|found| found >= counter),
            };
            if other_keeps_newest {
                self.erase_page(page).await?;
                *page_erased = true;
            }
        }
        let clean = match erased {
            [true, true] => true,
            [true, false] | [false, true] => {
                let kept = if erased[0] { 1 } else { 0 };
                self.scan_one_page(kept, 1).await.is_some_and(|scan| {
                    scan.newest_is_last
                        && scan.refused_after_newest.is_none()
                        && scan.newest_counter() == newest
                })
            }
            [false, false] => false,
        };
        Ok(Pruned {
            erased_page: (0..PAGE_COUNT)
                .zip(erased)
                .find_map(|(page, page_erased)| page_erased.then_some(page)),
            clean,
        })
    }

    /// sequential-storage appends the record to a clean layout; true if it then reads back as the
    /// newest record.
    async fn append(&mut self, record: &[u8], save_counter: u32) -> bool {
        self.set_view(View::Whole);
        let stored = self
            .map
            .store_item(&mut self.item_buffer.0, &CALIBRATION_KEY, &record)
            .await;
        stored.is_ok() && matches!(self.reads_back(record, save_counter).await, Ok(true))
    }

    /// Writes the record alone into an erased page (erasing one first if neither is), reads it
    /// back, and only then erases the other page.
    async fn write_into_erased_page(
        &mut self,
        record: &[u8],
        save_counter: u32,
    ) -> Result<(), StoreError<F::Error>> {
        let newest = self.newest_counter().await?;
        let target = match self.prune(newest).await?.erased_page {
            Some(page) => page,
            None => {
                let target = self.page_without(newest).await;
                self.erase_page(target).await?;
                target
            }
        };
        // sequential-storage sees the erased target as the first page of an empty region and
        // writes a page marker and the record there; the other page is out of its reach.
        self.set_view(View::OnePage {
            kept: target,
            shown_as: 0,
            writable: true,
        });
        let stored = self
            .map
            .store_item(&mut self.item_buffer.0, &CALIBRATION_KEY, &record)
            .await;
        self.set_view(View::Whole);
        stored.map_err(StoreError::from_map)?;
        if !self.reads_back(record, save_counter).await? {
            return Err(StoreError::VerifyFailed);
        }
        self.prune(Some(save_counter)).await?;
        Ok(())
    }

    /// The page to sacrifice when neither page can be erased without losing what the other
    /// shows: the one that, alone, does not show the newest record. No interrupted operation of
    /// this store leads here (every one leaves a page that shows the newest record alone); only
    /// damage to the flash does.
    async fn page_without(&mut self, newest: Option<u32>) -> u32 {
        for page in 0..PAGE_COUNT {
            let shows_newest = self
                .scan_one_page(page, 0)
                .await
                .is_some_and(|scan| scan.newest_counter() >= newest);
            if shows_newest {
                return other_page(page);
            }
        }
        0
    }

    /// Whether the whole region now reads `record` (with `save_counter`) as the newest record.
    async fn reads_back(
        &mut self,
        record: &[u8],
        save_counter: u32,
    ) -> Result<bool, StoreError<F::Error>> {
        let scan = self.scan_region().await.map_err(StoreError::from_map)?;
        Ok(scan.newest.is_some_and(|newest| {
            newest.save_counter == save_counter
                && self.newest.0.get(..newest.length) == Some(record)
        }))
    }

    fn page_range(&self, page: u32) -> Range<u32> {
        let start = self.map.flash_range().start + page * F::ERASE_SIZE as u32;
        start..start + F::ERASE_SIZE as u32
    }

    async fn erase_page(&mut self, page: u32) -> Result<(), StoreError<F::Error>> {
        let range = self.page_range(page);
        self.map
            .flash()
            .flash
            .erase(range.start, range.end)
            .await
            .map_err(StoreError::Flash)
    }

    /// Whether every byte of `page` reads erased (0xFF).
    async fn page_is_erased(&mut self, page: u32) -> Result<bool, F::Error> {
        let range = self.page_range(page);
        let chunk_len = ITEM_BUFFER_LEN - ITEM_BUFFER_LEN % F::READ_SIZE;
        let mut address = range.start;
        while address < range.end {
            let length = chunk_len.min((range.end - address) as usize);
            // `length` is at most `chunk_len`, which fits the buffer; were it not, the page would
            // count as written, which costs only an erase.
            let Some(chunk) = self.item_buffer.0.get_mut(..length) else {
                return Ok(false);
            };
            self.map.flash().flash.read(address, chunk).await?;
            if chunk.iter().any(|&byte| byte != 0xFF) {
                return Ok(false);
            }
            address += length as u32;
        }
        Ok(true)
    }
}

fn other_page(page: u32) -> u32 {
    PAGE_COUNT - 1 - page
}
