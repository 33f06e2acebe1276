//! Raw readings of a 2x2 capacitive tactile pad (TI FDC1004 codes, or recorded capacitances) to
//! pressure per taxel, with temperature correction, a baseline (tare), status flags for every way
//! a reading can be wrong, and several inversion tiers with measured speed and error.
//!
//! `no_std`, no allocation, no HAL: the same code runs in the firmware, in the desktop simulator
//! and in the host tools. With the feature `batch`, a host converting a recording can call
//! `PadModel::process_all` instead of [`PadModel::process`] set by set: the same outputs bit for
//! bit, with the tier's inverses of many sets computed together, which a superscalar core runs
//! faster. The device builds only the inversion tiers on the Pareto front of cost against error
//! (linear, table, monotone-cubic); the feature `research-tiers` adds the others for host tools
//! and reports (see [`inverse`]).
//!
//! ```
//! use model_core::{Calibration, PadModel, SampleInput, TaxelReading};
//!
//! let mut pad = PadModel::new(Calibration::default());
//! let unloaded = SampleInput::new([TaxelReading::CapacitancePf(4.5); 4], Some(25.0));
//! pad.start_tare(1);
//! pad.process(&unloaded);
//! let pressed = SampleInput::new(
//!     [
//!         TaxelReading::CapacitancePf(4.5 * 1.0829),
//!         TaxelReading::CapacitancePf(4.5),
//!         TaxelReading::CapacitancePf(4.5),
//!         TaxelReading::CapacitancePf(4.5),
//!     ],
//!     Some(25.0),
//! );
//! let output = pad.process(&pressed);
//! let pressure_kpa = output.taxels[0].pressure_kpa().unwrap_or(f32::NAN);
//! assert!((pressure_kpa - 10.0).abs() < 1e-3);
//! ```
#![no_std]
#![deny(missing_docs)]
// No panic path: every index is checked or provably in bounds (tests may index freely).
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

// The host's batch path asks the CPU which vector instructions it has (`inverse/cubic.rs`).
#[cfg(all(feature = "batch", target_arch = "x86_64"))]
extern crate std;

pub mod baseline;
mod bounds;
pub mod calibration;
pub mod conditioning;
pub mod contact;
pub mod flags;
pub mod inverse;
mod measured_instructions;
pub mod monotone_cubic;
pub mod pad;
#[cfg(feature = "batch")]
pub mod pad_batch;
pub mod pad_force;
pub mod pad_geometry;
pub mod pad_pipeline;
pub mod reading;
pub mod taxel;
pub mod temperature;
pub mod use_case;
pub mod validation;

pub use baseline::{Baseline, BaselineError, BaselineRecord, BaselineTracking};
pub use calibration::{
    Calibration, CalibrationCurve, CalibrationError, CalibrationSpec, CurvePoint, FaultThresholds,
    PermittivityPoint, TaxelCalibration, TaxelCalibrationSpec, TemperatureLaw, ARTICLE_TABLE_1,
    TAXEL_COUNT, TAXEL_NAMES,
};
pub use contact::{ContactConfig, ContactConfigError, ContactDetector, ContactEvent};
pub use flags::TaxelFlags;
pub use inverse::{InverseCurve, TaxelInverses, Tier};
pub use pad::{PadModel, PadOutput, SampleInput, TareStatus, TierUnavailable};
#[cfg(feature = "batch")]
pub use pad_batch::BATCH_SAMPLE_SETS;
pub use pad_force::{pad_force, pad_force_from_pressures, PadForce, PadForceFlags};
pub use pad_geometry::{GeometryError, PadGeometry, PadRole, TaxelGeometry};
pub use pad_pipeline::{ForceAndContact, PadContact, PadPipeline, PadReport};
pub use reading::{ReadingValue, SplitCapacitance, TaxelReading};
pub use taxel::{TaxelModel, TaxelOutput};
pub use temperature::{TemperatureTracker, TemperatureUsed, REFERENCE_TEMPERATURE_C};
pub use use_case::{select_tier_for_taxels, SelectionError, TaxelEvidence, TierChoice, UseCase};
pub use validation::leave_one_out_errors_kpa;
