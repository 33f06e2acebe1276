//! `taxel view` with several devices: two synthetic devices' frames rendered in memory (every
//! device's tiles, a line per device with its clock estimate or "estimating", staleness on the
//! host clock whatever the device clocks say), and `taxel view --once PORT PORT` against two
//! `taxel sim` processes.
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;
use support::info;
use support::SimulatorProcess;

use std::process::Command;
use std::time::{Duration, Instant};

use taxel::view::{render_devices_to_string, DevicesView, PadFreshness, KEYS_LINE_DEVICES};
use wire::{DeviceFrame, PadIndex, PadSummary, SampleFrame, TaxelSample, TemperatureSource};

/// Pad `pad`'s frame of set `sequence` at `timestamp_us` (device clock), pressing
/// `pressure_kpa` on every taxel.
fn frame(pad: u8, sequence: u32, timestamp_us: u64, pressure_kpa: f32) -> DeviceFrame {
    DeviceFrame::Sample(SampleFrame {
        pad: PadIndex::new(pad).unwrap(),
        sequence,
        timestamp_us,
        temperature_c: Some(24.0),
        temperature_source: TemperatureSource::Tmp117,
        taxels: [TaxelSample {
            pressure_kpa: Some(pressure_kpa),
            capacitance_pf: 4.6,
            flags: 0,
        }; 4],
        summary: PadSummary {
            force_n: Some(pressure_kpa * 0.1),
            centre_of_pressure_mm: Some([0.0, 0.0]),
            partial: false,
            contact: false,
        },
    })
}

/// Device 0 with two pads, device 1 with one, both connected.
fn two_devices() -> DevicesView {
    let mut view = DevicesView::new(vec!["/dev/ttyACM0".into(), "/dev/ttyACM1".into()], None);
    for (shown, pads) in view.devices.iter_mut().zip([2, 1]) {
        shown.state.connected_to(shown.state.source.clone());
        shown.state.info = Some(info(pads));
    }
    view
}

/// Feeds `sets` sets 10 ms apart from `first_set` on: device 0's clock starts at 0 and runs
/// with the host's, device 1's is 5000 s ahead and gains 100 ppm; 1 ms link latency.
fn feed(view: &mut DevicesView, start: Instant, first_set: u32, sets: u32, devices: &[usize]) {
    for set in first_set..first_set + sets {
        let host_us = u64::from(set) * 10_000;
        let received_at = start + Duration::from_micros(host_us + 1_000);
        for &device in devices {
            let device_us = match device {
                0 => host_us,
                _ => 5_000_000_000 + host_us + host_us / 10_000,
            };
            let pads = if device == 0 { 2 } else { 1 };
            for pad in 0..pads {
                let pressure_kpa = 10.0 * (device as f32 + 1.0) + f32::from(pad);
                view.devices[device].apply_frame_at(
                    &frame(pad, set, device_us, pressure_kpa),
                    received_at,
                    host_us + 1_000,
                );
            }
        }
    }
    view.refresh(start + Duration::from_micros(u64::from(first_set + sets) * 10_000));
}

fn line_of<'a>(text: &'a str, start: &str) -> &'a str {
    text.lines()
        .map(|line| line.trim_start_matches(['│', ' ']))
        .find(|line| line.starts_with(start))
        .unwrap_or_else(|| panic!("no line starting {start:?}:\n{text}"))
}

#[test]
fn two_devices_show_every_pad_and_a_clock_line_each() {
    let start = Instant::now();
    let mut view = two_devices();
    // 3 s of device 0 (enough for its clock estimate), 0.3 s of device 1 (not enough).
    feed(&mut view, start, 0, 270, &[0]);
    feed(&mut view, start, 270, 30, &[0, 1]);
    for (width, height) in [(80, 24), (120, 32)] {
        let text = render_devices_to_string(&view, width, height);
        println!("{text}");
        for words in [
            "taxel view: 2 devices",
            "dev 0: /dev/ttyACM0",
            "dev 1: /dev/ttyACM1",
            "dev 0 pad 0",
            "dev 0 pad 1",
            "dev 1 pad 0",
            "2.00 N",
            "1.10 N",
            "1.00 N",
            KEYS_LINE_DEVICES,
        ] {
            assert!(text.contains(words), "{words}:\n{text}");
        }
        assert!(!text.contains("dev 1 pad 1"), "{text}");
        assert!(!text.contains("STALE"), "{text}");
        let first = line_of(&text, "dev 0: connected");
        assert!(first.contains("100.0 sets/s"), "{first}");
        assert!(first.contains("sync error "), "{first}");
        assert!(first.contains(" ms"), "{first}");
        assert!(
            first.contains("+0.0 ppm") || first.contains("-0.0 ppm"),
            "{first}"
        );
        let second = line_of(&text, "dev 1: connected");
        assert!(second.contains("clock estimating"), "{second}");
    }
    // Device 1's clock, 5000 s ahead, makes no pad of device 0 stale.
    assert_eq!(view.devices[0].state.pad_freshness(0), PadFreshness::Live);
    let estimate = view.devices[0].clock.estimate().unwrap();
    assert!(estimate.offset_us.abs() < 2_000, "{estimate:?}");
}

#[test]
fn a_silent_device_goes_stale_on_the_host_clock_and_the_other_stays_live() {
    let start = Instant::now();
    let mut view = two_devices();
    feed(&mut view, start, 0, 300, &[0, 1]);
    let estimate = view.devices[1].clock.estimate().unwrap();
    assert!(
        (estimate.drift_ppm - 100.0).abs() < 20.0,
        "device 1 gains 100 ppm: {estimate:?}"
    );
    // Device 1 goes silent for 1 s; device 0 goes on.
    feed(&mut view, start, 300, 100, &[0]);
    assert!(matches!(
        view.devices[1].state.pad_freshness(0),
        PadFreshness::Stale { age_s } if age_s > 0.9
    ));
    let text = render_devices_to_string(&view, 100, 30);
    println!("{text}");
    assert_eq!(text.matches("STALE").count(), 1, "{text}");
    assert!(text.contains("1.10 N"), "{text}");
    assert!(
        !text.contains("2.00 N"),
        "stale values shown as live:\n{text}"
    );
    let second = line_of(&text, "dev 1: connected");
    assert!(second.contains("-5000.000 s +100.0 ppm"), "{second}");
    assert!(second.contains("sync error "), "{second}");
}

#[test]
fn a_layout_names_device_0s_pads_and_the_others_keep_their_numbers() {
    let layout = taxel::layout::Layout::built_in("gripper").unwrap().unwrap();
    let mut view = DevicesView::new(vec!["a".into(), "b".into()], Some(layout));
    for (shown, pads) in view.devices.iter_mut().zip([2, 1]) {
        shown.state.connected_to(shown.state.source.clone());
        shown.state.info = Some(info(pads));
    }
    let text = render_devices_to_string(&view, 120, 32);
    println!("{text}");
    for words in [
        "dev 0 left finger",
        "dev 0 right finger",
        "dev 1 pad 0",
        "layout gripper",
    ] {
        assert!(text.contains(words), "{words}:\n{text}");
    }
}

#[test]
fn a_snapshot_of_two_simulators_through_the_binary() {
    let directory = tempfile::tempdir().unwrap();
    let mut first =
        SimulatorProcess::start(directory.path(), "port1", &["--seed", "1", "--pads", "2"]);
    let first_port = first.port.clone();
    let mut second = SimulatorProcess::start(directory.path(), "port2", &["--seed", "2"]);
    let second_port = second.port.clone();
    let output = Command::new(support::taxel_binary())
        .args([
            "view",
            "--once",
            "--width",
            "120",
            "--height",
            "32",
            &first_port,
            &second_port,
        ])
        .output()
        .unwrap();
    first.stop();
    second.stop();
    let text = String::from_utf8_lossy(&output.stdout);
    println!("{text}");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    for words in [
        "taxel view: 2 devices",
        &format!("dev 0: {first_port}"),
        &format!("dev 1: {second_port}"),
        "dev 0 pad 0",
        "dev 0 pad 1",
        "dev 1 pad 0",
    ] {
        assert!(text.contains(words), "{words}:\n{text}");
    }
    assert!(!text.contains("dev 1 pad 1"), "{text}");
    for device in 0..2 {
        let line = line_of(&text, &format!("dev {device}: connected"));
        assert!(
            line.contains("clock estimating") || line.contains("sync error "),
            "{line}"
        );
    }
}
