//! The built-in scenes that exist to show a client every event and flag a scene can cause
//! (`temperature-fallback`, `converter-faults`, `tare-refused`): each is played for one pass on
//! the simulated device, its frames decoded by the host's decoder, and the events, flags and
//! temperature sources checked against the times and the order its file's header (and
//! PROTOCOL.md 5.5 and 7) gives.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic)]

use sim_device::testing::Host;
use sim_device::{SceneFile, SimulatedDeviceConfig};
use wire::{flags, DeviceEvent, DeviceFrame, EventFrame, PadIndex, SampleFrame, TemperatureSource};

/// The noise seeds played: `taxel sim`'s and another.
const SEEDS: [u64; 2] = [sim_device::DEFAULT_SEED, 9];

/// Everything the device sent while playing built-in scene `name` for `seconds`, in order.
fn play(name: &str, seconds: f64, seed: u64) -> Vec<DeviceFrame> {
    let scene = SceneFile::built_in(name).unwrap();
    assert_eq!(scene.pads.len(), 1, "{name} is a scene of one pad");
    let mut host = Host::with_config(SimulatedDeviceConfig::new(scene, 1).with_seed(seed));
    host.run_until_s(seconds)
}

fn seconds(timestamp_us: u64) -> f64 {
    timestamp_us as f64 / 1e6
}

/// The events, with their place among the frames.
fn events(frames: &[DeviceFrame]) -> Vec<(usize, EventFrame)> {
    frames
        .iter()
        .enumerate()
        .filter_map(|(index, frame)| match frame {
            DeviceFrame::Event(event) => Some((index, *event)),
            _ => None,
        })
        .collect()
}

fn samples(frames: &[DeviceFrame]) -> Vec<SampleFrame> {
    frames
        .iter()
        .filter_map(|frame| match frame {
            DeviceFrame::Sample(sample) => Some(*sample),
            _ => None,
        })
        .collect()
}

/// The next frame after `index` is a sample frame; it is returned.
fn sample_after(frames: &[DeviceFrame], index: usize) -> SampleFrame {
    match frames.get(index + 1) {
        Some(DeviceFrame::Sample(sample)) => *sample,
        other => panic!("frame {index} is followed by {other:?}, not a sample frame"),
    }
}

/// Whether taxel `taxel` of `sample` has `flag`.
fn has(sample: &SampleFrame, taxel: usize, flag: u16) -> bool {
    sample.taxels[taxel].flags & flag != 0
}

/// Times of the samples in which taxel `taxel` has `flag`, s.
fn flagged_s(samples: &[SampleFrame], taxel: usize, flag: u16) -> Vec<f64> {
    samples
        .iter()
        .filter(|sample| has(sample, taxel, flag))
        .map(|sample| seconds(sample.timestamp_us))
        .collect()
}

/// Asserts that taxel `taxel` has `flag` in at least one sample, in every sample within
/// `always` (s), and in none outside the windows `allowed` (s).
fn assert_flag_windows(
    samples: &[SampleFrame],
    taxel: usize,
    flag: u16,
    always: Option<(f64, f64)>,
    allowed: &[(f64, f64)],
) {
    let times = flagged_s(samples, taxel, flag);
    assert!(
        !times.is_empty(),
        "flag {flag:#06x} never set on taxel {taxel}"
    );
    for time_s in &times {
        assert!(
            allowed
                .iter()
                .any(|(start_s, end_s)| (start_s..=end_s).contains(&time_s)),
            "flag {flag:#06x} on taxel {taxel} at {time_s} s, outside {allowed:?}"
        );
    }
    if let Some((start_s, end_s)) = always {
        for sample in samples {
            let time_s = seconds(sample.timestamp_us);
            if (start_s..=end_s).contains(&time_s) {
                assert!(
                    has(sample, taxel, flag),
                    "flag {flag:#06x} missing on taxel {taxel} at {time_s} s: {sample:?}"
                );
            }
        }
    }
}

/// Asserts that every sample within `window` (s) has `flag` on every taxel, and that every
/// sample outside every window of `allowed` has it on none.
fn assert_pad_flag_windows(
    samples: &[SampleFrame],
    flag: u16,
    always: &[(f64, f64)],
    allowed: &[(f64, f64)],
) {
    for taxel in 0..4 {
        for window in always {
            assert_flag_windows(samples, taxel, flag, Some(*window), allowed);
        }
    }
}

/// The temperature sources of the samples, each run of one source once, with the time the run
/// started.
fn source_runs(samples: &[SampleFrame]) -> Vec<(TemperatureSource, f64)> {
    let mut runs: Vec<(TemperatureSource, f64)> = Vec::new();
    for sample in samples {
        if runs.last().map(|(source, _)| *source) != Some(sample.temperature_source) {
            runs.push((sample.temperature_source, seconds(sample.timestamp_us)));
        }
    }
    runs
}

/// Asserts the tare at power-on: every taxel NOT_TARED in every sample before TareFinished
/// (which comes before the first sample tared), and in none after.
fn assert_tared_at_power_on(frames: &[DeviceFrame], tare_finished_index: usize) {
    for (index, frame) in frames.iter().enumerate() {
        if let DeviceFrame::Sample(sample) = frame {
            let untared = (0..4).all(|taxel| has(sample, taxel, flags::NOT_TARED));
            let tared = (0..4).all(|taxel| !has(sample, taxel, flags::NOT_TARED));
            if index < tare_finished_index {
                assert!(untared, "{sample:?}");
            } else {
                assert!(tared, "{sample:?}");
            }
        }
    }
}

/// Asserts that a TemperatureSourceChanged event at `index` names the source of the sample frame
/// right after it, the first one from that source.
fn assert_source_change(frames: &[DeviceFrame], index: usize, source: TemperatureSource) {
    let DeviceFrame::Event(EventFrame {
        event: DeviceEvent::TemperatureSourceChanged { source: named, .. },
        ..
    }) = frames[index]
    else {
        panic!("frame {index} is {:?}", frames[index]);
    };
    assert_eq!(named, source);
    assert_eq!(sample_after(frames, index).temperature_source, source);
    let previous = frames[..index]
        .iter()
        .rev()
        .find_map(|frame| match frame {
            DeviceFrame::Sample(sample) => Some(*sample),
            _ => None,
        })
        .unwrap();
    assert_ne!(previous.temperature_source, source);
}

const PAD: PadIndex = match PadIndex::new(0) {
    Some(pad) => pad,
    None => panic!(),
};

#[test]
fn the_temperature_fallback_scene_goes_to_the_die_sensor_and_back() {
    for seed in SEEDS {
        check_temperature_fallback(&play("temperature-fallback", 47.0, seed));
    }
}

fn check_temperature_fallback(frames: &[DeviceFrame]) {
    let events = events(frames);
    let kinds: Vec<DeviceEvent> = events.iter().map(|(_, frame)| frame.event).collect();
    assert_eq!(
        kinds,
        [
            DeviceEvent::TareFinished {
                pad: PAD,
                tared_mask: 0b1111
            },
            DeviceEvent::ContactStarted { pad: PAD },
            DeviceEvent::TemperatureSourceChanged {
                pad: PAD,
                source: TemperatureSource::McuInternal
            },
            DeviceEvent::TemperatureSourceChanged {
                pad: PAD,
                source: TemperatureSource::Tmp117
            },
            DeviceEvent::ContactEnded { pad: PAD },
        ],
        "the events in the order the scene's header lists them"
    );
    let times: Vec<f64> = events
        .iter()
        .map(|(_, frame)| seconds(frame.timestamp_us))
        .collect();
    for (time_s, (start_s, end_s)) in times.iter().zip([
        (0.0, 0.5),
        (2.0, 2.5),
        (4.0, 4.05),
        // The TMP117 is tried again every 100 sample sets, a second at 100 sets/s.
        (7.0, 8.1),
        (9.0, 9.6),
    ]) {
        assert!((start_s..=end_s).contains(time_s), "{times:?}");
    }
    assert_tared_at_power_on(frames, events[0].0);
    assert_source_change(frames, events[2].0, TemperatureSource::McuInternal);
    assert_source_change(frames, events[3].0, TemperatureSource::Tmp117);

    let samples = samples(frames);
    let runs = source_runs(&samples);
    let sources: Vec<TemperatureSource> = runs.iter().map(|(source, _)| *source).collect();
    assert_eq!(
        sources,
        [
            TemperatureSource::Tmp117,
            TemperatureSource::McuInternal,
            TemperatureSource::Tmp117
        ]
    );
    for sample in &samples {
        let fallback = sample.temperature_source == TemperatureSource::McuInternal;
        for taxel in 0..4 {
            assert_eq!(
                has(sample, taxel, flags::TEMPERATURE_FALLBACK),
                fallback,
                "{sample:?}"
            );
        }
        // The die sensor's learned offset keeps the temperature, so the pressures, in place.
        let time_s = seconds(sample.timestamp_us);
        if (3.0..=8.5).contains(&time_s) {
            assert!(
                (sample.temperature_c.unwrap() - 25.0).abs() < 0.2,
                "{sample:?}"
            );
            for taxel in sample.taxels {
                assert!(
                    (taxel.pressure_kpa.unwrap() - 20.0).abs() < 1.0,
                    "{sample:?}"
                );
            }
        }
    }

    // The jump to 45 °C at 11.5 s reaches the TMP117's reading at its next conversion (12 s):
    // held, flagged, the unloaded pad below its baseline, until confirmed 0.25 s later.
    let implausible = flagged_s(&samples, 0, flags::TEMPERATURE_IMPLAUSIBLE);
    assert_pad_flag_windows(
        &samples,
        flags::TEMPERATURE_IMPLAUSIBLE,
        &[(implausible[0], implausible[0] + 0.24)],
        &[(11.5, 12.6)],
    );
    for sample in samples
        .iter()
        .filter(|sample| (0..4).any(|taxel| has(sample, taxel, flags::TEMPERATURE_IMPLAUSIBLE)))
    {
        assert!(
            (sample.temperature_c.unwrap() - 25.0).abs() < 0.2,
            "{sample:?}"
        );
        assert!(has(sample, 0, flags::BELOW_BASELINE), "{sample:?}");
    }
    assert_pad_flag_windows(
        &samples,
        flags::BELOW_BASELINE,
        &[(implausible[0], implausible[0] + 0.24)],
        &[(11.5, 12.6)],
    );
    // Above 55 °C from the TMP117's conversion at 20 s to the one at 24 s.
    assert_pad_flag_windows(
        &samples,
        flags::TEMPERATURE_OUT_OF_RANGE,
        &[(20.1, 24.0)],
        &[(19.7, 25.4)],
    );
    for sample in samples
        .iter()
        .filter(|sample| has(sample, 0, flags::TEMPERATURE_OUT_OF_RANGE))
    {
        assert_eq!(sample.temperature_c, Some(55.0));
    }
    // Nothing else goes wrong.
    let expected = flags::NOT_TARED
        | flags::TEMPERATURE_FALLBACK
        | flags::TEMPERATURE_IMPLAUSIBLE
        | flags::BELOW_BASELINE
        | flags::TEMPERATURE_OUT_OF_RANGE;
    for sample in &samples {
        for taxel in sample.taxels {
            assert_eq!(taxel.flags & !expected, 0, "{sample:?}");
        }
    }
}

#[test]
fn the_converter_faults_scene_flags_every_fault_and_reinitialises_the_converter() {
    for seed in SEEDS {
        check_converter_faults(&play("converter-faults", 24.0, seed));
    }
}

fn check_converter_faults(frames: &[DeviceFrame]) {
    let events = events(frames);

    // Every event but the re-initialisations, in order, each at its time.
    let others: Vec<(usize, EventFrame)> = events
        .iter()
        .copied()
        .filter(|(_, frame)| !matches!(frame.event, DeviceEvent::ConverterReinitialised { .. }))
        .collect();
    let expected = [
        (
            DeviceEvent::TareFinished {
                pad: PAD,
                tared_mask: 0b1111,
            },
            (0.0, 0.5),
        ),
        (DeviceEvent::ContactStarted { pad: PAD }, (2.0, 2.5)),
        (DeviceEvent::ContactEnded { pad: PAD }, (8.0, 8.6)),
        (
            DeviceEvent::TemperatureSourceChanged {
                pad: PAD,
                source: TemperatureSource::McuInternal,
            },
            (20.0, 20.05),
        ),
        (
            DeviceEvent::TemperatureSourceChanged {
                pad: PAD,
                source: TemperatureSource::Tmp117,
            },
            (22.0, 23.1),
        ),
    ];
    assert_eq!(others.len(), expected.len(), "{others:?}");
    for ((_, frame), (event, (start_s, end_s))) in others.iter().zip(expected) {
        assert_eq!(frame.event, event);
        let time_s = seconds(frame.timestamp_us);
        assert!((start_s..=end_s).contains(&time_s), "{frame:?}");
    }
    assert_tared_at_power_on(frames, others[0].0);
    assert_source_change(frames, others[3].0, TemperatureSource::McuInternal);
    assert_source_change(frames, others[4].0, TemperatureSource::Tmp117);

    // The re-initialisations: counted one by one, each announced just before the sample frame
    // of the set it happened in, and each within one of the converter faults (the frozen
    // channel found stuck, the NACKs, the DONE timeouts, the zero reads, the unplugged board).
    let reinits: Vec<(usize, EventFrame)> = events
        .iter()
        .copied()
        .filter(|(_, frame)| matches!(frame.event, DeviceEvent::ConverterReinitialised { .. }))
        .collect();
    let windows = [
        (10.4, 10.6),
        (13.0, 14.1),
        (16.0, 16.3),
        (18.0, 18.2),
        (20.0, 22.1),
    ];
    let mut per_window = [0; 5];
    for (count, (index, frame)) in (1u32..).zip(&reinits) {
        assert_eq!(
            frame.event,
            DeviceEvent::ConverterReinitialised {
                pad: PAD,
                reinit_count: count
            }
        );
        assert_eq!(
            sample_after(frames, *index).timestamp_us,
            frame.timestamp_us
        );
        let time_s = seconds(frame.timestamp_us);
        let window = windows
            .iter()
            .position(|(start_s, end_s)| (*start_s..=*end_s).contains(&time_s))
            .unwrap_or_else(|| panic!("re-initialised at {time_s} s"));
        per_window[window] += 1;
        // The order of the scene: no event of a later fault before one of an earlier fault.
        assert!(per_window[window + 1..].iter().all(|&later| later == 0));
    }
    // The frozen channel is found once; the converter that does not answer is re-initialised
    // when it is first retried and when it answers again, as is the unplugged board.
    assert_eq!(per_window[0], 1, "{reinits:?}");
    assert_eq!(per_window[1], 2, "{reinits:?}");
    assert!(per_window[2] >= 1 && per_window[3] >= 1, "{reinits:?}");
    assert_eq!(per_window[4], 2, "{reinits:?}");
    // Between the contact's end and the frozen channel, and after it, the stream goes on.
    assert!(others[2].0 < reinits[0].0 && reinits[0].0 < others[3].0);

    let samples = samples(frames);
    // The taxel faults under load: each faulted taxel has no pressure, and the pad's force is
    // partial. The fault windows are the scene's; a sample's conversions are up to 10 ms older
    // than its timestamp.
    assert_flag_windows(
        &samples,
        0,
        flags::SHORTED,
        Some((3.02, 3.98)),
        &[(3.0, 4.02)],
    );
    assert_flag_windows(&samples, 1, flags::OPEN, Some((4.52, 5.48)), &[(4.5, 5.52)]);
    assert_flag_windows(
        &samples,
        2,
        flags::SATURATED,
        Some((6.02, 6.98)),
        &[(6.0, 7.02)],
    );
    assert_flag_windows(
        &samples,
        0,
        flags::OVER_RANGE,
        Some((7.5, 8.0)),
        &[(7.0, 8.3)],
    );
    for sample in &samples {
        let time_s = seconds(sample.timestamp_us);
        let taxel_fault = (0..4).any(|taxel| flags::is_fault(sample.taxels[taxel].flags));
        for taxel in sample.taxels {
            assert_eq!(
                taxel.pressure_kpa.is_none(),
                flags::is_fault(taxel.flags),
                "{sample:?}"
            );
        }
        if (3.0..8.0).contains(&time_s) && taxel_fault {
            assert!(
                sample.summary.partial && sample.summary.contact,
                "{sample:?}"
            );
            assert!(sample.summary.force_n.is_some(), "{sample:?}");
        }
    }
    // The frozen channel: STUCK once, then 0 (OPEN) after the re-initialisation zeroed it.
    let stuck = flagged_s(&samples, 2, flags::STUCK);
    assert_eq!(stuck.len(), 1, "{stuck:?}");
    assert!((10.4..10.6).contains(&stuck[0]), "{stuck:?}");
    assert_flag_windows(
        &samples,
        2,
        flags::OPEN,
        Some((stuck[0] + 0.02, 10.58)),
        &[(stuck[0], 10.62)],
    );
    // The converter faults: every taxel CONVERTER_ERROR, no capacitance.
    assert_pad_flag_windows(
        &samples,
        flags::CONVERTER_ERROR,
        &[(13.02, 13.98), (20.02, 21.98)],
        &[(13.0, 14.1), (16.0, 16.3), (18.0, 18.2), (20.0, 22.1)],
    );
    for sample in &samples {
        if has(sample, 0, flags::CONVERTER_ERROR) {
            assert!(sample
                .taxels
                .iter()
                .all(|taxel| taxel.capacitance_pf.is_nan()));
        }
    }
    for (start_s, end_s) in [(16.0, 16.3), (18.0, 18.2)] {
        assert!(samples.iter().any(|sample| {
            (start_s..=end_s).contains(&seconds(sample.timestamp_us))
                && has(sample, 0, flags::CONVERTER_ERROR)
        }));
    }
    // Unplugged, the pad's TMP117 is gone with the converter: the die sensor stands in.
    let runs = source_runs(&samples);
    assert_eq!(runs.len(), 3, "{runs:?}");
    assert_eq!(runs[1].0, TemperatureSource::McuInternal);
    assert!((20.0..20.05).contains(&runs[1].1), "{runs:?}");
    assert_pad_flag_windows(
        &samples,
        flags::TEMPERATURE_FALLBACK,
        &[(runs[1].1, runs[2].1 - 0.001)],
        &[(runs[1].1, runs[2].1 - 0.001)],
    );
}

#[test]
fn the_fault_scenes_start_over_with_their_faults() {
    // A second pass repeats the faults (not the tare at power-on).
    let frames = play("converter-faults", 48.0, sim_device::DEFAULT_SEED);
    let second_pass: Vec<DeviceEvent> = events(&frames)
        .into_iter()
        .filter(|(_, frame)| seconds(frame.timestamp_us) >= 24.0)
        .map(|(_, frame)| frame.event)
        .filter(|event| !matches!(event, DeviceEvent::ConverterReinitialised { .. }))
        .collect();
    assert_eq!(
        second_pass,
        [
            DeviceEvent::ContactStarted { pad: PAD },
            DeviceEvent::ContactEnded { pad: PAD },
            DeviceEvent::TemperatureSourceChanged {
                pad: PAD,
                source: TemperatureSource::McuInternal
            },
            DeviceEvent::TemperatureSourceChanged {
                pad: PAD,
                source: TemperatureSource::Tmp117
            },
        ]
    );
    let stuck = flagged_s(&samples(&frames), 2, flags::STUCK);
    assert_eq!(stuck.len(), 2, "{stuck:?}");
    assert!((34.4..34.6).contains(&stuck[1]), "{stuck:?}");
}

#[test]
fn the_tare_refused_scene_leaves_the_unconnected_taxel_untared() {
    for seed in SEEDS {
        check_tare_refused(&play("tare-refused", 6.0, seed));
    }
}

fn check_tare_refused(frames: &[DeviceFrame]) {
    let events = events(frames);
    let kinds: Vec<DeviceEvent> = events.iter().map(|(_, frame)| frame.event).collect();
    assert_eq!(
        kinds,
        [
            DeviceEvent::TareRefused {
                pad: PAD,
                refused_mask: 0b1000
            },
            DeviceEvent::TareFinished {
                pad: PAD,
                tared_mask: 0b0111
            },
            DeviceEvent::ContactStarted { pad: PAD },
            DeviceEvent::ContactEnded { pad: PAD },
        ]
    );
    // TareRefused right before TareFinished, both when the tare at power-on ends.
    assert_eq!(events[0].0 + 1, events[1].0);
    for ((_, frame), (start_s, end_s)) in
        events
            .iter()
            .zip([(0.0, 0.5), (0.0, 0.5), (2.0, 2.5), (4.0, 4.6)])
    {
        let time_s = seconds(frame.timestamp_us);
        assert!((start_s..=end_s).contains(&time_s), "{events:?}");
    }
    let samples = samples(frames);
    assert_flag_windows(&samples, 3, flags::OPEN, Some((0.0, 0.49)), &[(0.0, 0.52)]);
    for (index, frame) in frames.iter().enumerate() {
        let DeviceFrame::Sample(sample) = frame else {
            continue;
        };
        let tared = index > events[1].0;
        for taxel in 0..3 {
            assert_eq!(has(sample, taxel, flags::NOT_TARED), !tared, "{sample:?}");
        }
        // C22 has no pressure all along: open, then without a baseline.
        let time_s = seconds(sample.timestamp_us);
        // (A sample's conversions are up to 10 ms older than its timestamp.)
        let c22_flags: &[u16] = if time_s < 0.5 {
            &[flags::OPEN]
        } else if time_s < 0.52 {
            &[flags::OPEN, flags::NOT_TARED]
        } else {
            &[flags::NOT_TARED]
        };
        assert!(c22_flags.contains(&sample.taxels[3].flags), "{sample:?}");
        assert_eq!(sample.taxels[3].pressure_kpa, None);
        if (2.6..=3.9).contains(&time_s) {
            assert!(
                sample.summary.partial && sample.summary.contact,
                "{sample:?}"
            );
            for taxel in &sample.taxels[..3] {
                assert!(
                    (taxel.pressure_kpa.unwrap() - 20.0).abs() < 1.0,
                    "{sample:?}"
                );
            }
        }
    }
}
