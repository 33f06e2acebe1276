//! The pads' calibrations in flash for the device application: [`FlashPersistence`] loads them
//! at boot, pad by pad, and implements `device::CalibrationPersistence` over `taxel-calibration-store`, in sectors 6 and 7,
//! feeding the watchdog between sector erases.

use calibration_store::{
    CalibrationStore, EraseHook, LoadOutcome, PadRecord, RecordScope, STM32F411_CALIBRATION_RANGE,
};
use defmt::{error, info, warn};
use device::{CalibrationPersistence, PersistenceFailed};
use embassy_stm32::flash::{self, Flash, FLASH_BASE};
use embassy_stm32::peripherals::FLASH;
use embassy_stm32::Peri;

use crate::board::Irqs;
use crate::watchdog;

/// The flash under the calibration store.
pub type CalibrationFlash = EraseHook<Flash<'static, flash::Async>, fn()>;

extern "C" {
    static __calibration_start: u8;
    static __calibration_end: u8;
}

/// The calibration store, or nothing if the flash region is unusable (then the defaults are used
/// and saving fails).
pub struct FlashPersistence {
    store: Option<CalibrationStore<CalibrationFlash>>,
}

impl FlashPersistence {
    /// Opens the store over the CALIBRATION region of `memory.x`.
    pub fn new(flash: Peri<'static, FLASH>) -> Self {
        if !calibration_range_matches_linker_script() {
            error!("the calibration range does not match memory.x; calibration storage disabled");
            return Self { store: None };
        }
        // Single-bank flash: a sector erase stalls the watchdog's supervisor; feed it between.
        let flash = EraseHook::new(Flash::new(flash, Irqs), watchdog::feed as fn());
        match CalibrationStore::new(flash, STM32F411_CALIBRATION_RANGE) {
            Ok(store) => Self { store: Some(store) },
            Err(region_error) => {
                error!(
                    "calibration region refused: {}; calibration storage disabled",
                    region_error
                );
                Self { store: None }
            }
        }
    }
}

impl CalibrationPersistence for FlashPersistence {
    type Error = flash::Error;

    /// Reads only: embassy-stm32's flash reads complete on the first poll.
    fn load(&mut self, pad: u8) -> Option<LoadOutcome<flash::Error>> {
        let store = self.store.as_mut()?;
        let outcome = embassy_futures::block_on(store.load(pad));
        match &outcome {
            LoadOutcome::Stored(record) => info!(
                "pad {=u8}: calibration {=u32} found in flash",
                pad, record.calibration.id
            ),
            LoadOutcome::Absent => info!("pad {=u8}: no calibration saved; the defaults", pad),
            LoadOutcome::Corrupt(reason) => warn!(
                "pad {=u8}: stored calibration corrupt ({}); the defaults",
                pad, reason
            ),
        }
        Some(outcome)
    }

    /// Stalls the whole MCU for 1-2 s per sector erase (single-bank flash); USB answers NAK meanwhile.
    async fn save(
        &mut self,
        scope: RecordScope,
        record: &PadRecord,
    ) -> Result<(), PersistenceFailed> {
        let store = self.store.as_mut().ok_or(PersistenceFailed)?;
        let id = record.calibration.id;
        match store.save_for(scope, record).await {
            Ok(()) => {
                info!("calibration {=u32} saved for {}", id, scope);
                Ok(())
            }
            Err(store_error) => {
                error!("saving calibration {=u32} failed: {}", id, store_error);
                Err(PersistenceFailed)
            }
        }
    }
}

fn calibration_range_matches_linker_script() -> bool {
    let start = &raw const __calibration_start as usize;
    let end = &raw const __calibration_end as usize;
    start == FLASH_BASE + STM32F411_CALIBRATION_RANGE.start as usize
        && end == FLASH_BASE + STM32F411_CALIBRATION_RANGE.end as usize
}
