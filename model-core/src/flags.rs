//! Status flags attached to every taxel reading: what may be wrong with it, and whether it is a fault.

use bitflags::bitflags;

bitflags! {
    /// Why a taxel reading is not (or not entirely) a trustworthy pressure.
    ///
    /// Flags in [`TaxelFlags::FAULTS`] mean the reading carries no pressure at all
    /// ([`crate::TaxelOutput::pressure_kpa`] is `None`). The others are warnings: the pressure is
    /// still given, with the caveat the flag names. The bit positions are part of the wire format
    /// and of recorded files; never renumber them.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
    #[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
    pub struct TaxelFlags: u16 {
        /// Warning: the capacitance fell below the baseline by more than the dead band (the
        /// baseline has drifted: re-tare). Reported as 0 kPa.
        const BELOW_BASELINE = 1 << 0;
        /// Warning: above the top calibration point; the pressure is clamped to it (a lower bound).
        const OVER_RANGE = 1 << 1;
        /// Fault: the electrodes conduct through the dielectric (negative capacitance, as under a
        /// concentrated load) or the capacitance is far below the baseline.
        const SHORTED = 1 << 2;
        /// Fault: implausibly small sensor capacitance: open or disconnected lead.
        const OPEN = 1 << 3;
        /// Fault: the converter reported a saturated code (input outside +-16 pF around CAPDAC).
        const SATURATED = 1 << 4;
        /// Warning: no valid temperature in this sample; the last valid one (or the tare's) was used.
        const TEMPERATURE_MISSING = 1 << 5;
        /// Warning: the temperature is outside the characterised 5-55 °C and was clamped.
        const TEMPERATURE_OUT_OF_RANGE = 1 << 6;
        /// Fault: no baseline has been taken for this taxel yet.
        const NOT_TARED = 1 << 7;
        /// Fault: the converter read failed, timed out, returned all zeros or is being re-initialised.
        const CONVERTER_ERROR = 1 << 8;
        /// Fault: the channel repeated one converter code for many consecutive cycles (a live
        /// channel's noise changes the code every few cycles): a frozen channel, or a converter
        /// returning stale results.
        const STUCK = 1 << 9;
        /// Fault: the input value is not a finite capacitance.
        const INVALID_INPUT = 1 << 10;
        /// Warning: slow baseline tracking has reached its bound; re-tare when unloaded.
        const BASELINE_TRACKING_LIMIT = 1 << 11;
        /// Warning: the temperature came from the fallback sensor (the MCU's die), corrected by
        /// the offset last learned against the pad's sensor: less accurate than the pad's own.
        const TEMPERATURE_FALLBACK = 1 << 12;
        /// Warning: the measured temperature jumped further from the one in use than the pad can
        /// change (more than [`crate::temperature::MAX_PLAUSIBLE_STEP_C`] plus
        /// [`crate::temperature::MAX_RATE_C_PER_S`] of the time since that one was measured);
        /// it was not applied, the sample was corrected with the temperature in use, until
        /// consistent readings confirm the new level (see [`crate::temperature`]).
        const TEMPERATURE_IMPLAUSIBLE = 1 << 13;
        /// Warning: the taxel's baseline (C0 at 25 °C) differs from the C0 recorded in its
        /// calibration by more than [`crate::pad::TARE_FAR_FROM_CALIBRATION_RELATIVE`]: the pad
        /// was loaded at the tare, has aged (the article loses 5.7 % in 5000 cycles) or is not
        /// the calibrated pad. Tare again unloaded, or calibrate again.
        const BASELINE_FAR_FROM_CALIBRATION = 1 << 14;

        /// Every flag that makes a reading carry no pressure.
        const FAULTS = Self::SHORTED.bits()
            | Self::OPEN.bits()
            | Self::SATURATED.bits()
            | Self::NOT_TARED.bits()
            | Self::CONVERTER_ERROR.bits()
            | Self::STUCK.bits()
            | Self::INVALID_INPUT.bits();
    }
}

impl TaxelFlags {
    /// True when the reading carries no pressure.
    pub const fn is_fault(self) -> bool {
        self.intersects(Self::FAULTS)
    }

    /// Stable, documented names of the individual flags, in bit order (used in CSV files).
    pub const NAMES: [(TaxelFlags, &'static str); 15] = [
        (Self::BELOW_BASELINE, "below_baseline"),
        (Self::OVER_RANGE, "over_range"),
        (Self::SHORTED, "shorted"),
        (Self::OPEN, "open"),
        (Self::SATURATED, "saturated"),
        (Self::TEMPERATURE_MISSING, "temperature_missing"),
        (Self::TEMPERATURE_OUT_OF_RANGE, "temperature_out_of_range"),
        (Self::NOT_TARED, "not_tared"),
        (Self::CONVERTER_ERROR, "converter_error"),
        (Self::STUCK, "stuck"),
        (Self::INVALID_INPUT, "invalid_input"),
        (Self::BASELINE_TRACKING_LIMIT, "baseline_tracking_limit"),
        (Self::TEMPERATURE_FALLBACK, "temperature_fallback"),
        (Self::TEMPERATURE_IMPLAUSIBLE, "temperature_implausible"),
        (
            Self::BASELINE_FAR_FROM_CALIBRATION,
            "baseline_far_from_calibration",
        ),
    ];

    /// The flag with this documented name, if any.
    pub fn from_documented_name(name: &str) -> Option<TaxelFlags> {
        Self::NAMES
            .iter()
            .find(|(_, flag_name)| *flag_name == name)
            .map(|(flag, _)| *flag)
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for TaxelFlags {
    fn format(&self, fmt: defmt::Formatter) {
        defmt::write!(fmt, "TaxelFlags({=u16:#x})", self.bits())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_cover_every_flag_once_in_bit_order() {
        let mut union = TaxelFlags::empty();
        for (index, (flag, name)) in TaxelFlags::NAMES.iter().enumerate() {
            assert_eq!(flag.bits(), 1 << index);
            assert_eq!(TaxelFlags::from_documented_name(name), Some(*flag));
            union |= *flag;
        }
        assert_eq!(union, TaxelFlags::all());
    }

    #[test]
    fn warnings_are_not_faults() {
        assert!(!TaxelFlags::OVER_RANGE.is_fault());
        assert!(!(TaxelFlags::BELOW_BASELINE | TaxelFlags::TEMPERATURE_MISSING).is_fault());
        assert!((TaxelFlags::OVER_RANGE | TaxelFlags::SHORTED).is_fault());
    }
}
