//! [`CalibrationStore`]: the calibration record as one key of a `sequential-storage` map over a
//! flash range, with the load outcomes the firmware turns into a calibration source.
//!
//! sequential-storage appends every save as a new item (header with a CRC-protected length and a
//! CRC-32 of the data, then the data) and only erases a page after copying the newest item out of
//! it, so the previous record stays readable until the new one is completely written. A torn or
//! corrupted newest item fails its CRC and is skipped: [`CalibrationStore::load`] then returns the
//! previous record if it is still in flash, or [`LoadOutcome::Absent`] if it is not. Only an
//! intact item whose record is unacceptable, a layout sequential-storage cannot repair, or a
//! flash read error gives [`LoadOutcome::Corrupt`].

use core::fmt;
use core::ops::Range;

use embedded_storage_async::nor_flash::NorFlash;
use model_core::CalibrationSpec;
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapConfigError, MapStorage};

use crate::record::{decode_record, encode_record, RecordError, MAX_RECORD_LEN};

/// The map key of the calibration record (the only key this store writes).
pub const CALIBRATION_KEY: u8 = 0;

/// The region the STM32F411CE firmware uses: sectors 6 and 7 (2 x 128 KiB, 0x0804_0000 to
/// 0x0807_FFFF) as offsets from the start of flash, which is how embassy-stm32's `Flash`
/// addresses them. The firmware's `memory.x` must then end FLASH at 0x0804_0000 (256 KiB).
pub const STM32F411_CALIBRATION_RANGE: Range<u32> = 0x0004_0000..0x0008_0000;

const KEY_LEN: usize = 1;
/// sequential-storage supports flash words of up to 32 bytes and reads whole words into the
/// buffer, so key + record rounded up to 32 fits every flash.
const LARGEST_WORD_SIZE: usize = 32;
const ITEM_BUFFER_LEN: usize = (KEY_LEN + MAX_RECORD_LEN).next_multiple_of(LARGEST_WORD_SIZE);

/// Item data is written to flash straight from this buffer; some flash drivers need word-aligned
/// source buffers.
#[repr(align(4))]
struct ItemBuffer([u8; ITEM_BUFFER_LEN]);

type Map<F> = MapStorage<u8, F, Cache<Uncached, Uncached, Uncached, u8>>;

/// Why a flash range cannot hold the calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RegionError {
    /// The range does not start and end on erase-page boundaries.
    NotPageAligned,
    /// The range has fewer than two erase pages (one is always kept erased for the next copy).
    TooFewPages,
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
    fn from_map(error: sequential_storage::Error<E>) -> Self {
        match error {
            sequential_storage::Error::Storage { value, .. } => StoreError::Flash(value),
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
    /// The newest intact item holds no acceptable record (unknown version, CRC, does not parse,
    /// does not validate).
    Record(RecordError),
    /// The region's layout is inconsistent and sequential-storage's repair did not fix it; the
    /// next [`CalibrationStore::save`] erases and rewrites the region.
    Layout,
    /// Reading (or repairing) the flash failed.
    Flash(E),
    /// sequential-storage refused the region for another reason (for example an item longer than
    /// any record).
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
    /// The newest intact record, validated.
    Stored(CalibrationSpec),
    /// Nothing was ever saved, the region was erased, or no intact record is left (a torn first
    /// save, or the only record corrupted).
    Absent,
    /// The region holds something that cannot be used.
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

/// The calibration in a flash range of at least two erase pages.
///
/// `F` is any async NOR flash: embassy-stm32's `Flash` (directly, or blocking through
/// `embassy_embedded_hal::adapter::BlockingAsync`), a `&mut` to one, or `RamFlash`.
pub struct CalibrationStore<F: NorFlash> {
    map: Map<F>,
    item_buffer: ItemBuffer,
}

impl<F: NorFlash> CalibrationStore<F> {
    /// A store over `range` (offsets in `flash`'s own address space), checked: page-aligned, at
    /// least two pages, pages large enough for two records, inside the flash.
    pub fn new(flash: F, range: Range<u32>) -> Result<Self, RegionError> {
        let config = MapConfig::<F>::try_new(range.clone())?;
        if range.end as usize > flash.capacity() {
            return Err(RegionError::BeyondFlash);
        }
        let word_size = F::WRITE_SIZE.max(F::READ_SIZE);
        let item_len = Map::<F>::item_overhead_size() as usize
            + (KEY_LEN + MAX_RECORD_LEN).next_multiple_of(word_size);
        let page_markers_len = 2 * word_size;
        if F::ERASE_SIZE < page_markers_len + 2 * item_len {
            return Err(RegionError::PagesTooSmall);
        }
        Ok(Self {
            map: MapStorage::new(flash, config, Cache::new_uncached()),
            item_buffer: ItemBuffer([0; ITEM_BUFFER_LEN]),
        })
    }

    /// The newest stored calibration, or why there is none. Never fails: every problem is an
    /// outcome. May write to the flash: sequential-storage finishes or undoes an operation that a
    /// power loss interrupted.
    pub async fn load(&mut self) -> LoadOutcome<F::Error> {
        let fetched = self
            .map
            .fetch_item::<&[u8]>(&mut self.item_buffer.0, &CALIBRATION_KEY)
            .await;
        match fetched {
            Ok(None) => LoadOutcome::Absent,
            Ok(Some(record)) => match decode_record(record) {
                Ok(spec) => LoadOutcome::Stored(spec),
                Err(error) => LoadOutcome::Corrupt(CorruptReason::Record(error)),
            },
            Err(error) => LoadOutcome::Corrupt(match error {
                sequential_storage::Error::Storage { value, .. } => CorruptReason::Flash(value),
                sequential_storage::Error::Corrupted { .. } => CorruptReason::Layout,
                _ => CorruptReason::Storage,
            }),
        }
    }

    /// Saves `spec` as the newest record and reads it back.
    ///
    /// If that fails (a layout sequential-storage cannot repair, a flash error, a read-back
    /// mismatch), the whole region is erased and the record written once more: the region must
    /// not stay unwritable, and the record being replaced is the only thing it holds. A power
    /// loss during that second attempt leaves the region empty ([`LoadOutcome::Absent`]).
    pub async fn save(&mut self, spec: &CalibrationSpec) -> Result<(), StoreError<F::Error>> {
        let mut record = [0u8; MAX_RECORD_LEN];
        let record_len = encode_record(spec, &mut record).map_err(StoreError::Record)?;
        let record = &record[..record_len];
        if self.write_and_verify(record).await.is_ok() {
            return Ok(());
        }
        self.erase_all().await?;
        self.write_and_verify(record).await
    }

    /// Erases the whole region: the next [`Self::load`] gives [`LoadOutcome::Absent`].
    pub async fn erase_all(&mut self) -> Result<(), StoreError<F::Error>> {
        self.map.erase_all().await.map_err(StoreError::from_map)
    }

    /// The flash range in use.
    pub fn range(&self) -> Range<u32> {
        self.map.flash_range()
    }

    /// The flash, for inspection. Changing its content under the store is allowed: the store
    /// keeps no cache.
    pub fn flash(&mut self) -> &mut F {
        self.map.flash()
    }

    /// Gives the flash back.
    pub fn into_flash(self) -> F {
        self.map.destroy().0
    }

    async fn write_and_verify(&mut self, record: &[u8]) -> Result<(), StoreError<F::Error>> {
        self.map
            .store_item(&mut self.item_buffer.0, &CALIBRATION_KEY, &record)
            .await
            .map_err(StoreError::from_map)?;
        let read_back = self
            .map
            .fetch_item::<&[u8]>(&mut self.item_buffer.0, &CALIBRATION_KEY)
            .await
            .map_err(StoreError::from_map)?;
        if read_back == Some(record) {
            Ok(())
        } else {
            Err(StoreError::VerifyFailed)
        }
    }
}
