//! Which temperature a sample is corrected with: the measured one clamped to the characterised
//! range, or, when it is missing, the temperature in use (else the tare's, else the reference);
//! and whether a reading that jumps is a glitch or a new level.
//!
//! # Plausibility
//!
//! The pad (1 mm of PDMS composite on a gripper or glove, its sensor on the board beneath)
//! cannot warm or cool faster than [`MAX_RATE_C_PER_S`]. A reading is *plausible* when it is
//! within `MAX_PLAUSIBLE_STEP_C + MAX_RATE_C_PER_S x (time since the reading in use was
//! measured)` of the temperature in use ([`MAX_PLAUSIBLE_STEP_C`] alone when that time is
//! unknown: no sample times, or a clock that went back). A plausible reading is applied as
//! measured and becomes the temperature in use.
//!
//! An implausible reading is either a glitch (a bad transfer, a sensor hiccup) or a new level
//! (a sensor back after a gap, a recording whose temperature steps). It starts a *pending
//! level*, or continues the one pending when it is within [`CONFIRM_TOLERANCE_C`] of that
//! level's first reading (one further away starts a new pending level from itself). The level
//! is *confirmed*, and its confirming reading applied as measured, when it has
//! [`CONFIRM_READINGS`] readings (the first included) spanning at least [`CONFIRM_SPAN_US`] of
//! sample time; when a sample time is missing (a caller that gives none, a clock that went
//! back), when it has [`CONFIRM_SETS_WITHOUT_TIME`] readings instead. Until then every set is
//! flagged `temperature_implausible` and corrected with the temperature in use before the jump,
//! held as it was: a glitch moves nothing, and a real step costs its sets the old temperature's
//! error for the confirmation time, flagged. A plausible reading in between is applied and
//! drops the pending level; a missing reading neither confirms nor drops it.
//!
//! So a glitch shorter than [`CONFIRM_SPAN_US`] (with sample times) or than
//! [`CONFIRM_SETS_WITHOUT_TIME`] sets (without) is never applied, and a new level that every
//! reading confirms is applied at the first set at least [`CONFIRM_SPAN_US`] after the jump and
//! at least the [`CONFIRM_READINGS`]th reading of it: within 0.29 s at the device's slowest set
//! rate (25 sets/s), within 0.5 s whenever sets are at most 0.25 s apart. Without sample times,
//! [`CONFIRM_SETS_WITHOUT_TIME`] sets are 0.12–0.48 s at the 25–100 sets/s the device runs.
//! The price: a wrong value that a sensor keeps reporting for longer than that (the TMP117
//! holds each conversion for its one-second period) is taken as a level, flagged only until
//! it is confirmed.
//!
//! A noisy but steady temperature is never flagged while consecutive applied readings stay
//! within [`MAX_PLAUSIBLE_STEP_C`] of each other (noise within ±1 °C of the level).
//!
//! When the acquisition switches to another sensor (the pad's TMP117 lost and the MCU's die
//! sensor taking over with its offset, or the TMP117 back), the step between the two sensors is
//! no glitch: [`TemperatureTracker::source_changed`] makes the next valid reading be applied as
//! measured (and drops a pending level).

use crate::bounds::clamp_f32;
use crate::calibration::TemperatureLaw;
use crate::flags::TaxelFlags;

/// Temperature at which the calibration curve holds and the permittivity ratio is 1, °C.
pub const REFERENCE_TEMPERATURE_C: f32 = 25.0;

/// Largest step from the temperature in use that is applied as measured however little time
/// passed since it was measured, °C (the whole allowance when sample times are unknown).
pub const MAX_PLAUSIBLE_STEP_C: f32 = 2.0;

/// Fastest the pad's temperature can change, °C per second.
pub const MAX_RATE_C_PER_S: f32 = 5.0;

/// Largest distance of a reading from the first reading of a pending level for it to confirm
/// that level, °C: over [`CONFIRM_SPAN_US`] the pad moves by at most 1.25 °C, and the die
/// sensor's conversions scatter by about ±0.6 °C (±2 ADC codes of 0.32 °C).
pub const CONFIRM_TOLERANCE_C: f32 = 2.0;

/// Fewest readings of a pending level (its first included) that confirm it.
pub const CONFIRM_READINGS: u8 = 3;

/// Shortest span of sample time, from a pending level's first reading to its confirming
/// reading, µs: a glitch shorter than this is never applied.
pub const CONFIRM_SPAN_US: u64 = 250_000;

/// Readings of a pending level (its first included) that confirm it when a sample time is
/// missing: 0.12 s at 100 sets/s, 0.48 s at 25 sets/s, so within 0.5 s at every set rate of
/// the device.
pub const CONFIRM_SETS_WITHOUT_TIME: u8 = 12;

/// The temperature a sample was corrected with.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TemperatureUsed {
    /// Temperature used, °C (always finite and within the characterised range).
    pub temperature_c: f32,
    /// eps_r at that temperature over eps_r at the reference.
    pub permittivity_ratio: f32,
    /// TEMPERATURE_MISSING, TEMPERATURE_OUT_OF_RANGE and/or TEMPERATURE_IMPLAUSIBLE, or empty.
    pub flags: TaxelFlags,
}

bitflags::bitflags! {
    /// Which of a tracker's stored values hold something.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    struct Known: u8 {
        /// `in_use_c` is the temperature in use.
        const IN_USE = 1 << 0;
        /// `in_use_time_us` is when it was measured.
        const IN_USE_TIME = 1 << 1;
        /// `pending_after_us` is when the pending level's first reading came.
        const PENDING_TIME = 1 << 2;
        /// The next valid reading comes from another sensor: it is applied as measured.
        const NEW_SOURCE = 1 << 3;
    }
}

/// The temperature in use between samples, and a jump waiting for confirmation (see the
/// module doc).
// Every pad model holds one, and the pad model's size is budgeted (pad.rs): 24 bytes on the
// Cortex-M4F, so what is optional is marked in `known` rather than wrapped in `Option`s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TemperatureTracker {
    /// When the temperature in use was measured, µs (with [`Known::IN_USE_TIME`]).
    in_use_time_us: u64,
    /// The temperature in use, °C (with [`Known::IN_USE`]).
    in_use_c: f32,
    /// The first reading of the pending level, °C (with `pending_readings > 0`).
    pending_c: f32,
    /// When the pending level's first reading came, µs after `in_use_time_us`, saturating (with
    /// [`Known::PENDING_TIME`]). A level can only be pending while the allowance is below the
    /// characterised range, within seconds of the reading in use.
    pending_after_us: u32,
    /// Readings of the pending level so far; 0: none is pending.
    pending_readings: u8,
    known: Known,
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
    /// clock that only moves forward (a time earlier than the reading in use counts as
    /// unknown).
    pub fn resolve_at(
        &mut self,
        measured_c: Option<f32>,
        fallback_c: Option<f32>,
        law: &TemperatureLaw,
        time_us: Option<u64>,
    ) -> TemperatureUsed {
        let (temperature_c, flags) = self.temperature_at(measured_c, fallback_c, law, time_us);
        TemperatureUsed {
            temperature_c,
            permittivity_ratio: law.permittivity_ratio(temperature_c),
            flags,
        }
    }

    /// [`TemperatureTracker::resolve_at`] without the permittivity: the temperature used and
    /// its flags (a pad model keeps the permittivity of the last temperature).
    pub(crate) fn temperature_at(
        &mut self,
        measured_c: Option<f32>,
        fallback_c: Option<f32>,
        law: &TemperatureLaw,
        time_us: Option<u64>,
    ) -> (f32, TaxelFlags) {
        let (minimum_c, maximum_c) = (law.characterised_min_c(), law.characterised_max_c());
        match measured_c {
            Some(value) if value.is_finite() => {
                let clamped = clamp_f32(value, minimum_c, maximum_c);
                let range_flags = if clamped != value {
                    TaxelFlags::TEMPERATURE_OUT_OF_RANGE
                } else {
                    TaxelFlags::empty()
                };
                if self.applies(clamped, time_us) {
                    (clamped, range_flags)
                } else {
                    (
                        self.in_use_c,
                        range_flags | TaxelFlags::TEMPERATURE_IMPLAUSIBLE,
                    )
                }
            }
            _ => {
                let substitute = self
                    .last_valid_c()
                    .or(fallback_c.filter(|value| value.is_finite()))
                    .unwrap_or(REFERENCE_TEMPERATURE_C);
                let substitute = clamp_f32(substitute, minimum_c, maximum_c);
                (substitute, TaxelFlags::TEMPERATURE_MISSING)
            }
        }
    }

    /// The next valid reading comes from another sensor (the acquisition switched between the
    /// pad's sensor and the fallback): it is applied as measured, whatever its step from the
    /// temperature in use, and a pending level is dropped.
    pub fn source_changed(&mut self) {
        self.known.insert(Known::NEW_SOURCE);
    }

    /// The temperature in use: the last reading applied as measured, °C (None until one was).
    pub fn last_valid_c(&self) -> Option<f32> {
        self.known.contains(Known::IN_USE).then_some(self.in_use_c)
    }

    /// Whether a finite reading already clamped to the characterised range is applied as
    /// measured (it then is the temperature in use); otherwise it was counted towards a pending
    /// level and the temperature in use stays.
    fn applies(&mut self, reading_c: f32, time_us: Option<u64>) -> bool {
        // Sample time since the reading in use, µs, when both times are known and in order.
        let elapsed_us = match (time_us, self.known.contains(Known::IN_USE_TIME)) {
            (Some(now_us), true) => now_us.checked_sub(self.in_use_time_us),
            _ => None,
        };
        // u32 µs (71 minutes) are plenty for the allowance and convert to f32 in one
        // instruction on the M4 (u64 needs a library call).
        let elapsed_us = elapsed_us.map(|elapsed_us| u32::try_from(elapsed_us).unwrap_or(u32::MAX));
        let plausible = match self.last_valid_c() {
            Some(in_use_c) if !self.known.contains(Known::NEW_SOURCE) => {
                let allowed_c = MAX_PLAUSIBLE_STEP_C
                    + MAX_RATE_C_PER_S
                        * elapsed_us.map_or(0.0, |elapsed_us| elapsed_us as f32 * 1.0e-6);
                // NaN cannot reach here (the reading is finite, so is the temperature in use).
                (reading_c - in_use_c).abs() <= allowed_c
            }
            _ => true,
        };
        if !plausible && !self.confirms(reading_c, elapsed_us) {
            return false;
        }
        self.in_use_c = reading_c;
        self.in_use_time_us = time_us.unwrap_or(0);
        self.known = if time_us.is_some() {
            Known::IN_USE | Known::IN_USE_TIME
        } else {
            Known::IN_USE
        };
        self.pending_readings = 0;
        true
    }

    /// Counts an implausible reading towards the pending level (or starts one with it);
    /// whether the level is now confirmed. `after_us` is the reading's time after the reading in
    /// use, when known.
    fn confirms(&mut self, reading_c: f32, after_us: Option<u32>) -> bool {
        let continues =
            self.pending_readings > 0 && (reading_c - self.pending_c).abs() <= CONFIRM_TOLERANCE_C;
        if !continues {
            self.pending_c = reading_c;
            self.pending_readings = 1;
            self.pending_after_us = after_us.unwrap_or(0);
            self.known.set(Known::PENDING_TIME, after_us.is_some());
            return false;
        }
        self.pending_readings = self.pending_readings.saturating_add(1);
        let span_us = match (after_us, self.known.contains(Known::PENDING_TIME)) {
            (Some(after_us), true) => after_us.checked_sub(self.pending_after_us),
            _ => None,
        };
        match span_us {
            Some(span_us) => {
                self.pending_readings >= CONFIRM_READINGS && u64::from(span_us) >= CONFIRM_SPAN_US
            }
            None => self.pending_readings >= CONFIRM_SETS_WITHOUT_TIME,
        }
    }
}

// The tracker sits in every pad model, whose size is budgeted (pad.rs).
const _: () = assert!(core::mem::size_of::<TemperatureTracker>() <= 24);

#[cfg(test)]
mod tests {
    use super::*;

    /// 100 sample sets per second.
    const SET_US: u64 = 10_000;

    #[test]
    fn a_one_set_glitch_is_flagged_and_not_applied() {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        assert_eq!(tracker.resolve(Some(25.0), None, &law).temperature_c, 25.0);
        let glitch = tracker.resolve(Some(55.0), None, &law);
        assert_eq!(glitch.flags, TaxelFlags::TEMPERATURE_IMPLAUSIBLE);
        assert_eq!(glitch.temperature_c, 25.0);
        assert_eq!(glitch.permittivity_ratio, 1.0);
        let back = tracker.resolve(Some(25.0), None, &law);
        assert_eq!(back.flags, TaxelFlags::empty());
        assert_eq!(back.temperature_c, 25.0);
        // A real warm-up of 1 °C per update is applied as measured.
        for step in 1..=10 {
            let used = tracker.resolve(Some(25.0 + step as f32), None, &law);
            assert_eq!(used.temperature_c, 25.0 + step as f32);
            assert_eq!(used.flags, TaxelFlags::empty());
        }
    }

    #[test]
    fn without_times_a_lasting_jump_is_applied_at_its_twelfth_reading() {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        tracker.resolve(Some(35.0), None, &law);
        // One set short of the confirmation, then back: never applied.
        for _ in 1..CONFIRM_SETS_WITHOUT_TIME {
            let used = tracker.resolve(Some(50.0), None, &law);
            assert_eq!(used.temperature_c, 35.0);
            assert_eq!(used.flags, TaxelFlags::TEMPERATURE_IMPLAUSIBLE);
        }
        assert_eq!(
            tracker.resolve(Some(35.5), None, &law).flags,
            TaxelFlags::empty()
        );
        for set in 1..=CONFIRM_SETS_WITHOUT_TIME {
            let used = tracker.resolve(Some(50.0), None, &law);
            if set < CONFIRM_SETS_WITHOUT_TIME {
                assert_eq!(used.temperature_c, 35.5);
                assert_eq!(used.flags, TaxelFlags::TEMPERATURE_IMPLAUSIBLE);
            } else {
                assert_eq!(used.temperature_c, 50.0);
                assert_eq!(used.flags, TaxelFlags::empty());
            }
        }
        assert_eq!(tracker.last_valid_c(), Some(50.0));
        let after = tracker.resolve(Some(50.2), None, &law);
        assert_eq!(
            (after.temperature_c, after.flags),
            (50.2, TaxelFlags::empty())
        );
    }

    #[test]
    fn with_times_a_lasting_jump_is_applied_a_quarter_second_after_it() {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        tracker.resolve_at(Some(25.0), None, &law, Some(1_000_000));
        let step_us = 1_000_000 + SET_US;
        let mut set = 0u64;
        let accepted_us = loop {
            let now_us = step_us + set * SET_US;
            let used = tracker.resolve_at(Some(55.0), None, &law, Some(now_us));
            if used.flags.is_empty() {
                assert_eq!(used.temperature_c, 55.0);
                break now_us;
            }
            assert_eq!(used.flags, TaxelFlags::TEMPERATURE_IMPLAUSIBLE);
            assert_eq!(used.temperature_c, 25.0);
            set += 1;
            assert!(set < 100);
        };
        assert_eq!(accepted_us - step_us, CONFIRM_SPAN_US);
    }

    #[test]
    fn with_sparse_times_three_readings_are_needed() {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        tracker.resolve_at(Some(25.0), None, &law, Some(0));
        // Sets 0.2 s apart: a 20 °C jump is beyond 2 + 5 x 0.4 °C. The second reading of the
        // level is 0.2 s after its first (too soon), the third 0.4 s (confirmed).
        for (time_us, expected_c, flags) in [
            (200_000, 25.0, TaxelFlags::TEMPERATURE_IMPLAUSIBLE),
            (400_000, 25.0, TaxelFlags::TEMPERATURE_IMPLAUSIBLE),
            (600_000, 45.0, TaxelFlags::empty()),
        ] {
            let used = tracker.resolve_at(Some(45.0), None, &law, Some(time_us));
            assert_eq!(
                (used.temperature_c, used.flags),
                (expected_c, flags),
                "{time_us}"
            );
        }
    }

    #[test]
    fn a_reading_far_from_the_pending_level_starts_another() {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        tracker.resolve_at(Some(25.0), None, &law, Some(0));
        // 0.2 s at 55 °C, then 40 °C for good: the 40 °C level is counted from its own start.
        let mut time_us = 0;
        for _ in 0..20 {
            time_us += SET_US;
            let used = tracker.resolve_at(Some(55.0), None, &law, Some(time_us));
            assert_eq!(used.temperature_c, 25.0);
        }
        let level_start_us = time_us + SET_US;
        let accepted_us = loop {
            time_us += SET_US;
            let used = tracker.resolve_at(Some(40.0), None, &law, Some(time_us));
            if used.temperature_c == 40.0 {
                break time_us;
            }
            assert_eq!(used.temperature_c, 25.0);
            assert!(time_us < 2_000_000);
        };
        assert_eq!(accepted_us - level_start_us, CONFIRM_SPAN_US);
    }

    #[test]
    fn with_sample_times_the_allowance_grows_with_the_time_between_them() {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        tracker.resolve_at(Some(25.0), None, &law, Some(0));
        // 15 °C in 1 s: more than 2 + 5 x 1 °C.
        let fast = tracker.resolve_at(Some(40.0), None, &law, Some(1_000_000));
        assert_eq!(fast.flags, TaxelFlags::TEMPERATURE_IMPLAUSIBLE);
        assert_eq!(fast.temperature_c, 25.0);
        // 10 s after the reading in use, 45 °C is plausible: 2 + 5 x 10 °C.
        let slow = tracker.resolve_at(Some(45.0), None, &law, Some(10_000_000));
        assert_eq!(slow.flags, TaxelFlags::empty());
        assert_eq!(slow.temperature_c, 45.0);
        // A clock that goes back counts as unknown time: the step allowance and the set count.
        let back = tracker.resolve_at(Some(50.0), None, &law, Some(5));
        assert_eq!(back.flags, TaxelFlags::TEMPERATURE_IMPLAUSIBLE);
        assert_eq!(back.temperature_c, 45.0);
    }

    #[test]
    fn a_new_source_is_applied_at_once() {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        tracker.resolve_at(Some(30.0), None, &law, Some(0));
        tracker.resolve_at(Some(55.0), None, &law, Some(SET_US));
        tracker.source_changed();
        // A missing reading in between keeps the temperature in use, and the change pending.
        let missing = tracker.resolve_at(None, None, &law, Some(2 * SET_US));
        assert_eq!(missing.temperature_c, 30.0);
        let switched = tracker.resolve_at(Some(38.0), None, &law, Some(3 * SET_US));
        assert_eq!(
            (switched.temperature_c, switched.flags),
            (38.0, TaxelFlags::empty())
        );
        // Once only: the next jump is judged again.
        let jump = tracker.resolve_at(Some(30.0), None, &law, Some(4 * SET_US));
        assert_eq!(
            (jump.temperature_c, jump.flags),
            (38.0, TaxelFlags::TEMPERATURE_IMPLAUSIBLE)
        );
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
        // Out of range and implausible at once: both flags, the temperature in use kept.
        let mut tracker = TemperatureTracker::default();
        tracker.resolve(Some(25.0), None, &law);
        let used = tracker.resolve(Some(85.0), None, &law);
        assert_eq!(used.temperature_c, 25.0);
        assert_eq!(
            used.flags,
            TaxelFlags::TEMPERATURE_OUT_OF_RANGE | TaxelFlags::TEMPERATURE_IMPLAUSIBLE
        );
    }
}
