//! The per-taxel flag bits carried raw in [`crate::TaxelSample::flags`]. Their meaning is defined
//! by the pressure model (model-core's `TaxelFlags`); the wire only transports and documents them.

/// The capacitance is below the tared baseline (the taxel reads a negative load).
pub const BELOW_BASELINE: u16 = 1 << 0;
/// The pressure is above the calibrated range.
pub const OVER_RANGE: u16 = 1 << 1;
/// The taxel looks shorted (for example a negative capacitance under a concentrated load).
pub const SHORTED: u16 = 1 << 2;
/// The taxel looks open (no sensor capacitance).
pub const OPEN: u16 = 1 << 3;
/// The converter reading is at its full-scale limit.
pub const SATURATED: u16 = 1 << 4;
/// No temperature was available; no temperature correction was applied.
pub const TEMPERATURE_MISSING: u16 = 1 << 5;
/// The temperature is outside the characterised range.
pub const TEMPERATURE_OUT_OF_RANGE: u16 = 1 << 6;
/// No tare has been taken since boot.
pub const NOT_TARED: u16 = 1 << 7;
/// The converter reported an error for this sample set.
pub const CONVERTER_ERROR: u16 = 1 << 8;
/// The reading has not changed for an implausibly long time.
pub const STUCK: u16 = 1 << 9;
/// The model was given an invalid input (for example a non-finite number).
pub const INVALID_INPUT: u16 = 1 << 10;
/// Baseline tracking reached its limit.
pub const BASELINE_TRACKING_LIMIT: u16 = 1 << 11;
/// The temperature came from the fallback sensor (MCU die), offset-corrected: less accurate.
pub const TEMPERATURE_FALLBACK: u16 = 1 << 12;
/// The measured temperature jumped further than the pad can change between two sample sets; it
/// was not applied as measured (the temperature in use follows it at a bounded rate).
pub const TEMPERATURE_IMPLAUSIBLE: u16 = 1 << 13;
/// The taxel's baseline differs from the C0 in its calibration by more than 5 %: loaded at the
/// tare, aged, or not the calibrated pad.
pub const BASELINE_FAR_FROM_CALIBRATION: u16 = 1 << 14;

/// The flags that make the pressure unusable; a taxel with any of them has no pressure.
pub const FAULT_MASK: u16 =
    SHORTED | OPEN | SATURATED | NOT_TARED | CONVERTER_ERROR | STUCK | INVALID_INPUT;

/// Every bit defined so far; the others are reserved and sent as zero.
pub const DEFINED_MASK: u16 = (1 << 15) - 1;

/// Whether `flags` contains a fault.
pub const fn is_fault(flags: u16) -> bool {
    flags & FAULT_MASK != 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fault_mask_is_bits_2_3_4_7_8_9_10() {
        assert_eq!(FAULT_MASK, 0b0111_1001_1100);
        assert!(is_fault(SHORTED));
        assert!(!is_fault(BELOW_BASELINE | OVER_RANGE | TEMPERATURE_MISSING));
        assert_eq!(DEFINED_MASK, 0x7FFF);
    }
}
