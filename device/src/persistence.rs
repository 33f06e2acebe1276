//! Where a saved calibration goes (flash on the board, a RAM or file model on the desktop).

use model_core::CalibrationSpec;

/// Saving failed; the previous saved calibration is still in place.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PersistenceFailed;

/// Stores a calibration so that it survives a reset.
#[allow(async_fn_in_trait)]
pub trait CalibrationPersistence {
    /// Saves the calibration; on failure the previous one must still load.
    async fn save(&mut self, spec: &CalibrationSpec) -> Result<(), PersistenceFailed>;
}
