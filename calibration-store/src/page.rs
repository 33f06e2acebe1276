//! The store's pages in flash: which page is current, what a walk through a page finds, what
//! every pad must load after a save, and the word-aligned reads, copies and erases saving and
//! loading are made of. The format itself is the `format` module's.

use core::ops::Range;

use embedded_storage_async::nor_flash::NorFlash;

use crate::format::{
    decode_page_header, decode_record_header, PageHeader, RecordHeader, RecordScope, RecordSlot,
    COMMIT_BYTE, ERASED_BYTE, MAX_PADS, PAGE_HEADER_LEN, RECORD_HEADER_LEN,
};
use crate::store::CalibrationStore;

/// The store works on exactly two pages: the current one, and one erased for the next move.
pub(crate) const PAGE_COUNT: u32 = 2;
/// The largest flash word supported; every word size must divide it.
pub(crate) const LARGEST_WORD_SIZE: usize = 32;
/// Reads and copies go through this many bytes at a time (a multiple of every word size).
const CHUNK_LEN: usize = 2 * LARGEST_WORD_SIZE;
/// Scope slots a walk keeps: one per pad, then one for every pad.
const SCOPE_SLOTS: usize = MAX_PADS as usize + 1;
/// The slot of the records for every pad, which is also what a pad index of [`MAX_PADS`] or
/// more loads.
const EVERY_PAD_SLOT: usize = MAX_PADS as usize;

/// Flash drivers may need word-aligned buffers.
#[repr(align(4))]
struct Chunk([u8; CHUNK_LEN]);

/// An intact record a walk found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Located {
    pub(crate) save_counter: u32,
    /// Where its header starts.
    pub(crate) address: u32,
    pub(crate) body_len: u16,
}

/// What a walk through a page found.
#[derive(Debug, Default)]
pub(crate) struct Walk {
    /// Per scope slot (pads 0 to 7, then every pad), the intact record with the highest save
    /// counter (of equal ones, the later).
    newest: [Option<Located>; SCOPE_SLOTS],
    /// The highest save counter of an intact record, whatever its scope.
    pub(crate) highest: Option<u32>,
    /// Where the erased space after the last record starts; none if the walk reached the page's
    /// end without finding erased space.
    pub(crate) free_start: Option<u32>,
    /// Whether the page holds a torn or damaged record.
    pub(crate) damaged: bool,
}

impl Walk {
    /// The record `pad` loads: the newer of its own newest record and the newest record for
    /// every pad (its own of equal counters). A pad index of [`MAX_PADS`] or more loads only
    /// records for every pad.
    pub(crate) fn answer(&self, pad: u8) -> Option<Located> {
        let own = self.newest(usize::from(pad).min(EVERY_PAD_SLOT));
        let every = self.newest(EVERY_PAD_SLOT);
        match (own, every) {
            (Some(own), Some(every)) if every.save_counter > own.save_counter => Some(every),
            (own, every) => own.or(every),
        }
    }

    fn newest(&self, slot: usize) -> Option<Located> {
        self.newest.get(slot).copied().flatten()
    }

    fn add(&mut self, header: &RecordHeader, address: u32) {
        let counter = header.save_counter;
        self.highest = Some(self.highest.map_or(counter, |highest| highest.max(counter)));
        // A pad index this firmware does not hold (a later firmware's): no pad loads it.
        let Some(scope) = RecordScope::from_byte(header.pads) else {
            return;
        };
        let slot = match scope {
            RecordScope::EveryPad => EVERY_PAD_SLOT,
            RecordScope::Pad(pad) => usize::from(pad),
        };
        if let Some(newest) = self.newest.get_mut(slot) {
            if newest.is_none_or(|newest| counter >= newest.save_counter) {
                *newest = Some(Located {
                    save_counter: counter,
                    address,
                    body_len: header.body_len,
                });
            }
        }
    }
}

/// The save counter every pad must load after a save (none: no record), for pads 0 to 7 and,
/// last, for any pad index beyond them.
pub(crate) struct Expected([Option<u32>; SCOPE_SLOTS]);

impl Expected {
    /// What every pad loads once the record of `save_counter` for `scope` is in, when `walk`
    /// is what the current page held before.
    pub(crate) fn after_save(walk: &Walk, scope: RecordScope, save_counter: u32) -> Self {
        let mut counters = [None; SCOPE_SLOTS];
        for (pad, counter) in (0..=MAX_PADS).zip(counters.iter_mut()) {
            *counter = if scope.covers(pad) {
                Some(save_counter)
            } else {
                walk.answer(pad).map(|record| record.save_counter)
            };
        }
        Self(counters)
    }

    /// Whether every pad loads from the page `walk` went through what it should.
    pub(crate) fn holds(&self, walk: &Walk) -> bool {
        (0..=MAX_PADS)
            .zip(self.0)
            .all(|(pad, expected)| walk.answer(pad).map(|record| record.save_counter) == expected)
    }

    /// The records of `walk` some pad still loads after the save: what a move copies. A scope's
    /// newest record is loaded by the pad of its slot when nothing newer covers that pad (for
    /// the slot of every pad, by pad indices beyond the last).
    pub(crate) fn live(&self, walk: &Walk) -> [Option<Located>; SCOPE_SLOTS] {
        let mut live = walk.newest;
        for (record, expected) in live.iter_mut().zip(self.0) {
            if record.is_some_and(|record| Some(record.save_counter) != expected) {
                *record = None;
            }
        }
        live
    }
}

impl<F: NorFlash> CalibrationStore<F> {
    /// The flash word: the larger of the read and write sizes.
    pub(crate) const WORD_LEN: u32 = if F::WRITE_SIZE > F::READ_SIZE {
        F::WRITE_SIZE
    } else {
        F::READ_SIZE
    } as u32;
    pub(crate) const PAGE_LEN: u32 = F::ERASE_SIZE as u32;
    pub(crate) const PAGE_HEADER_SPAN: u32 =
        (PAGE_HEADER_LEN as u32).next_multiple_of(Self::WORD_LEN);
    /// Where a page's first record starts, after the header and the commit word.
    pub(crate) const RECORDS_AT: u32 = Self::PAGE_HEADER_SPAN + Self::WORD_LEN;
    pub(crate) const RECORD_HEADER_SPAN: u32 =
        (RECORD_HEADER_LEN as u32).next_multiple_of(Self::WORD_LEN);

    /// Bytes of flash a record with a body of `body_len` bytes takes.
    pub(crate) const fn record_span(body_len: u16) -> u32 {
        Self::RECORD_HEADER_SPAN + (body_len as u32).next_multiple_of(Self::WORD_LEN)
    }

    pub(crate) fn page_range(&self, page: u32) -> Range<u32> {
        let start = self.range.start + page * Self::PAGE_LEN;
        start..start + Self::PAGE_LEN
    }

    /// The current page and its header: the complete page with the highest generation (page 0
    /// of equal ones), if any.
    pub(crate) async fn current_page(&mut self) -> Result<Option<(u32, PageHeader)>, F::Error> {
        let mut current: Option<(u32, PageHeader)> = None;
        for page in 0..PAGE_COUNT {
            if let Some(header) = self.complete_header(page).await? {
                if current.is_none_or(|(_, best)| header.generation > best.generation) {
                    current = Some((page, header));
                }
            }
        }
        Ok(current)
    }

    /// The header of `page` if the page is complete (header intact, commit word written).
    async fn complete_header(&mut self, page: u32) -> Result<Option<PageHeader>, F::Error> {
        let mut chunk = Chunk([0; CHUNK_LEN]);
        let Some(bytes) = chunk.0.get_mut(..Self::RECORDS_AT as usize) else {
            return Ok(None);
        };
        self.flash.read(self.page_range(page).start, bytes).await?;
        let committed = bytes
            .get(Self::PAGE_HEADER_SPAN as usize..)
            .is_some_and(|commit| commit.iter().all(|&byte| byte == COMMIT_BYTE));
        Ok(bytes
            .first_chunk::<PAGE_HEADER_LEN>()
            .and_then(decode_page_header)
            .filter(|_| committed))
    }

    /// Goes through the records of `page`, checking every CRC, without writing.
    pub(crate) async fn walk(&mut self, page: u32) -> Result<Walk, F::Error> {
        let range = self.page_range(page);
        let mut walk = Walk::default();
        let mut address = range.start + Self::RECORDS_AT;
        while address.saturating_add(Self::RECORD_HEADER_SPAN) <= range.end {
            match self.read_slot(address).await? {
                RecordSlot::Erased => {
                    walk.free_start = Some(address);
                    break;
                }
                RecordSlot::Damaged => {
                    walk.damaged = true;
                    address += Self::WORD_LEN;
                }
                RecordSlot::Header(header) => {
                    let end = address.saturating_add(Self::record_span(header.body_len));
                    if end > range.end {
                        walk.damaged = true;
                        address += Self::WORD_LEN;
                        continue;
                    }
                    if self.intact(address, &header).await? {
                        walk.add(&header, address);
                    } else {
                        walk.damaged = true;
                    }
                    address = end;
                }
            }
        }
        Ok(walk)
    }

    async fn read_slot(&mut self, address: u32) -> Result<RecordSlot, F::Error> {
        let mut chunk = Chunk([0; CHUNK_LEN]);
        let Some(bytes) = chunk.0.get_mut(..Self::RECORD_HEADER_SPAN as usize) else {
            return Ok(RecordSlot::Damaged);
        };
        self.flash.read(address, bytes).await?;
        Ok(bytes
            .first_chunk::<RECORD_HEADER_LEN>()
            .map_or(RecordSlot::Damaged, decode_record_header))
    }

    /// Whether the body of the record whose header `header` is at `address` matches its CRC.
    async fn intact(&mut self, address: u32, header: &RecordHeader) -> Result<bool, F::Error> {
        let mut digest = header.digest();
        let mut chunk = Chunk([0; CHUNK_LEN]);
        let body_start = address + Self::RECORD_HEADER_SPAN;
        let body_len = u32::from(header.body_len);
        let mut done = 0;
        while done < body_len {
            let part_len = (body_len - done).min(CHUNK_LEN as u32);
            let Some(bytes) = chunk
                .0
                .get_mut(..part_len.next_multiple_of(Self::WORD_LEN) as usize)
            else {
                return Ok(false);
            };
            self.flash.read(body_start + done, bytes).await?;
            digest.update(bytes.get(..part_len as usize).unwrap_or_default());
            done += part_len;
        }
        Ok(header.matches(digest))
    }

    /// Reads the body of the record at `address` into `body` and returns its length, if the
    /// record is intact and its body fits.
    pub(crate) async fn read_body(
        &mut self,
        address: u32,
        body: &mut [u8],
    ) -> Result<Option<usize>, F::Error> {
        let RecordSlot::Header(header) = self.read_slot(address).await? else {
            return Ok(None);
        };
        let body_len = usize::from(header.body_len);
        let read_len = body_len.next_multiple_of(Self::WORD_LEN as usize);
        let Some(bytes) = body.get_mut(..read_len) else {
            return Ok(None);
        };
        self.flash
            .read(address + Self::RECORD_HEADER_SPAN, bytes)
            .await?;
        let mut digest = header.digest();
        digest.update(bytes.get(..body_len).unwrap_or_default());
        Ok(header.matches(digest).then_some(body_len))
    }

    /// Copies `length` bytes (a whole number of words) from `from` to the erased `to`.
    pub(crate) async fn copy(&mut self, from: u32, to: u32, length: u32) -> Result<(), F::Error> {
        let mut chunk = Chunk([0; CHUNK_LEN]);
        let mut done = 0;
        while done < length {
            let part_len = (length - done).min(CHUNK_LEN as u32);
            let Some(bytes) = chunk.0.get_mut(..part_len as usize) else {
                return Ok(());
            };
            self.flash.read(from + done, bytes).await?;
            self.flash.write(to + done, bytes).await?;
            done += part_len;
        }
        Ok(())
    }

    /// Whether every byte of `range` (whole words) reads erased.
    pub(crate) async fn is_erased(&mut self, range: Range<u32>) -> Result<bool, F::Error> {
        let mut chunk = Chunk([0; CHUNK_LEN]);
        let mut address = range.start;
        while address < range.end {
            let part_len = (range.end - address).min(CHUNK_LEN as u32);
            let Some(bytes) = chunk.0.get_mut(..part_len as usize) else {
                return Ok(false);
            };
            self.flash.read(address, bytes).await?;
            if bytes.iter().any(|&byte| byte != ERASED_BYTE) {
                return Ok(false);
            }
            address += part_len;
        }
        Ok(true)
    }

    /// Erases `page` unless it reads erased already (an erase stalls the MCU and wears the
    /// sector).
    pub(crate) async fn erase_if_written(&mut self, page: u32) -> Result<(), F::Error> {
        let range = self.page_range(page);
        if self.is_erased(range.clone()).await? {
            return Ok(());
        }
        self.flash.erase(range.start, range.end).await
    }
}
