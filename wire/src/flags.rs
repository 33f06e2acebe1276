//! The per-taxel flag bits carried raw in [`crate::TaxelSample::flags`], as constants for
//! clients. Their meaning has one definition, model-core's [`TaxelFlags`] (documented there and in
//! PROTOCOL.md section 7); these are its bits.

use model_core::TaxelFlags;

/// [`TaxelFlags::BELOW_BASELINE`].
pub const BELOW_BASELINE: u16 = TaxelFlags::BELOW_BASELINE.bits();
/// [`TaxelFlags::OVER_RANGE`].
pub const OVER_RANGE: u16 = TaxelFlags::OVER_RANGE.bits();
/// [`TaxelFlags::SHORTED`].
pub const SHORTED: u16 = TaxelFlags::SHORTED.bits();
/// [`TaxelFlags::OPEN`].
pub const OPEN: u16 = TaxelFlags::OPEN.bits();
/// [`TaxelFlags::SATURATED`].
pub const SATURATED: u16 = TaxelFlags::SATURATED.bits();
/// [`TaxelFlags::TEMPERATURE_MISSING`].
pub const TEMPERATURE_MISSING: u16 = TaxelFlags::TEMPERATURE_MISSING.bits();
/// [`TaxelFlags::TEMPERATURE_OUT_OF_RANGE`].
pub const TEMPERATURE_OUT_OF_RANGE: u16 = TaxelFlags::TEMPERATURE_OUT_OF_RANGE.bits();
/// [`TaxelFlags::NOT_TARED`].
pub const NOT_TARED: u16 = TaxelFlags::NOT_TARED.bits();
/// [`TaxelFlags::CONVERTER_ERROR`].
pub const CONVERTER_ERROR: u16 = TaxelFlags::CONVERTER_ERROR.bits();
/// [`TaxelFlags::STUCK`].
pub const STUCK: u16 = TaxelFlags::STUCK.bits();
/// [`TaxelFlags::INVALID_INPUT`].
pub const INVALID_INPUT: u16 = TaxelFlags::INVALID_INPUT.bits();
/// [`TaxelFlags::BASELINE_TRACKING_LIMIT`].
pub const BASELINE_TRACKING_LIMIT: u16 = TaxelFlags::BASELINE_TRACKING_LIMIT.bits();
/// [`TaxelFlags::TEMPERATURE_FALLBACK`].
pub const TEMPERATURE_FALLBACK: u16 = TaxelFlags::TEMPERATURE_FALLBACK.bits();
/// [`TaxelFlags::TEMPERATURE_IMPLAUSIBLE`].
pub const TEMPERATURE_IMPLAUSIBLE: u16 = TaxelFlags::TEMPERATURE_IMPLAUSIBLE.bits();
/// [`TaxelFlags::BASELINE_FAR_FROM_CALIBRATION`].
pub const BASELINE_FAR_FROM_CALIBRATION: u16 = TaxelFlags::BASELINE_FAR_FROM_CALIBRATION.bits();

/// The flags that make the pressure unusable ([`TaxelFlags::FAULTS`]); a taxel with any of them
/// has no pressure.
pub const FAULT_MASK: u16 = TaxelFlags::FAULTS.bits();

/// Every bit defined so far; the others are reserved and sent as zero.
pub const DEFINED_MASK: u16 = TaxelFlags::all().bits();

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
