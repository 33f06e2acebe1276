//! Issue 23, section 5, as `taxel convert` met it: a recording whose temperature steps from 25 to
//! 55 °C and stays there was flagged `temperature_implausible` and kilopascals off for seconds
//! while the model slewed towards the new temperature. Re-converted through the host's
//! conversion engine (what `taxel convert` runs), the step is now applied within 0.5 s of device
//! time, only the sets before are flagged, and every pressure after it is the one the
//! calibration gives at the permittivity ratio of the documented law (computed here, not by the
//! model). A recorded change of sensor, which the recording's rows carry but the engine does not
//! pass to the model, is applied within the same 0.5 s.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic)]

use model_core::{Calibration, TaxelFlags};
use taxel_host::convert::{ConversionEngine, ConvertSettings, RecordedStates};
use taxel_host::schema::{PadReading, PadRow};
use wire::TemperatureSource;

/// 100 sample sets per second.
const PERIOD_US: u64 = 10_000;
/// The device time of the step, µs.
const STEP_US: u64 = 2_000_000;
/// The guarantee asked for: the new level applied within this much device time.
const ACCEPTED_WITHIN_US: u64 = 500_000;
/// The unloaded sensor capacitance of every taxel, pF.
const SENSOR_PF: f32 = 4.5;
/// Table 1 points on the four taxels: (pressure kPa, cumulative dC/C0).
const LOADS: [(f32, f32); 4] = [
    (10.0, 0.0829),
    (20.0, 0.1475),
    (30.0, 0.1981),
    (40.0, 0.2317),
];

/// eps_r(T) / eps_r(25 °C), the article's law as the README states it: flat at or below 25 °C,
/// linear to -3.24 % at 55 °C.
fn documented_permittivity_ratio(temperature_c: f32) -> f32 {
    if temperature_c <= 25.0 {
        1.0
    } else {
        1.0 - 0.0324 * (temperature_c - 25.0) / 30.0
    }
}

/// A recorded row: the pad at `temperature_c`, unloaded or loaded as [`LOADS`], the
/// temperature as recorded (`recorded_c`, from `source`).
fn row(
    sequence: u32,
    loaded: bool,
    temperature_c: f32,
    recorded_c: f32,
    source: TemperatureSource,
) -> PadRow {
    let calibration = Calibration::default();
    let device_time_us = u64::from(sequence) * PERIOD_US;
    let capacitance_pf = std::array::from_fn(|taxel| {
        let relative_change = if loaded { LOADS[taxel].1 } else { 0.0 };
        Some(
            calibration.taxels()[taxel].parasitic_pf()
                + SENSOR_PF
                    * (1.0 + relative_change)
                    * documented_permittivity_ratio(temperature_c),
        )
    });
    PadRow {
        host_time_us: 1_700_000_000_000_000 + device_time_us,
        device: 0,
        pad: 0,
        sequence,
        sync_error_us: None,
        reading: Some(PadReading {
            device_time_us,
            temperature_c: Some(recorded_c),
            temperature_source: source,
            capacitance_pf,
            pressure_kpa: [None; 4],
            flags: [TaxelFlags::empty(); 4],
            force_n: None,
            centre_of_pressure_mm: None,
            partial: false,
            contact: false,
        }),
        marker: String::new(),
    }
}

/// What the engine made of a recording from the step on: when the new temperature was
/// applied, and the largest pressure error outside the flagged transition.
struct Converted {
    applied_after_us: u64,
    flagged_sets: usize,
    worst_error_kpa: f32,
}

/// Converts 5 s at 100 sets/s: the first row unloaded at 25 °C (the tare), then the load; the
/// pad's temperature and the recorded one given per device time.
fn convert(
    pad_c: impl Fn(u64) -> f32,
    recorded: impl Fn(u64) -> (f32, TemperatureSource),
) -> Converted {
    // No device state: the defaults and a tare on the first row, as `taxel convert` does for a
    // recording without its state file.
    let mut engine = ConversionEngine::new(ConvertSettings::default(), RecordedStates::default());
    let mut applied_us = None;
    let mut flagged_sets = 0;
    let mut worst_error_kpa = 0.0f32;
    for sequence in 0..500u32 {
        let time_us = u64::from(sequence) * PERIOD_US;
        let (recorded_c, source) = recorded(time_us);
        let mut row = row(sequence, sequence > 0, pad_c(time_us), recorded_c, source);
        engine.convert(&mut row).unwrap();
        if sequence == 0 {
            continue;
        }
        let reading = row.reading.unwrap();
        let implausible = reading
            .flags
            .iter()
            .any(|flags| flags.contains(TaxelFlags::TEMPERATURE_IMPLAUSIBLE));
        let in_transition = time_us >= STEP_US && applied_us.is_none() && implausible;
        if in_transition {
            flagged_sets += 1;
            for flags in reading.flags {
                assert_eq!(flags, TaxelFlags::TEMPERATURE_IMPLAUSIBLE, "{time_us} us");
            }
            continue;
        }
        assert!(!implausible, "{time_us} us: flagged outside the transition");
        if time_us >= STEP_US && applied_us.is_none() {
            applied_us = Some(time_us);
        }
        for ((pressure_kpa, flags), (expected_kpa, _)) in
            reading.pressure_kpa.iter().zip(reading.flags).zip(LOADS)
        {
            let pressure_kpa = pressure_kpa.unwrap_or_else(|| panic!("{time_us} us: {flags:?}"));
            let error_kpa = (pressure_kpa - expected_kpa).abs();
            worst_error_kpa = worst_error_kpa.max(error_kpa);
            assert!(
                error_kpa < 0.01,
                "{time_us} us: {pressure_kpa} kPa for {expected_kpa} kPa ({flags:?})"
            );
        }
    }
    Converted {
        applied_after_us: applied_us.unwrap() - STEP_US,
        flagged_sets,
        worst_error_kpa,
    }
}

#[test]
fn a_recorded_step_from_25_to_55_c_is_applied_within_half_a_second() {
    let temperature = |time_us: u64| if time_us < STEP_US { 25.0 } else { 55.0 };
    let converted = convert(temperature, |time_us| {
        (temperature(time_us), TemperatureSource::Tmp117)
    });
    println!(
        "step applied {} us after it, {} sets flagged, worst error otherwise {:.5} kPa",
        converted.applied_after_us, converted.flagged_sets, converted.worst_error_kpa
    );
    assert!(converted.applied_after_us <= ACCEPTED_WITHIN_US);
    assert_eq!(
        converted.flagged_sets as u64,
        converted.applied_after_us / PERIOD_US
    );
}

/// At the step the recording switches from the TMP117 (30 °C) to the die sensor (38 °C: its
/// offset never learned, or the pad warmed while it was lost). The device applied that at once
/// (acquisition's test); the engine sees only the temperature and confirms it, within 0.5 s.
/// The capacitances are a pad's at the recorded temperature, so the pressures check that the
/// recorded temperature is the one applied.
#[test]
fn a_recorded_change_of_sensor_is_applied_at_once_as_on_the_device() {
    let recorded = |time_us: u64| {
        if time_us < STEP_US {
            (30.0, TemperatureSource::Tmp117)
        } else {
            (38.0, TemperatureSource::McuInternal)
        }
    };
    let converted = convert(|time_us| recorded(time_us).0, recorded);
    println!(
        "change of sensor applied {} us after it, {} sets flagged",
        converted.applied_after_us, converted.flagged_sets
    );
    // The recording's temperature source says the sensor changed: the engine tells the model,
    // as the device does, so the new level is no glitch to confirm.
    assert_eq!(converted.applied_after_us, 0);
    assert_eq!(converted.flagged_sets, 0);
}
