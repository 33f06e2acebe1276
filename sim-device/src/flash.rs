//! The simulated board's calibration flash: the firmware's region (two 128 KiB erase sectors,
//! STM32F411 sectors 6 and 7) held in RAM, with the power-loss and bit-flip injection of
//! calibration-store's `RamFlash`. Boxed: 256 KiB is too large to move around on a stack.

use core::ops::{Deref, DerefMut};

use calibration_store::{RamFlash, RamFlashError, STM32F411_CALIBRATION_RANGE};
use embedded_storage_async::nor_flash::{ErrorType, NorFlash, ReadNorFlash};

/// Bytes of the calibration region, as on the board.
pub const FLASH_REGION_LEN: usize =
    (STM32F411_CALIBRATION_RANGE.end - STM32F411_CALIBRATION_RANGE.start) as usize;

/// Erase sector of the region, as on the board (128 KiB).
pub const FLASH_SECTOR_LEN: usize = FLASH_REGION_LEN / 2;

/// The RAM model of the region.
pub type BoardFlash = RamFlash<FLASH_REGION_LEN, FLASH_SECTOR_LEN>;

/// The simulated calibration flash, erased.
pub struct SimulatedFlash(Box<BoardFlash>);

impl SimulatedFlash {
    /// An erased region.
    pub fn new() -> Self {
        Self(Box::new(BoardFlash::new()))
    }
}

impl Default for SimulatedFlash {
    fn default() -> Self {
        Self::new()
    }
}

impl Deref for SimulatedFlash {
    type Target = BoardFlash;

    fn deref(&self) -> &BoardFlash {
        &self.0
    }
}

impl DerefMut for SimulatedFlash {
    fn deref_mut(&mut self) -> &mut BoardFlash {
        &mut self.0
    }
}

impl ErrorType for SimulatedFlash {
    type Error = RamFlashError;
}

impl ReadNorFlash for SimulatedFlash {
    const READ_SIZE: usize = BoardFlash::READ_SIZE;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.0.read(offset, bytes).await
    }

    fn capacity(&self) -> usize {
        self.0.capacity()
    }
}

impl NorFlash for SimulatedFlash {
    const WRITE_SIZE: usize = BoardFlash::WRITE_SIZE;
    const ERASE_SIZE: usize = BoardFlash::ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.0.erase(from, to).await
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.0.write(offset, bytes).await
    }
}
