//! Where saved calibrations go (flash on the board, a RAM model on the desktop).

use calibration_store::{LoadOutcome, PadRecord, RecordScope};

/// Saving failed; the previous saved calibrations still load.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PersistenceFailed;

/// Stores calibrations, one per pad or one for every pad, so that they survive a reset.
#[allow(async_fn_in_trait)]
pub trait CalibrationPersistence {
    /// The flash driver's error, in load outcomes.
    type Error;

    /// What flash holds for pad `pad` (its own calibration, or the one saved for every pad),
    /// read by the boot one pad at a time so that a single calibration is held at once; `None`
    /// when there is no usable flash region. It only reads, and flash reads do not wait, so it
    /// is not async.
    fn load(&mut self, pad: u8) -> Option<LoadOutcome<Self::Error>>;

    /// Saves a pad's calibration and geometry for `scope`; on failure every pad's previous
    /// record must still load.
    async fn save(
        &mut self,
        scope: RecordScope,
        record: &PadRecord,
    ) -> Result<(), PersistenceFailed>;
}
