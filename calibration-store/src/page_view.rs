//! [`PageView`]: the flash as the store lets sequential-storage see its two pages, so that the
//! store can ask "what would sequential-storage find if only this page were left?" before it
//! erases the other one, and can write a fresh copy into one erased page without sequential-storage
//! touching the other.
//!
//! The view changes nothing in the flash; it only translates addresses inside the region, answers
//! reads of a hidden page with erased bytes, and refuses what the mode does not allow.

use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// How sequential-storage sees the region.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum View {
    /// The region as it is: every operation goes through unchanged.
    Whole,
    /// The region as it is, read-only: writes and erases are refused.
    ReadOnly,
    /// Page `kept` alone, shown as page `shown_as` (0 or 1); the other page reads as erased and
    /// can be neither written nor erased. With `writable`, writes to `kept` go through; erases
    /// are always refused.
    OnePage {
        /// The real page (0 or 1) that stays visible.
        kept: u32,
        /// Where sequential-storage sees it (0 or 1).
        shown_as: u32,
        /// Whether writes to it are allowed.
        writable: bool,
    },
}

/// Why an operation through the view failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ViewError<E> {
    /// The flash driver reported an error.
    Flash(E),
    /// The view does not allow the operation (a write or an erase while probing).
    Refused,
}

impl<E: NorFlashError> NorFlashError for ViewError<E> {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            ViewError::Flash(error) => error.kind(),
            ViewError::Refused => NorFlashErrorKind::Other,
        }
    }
}

/// A flash seen through a [`View`] of the two-page region starting at `region_start`.
pub(crate) struct PageView<F> {
    pub(crate) flash: F,
    region_start: u32,
    pub(crate) view: View,
}

/// Where a run of bytes of the view is in the real flash.
enum Location {
    /// At this real address.
    Real(u32),
    /// In the hidden page.
    Hidden,
}

impl<F: NorFlash> PageView<F> {
    /// The whole region starting at `region_start`, seen as it is.
    pub(crate) fn new(flash: F, region_start: u32) -> Self {
        Self {
            flash,
            region_start,
            view: View::Whole,
        }
    }

    const PAGE_LEN: u32 = F::ERASE_SIZE as u32;

    /// Where `offset` of the view is, and how many bytes from there stay in the same page.
    fn locate(&self, offset: u32, length: usize) -> (Location, usize) {
        let View::OnePage { kept, shown_as, .. } = self.view else {
            return (Location::Real(offset), length);
        };
        let Some(relative) = offset.checked_sub(self.region_start) else {
            return (Location::Real(offset), length);
        };
        let page = relative / Self::PAGE_LEN;
        let within_page = relative % Self::PAGE_LEN;
        let run = length.min((Self::PAGE_LEN - within_page) as usize);
        let location = if page == shown_as {
            Location::Real(self.region_start + kept * Self::PAGE_LEN + within_page)
        } else if page < 2 {
            Location::Hidden
        } else {
            Location::Real(offset)
        };
        (location, run)
    }
}

impl<F: NorFlash> ErrorType for PageView<F> {
    type Error = ViewError<F::Error>;
}

impl<F: NorFlash> ReadNorFlash for PageView<F> {
    const READ_SIZE: usize = F::READ_SIZE;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let mut offset = offset;
        let mut rest = bytes;
        while !rest.is_empty() {
            let (location, run) = self.locate(offset, rest.len());
            let (chunk, tail) = rest.split_at_mut(run);
            match location {
                Location::Real(address) => self
                    .flash
                    .read(address, chunk)
                    .await
                    .map_err(ViewError::Flash)?,
                Location::Hidden => chunk.fill(0xFF),
            }
            offset += run as u32;
            rest = tail;
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.flash.capacity()
    }
}

impl<F: NorFlash> NorFlash for PageView<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        match self.view {
            View::Whole => self.flash.erase(from, to).await.map_err(ViewError::Flash),
            View::ReadOnly | View::OnePage { .. } => Err(ViewError::Refused),
        }
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let writable = match self.view {
            View::Whole => true,
            View::ReadOnly => false,
            View::OnePage { writable, .. } => writable,
        };
        match self.locate(offset, bytes.len()) {
            (Location::Real(address), run) if writable && run == bytes.len() => self
                .flash
                .write(address, bytes)
                .await
                .map_err(ViewError::Flash),
            _ => Err(ViewError::Refused),
        }
    }
}
