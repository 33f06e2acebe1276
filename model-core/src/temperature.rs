//! Which temperature a sample is corrected with: the measured one clamped to the characterised
//! range, or, when it is missing, the last valid one (else the tare's, else the reference).
//!
//! Plausibility: the pad (1 mm of PDMS composite on a gripper or glove, its sensor on the board
//! beneath) cannot warm or cool faster than [`MAX_RATE_C_PER_S`]; its sensor updates about once a
//! second, so one update may step by [`MAX_PLAUSIBLE_STEP_C`]. A reading further from the
//! temperature in use than `MAX_PLAUSIBLE_STEP_C + MAX_RATE_C_PER_S x (time since the last
//! reading)` is flagged `temperature_implausible` and not applied as measured: the temperature
//! in use moves towards it at `MAX_RATE_C_PER_S`, flagged until it gets there. So a one-set
//! glitch (25 -> 55 °C) barely moves it, and a real jump (a sensor back after a gap) is followed
//! within seconds. Without sample times (a caller that gives none) the time between sets is
//! taken as unknown: the step allowance is `MAX_PLAUSIBLE_STEP_C` and the move
//! [`SLEW_C_PER_SET`] per set (5–20 °C/s at 100–400 sets/s).

use crate::bounds::clamp_f32;
use crate::calibration::TemperatureLaw;
use crate::flags::TaxelFlags;

/// Temperature at which the calibration curve holds and the permittivity ratio is 1, °C.
pub const REFERENCE_TEMPERATURE_C: f32 = 25.0;

/// Largest step of one sensor update that is applied as measured, °C.
pub const MAX_PLAUSIBLE_STEP_C: f32 = 2.0;

/// Fastest the pad's temperature can change, °C per second.
pub const MAX_RATE_C_PER_S: f32 = 5.0;

/// Largest move of the temperature in use towards an implausible reading per sample set when
/// the time between sets is unknown, °C.
pub const SLEW_C_PER_SET: f32 = 0.05;

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
    last_valid_time_us: Option<u64>,
}

impl TemperatureTracker {
    /// Resolves this sample's temperature without a sample time (see the module doc).
    /// `fallback_c` (the tare temperature) is used when no valid temperature was ever seen.
    pub fn resolve(
        &mut self,
        measured_c: Option<f32>,
        fallback_c: Option<f32>,
        law: &TemperatureLaw,
    ) -> TemperatureUsed {
        self.resolve_at(measured_c, fallback_c, law, None)
    }

    /// Resolves this sample's temperature; `time_us` is the sample's time, when known, on any
    /// clock that only moves forward (a time earlier than the last counts as unknown).
    pub fn resolve_at(
        &mut self,
        measured_c: Option<f32>,
        fallback_c: Option<f32>,
        law: &TemperatureLaw,
        time_us: Option<u64>,
    ) -> TemperatureUsed {
        let (minimum_c, maximum_c) = (law.characterised_min_c(), law.characterised_max_c());
        let (temperature_c, flags) = match measured_c {
            Some(value) if value.is_finite() => {
                let clamped = clamp_f32(value, minimum_c, maximum_c);
                let mut flags = if clamped != value {
                    TaxelFlags::TEMPERATURE_OUT_OF_RANGE
                } else {
                    TaxelFlags::empty()
                };
                let elapsed_s = match (time_us, self.last_valid_time_us) {
                    (Some(now), Some(then)) if now >= then => Some((now - then) as f32 * 1.0e-6),
                    _ => None,
                };
                let (allowed_c, slew_c) = match elapsed_s {
                    Some(elapsed_s) => (
                        MAX_PLAUSIBLE_STEP_C + MAX_RATE_C_PER_S * elapsed_s,
                        MAX_RATE_C_PER_S * elapsed_s,
                    ),
                    None => (MAX_PLAUSIBLE_STEP_C, SLEW_C_PER_SET),
                };
                let applied = match self.last_valid_c {
                    Some(last) if !((clamped - last).abs() <= allowed_c) => {
                        flags |= TaxelFlags::TEMPERATURE_IMPLAUSIBLE;
                        last + clamp_f32(clamped - last, -slew_c, slew_c)
                    }
                    _ => clamped,
                };
                self.last_valid_c = Some(applied);
                self.last_valid_time_us = time_us;
                (applied, flags)
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
    fn a_one_set_glitch_is_flagged_and_barely_applied() {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        assert_eq!(tracker.resolve(Some(25.0), None, &law).temperature_c, 25.0);
        let glitch = tracker.resolve(Some(55.0), None, &law);
        assert_eq!(glitch.flags, TaxelFlags::TEMPERATURE_IMPLAUSIBLE);
        assert!((glitch.temperature_c - 25.05).abs() < 1e-5);
        let back = tracker.resolve(Some(25.0), None, &law);
        assert_eq!(back.flags, TaxelFlags::empty());
        assert_eq!(back.temperature_c, 25.0);
        // A real warm-up of 1 °C per update is applied as measured.
        for step in 1..=10 {
            let used = tracker.resolve(Some(25.0 + step as f32), None, &law);
            assert_eq!(used.temperature_c, 25.0 + step as f32);
            assert_eq!(used.flags, TaxelFlags::empty());
        }
        // A lasting jump is followed at the slew rate, flagged until it is reached.
        let mut sets = 0;
        loop {
            let used = tracker.resolve(Some(50.0), None, &law);
            sets += 1;
            if used.flags.is_empty() {
                assert_eq!(used.temperature_c, 50.0);
                break;
            }
            assert!(sets < 1000);
        }
        assert!((250..=300).contains(&sets), "{sets}");
    }

    #[test]
    fn with_sample_times_the_allowance_grows_with_the_time_between_them() {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        tracker.resolve_at(Some(25.0), None, &law, Some(0));
        // 15 °C in 1 s: more than 2 + 5 x 1 °C.
        let fast = tracker.resolve_at(Some(40.0), None, &law, Some(1_000_000));
        assert_eq!(fast.flags, TaxelFlags::TEMPERATURE_IMPLAUSIBLE);
        assert!(
            (fast.temperature_c - 30.0).abs() < 1e-4,
            "{}",
            fast.temperature_c
        );
        // 10 s later 40 °C is plausible: 2 + 5 x 10 °C.
        let slow = tracker.resolve_at(Some(40.0), None, &law, Some(11_000_000));
        assert_eq!(slow.flags, TaxelFlags::empty());
        assert_eq!(slow.temperature_c, 40.0);
        // A clock that goes back counts as unknown time: the per-set rule.
        let back = tracker.resolve_at(Some(50.0), None, &law, Some(5));
        assert_eq!(back.flags, TaxelFlags::TEMPERATURE_IMPLAUSIBLE);
        assert!((back.temperature_c - 40.05).abs() < 1e-4);
    }

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
            // Each input as the first reading (so no plausibility step), the non-finite ones
            // after a valid 55 °C.
            let mut tracker = TemperatureTracker::default();
            if !input.is_finite() {
                tracker.resolve(Some(55.0), None, &law);
            }
            let used = tracker.resolve(Some(input), None, &law);
            assert_eq!(used.temperature_c, expected, "input {input}");
            assert_eq!(used.flags, flags, "input {input}");
            assert!(used.permittivity_ratio.is_finite());
        }
    }
}
