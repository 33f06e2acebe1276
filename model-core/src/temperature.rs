//! Which temperature a sample is corrected with: the measured one clamped to the characterised
//! range, or, when it is missing, the last valid one (else the tare's, else the reference).

use crate::bounds::clamp_f32;
use crate::calibration::TemperatureLaw;
use crate::flags::TaxelFlags;

/// Temperature at which the calibration curve holds and the permittivity ratio is 1, °C.
pub const REFERENCE_TEMPERATURE_C: f32 = 25.0;

/// The temperature a sample was corrected with.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TemperatureUsed {
    /// Temperature used, °C (always finite and within the characterised range).
    pub temperature_c: f32,
    /// eps_r at that temperature over eps_r at the reference.
    pub permittivity_ratio: f32,
    /// TEMPERATURE_MISSING and/or TEMPERATURE_OUT_OF_RANGE, or empty.
    pub flags: TaxelFlags,
}

/// Remembers the last valid temperature between samples.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TemperatureTracker {
    last_valid_c: Option<f32>,
}

impl TemperatureTracker {
    /// Resolves this sample's temperature. `fallback_c` (the tare temperature) is used when no
    /// valid temperature was ever seen.
    pub fn resolve(
        &mut self,
        measured_c: Option<f32>,
        fallback_c: Option<f32>,
        law: &TemperatureLaw,
    ) -> TemperatureUsed {
        let (minimum_c, maximum_c) = (law.characterised_min_c(), law.characterised_max_c());
        let (temperature_c, flags) = match measured_c {
            Some(value) if value.is_finite() => {
                let clamped = clamp_f32(value, minimum_c, maximum_c);
                self.last_valid_c = Some(clamped);
                let flags = if clamped != value {
                    TaxelFlags::TEMPERATURE_OUT_OF_RANGE
                } else {
                    TaxelFlags::empty()
                };
                (clamped, flags)
            }
            _ => {
                let substitute = self
                    .last_valid_c
                    .or(fallback_c.filter(|value| value.is_finite()))
                    .unwrap_or(REFERENCE_TEMPERATURE_C);
                let substitute = clamp_f32(substitute, minimum_c, maximum_c);
                (substitute, TaxelFlags::TEMPERATURE_MISSING)
            }
        };
        TemperatureUsed {
            temperature_c,
            permittivity_ratio: law.permittivity_ratio(temperature_c),
            flags,
        }
    }

    /// The last valid temperature seen, °C.
    pub fn last_valid_c(&self) -> Option<f32> {
        self.last_valid_c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hard_temperatures_are_clamped_or_substituted_and_flagged() {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        let missing = tracker.resolve(None, None, &law);
        assert_eq!(missing.temperature_c, REFERENCE_TEMPERATURE_C);
        assert_eq!(missing.flags, TaxelFlags::TEMPERATURE_MISSING);
        let from_tare = tracker.resolve(Some(f32::NAN), Some(31.0), &law);
        assert_eq!(from_tare.temperature_c, 31.0);
        for (input, expected, flags) in [
            (-40.0, 5.0, TaxelFlags::TEMPERATURE_OUT_OF_RANGE),
            (5.0, 5.0, TaxelFlags::empty()),
            (25.0, 25.0, TaxelFlags::empty()),
            (55.0, 55.0, TaxelFlags::empty()),
            (85.0, 55.0, TaxelFlags::TEMPERATURE_OUT_OF_RANGE),
            (f32::INFINITY, 55.0, TaxelFlags::TEMPERATURE_MISSING),
            (f32::NEG_INFINITY, 55.0, TaxelFlags::TEMPERATURE_MISSING),
            (f32::NAN, 55.0, TaxelFlags::TEMPERATURE_MISSING),
        ] {
            let used = tracker.resolve(Some(input), None, &law);
            assert_eq!(used.temperature_c, expected, "input {input}");
            assert_eq!(used.flags, flags, "input {input}");
            assert!(used.permittivity_ratio.is_finite());
        }
    }
}
