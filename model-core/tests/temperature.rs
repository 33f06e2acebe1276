//! The temperature plausibility rule, fed reading sequences written out here: a glitch shorter
//! than the confirmation is never applied, a level every reading confirms is applied within
//! 0.5 s (or its set count without times), a noisy but steady temperature is never flagged, and a
//! change of sensor is applied at once. Expectations follow from the rule as the module doc
//! states it, not from the tracker.

use model_core::temperature::{
    CONFIRM_READINGS, CONFIRM_SETS_WITHOUT_TIME, CONFIRM_SPAN_US, MAX_PLAUSIBLE_STEP_C,
    MAX_RATE_C_PER_S,
};
use model_core::{TaxelFlags, TemperatureLaw, TemperatureTracker};
use proptest::prelude::*;

/// The guarantee the issue asks for: a lasting new level is applied within this much device
/// time of its first reading.
const ACCEPTED_WITHIN_US: u64 = 500_000;

/// A level and a jump away from it, both inside the characterised 5–55 °C, the jump further
/// than the step allowance plus what the pad could move during the confirmation (so that only
/// the confirmation can apply it).
fn level_and_jump() -> impl Strategy<Value = (f32, f32)> {
    let smallest_jump_c = MAX_PLAUSIBLE_STEP_C + MAX_RATE_C_PER_S * 0.8 + 0.1;
    (5.0f32..=55.0, smallest_jump_c..50.0, any::<bool>())
        .prop_map(|(level_c, jump_c, up)| {
            (
                level_c,
                if up {
                    level_c + jump_c
                } else {
                    level_c - jump_c
                },
            )
        })
        .prop_filter(
            "the jump stays in the characterised range",
            |(_, jumped_c)| (5.0..=55.0).contains(jumped_c),
        )
}

/// Noise within ±0.9 °C, one value per set.
fn noise(sets: usize) -> impl Strategy<Value = Vec<f32>> {
    prop::collection::vec(-0.9f32..=0.9, sets)
}

fn clamp_to_range(value_c: f32) -> f32 {
    value_c.clamp(5.0, 55.0)
}

proptest! {
    /// A glitch of one set, or of a few sets spanning less than the confirmation (with sample
    /// times at 25 to 400 sets/s), is flagged and never applied; the first reading back at the
    /// level is applied unflagged.
    #[test]
    fn a_glitch_shorter_than_the_confirmation_is_never_applied(
        (level_c, glitch_c) in level_and_jump(),
        period_us in 2_500u64..=40_000,
        length_fraction in 0.0f64..1.0,
        glitch_noise in noise(200),
        timed in any::<bool>(),
    ) {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        // The longest glitch the rule must reject: its first to last reading less than the span
        // apart with times, one set short of the count without.
        let longest_sets = if timed {
            ((CONFIRM_SPAN_US - 1) / period_us + 1) as usize
        } else {
            usize::from(CONFIRM_SETS_WITHOUT_TIME) - 1
        };
        let glitch_sets = 1 + (length_fraction * longest_sets as f64) as usize;
        let glitch_sets = glitch_sets.min(longest_sets);
        let time = |set: usize| timed.then_some(1_000_000 + set as u64 * period_us);
        let first = tracker.resolve_at(Some(level_c), None, &law, time(0));
        prop_assert_eq!(first.temperature_c, level_c);
        for (set, noise_c) in (1..=glitch_sets).zip(&glitch_noise) {
            let reading_c = clamp_to_range(glitch_c + noise_c);
            let used = tracker.resolve_at(Some(reading_c), None, &law, time(set));
            prop_assert_eq!(used.temperature_c, level_c, "set {} of {}", set, glitch_sets);
            prop_assert!(used.flags.contains(TaxelFlags::TEMPERATURE_IMPLAUSIBLE));
        }
        let back = tracker.resolve_at(Some(level_c), None, &law, time(glitch_sets + 1));
        prop_assert_eq!(back.temperature_c, level_c);
        prop_assert_eq!(back.flags, TaxelFlags::empty());
    }

    /// A new level that every reading confirms (noisy within ±0.9 °C) is applied within 0.5 s
    /// of its first reading whenever sets are at most 0.25 s apart, at the first set at least
    /// the span after it that is also its third reading; only the sets before are flagged, and
    /// every set after is applied as measured.
    #[test]
    fn a_lasting_step_is_applied_within_half_a_second(
        (level_c, new_level_c) in level_and_jump(),
        period_us in 2_500u64..=250_000,
        step_noise in noise(400),
    ) {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        let start_us = 7_000_000;
        tracker.resolve_at(Some(level_c), None, &law, Some(start_us));
        let step_us = start_us + period_us;
        let mut accepted_us = None;
        for (set, noise_c) in step_noise.iter().enumerate() {
            let now_us = step_us + set as u64 * period_us;
            if now_us > step_us + 2 * ACCEPTED_WITHIN_US {
                break;
            }
            let reading_c = clamp_to_range(new_level_c + noise_c);
            let used = tracker.resolve_at(Some(reading_c), None, &law, Some(now_us));
            if accepted_us.is_none() && used.flags.contains(TaxelFlags::TEMPERATURE_IMPLAUSIBLE) {
                prop_assert_eq!(used.temperature_c, level_c, "held during the transition");
                continue;
            }
            accepted_us.get_or_insert(now_us);
            prop_assert_eq!(used.temperature_c, reading_c, "set {} at {} us", set, now_us);
            prop_assert_eq!(used.flags, TaxelFlags::empty());
        }
        let accepted_us = accepted_us.ok_or_else(|| TestCaseError::fail("never applied"))?;
        prop_assert!(accepted_us - step_us <= ACCEPTED_WITHIN_US, "after {} us", accepted_us - step_us);
        // The rule as stated: the first set at least the span after the step that is also the
        // third reading of the level, unless the allowance (grown with the time since the
        // reading in use) took it earlier.
        let confirmed_us = (0u64..)
            .map(|set| step_us + set * period_us)
            .skip(usize::from(CONFIRM_READINGS) - 1)
            .find(|time_us| time_us - step_us >= CONFIRM_SPAN_US)
            .unwrap_or(u64::MAX);
        prop_assert!(accepted_us <= confirmed_us, "{} > {}", accepted_us, confirmed_us);
        let elapsed_at_acceptance_s = (accepted_us - start_us) as f32 * 1e-6;
        if accepted_us < confirmed_us {
            // Taken by the allowance: the jump was within it by then.
            prop_assert!(
                (new_level_c - level_c).abs() <= MAX_PLAUSIBLE_STEP_C + MAX_RATE_C_PER_S * elapsed_at_acceptance_s + 0.9
            );
        }
    }

    /// Without sample times the same step is applied at its twelfth reading: within 0.5 s at
    /// every set rate of the device (25 to 100 sets/s).
    #[test]
    fn without_times_a_lasting_step_is_applied_at_the_set_count(
        (level_c, new_level_c) in level_and_jump(),
        step_noise in noise(40),
    ) {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        tracker.resolve(Some(level_c), None, &law);
        for (set, noise_c) in step_noise.iter().enumerate() {
            let reading_c = clamp_to_range(new_level_c + noise_c);
            let used = tracker.resolve(Some(reading_c), None, &law);
            if set + 1 < usize::from(CONFIRM_SETS_WITHOUT_TIME) {
                prop_assert_eq!(used.temperature_c, level_c);
                prop_assert_eq!(used.flags, TaxelFlags::TEMPERATURE_IMPLAUSIBLE);
            } else {
                prop_assert_eq!(used.temperature_c, reading_c);
                prop_assert_eq!(used.flags, TaxelFlags::empty());
            }
        }
        prop_assert!(f32::from(CONFIRM_SETS_WITHOUT_TIME) / 25.0 <= 0.5);
    }

    /// A steady temperature with noise within ±0.99 °C (and a drift of up to 2 °C/s when times
    /// are given) is applied as measured in every set and never flagged.
    #[test]
    fn a_noisy_steady_temperature_is_never_flagged(
        level_c in 15.0f32..=45.0,
        drift_c_per_s in -2.0f32..=2.0,
        readings_noise in prop::collection::vec(-0.99f32..=0.99, 300),
        timed in any::<bool>(),
    ) {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        for (set, noise_c) in readings_noise.iter().enumerate() {
            // 100 sets/s; without times the pad is steady.
            let time_s = set as f32 * 0.01;
            let drift_c = if timed { drift_c_per_s * time_s } else { 0.0 };
            let reading_c = level_c + drift_c + noise_c;
            let time_us = timed.then_some(set as u64 * 10_000);
            let used = tracker.resolve_at(Some(reading_c), None, &law, time_us);
            prop_assert_eq!(used.flags, TaxelFlags::empty(), "set {}", set);
            prop_assert_eq!(used.temperature_c, reading_c);
        }
    }

    /// After a change of sensor any reading in the characterised range is applied at once,
    /// even while a jump is pending; the next jump is judged again.
    #[test]
    fn a_change_of_sensor_is_applied_at_once(
        (level_c, other_c) in level_and_jump(),
        pending_sets in 0usize..5,
        timed in any::<bool>(),
    ) {
        let law = TemperatureLaw::article_default();
        let mut tracker = TemperatureTracker::default();
        let time = |set: usize| timed.then_some(set as u64 * 10_000);
        tracker.resolve_at(Some(level_c), None, &law, time(0));
        for set in 1..=pending_sets {
            tracker.resolve_at(Some(other_c), None, &law, time(set));
        }
        tracker.source_changed();
        let switched = tracker.resolve_at(Some(other_c), None, &law, time(pending_sets + 1));
        prop_assert_eq!(switched.temperature_c, other_c);
        prop_assert_eq!(switched.flags, TaxelFlags::empty());
        let jump_back = tracker.resolve_at(Some(level_c), None, &law, time(pending_sets + 2));
        prop_assert_eq!(jump_back.temperature_c, other_c);
        prop_assert_eq!(jump_back.flags, TaxelFlags::TEMPERATURE_IMPLAUSIBLE);
    }
}
