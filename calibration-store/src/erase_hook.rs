//! A NOR flash that runs a hook before erasing each sector. On a single-bank part such as the
//! STM32F411, a sector erase stalls every instruction fetch for up to 2 s per 128 KiB sector,
//! and with it whatever keeps a watchdog fed: the hook feeds it between sectors.

use embedded_storage_async::nor_flash::{ErrorType, NorFlash, ReadNorFlash};

/// `flash`, with `hook` called before each sector erase and once after the last.
pub struct EraseHook<F, H> {
    flash: F,
    hook: H,
}

impl<F, H: FnMut()> EraseHook<F, H> {
    /// Wraps `flash`.
    pub fn new(flash: F, hook: H) -> Self {
        Self { flash, hook }
    }

    /// The wrapped flash.
    pub fn inner_mut(&mut self) -> &mut F {
        &mut self.flash
    }
}

impl<F: ErrorType, H> ErrorType for EraseHook<F, H> {
    type Error = F::Error;
}

impl<F: ReadNorFlash, H> ReadNorFlash for EraseHook<F, H> {
    const READ_SIZE: usize = F::READ_SIZE;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.flash.read(offset, bytes).await
    }

    fn capacity(&self) -> usize {
        self.flash.capacity()
    }
}

impl<F: NorFlash, H: FnMut()> NorFlash for EraseHook<F, H> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.flash.write(offset, bytes).await
    }

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let mut sector_start = from;
        while sector_start < to {
            let sector_end = sector_start.saturating_add(Self::ERASE_SIZE as u32).min(to);
            (self.hook)();
            self.flash.erase(sector_start, sector_end).await?;
            sector_start = sector_end;
        }
        (self.hook)();
        Ok(())
    }
}

#[cfg(all(test, feature = "ram-flash"))]
mod tests {
    use super::*;
    use crate::RamFlash;

    #[test]
    fn the_hook_runs_before_every_sector_and_after_the_last() {
        let mut calls = 0u32;
        {
            let mut flash = EraseHook::new(RamFlash::<4096, 1024>::new(), || calls += 1);
            embassy_futures::block_on(flash.erase(0, 3 * 1024)).unwrap();
        }
        assert_eq!(calls, 4);
    }
}
