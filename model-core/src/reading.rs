//! Converter readings as the model takes them, and their capacitance kept as two exact parts.
//!
//! An FDC1004 code resolves 1.907 aF, but an f32 capacitance near the top CAPDAC offset
//! (96.875 pF) has a step of 7.6 aF: forming the capacitance first and the change from the
//! baseline second would lose the smallest changes. The capacitance is therefore kept as
//! `offset_pf` (CAPDAC x 3.125 pF) plus `fine_pf` (code / 2^19), both exact in f32, and changes are
//! formed part by part.

/// FDC1004 code reported when the input is above the measurable range.
pub const SATURATED_HIGH_CODE: i32 = 0x7F_FFFF;
/// FDC1004 code reported when the input is below the measurable range.
pub const SATURATED_LOW_CODE: i32 = -0x80_0000;
/// Capacitance of one CAPDAC step, pF.
pub const CAPDAC_STEP_PF: f32 = 3.125;
/// Highest CAPDAC setting.
pub const CAPDAC_MAX: u8 = 31;
/// Codes per pF (2^19).
pub const CODES_PER_PF: f32 = 524_288.0;
/// Largest capacitance the converter can report: the top CAPDAC offset plus the top of the
/// +-16 pF input range, pF. A recorded capacitance above it cannot have come from the converter.
pub const MAX_MEASURABLE_PF: f32 = CAPDAC_MAX as f32 * CAPDAC_STEP_PF + 16.0;
/// Smallest capacitance the converter can report (CAPDAC 0, bottom of the input range), pF.
pub const MIN_MEASURABLE_PF: f32 = -16.0;

/// One taxel's reading, as the converter or a recording gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TaxelReading {
    /// The FDC1004's sign-extended 24-bit result and the CAPDAC setting it was measured against.
    Raw {
        /// Two's complement result, -2^23 ..= 2^23 - 1.
        code: i32,
        /// CAPDAC setting, 0 ..= 31.
        capdac: u8,
    },
    /// A capacitance in pF (recorded data).
    CapacitancePf(f32),
    /// No reading this cycle (the acquisition says why in its flags).
    Unavailable,
}

/// A capacitance split into two parts that are each exact in f32.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SplitCapacitance {
    /// The coarse part (CAPDAC offset), pF.
    pub offset_pf: f32,
    /// The fine part (converter code), pF.
    pub fine_pf: f32,
}

impl SplitCapacitance {
    /// The whole capacitance, pF (rounded to f32).
    pub fn total_pf(self) -> f32 {
        self.offset_pf + self.fine_pf
    }

    /// `self - other` in pF, formed part by part so no resolution is lost when both share the
    /// same large offset.
    pub fn minus(self, other: SplitCapacitance) -> f32 {
        (self.offset_pf - other.offset_pf) + (self.fine_pf - other.fine_pf)
    }
}

/// What a reading turned out to be before any baseline is applied.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReadingValue {
    /// A usable capacitance.
    Capacitance(SplitCapacitance),
    /// The converter reported a saturated code.
    Saturated,
    /// The code or CAPDAC is out of the converter's range, or the value is not finite or beyond
    /// what the converter can report.
    Invalid,
    /// There was no reading.
    Unavailable,
}

impl TaxelReading {
    /// Interprets the reading.
    pub fn value(self) -> ReadingValue {
        match self {
            TaxelReading::Raw { code, capdac } => {
                if code == SATURATED_HIGH_CODE || code == SATURATED_LOW_CODE {
                    ReadingValue::Saturated
                } else if !(SATURATED_LOW_CODE..=SATURATED_HIGH_CODE).contains(&code)
                    || capdac > CAPDAC_MAX
                {
                    ReadingValue::Invalid
                } else {
                    ReadingValue::Capacitance(SplitCapacitance {
                        offset_pf: capdac as f32 * CAPDAC_STEP_PF,
                        fine_pf: code as f32 / CODES_PER_PF,
                    })
                }
            }
            TaxelReading::CapacitancePf(pf)
                if (MIN_MEASURABLE_PF..=MAX_MEASURABLE_PF).contains(&pf) =>
            {
                ReadingValue::Capacitance(SplitCapacitance {
                    offset_pf: 0.0,
                    fine_pf: pf,
                })
            }
            TaxelReading::CapacitancePf(_) => ReadingValue::Invalid,
            TaxelReading::Unavailable => ReadingValue::Unavailable,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn saturation_codes_are_recognised() {
        for code in [SATURATED_HIGH_CODE, SATURATED_LOW_CODE] {
            let reading = TaxelReading::Raw { code, capdac: 4 };
            assert_eq!(reading.value(), ReadingValue::Saturated);
        }
        let reading = TaxelReading::Raw {
            code: SATURATED_HIGH_CODE - 1,
            capdac: 4,
        };
        assert!(matches!(reading.value(), ReadingValue::Capacitance(_)));
    }

    #[test]
    fn out_of_range_code_or_capdac_is_invalid() {
        let too_big = TaxelReading::Raw {
            code: 1 << 24,
            capdac: 0,
        };
        assert_eq!(too_big.value(), ReadingValue::Invalid);
        let bad_capdac = TaxelReading::Raw {
            code: 0,
            capdac: 32,
        };
        assert_eq!(bad_capdac.value(), ReadingValue::Invalid);
        for beyond_reach in [f32::INFINITY, 1e30, -1e30, 112.9, -16.1, f32::NAN] {
            assert_eq!(
                TaxelReading::CapacitancePf(beyond_reach).value(),
                ReadingValue::Invalid,
                "{beyond_reach}"
            );
        }
        for within_reach in [112.875f32, 4.5, 0.0, -16.0] {
            assert!(matches!(
                TaxelReading::CapacitancePf(within_reach).value(),
                ReadingValue::Capacitance(_)
            ));
        }
    }

    #[test]
    fn one_code_on_top_of_the_largest_capdac_is_resolved() {
        let split = |code| match (TaxelReading::Raw { code, capdac: 31 }).value() {
            ReadingValue::Capacitance(split) => split,
            other => panic!("unexpected {other:?}"),
        };
        let base = split(1_000_000);
        let up = split(1_000_001);
        let difference_pf = up.minus(base);
        assert!((difference_pf - 1.0 / 524_288.0).abs() < 1e-12);
        assert!(split(999_999).minus(base) < 0.0);
        // The naive way loses it: 96.875 pF + 1.9 aF rounds to the same f32.
        assert_eq!(up.total_pf() - base.total_pf(), 0.0);
    }
}
