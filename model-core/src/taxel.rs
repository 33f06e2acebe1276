//! One taxel's conversion: a classified reading, its baseline and the temperature in; a pressure
//! (or a fault) and flags out. This is the hot path measured in the performance report.

use crate::baseline::Baseline;
use crate::calibration::{FaultThresholds, TaxelCalibration};
use crate::flags::TaxelFlags;
use crate::inverse::{ActiveInverse, Tier};
use crate::reading::ReadingValue;

/// The result for one taxel.
// 16 bytes rather than 24 with two `Option<f32>`s: the device writes and copies four per set
// (a value that is absent is held as 0.0, so the derived equality is the values').
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TaxelOutput {
    pressure_kpa: f32,
    capacitance_pf: f32,
    relative_change: f32,
    flags: TaxelFlags,
    present: Present,
}

/// Which of a [`TaxelOutput`]'s optional values it holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
enum Present {
    /// Neither: the converter gave no capacitance.
    Nothing,
    /// The capacitance only (no dC/C0: a fault before it, or no baseline).
    Capacitance,
    /// The capacitance and dC/C0.
    Both,
}

impl TaxelOutput {
    /// A faulted output: no pressure. `flags` should name the fault; when none of them is a
    /// fault, INVALID_INPUT is added, so that a "fault" can never read as a pressure.
    pub fn fault(flags: TaxelFlags, capacitance_pf: Option<f32>) -> Self {
        let flags = if flags.is_fault() {
            flags
        } else {
            flags | TaxelFlags::INVALID_INPUT
        };
        Self {
            pressure_kpa: 0.0,
            capacitance_pf: capacitance_pf.unwrap_or(0.0),
            relative_change: 0.0,
            flags,
            present: if capacitance_pf.is_some() {
                Present::Capacitance
            } else {
                Present::Nothing
            },
        }
    }

    /// Pressure in kPa, within `0 ..= top of the curve`; `None` when a fault flag is set, so a
    /// faulted taxel can never be read as a pressure.
    pub fn pressure_kpa(&self) -> Option<f32> {
        if self.flags.is_fault() {
            None
        } else {
            Some(self.pressure_kpa)
        }
    }

    /// The measured capacitance, pF, when the converter gave one.
    pub fn capacitance_pf(&self) -> Option<f32> {
        (self.present != Present::Nothing).then_some(self.capacitance_pf)
    }

    /// dC/C0 referenced to 25 °C, when it could be formed.
    pub fn relative_change(&self) -> Option<f32> {
        (self.present == Present::Both).then_some(self.relative_change)
    }

    /// Status flags.
    pub fn flags(&self) -> TaxelFlags {
        self.flags
    }

    /// The same output with the pressure an inverse gave (a batch of inverses fills them in).
    #[cfg(feature = "batch")]
    pub(crate) fn with_pressure_kpa(mut self, pressure_kpa: f32) -> Self {
        self.pressure_kpa = pressure_kpa;
        self
    }

    /// Adds flags (e.g. the sample's temperature flags, the acquisition's converter flags).
    pub fn with_flags(mut self, flags: TaxelFlags) -> Self {
        self.flags |= flags;
        self
    }
}

/// A taxel's active tier, ready to convert readings together with the taxel's calibration
/// (which holds the curve's points, the parasitic capacitance and the top of the curve, so they
/// are not kept twice).
#[derive(Debug, Clone, PartialEq)]
pub struct TaxelModel {
    inverse: ActiveInverse,
}

impl TaxelModel {
    /// The default tier for a taxel's calibration.
    pub fn new(calibration: &TaxelCalibration) -> Self {
        Self {
            inverse: ActiveInverse::default_tier(calibration.curve()),
        }
    }

    /// A tier for a taxel's calibration, or `None` when its curve does not support the tier.
    pub fn with_tier(calibration: &TaxelCalibration, tier: Tier) -> Option<Self> {
        ActiveInverse::new(calibration.curve(), tier).map(Self::from_inverse)
    }

    /// A model from an inverse built for the calibration it will convert with.
    pub fn from_inverse(inverse: ActiveInverse) -> Self {
        Self { inverse }
    }

    /// The active tier.
    pub fn tier(&self) -> Tier {
        self.inverse.tier()
    }

    /// The active tier's inverse.
    pub fn inverse(&self) -> &ActiveInverse {
        &self.inverse
    }

    /// Converts one reading with the active tier. `calibration` is the taxel's, the one the
    /// model was built for; `inverse_permittivity_ratio` is eps(25 °C) / eps(T) for the sample's
    /// temperature (computed once per sample set).
    #[inline]
    pub fn convert(
        &self,
        calibration: &TaxelCalibration,
        reading: ReadingValue,
        baseline: Option<&Baseline>,
        inverse_permittivity_ratio: f32,
        thresholds: &FaultThresholds,
    ) -> TaxelOutput {
        self.convert_with(
            calibration,
            reading,
            baseline,
            inverse_permittivity_ratio,
            thresholds,
            |relative_change| {
                self.inverse
                    .pressure_kpa(calibration.curve(), relative_change)
            },
        )
    }

    /// [`TaxelModel::convert`] with the pressure of an in-range reading (`0 < dC/C0 <= top`)
    /// given by `in_range` (the tier's inverse, or a placeholder when a batch of inverses
    /// fills it in later).
    #[inline(always)]
    pub(crate) fn convert_with(
        &self,
        calibration: &TaxelCalibration,
        reading: ReadingValue,
        baseline: Option<&Baseline>,
        inverse_permittivity_ratio: f32,
        thresholds: &FaultThresholds,
        in_range: impl FnOnce(f32) -> f32,
    ) -> TaxelOutput {
        let capacitance = match reading {
            ReadingValue::Capacitance(capacitance) => capacitance,
            ReadingValue::Saturated => return TaxelOutput::fault(TaxelFlags::SATURATED, None),
            ReadingValue::Invalid => return TaxelOutput::fault(TaxelFlags::INVALID_INPUT, None),
            ReadingValue::Unavailable => {
                return TaxelOutput::fault(TaxelFlags::CONVERTER_ERROR, None)
            }
        };
        let total_pf = capacitance.total_pf();
        if total_pf < 0.0 {
            return TaxelOutput::fault(TaxelFlags::SHORTED, Some(total_pf));
        }
        let sensor_pf = (capacitance.offset_pf - calibration.parasitic_pf()) + capacitance.fine_pf;
        if !(sensor_pf >= thresholds.open_below_pf) {
            return TaxelOutput::fault(TaxelFlags::OPEN, Some(total_pf));
        }
        let Some(baseline) = baseline else {
            return TaxelOutput::fault(TaxelFlags::NOT_TARED, Some(total_pf));
        };
        let relative_change = baseline.relative_change(capacitance, inverse_permittivity_ratio);
        let top = calibration.curve().top();
        let (pressure_kpa, flags) = if !relative_change.is_finite() {
            (0.0, TaxelFlags::INVALID_INPUT)
        } else if relative_change < -thresholds.shorted_below_relative {
            (0.0, TaxelFlags::SHORTED)
        } else if relative_change < -thresholds.dead_band_relative {
            (0.0, TaxelFlags::BELOW_BASELINE)
        } else if relative_change <= 0.0 {
            (0.0, TaxelFlags::empty())
        } else if relative_change > top.relative_change {
            (top.pressure_kpa, TaxelFlags::OVER_RANGE)
        } else {
            (in_range(relative_change), TaxelFlags::empty())
        };
        TaxelOutput {
            pressure_kpa,
            capacitance_pf: total_pf,
            relative_change,
            flags,
            present: Present::Both,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fault_without_a_fault_flag_still_has_no_pressure() {
        let output = TaxelOutput::fault(TaxelFlags::BELOW_BASELINE, Some(4.5));
        assert_eq!(output.pressure_kpa(), None);
        assert!(output
            .flags()
            .contains(TaxelFlags::INVALID_INPUT | TaxelFlags::BELOW_BASELINE));
        let shorted = TaxelOutput::fault(TaxelFlags::SHORTED, None);
        assert_eq!(shorted.flags(), TaxelFlags::SHORTED);
    }
}
