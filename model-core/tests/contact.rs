//! Contact on/off with hysteresis and debounce, fed force sequences written out here; expected
//! events and timestamps follow from the sequences by the rule as stated ("the last N forces all
//! above on / below off"), not from the detector.

use model_core::contact::{DEFAULT_DEBOUNCE_SETS, DEFAULT_OFF_THRESHOLD_N, DEFAULT_ON_THRESHOLD_N};
use model_core::{
    pad_force_from_pressures, ContactConfig, ContactConfigError, ContactDetector, ContactEvent,
    PadForce, PadForceFlags, PadGeometry,
};

const START_US: u64 = 5_000_000;
/// 100 sample sets per second.
const PERIOD_US: u64 = 10_000;

fn timestamp_us(index: usize) -> u64 {
    START_US + index as u64 * PERIOD_US
}

fn full(force_n: f32) -> PadForce {
    PadForce {
        force_n: Some(force_n),
        centre_of_pressure_mm: None,
        flags: PadForceFlags::empty(),
    }
}

fn missing() -> PadForce {
    PadForce {
        force_n: None,
        centre_of_pressure_mm: None,
        flags: PadForceFlags::EXCLUDED | PadForceFlags::NO_READING,
    }
}

/// Feeds the sets in order from index `first`; returns the events with their set index.
fn run(
    detector: &mut ContactDetector,
    first: usize,
    sets: &[PadForce],
) -> Vec<(usize, ContactEvent)> {
    let mut events = Vec::new();
    for (offset, set) in sets.iter().enumerate() {
        let index = first + offset;
        if let Some(event) = detector.update(set, timestamp_us(index)) {
            events.push((index, event));
        }
    }
    events
}

fn forces(values_n: &[f32]) -> Vec<PadForce> {
    values_n.iter().copied().map(full).collect()
}

fn in_contact() -> ContactDetector {
    let mut detector = ContactDetector::new(ContactConfig::default());
    let events = run(&mut detector, 0, &forces(&[0.5; 3]));
    assert_eq!(events.len(), 1);
    assert!(detector.in_contact());
    detector
}

#[test]
fn defaults_are_the_documented_numbers() {
    let config = ContactConfig::default();
    // 2 kPa on one 25 mm² taxel; 1.2 kPa for the off threshold.
    assert!((config.on_threshold_n() - 2.0 * 25.0 * 1e-3).abs() < 1e-7);
    assert!((config.off_threshold_n() - 1.2 * 25.0 * 1e-3).abs() < 1e-7);
    assert_eq!(config.debounce_sets(), 3);
    assert_eq!(
        (
            config.on_threshold_n(),
            config.off_threshold_n(),
            config.debounce_sets()
        ),
        (
            DEFAULT_ON_THRESHOLD_N,
            DEFAULT_OFF_THRESHOLD_N,
            DEFAULT_DEBOUNCE_SETS
        )
    );
    assert_eq!(ContactConfig::new(0.05, 0.03, 3), Ok(config));
}

#[test]
fn invalid_configurations_are_refused() {
    use ContactConfigError::*;
    let cases = [
        ((f32::NAN, 0.03, 3), NotFinite),
        ((0.05, f32::INFINITY, 3), NotFinite),
        ((0.05, 0.0, 3), OffThresholdNotPositive),
        ((0.05, -0.01, 3), OffThresholdNotPositive),
        ((0.05, 0.05, 3), OffNotBelowOn),
        ((0.03, 0.05, 3), OffNotBelowOn),
        ((0.05, 0.03, 0), ZeroDebounce),
    ];
    for ((on_n, off_n, debounce_sets), error) in cases {
        assert_eq!(ContactConfig::new(on_n, off_n, debounce_sets), Err(error));
    }
    assert!(ContactConfig::new(1.0, 0.5, 1).is_ok());
}

#[test]
fn a_clean_press_gives_one_start_and_one_end_at_the_confirming_sets() {
    let mut detector = ContactDetector::new(ContactConfig::default());
    let mut sequence = vec![0.0f32; 5];
    sequence.extend([0.5f32; 20]);
    sequence.extend([0.0f32; 10]);
    let events = run(&mut detector, 0, &forces(&sequence));
    // The third set above the threshold (index 5 + 2) and the third below (25 + 2).
    assert_eq!(
        events,
        vec![
            (
                7,
                ContactEvent::Started {
                    timestamp_us: START_US + 7 * PERIOD_US
                }
            ),
            (
                27,
                ContactEvent::Ended {
                    timestamp_us: START_US + 27 * PERIOD_US
                }
            ),
        ]
    );
    assert!(!detector.in_contact());
}

#[test]
fn chatter_around_the_on_threshold_starts_nothing() {
    let mut detector = ContactDetector::new(ContactConfig::default());
    // Never three sets in a row above 0.05 N.
    let chatter = [0.052f32, 0.054, 0.047, 0.051, 0.053, 0.049, 0.055, 0.046];
    let sequence: Vec<f32> = chatter.iter().copied().cycle().take(400).collect();
    assert!(run(&mut detector, 0, &forces(&sequence)).is_empty());
    assert!(!detector.in_contact());
    // Anywhere between the thresholds holds the state, however long.
    assert!(run(&mut detector, 400, &forces(&[0.04; 100])).is_empty());
    assert!(!detector.in_contact());
}

#[test]
fn chatter_around_the_off_threshold_ends_nothing() {
    let mut detector = in_contact();
    let chatter = [
        0.028f32, 0.025, 0.033, 0.029, 0.027, 0.031, 0.02, 0.01, 0.035,
    ];
    let sequence: Vec<f32> = chatter.iter().copied().cycle().take(400).collect();
    assert!(run(&mut detector, 3, &forces(&sequence)).is_empty());
    assert!(detector.in_contact());
    assert!(run(&mut detector, 403, &forces(&[0.04; 100])).is_empty());
    assert!(detector.in_contact());
}

/// The first index at or after `from` where the last `count` values all satisfy `condition`.
fn first_run_end(
    values: &[f32],
    from: usize,
    count: usize,
    condition: impl Fn(f32) -> bool,
) -> Option<usize> {
    (from..values.len()).find(|&index| {
        index + 1 >= count
            && values[index + 1 - count..=index]
                .iter()
                .all(|value| condition(*value))
    })
}

#[test]
fn a_noisy_press_gives_exactly_one_start_and_one_end() {
    // A press ramped up to 0.3 N, held, ramped down, with noise of up to ±0.009 N: less than
    // half the 0.02 N hysteresis band, so the ramps chatter across each threshold but never
    // across both.
    let mut state = 0x2545_f491u32;
    let mut noise_n = || {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (state >> 8) as f32 / (1u32 << 24) as f32 * 0.018 - 0.009
    };
    let mut sequence = Vec::new();
    sequence.extend((0..20).map(|_| 0.0f32));
    sequence.extend((0..60).map(|step| 0.3 * step as f32 / 60.0));
    sequence.extend((0..50).map(|_| 0.3f32));
    sequence.extend((0..60).map(|step| 0.3 * (60 - step) as f32 / 60.0));
    sequence.extend((0..30).map(|_| 0.0f32));
    let noisy: Vec<f32> = sequence.iter().map(|value| value + noise_n()).collect();
    let config = ContactConfig::default();
    let started = first_run_end(&noisy, 0, 3, |force_n| force_n > config.on_threshold_n()).unwrap();
    let ended = first_run_end(&noisy, started + 1, 3, |force_n| {
        force_n < config.off_threshold_n()
    })
    .unwrap();
    assert!(started > 20 && started < 80 && ended > 130 && ended < 220);

    let mut detector = ContactDetector::new(config);
    let events = run(&mut detector, 0, &forces(&noisy));
    assert_eq!(
        events,
        vec![
            (
                started,
                ContactEvent::Started {
                    timestamp_us: timestamp_us(started)
                }
            ),
            (
                ended,
                ContactEvent::Ended {
                    timestamp_us: timestamp_us(ended)
                }
            ),
        ]
    );
}

#[test]
fn a_missing_force_holds_the_state_and_restarts_the_count() {
    let mut detector = in_contact();
    assert!(run(&mut detector, 3, &vec![missing(); 50]).is_empty());
    assert!(detector.in_contact());
    let nan = PadForce {
        force_n: Some(f32::NAN),
        ..full(0.0)
    };
    let interrupted = [
        full(0.0),
        full(0.0),
        missing(),
        full(0.0),
        full(0.0),
        nan,
        full(0.0),
        full(0.0),
    ];
    assert!(run(&mut detector, 53, &interrupted).is_empty());
    assert!(detector.in_contact());
    assert_eq!(
        run(&mut detector, 61, &[full(0.0)]),
        vec![(
            61,
            ContactEvent::Ended {
                timestamp_us: timestamp_us(61)
            }
        )]
    );

    let interrupted = [full(0.5), full(0.5), missing(), full(0.5), full(0.5)];
    assert!(run(&mut detector, 62, &interrupted).is_empty());
    assert_eq!(
        run(&mut detector, 67, &[full(0.5)]),
        vec![(
            67,
            ContactEvent::Started {
                timestamp_us: timestamp_us(67)
            }
        )]
    );
}

#[test]
fn a_taxel_that_faults_during_a_contact_cannot_end_it() {
    let geometry = PadGeometry::default();
    let mut detector = ContactDetector::new(ContactConfig::default());
    // Pressed on C11 with every taxel reading.
    let pressed =
        pad_force_from_pressures(&[Some(40.0), Some(0.0), Some(0.0), Some(0.0)], &geometry);
    assert_eq!(run(&mut detector, 0, &[pressed; 3]).len(), 1);
    // C11 saturates under the load: the three others read nothing.
    let c11_faulted = pad_force_from_pressures(&[None, Some(0.0), Some(0.0), Some(0.0)], &geometry);
    assert_eq!(c11_faulted.force_n, Some(0.0));
    assert!(run(&mut detector, 3, &[c11_faulted; 30]).is_empty());
    assert!(detector.in_contact());
    // Released with every taxel reading again.
    let released = pad_force_from_pressures(&[Some(0.0); 4], &geometry);
    assert_eq!(
        run(&mut detector, 33, &[released; 3]),
        vec![(
            35,
            ContactEvent::Ended {
                timestamp_us: timestamp_us(35)
            }
        )]
    );
}

#[test]
fn a_taxel_dead_before_the_contact_neither_starts_nor_prevents_anything() {
    let geometry = PadGeometry::default();
    let mut detector = ContactDetector::new(ContactConfig::default());
    let unloaded = pad_force_from_pressures(&[Some(0.0), Some(0.0), Some(0.0), None], &geometry);
    let pressed = pad_force_from_pressures(&[Some(0.0), Some(30.0), Some(0.0), None], &geometry);
    assert!(pressed.flags.contains(PadForceFlags::PARTIAL));
    assert!(run(&mut detector, 0, &[unloaded; 10]).is_empty());
    // A partial force is a lower bound: enough to start.
    assert_eq!(
        run(&mut detector, 10, &[pressed; 3]),
        vec![(
            12,
            ContactEvent::Started {
                timestamp_us: timestamp_us(12)
            }
        )]
    );
    // The same taxels read as at the start: enough to end.
    assert_eq!(
        run(&mut detector, 13, &[unloaded; 3]),
        vec![(
            15,
            ContactEvent::Ended {
                timestamp_us: timestamp_us(15)
            }
        )]
    );
}

#[test]
fn a_debounce_of_one_changes_on_the_first_set() {
    let mut detector = ContactDetector::new(ContactConfig::new(0.05, 0.03, 1).unwrap());
    let events = run(&mut detector, 0, &forces(&[0.0, 0.06, 0.04, 0.02, 0.04]));
    assert_eq!(
        events,
        vec![
            (
                1,
                ContactEvent::Started {
                    timestamp_us: timestamp_us(1)
                }
            ),
            (
                3,
                ContactEvent::Ended {
                    timestamp_us: timestamp_us(3)
                }
            ),
        ]
    );
}

#[test]
fn reset_returns_to_no_contact_without_an_event() {
    let mut detector = in_contact();
    // Two sets towards the end pending, then a reset: nothing carries over.
    assert!(run(&mut detector, 3, &forces(&[0.0, 0.0])).is_empty());
    detector.reset();
    assert!(!detector.in_contact());
    assert_eq!(detector.config(), &ContactConfig::default());
    assert!(run(&mut detector, 5, &forces(&[0.5, 0.5])).is_empty());
    assert_eq!(run(&mut detector, 7, &forces(&[0.5])).len(), 1);
}
