//! [`CalibrationStore`]: the pads' calibration records in a flash range of two erase pages (the
//! `format` module gives the layout), with the load outcomes the firmware turns into a
//! calibration source.
//!
//! # Saving
//!
//! [`CalibrationStore::save_for`] gives the new record the highest save counter of the current
//! page plus one (0 in a new region), then:
//! - *appends* it after the last record of the current page when it fits in erased space there
//!   and the page holds no torn or damaged record (erasing the other page first if it is not
//!   erased), and checks that every pad loads what it should. Appending keeps sector erases
//!   rare: an F411 128 KiB sector takes 1 to 2 s to erase and wears out after 10 000 erases;
//! - otherwise, or if the appended record does not read back, *moves*: erases the other page
//!   unless it reads erased, writes its header with the next generation, copies every record a
//!   pad still loads once the new one is in (at most one per pad and one for every pad, copied
//!   whole whatever their body), writes the new record, checks that every pad loads from the
//!   new page what it should, writes the commit word, checks the new page is the current one,
//!   and only then erases the page it came from. Before erasing anything it refuses the save
//!   when those records do not fit a page ([`StoreError::Full`]; with the firmware's 128 KiB
//!   pages it cannot happen: ten records take under 7 KiB).
//!
//! So outside a save one page at most holds anything; a move drops records no pad loads any more
//! and torn or damaged ones.
//!
//! # Power loss
//!
//! Only the current page is read, and a save changes it only by writing erased space after its
//! records; every erase is of a page that is not current. So an interrupted operation leaves:
//! - during an append: at most a torn record after the others, which is not intact, so every pad
//!   loads what it did before, or the saved pads the new record once it is whole;
//! - during a move, before the commit word is whole: the same current page as before, whatever
//!   the other page holds (an erase interrupted from its start, from its end or in random bits,
//!   a header, some copies);
//! - once the commit word is whole: the new page, already checked, with a higher generation than
//!   anything an interrupted erase leaves of the old one.
//!
//! A torn record can pass for intact only by matching its length complement and its CRC-32; a
//! torn commit word never reads all zeros. A load never writes, so a power loss during a boot
//! changes nothing. [`CalibrationStore::erase_all`] first makes an empty page current, so an
//! interrupted erase cannot bring back older records either.

use core::fmt;
use core::ops::Range;

use crate::record::PadRecord;
use embedded_storage_async::nor_flash::NorFlash;

use crate::format::{
    encode_page_header, encode_record_header, RecordScope, COMMIT_BYTE, ERASED_BYTE, MAX_PADS,
    PAGE_HEADER_LEN, RECORD_HEADER_LEN, STORE_FORMAT_VERSION,
};
use crate::page::{Expected, Walk, LARGEST_WORD_SIZE, PAGE_COUNT};
use crate::record::{decode_body, encode_body, RecordError, MAX_BODY_LEN};

/// The region the STM32F411CE firmware uses: sectors 6 and 7 (2 x 128 KiB, 0x0804_0000 to
/// 0x0807_FFFF) as offsets from the start of flash, which is how embassy-stm32's `Flash`
/// addresses them. The firmware's `memory.x` must then end FLASH at 0x0804_0000 (256 KiB).
pub const STM32F411_CALIBRATION_RANGE: Range<u32> = 0x0004_0000..0x0008_0000;

/// A whole number of words of every supported size that holds a record header and the longest
/// body.
const RECORD_BUFFER_LEN: usize =
    (LARGEST_WORD_SIZE + MAX_BODY_LEN).next_multiple_of(LARGEST_WORD_SIZE);
/// A whole number of words of every supported size that holds the longest body.
const BODY_BUFFER_LEN: usize = MAX_BODY_LEN.next_multiple_of(LARGEST_WORD_SIZE);

/// Flash drivers may need word-aligned source buffers.
#[repr(align(4))]
struct Aligned<const N: usize>([u8; N]);

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
    /// An erase page cannot hold its header, its commit word and two of the longest records.
    PagesTooSmall,
    /// The flash's word (the larger of its write and read sizes) is above 32 bytes, does not
    /// divide 32, or does not divide the erase page.
    UnsupportedWordSize,
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
            RegionError::UnsupportedWordSize => "flash word size not a divisor of 32 bytes",
            RegionError::BeyondFlash => "range ends beyond the flash",
        };
        formatter.write_str(text)
    }
}

impl core::error::Error for RegionError {}

/// Why a save or an erase failed. Whatever it is, every pad still loads what it loaded before
/// (or, for a failed erase, its calibration or none).
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreError<E> {
    /// The calibration does not validate (nothing was written).
    Record(RecordError),
    /// A pad index of [`MAX_PADS`] or more (nothing was written).
    PadOutOfRange {
        /// The pad index.
        pad: u8,
    },
    /// The flash driver reported an error.
    Flash(E),
    /// What was written does not read back as it should.
    VerifyFailed,
    /// The records other pads still load and the new one do not fit in an erase page (nothing
    /// was written).
    Full,
    /// The current page is of a later format version, which this firmware cannot carry over:
    /// only a save for every pad, which replaces everything, can go over it (nothing was
    /// written).
    Unreadable,
    /// The save counter or the page generation is at its maximum (only damage can get there;
    /// nothing was written).
    Exhausted,
}

impl<E: fmt::Debug> fmt::Display for StoreError<E> {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StoreError::Record(error) => write!(formatter, "calibration record: {error}"),
            StoreError::PadOutOfRange { pad } => {
                write!(
                    formatter,
                    "pad {pad} out of range (at most {MAX_PADS} pads)"
                )
            }
            StoreError::Flash(error) => write!(formatter, "flash: {error:?}"),
            StoreError::VerifyFailed => write!(formatter, "read-back verification failed"),
            StoreError::Full => write!(formatter, "the records do not fit in an erase page"),
            StoreError::Unreadable => write!(
                formatter,
                "flash holds a later firmware's format; save every pad's calibration at once"
            ),
            StoreError::Exhausted => write!(formatter, "save counter exhausted"),
        }
    }
}

impl<E: fmt::Debug> core::error::Error for StoreError<E> {}

/// Why [`CalibrationStore::load`] found no usable calibration in a region that holds something.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CorruptReason<E> {
    /// The pad's newest record is intact but its body is refused (unknown body version, does
    /// not parse, does not validate, longer than this firmware reads).
    Record(RecordError),
    /// No intact record for the pad, and the region holds a torn or damaged record (which may
    /// have been the pad's) or no complete page at all.
    NoIntactRecord,
    /// The current page is of a format version this firmware does not read (a later firmware's).
    UnsupportedFormat {
        /// The page header's format version.
        found: u8,
    },
    /// Reading the flash failed.
    Flash(E),
}

/// What [`CalibrationStore::load`] found. Whatever it is, the caller carries on: with the stored
/// calibration, or with the defaults (flagging the hello frame when the flash was corrupt).
#[derive(Debug, Clone, PartialEq)]
#[allow(
    clippy::large_enum_variant,
    reason = "no allocation: the record is returned by value, once per boot"
)]
pub enum LoadOutcome<E> {
    /// The pad's newest record.
    Stored(PadRecord),
    /// Nothing saved for the pad: the region is erased, or holds only other pads' intact records.
    Absent,
    /// The region holds something, but no calibration for the pad that can be used.
    Corrupt(CorruptReason<E>),
}

impl<E> LoadOutcome<E> {
    /// The stored record, if there is one.
    pub fn stored(&self) -> Option<&PadRecord> {
        match self {
            LoadOutcome::Stored(record) => Some(record),
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
            LoadOutcome::Stored(record) => {
                defmt::write!(formatter, "Stored(id {=u32})", record.calibration.id)
            }
            LoadOutcome::Absent => defmt::write!(formatter, "Absent"),
            LoadOutcome::Corrupt(reason) => defmt::write!(formatter, "Corrupt({})", reason),
        }
    }
}

/// The calibration in a flash range of two erase pages.
///
/// `F` is any async NOR flash: embassy-stm32's `Flash` (directly, or blocking through
/// `embassy_embedded_hal::adapter::BlockingAsync`), a `&mut` to one, or `RamFlash`. The store
/// keeps no cache: every load and save reads the flash again.
pub struct CalibrationStore<F: NorFlash> {
    pub(crate) flash: F,
    pub(crate) range: Range<u32>,
}

impl<F: NorFlash> CalibrationStore<F> {
    /// A store over `range` (offsets in `flash`'s own address space), checked: page-aligned,
    /// exactly two pages, pages large enough for two of the longest records, inside the flash.
    pub fn new(flash: F, range: Range<u32>) -> Result<Self, RegionError> {
        let word = Self::WORD_LEN as usize;
        if word == 0
            || !LARGEST_WORD_SIZE.is_multiple_of(word)
            || !F::ERASE_SIZE.is_multiple_of(word)
            || !F::ERASE_SIZE.is_multiple_of(F::READ_SIZE.max(1))
        {
            return Err(RegionError::UnsupportedWordSize);
        }
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
        let longest = Self::record_span(MAX_BODY_LEN as u16);
        if Self::PAGE_LEN < Self::RECORDS_AT + 2 * longest {
            return Err(RegionError::PagesTooSmall);
        }
        Ok(Self { flash, range })
    }

    /// The calibration of pad `pad`: its newest record, its own or one for every pad, in the
    /// current page, or why there is none. Never fails: every problem is an outcome. Never
    /// writes: the next save cleans up whatever a power loss left, so a power loss during a boot
    /// cannot change anything. A single-pad device loads pad 0.
    pub async fn load(&mut self, pad: u8) -> LoadOutcome<F::Error> {
        match self.try_load(pad).await {
            Ok(outcome) => outcome,
            Err(error) => LoadOutcome::Corrupt(CorruptReason::Flash(error)),
        }
    }

    async fn try_load(&mut self, pad: u8) -> Result<LoadOutcome<F::Error>, F::Error> {
        let Some((page, header)) = self.current_page().await? else {
            let range = self.range.clone();
            return Ok(if self.is_erased(range).await? {
                LoadOutcome::Absent
            } else {
                LoadOutcome::Corrupt(CorruptReason::NoIntactRecord)
            });
        };
        if header.format_version != STORE_FORMAT_VERSION {
            return Ok(LoadOutcome::Corrupt(CorruptReason::UnsupportedFormat {
                found: header.format_version,
            }));
        }
        let walk = self.walk(page).await?;
        let Some(record) = walk.answer(pad) else {
            return Ok(if walk.damaged {
                LoadOutcome::Corrupt(CorruptReason::NoIntactRecord)
            } else {
                LoadOutcome::Absent
            });
        };
        if usize::from(record.body_len) > MAX_BODY_LEN {
            return Ok(LoadOutcome::Corrupt(CorruptReason::Record(
                RecordError::TooLong,
            )));
        }
        let mut body = Aligned([0; BODY_BUFFER_LEN]);
        let Some(body_len) = self.read_body(record.address, &mut body.0).await? else {
            // The flash changed between the walk and this read.
            return Ok(LoadOutcome::Corrupt(CorruptReason::NoIntactRecord));
        };
        Ok(
            match decode_body(body.0.get(..body_len).unwrap_or_default()) {
                Ok(spec) => LoadOutcome::Stored(spec),
                Err(error) => LoadOutcome::Corrupt(CorruptReason::Record(error)),
            },
        )
    }

    /// Saves `record` for every pad (every pad loads it until it gets a newer record of its
    /// own); see [`Self::save_for`].
    pub async fn save(&mut self, record: &PadRecord) -> Result<(), StoreError<F::Error>> {
        self.save_for(RecordScope::EveryPad, record).await
    }

    /// Saves `record` for `scope` with the next save counter and reads it back: appended to the
    /// current page when it fits, otherwise moved into the other page with every record
    /// another pad still loads, the page they came from being erased only once the new page is
    /// complete and reads back (see the module documentation). A power loss at any point leaves
    /// every pad with its previous calibration, or the saved pads with the new one.
    pub async fn save_for(
        &mut self,
        scope: RecordScope,
        spec: &PadRecord,
    ) -> Result<(), StoreError<F::Error>> {
        if let RecordScope::Pad(pad) = scope {
            if pad >= MAX_PADS {
                return Err(StoreError::PadOutOfRange { pad });
            }
        }
        let mut record = Aligned([ERASED_BYTE; RECORD_BUFFER_LEN]);
        let body_at = Self::RECORD_HEADER_SPAN as usize;
        let body_space = record
            .0
            .get_mut(body_at..body_at + MAX_BODY_LEN)
            .ok_or(StoreError::Record(RecordError::BufferTooSmall))?;
        // Nothing is read or written before the calibration validates.
        let body_len = encode_body(spec, body_space).map_err(StoreError::Record)?;
        let current = self.current_page().await.map_err(StoreError::Flash)?;
        let walk = match current {
            None => Walk::default(),
            Some((page, header)) if header.format_version == STORE_FORMAT_VERSION => {
                self.walk(page).await.map_err(StoreError::Flash)?
            }
            // A move would drop the later firmware's records of the pads the save is not for.
            Some(_) if scope != RecordScope::EveryPad => return Err(StoreError::Unreadable),
            Some(_) => Walk::default(),
        };
        let save_counter = match walk.highest {
            None => 0,
            Some(highest) => highest.checked_add(1).ok_or(StoreError::Exhausted)?,
        };
        let body = record
            .0
            .get(body_at..body_at + body_len)
            .ok_or(StoreError::Record(RecordError::BufferTooSmall))?;
        let header = encode_record_header(body, save_counter, scope)
            .ok_or(StoreError::Record(RecordError::BufferTooSmall))?;
        record
            .0
            .get_mut(..RECORD_HEADER_LEN)
            .ok_or(StoreError::Record(RecordError::BufferTooSmall))?
            .copy_from_slice(&header);
        let span = Self::record_span(body_len as u16);
        let record = record
            .0
            .get(..span as usize)
            .ok_or(StoreError::Record(RecordError::BufferTooSmall))?;
        let expected = Expected::after_save(&walk, scope, save_counter);
        if let Some((page, header)) = current {
            if header.format_version == STORE_FORMAT_VERSION
                && !walk.damaged
                && self.append(page, &walk, record, &expected).await?
            {
                return Ok(());
            }
        }
        self.move_records(
            current.map(|(page, header)| (page, header.generation)),
            &walk,
            record,
            &expected,
        )
        .await
    }

    /// Appends `record` to `page` if it fits there in erased space; whether every pad then loads
    /// what `expected` says.
    async fn append(
        &mut self,
        page: u32,
        walk: &Walk,
        record: &[u8],
        expected: &Expected,
    ) -> Result<bool, StoreError<F::Error>> {
        let Some(start) = walk.free_start else {
            return Ok(false);
        };
        let end = start.saturating_add(record.len() as u32);
        if end > self.page_range(page).end
            || !self
                .is_erased(start..end)
                .await
                .map_err(StoreError::Flash)?
        {
            return Ok(false);
        }
        // What a torn move left in the other page: erased now, so that it cannot outlive the
        // current page's records (by damage to the current page's header).
        self.erase_if_written(other_page(page))
            .await
            .map_err(StoreError::Flash)?;
        self.flash
            .write(start, record)
            .await
            .map_err(StoreError::Flash)?;
        let after = self.walk(page).await.map_err(StoreError::Flash)?;
        Ok(expected.holds(&after))
    }

    /// Writes the records of `walk` some pad still loads and `record` into the page after
    /// `current` (page and generation; page 0 when there is none), makes that page current
    /// once they read back, then erases the other page.
    async fn move_records(
        &mut self,
        current: Option<(u32, u32)>,
        walk: &Walk,
        record: &[u8],
        expected: &Expected,
    ) -> Result<(), StoreError<F::Error>> {
        let target = current.map_or(0, |(page, _)| other_page(page));
        let generation = match current {
            None => 0,
            Some((_, generation)) => generation.checked_add(1).ok_or(StoreError::Exhausted)?,
        };
        let copies = expected.live(walk);
        let needed = copies
            .iter()
            .flatten()
            .fold(Self::RECORDS_AT + record.len() as u32, |total, copy| {
                total.saturating_add(Self::record_span(copy.body_len))
            });
        if needed > Self::PAGE_LEN {
            return Err(StoreError::Full);
        }
        self.start_page(target, generation).await?;
        let mut address = self.page_range(target).start + Self::RECORDS_AT;
        for copy in copies.iter().flatten() {
            let span = Self::record_span(copy.body_len);
            self.copy(copy.address, address, span)
                .await
                .map_err(StoreError::Flash)?;
            address += span;
        }
        self.flash
            .write(address, record)
            .await
            .map_err(StoreError::Flash)?;
        // Checked before the commit word: a page that does not read back is never current, and
        // the next save erases it.
        let after = self.walk(target).await.map_err(StoreError::Flash)?;
        if !expected.holds(&after) {
            return Err(StoreError::VerifyFailed);
        }
        self.commit(target).await?;
        for page in (0..PAGE_COUNT).filter(|&page| page != target) {
            self.erase_if_written(page)
                .await
                .map_err(StoreError::Flash)?;
        }
        Ok(())
    }

    /// Erases `page` unless it reads erased, then writes its header with `generation`.
    async fn start_page(&mut self, page: u32, generation: u32) -> Result<(), StoreError<F::Error>> {
        self.erase_if_written(page)
            .await
            .map_err(StoreError::Flash)?;
        let mut bytes = Aligned([ERASED_BYTE; LARGEST_WORD_SIZE]);
        if let Some(header) = bytes.0.get_mut(..PAGE_HEADER_LEN) {
            header.copy_from_slice(&encode_page_header(generation));
        }
        let header = bytes
            .0
            .get(..Self::PAGE_HEADER_SPAN as usize)
            .ok_or(StoreError::VerifyFailed)?;
        let start = self.page_range(page).start;
        self.flash
            .write(start, header)
            .await
            .map_err(StoreError::Flash)
    }

    /// Writes the commit word of `page` and checks that `page` is then the current page.
    async fn commit(&mut self, page: u32) -> Result<(), StoreError<F::Error>> {
        let commit = Aligned([COMMIT_BYTE; LARGEST_WORD_SIZE]);
        let commit = commit
            .0
            .get(..Self::WORD_LEN as usize)
            .ok_or(StoreError::VerifyFailed)?;
        let address = self.page_range(page).start + Self::PAGE_HEADER_SPAN;
        self.flash
            .write(address, commit)
            .await
            .map_err(StoreError::Flash)?;
        match self.current_page().await.map_err(StoreError::Flash)? {
            Some((current, _)) if current == page => Ok(()),
            _ => Err(StoreError::VerifyFailed),
        }
    }

    /// Erases the whole region: the next [`Self::load`] gives [`LoadOutcome::Absent`]. An empty
    /// page is made current first, so that an interrupted erase leaves every pad its
    /// calibration, none, or the defaults flagged as corrupt, never an older calibration.
    pub async fn erase_all(&mut self) -> Result<(), StoreError<F::Error>> {
        let mut order = [0, 1];
        if let Some((page, header)) = self.current_page().await.map_err(StoreError::Flash)? {
            let empty = other_page(page);
            let generation = header
                .generation
                .checked_add(1)
                .ok_or(StoreError::Exhausted)?;
            self.start_page(empty, generation).await?;
            self.commit(empty).await?;
            // The empty page last: while it is complete, nothing else is read.
            order = [page, empty];
        }
        for page in order {
            self.erase_if_written(page)
                .await
                .map_err(StoreError::Flash)?;
        }
        Ok(())
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
}

fn other_page(page: u32) -> u32 {
    PAGE_COUNT - 1 - page
}
