//! Every fault of the reliability report, end to end through the simulated device, a few runs
//! each: no wrong pressure is ever reported, every missing sample set is accounted for, and the
//! stream recovers. The full report (20 runs per fault) is
//! `cargo run --release -p taxel-tests --bin reliability`.

// Test helpers may panic: a failure is the test failing.
#![allow(clippy::panic)]

use taxel_tests::reliability::{run_fault, FaultKind};

#[test]
fn every_fault_is_flagged_counted_and_recovered() {
    for kind in FaultKind::ALL {
        let outcome = run_fault(kind, 2).unwrap_or_else(|error| panic!("{}: {error}", kind.name()));
        println!(
            "{}: {} pressures, RMS {:.4} kPa, max {:.4} kPa from the truth",
            kind.name(),
            outcome.pressures_checked,
            outcome.rms_error_kpa(),
            outcome.max_error_kpa
        );
        assert_eq!(outcome.wrong_pressures, 0, "{}: {outcome:?}", kind.name());
        assert_eq!(
            outcome.sets_lost_silently(),
            0,
            "{}: {outcome:?}",
            kind.name()
        );
        assert_eq!(
            outcome.recovery_us.len(),
            2,
            "{}: did not recover: {outcome:?}",
            kind.name()
        );
        assert!(
            outcome.pressures_checked > 1000,
            "{}: {outcome:?}",
            kind.name()
        );
        // Against the simulator's independent truth: noise (about 0.05 kPa rms over 3-41 kPa)
        // and the factory calibration's interpolation; a model 0.5 kPa off fails this.
        assert!(
            outcome.rms_error_kpa() < 0.1,
            "{}: RMS {} kPa",
            kind.name(),
            outcome.rms_error_kpa()
        );
    }
}

#[test]
fn wire_flag_bits_are_model_core_flag_bits() {
    use model_core::TaxelFlags;
    let pairs = [
        (wire::flags::BELOW_BASELINE, TaxelFlags::BELOW_BASELINE),
        (wire::flags::OVER_RANGE, TaxelFlags::OVER_RANGE),
        (wire::flags::SHORTED, TaxelFlags::SHORTED),
        (wire::flags::OPEN, TaxelFlags::OPEN),
        (wire::flags::SATURATED, TaxelFlags::SATURATED),
        (
            wire::flags::TEMPERATURE_MISSING,
            TaxelFlags::TEMPERATURE_MISSING,
        ),
        (
            wire::flags::TEMPERATURE_OUT_OF_RANGE,
            TaxelFlags::TEMPERATURE_OUT_OF_RANGE,
        ),
        (wire::flags::NOT_TARED, TaxelFlags::NOT_TARED),
        (wire::flags::CONVERTER_ERROR, TaxelFlags::CONVERTER_ERROR),
        (wire::flags::STUCK, TaxelFlags::STUCK),
        (wire::flags::INVALID_INPUT, TaxelFlags::INVALID_INPUT),
        (
            wire::flags::BASELINE_TRACKING_LIMIT,
            TaxelFlags::BASELINE_TRACKING_LIMIT,
        ),
        (
            wire::flags::TEMPERATURE_FALLBACK,
            TaxelFlags::TEMPERATURE_FALLBACK,
        ),
        (
            wire::flags::TEMPERATURE_IMPLAUSIBLE,
            TaxelFlags::TEMPERATURE_IMPLAUSIBLE,
        ),
        (
            wire::flags::BASELINE_FAR_FROM_CALIBRATION,
            TaxelFlags::BASELINE_FAR_FROM_CALIBRATION,
        ),
    ];
    for (wire_bit, model_flag) in pairs {
        assert_eq!(wire_bit, model_flag.bits());
    }
    assert_eq!(wire::flags::FAULT_MASK, TaxelFlags::FAULTS.bits());
    assert_eq!(wire::flags::DEFINED_MASK, TaxelFlags::all().bits());
}

/// One pad of several fails: it is flagged while it fails and recovers on its own; the others
/// keep their values and their flags, nothing is lost, and they keep their rate: 95 % or more
/// when the pad is unplugged, NACKs or its channel sticks, 80 % or more when its converter
/// stalls (every retry of a stalled converter waits out its DONE timeout, 25 ms, which the
/// back-off spaces to one per 320 ms).
#[test]
fn a_failing_pad_is_flagged_and_recovers_and_the_others_do_not_notice() {
    use taxel_tests::pad_faults::{run_pad_fault, PadFaultKind};
    for kind in PadFaultKind::ALL {
        let outcome =
            run_pad_fault(kind, 2).unwrap_or_else(|error| panic!("{}: {error}", kind.name()));
        println!("{outcome:?}");
        assert!(outcome.failing_frames_during > 100, "{outcome:?}");
        assert_eq!(
            outcome.failing_frames_flagged, outcome.failing_frames_during,
            "{outcome:?}"
        );
        assert_eq!(outcome.recovery_us.len(), 2, "did not recover: {outcome:?}");
        let rate_kept = match kind {
            PadFaultKind::DoneStuck => 0.80,
            _ => 0.95,
        };
        assert!(outcome.other_rate_share() >= rate_kept, "{outcome:?}");
        assert_eq!(outcome.other_frames_flagged, 0, "{outcome:?}");
        assert_eq!(outcome.wrong_pressures, 0, "{outcome:?}");
        assert!(outcome.pressures_checked > 10_000, "{outcome:?}");
        assert_eq!(outcome.frames_missing, 0, "{outcome:?}");
    }
}
