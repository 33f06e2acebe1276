//! `taxel view` of several devices, one program for any number: two synthetic devices' sets
//! rendered in memory (every device's tiles, a line per device with its clock estimate or
//! "estimating", staleness on the host clock whatever the device clocks say, one pad of any
//! device in detail), `taxel view --once PORT PORT` against two `taxel sim` processes, and the
//! view's engine on two simulated devices: tare, and recordings from the record key read back
//! with the recording schema's reader; on one device of two pads, the tare key with a pad shown
//! in detail tares that pad only.
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;
use support::info;
use support::SimulatorProcess;

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use taxel::view::{
    render_devices_to_string, DevicesView, LiveView, PadFreshness, ViewArgs, KEYS_LINE_DEVICES,
};
use taxel_host::device_state::RecordedDeviceState;
use taxel_host::pad_set::PadSet;
use taxel_host::schema::{PadRow, RowReader};
use taxel_host::session::SessionEvent;
use wire::{PadSummary, SampleFrame, TaxelSample};

/// Pad `pad`'s frame of set `sequence` at `timestamp_us` (device clock), pressing
/// `pressure_kpa` on every taxel.
fn frame(pad: u8, sequence: u32, timestamp_us: u64, pressure_kpa: f32) -> SampleFrame {
    let base = wire::testing::sample_frame(pad);
    SampleFrame {
        sequence,
        timestamp_us,
        temperature_c: Some(24.0),
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
        ..base
    }
}

/// Device 0 with two pads, device 1 with one, both connected.
fn two_devices() -> DevicesView {
    let mut view = DevicesView::new(vec!["/dev/ttyACM0".into(), "/dev/ttyACM1".into()], None);
    for (shown, pads) in view.devices.iter_mut().zip([2, 1]) {
        let source = shown.state.source.clone();
        shown.connected_to(source, info(pads));
    }
    view
}

/// Feeds `sets` sets 10 ms apart from `first_set` on, arriving on the host clock (µs) from
/// `start_us`: device 0's clock starts at 0 and runs with the host's, device 1's is 5000 s
/// ahead and gains 100 ppm; 1 ms link latency.
fn feed(view: &mut DevicesView, start_us: u64, first_set: u32, sets: u32, devices: &[usize]) {
    for set in first_set..first_set + sets {
        let host_us = u64::from(set) * 10_000;
        for &device in devices {
            let device_us = match device {
                0 => host_us,
                _ => 5_000_000_000 + host_us + host_us / 10_000,
            };
            let pads = if device == 0 { 2 } else { 1 };
            let frames = (0..pads)
                .map(|pad| {
                    let pressure_kpa = 10.0 * (device as f32 + 1.0) + f32::from(pad);
                    Some(frame(pad, set, device_us, pressure_kpa))
                })
                .collect();
            let event = SessionEvent::Set {
                set: PadSet {
                    sequence: set,
                    pads: frames,
                },
                sets_missing_before: 0,
            };
            view.devices[device].apply_event(&event, start_us + host_us + 1_000);
        }
    }
    view.refresh(start_us + u64::from(first_set + sets) * 10_000);
}

fn line_of<'a>(text: &'a str, start: &str) -> &'a str {
    text.lines()
        .map(|line| line.trim_start_matches(['│', ' ']))
        .find(|line| line.starts_with(start))
        .unwrap_or_else(|| panic!("no line starting {start:?}:\n{text}"))
}

#[test]
fn two_devices_show_every_pad_and_a_clock_line_each() {
    let start = 0;
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
    let start = 0;
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
        let source = shown.state.source.clone();
        shown.connected_to(source, info(pads));
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

/// Per-pad detail for any number of devices: the number keys show a pad of the chosen device
/// in the detailed view (heat map, time series, force), `d` moves to the next device, `a`
/// shows every device again.
#[test]
fn one_pad_of_any_device_in_the_detailed_view() {
    let start = 1_000_000;
    let mut view = two_devices();
    feed(&mut view, start, 0, 300, &[0, 1]);
    assert_eq!(view.shown_device(), None);
    view.show_pad(Some(1));
    assert_eq!(view.shown_device(), Some(0));
    let text = render_devices_to_string(&view, 80, 24);
    println!("{text}");
    for words in [
        "pad 1: dev 0 pad 1",
        " C11 ",
        " C22 ",
        "11.00 kPa",
        "pressure (kPa), last 10 s",
        "Force: 1.100 N",
        KEYS_LINE_DEVICES,
    ] {
        assert!(text.contains(words), "{words}:\n{text}");
    }
    assert!(!text.contains("10.00 kPa"), "pad 0's values:\n{text}");
    // The next device: its pad 1 does not exist, then its pad 0.
    view.select_next_device();
    assert_eq!(view.shown_device(), Some(1));
    assert!(render_devices_to_string(&view, 80, 24).contains("not on this device"));
    view.show_pad(Some(0));
    let text = render_devices_to_string(&view, 100, 30);
    println!("{text}");
    for words in [
        "taxel view: dev 1: /dev/ttyACM1",
        "20.00 kPa",
        "Force: 2.000 N",
    ] {
        assert!(text.contains(words), "{words}:\n{text}");
    }
    view.show_pad(None);
    let text = render_devices_to_string(&view, 80, 24);
    assert!(text.contains("taxel view: 2 devices"), "{text}");
    assert!(
        text.contains("▶ dev 1"),
        "the chosen device is marked:\n{text}"
    );
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

/// Two simulated devices (two pads and one) in this process, each on its pseudo-terminal.
fn two_simulators() -> (sim_device::SimulatorThread, sim_device::SimulatorThread) {
    let start = |pads, seed| {
        let config = sim_device::scene_config(None, Some(pads), Some(1.0), seed).unwrap();
        sim_device::SimulatorThread::start(config, Some(60.0)).unwrap()
    };
    (start(2, 1), start(1, 2))
}

/// Ticks the view every 20 ms until `done` or `timeout` (a failure).
fn tick_until(live: &mut LiveView, timeout: Duration, done: impl Fn(&LiveView) -> bool) {
    let deadline = Instant::now() + timeout;
    while !done(live) {
        assert!(Instant::now() < deadline, "timed out");
        std::thread::sleep(Duration::from_millis(20));
        live.tick();
    }
}

/// Ticks the view every 20 ms for `duration`.
fn tick_for(live: &mut LiveView, duration: Duration) {
    let until = Instant::now() + duration;
    while Instant::now() < until {
        std::thread::sleep(Duration::from_millis(20));
        live.tick();
    }
}

/// Every row of a recording, read with the schema's reader (which refuses anything else).
fn read_rows(path: &Path) -> Vec<PadRow> {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = RowReader::new(file).unwrap();
    let mut rows = Vec::new();
    while let Some(row) = reader.next_row() {
        rows.push(row.unwrap());
    }
    rows
}

/// The one recording in `directory` not in `known`.
fn new_recording(directory: &Path, known: &[std::path::PathBuf]) -> std::path::PathBuf {
    let found: Vec<_> = std::fs::read_dir(directory)
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|extension| extension == "csv"))
        .filter(|path| !known.contains(path))
        .collect();
    assert_eq!(found.len(), 1, "{found:?}");
    found[0].clone()
}

/// Checks one recording of the two simulated devices: rows of device 0's two pads and device
/// 1's pad, each device's sets in order, the marker, and each device's state beside it.
fn check_recording(csv: &Path, marked: bool) -> Vec<PadRow> {
    let rows = read_rows(csv);
    for (device, pads) in [(0u32, 2u8), (1, 1)] {
        let of_device: Vec<&PadRow> = rows.iter().filter(|row| row.device == device).collect();
        assert!(
            of_device.len() > 20,
            "device {device}: {} rows",
            of_device.len()
        );
        assert!(of_device.iter().all(|row| row.pad < pads));
        assert!(of_device
            .windows(2)
            .all(|pair| pair[0].sequence <= pair[1].sequence));
        let present = of_device.iter().filter(|row| row.reading.is_some()).count();
        assert!(present * 10 >= of_device.len() * 9, "device {device}");
        let state_path = format!("{}.dev{device}.device.json", csv.display());
        let state = RecordedDeviceState::read(Path::new(&state_path)).unwrap();
        assert_eq!(state.pad_count, pads, "{state_path}");
    }
    let markers: Vec<&PadRow> = rows.iter().filter(|row| !row.marker.is_empty()).collect();
    if marked {
        assert!(!markers.is_empty(), "no marker");
        assert!(markers.iter().all(|row| row.marker == "marker 1"));
    } else {
        assert!(markers.is_empty());
    }
    rows
}

/// The record key records every device the view shows into one file of the recording schema,
/// with each device's state: stopped with the key (the states asked of the running sessions,
/// a tare during the recording in device 1's baselines) and stopped by quitting (the states
/// from the devices' ends). Recorded and shown alike: the view's accounting is the sessions'.
#[test]
fn the_record_key_records_every_device_into_the_schema() {
    let (first, second) = two_simulators();
    let directory = tempfile::tempdir().unwrap();
    let ports = [first.path(), second.path()]
        .map(|path| path.to_string_lossy().into_owned())
        .to_vec();
    let mut args = ViewArgs::for_ports(ports, false);
    args.record_dir = directory.path().to_path_buf();
    args.tare_sets = 8;
    let mut live = LiveView::new(&args, None).unwrap();
    live.press('r');
    assert!(!live.is_recording(), "nothing connected yet");
    live.tick();
    tick_until(&mut live, Duration::from_secs(10), |live| {
        live.view().every_device_has(10)
    });
    assert!(live.press('r'));
    assert!(live.is_recording());
    tick_for(&mut live, Duration::from_millis(500));
    live.press('m');
    live.press('t');
    tick_for(&mut live, Duration::from_millis(1000));
    let recording = live.view().recording.clone().unwrap();
    assert!(recording.sets > 50, "{recording:?}");
    assert_eq!(recording.markers, 1);
    let text = render_devices_to_string(live.view(), 100, 30);
    println!("{text}");
    assert!(text.contains("● REC "), "{text}");
    live.press('r');
    tick_until(&mut live, Duration::from_secs(5), |live| {
        !live.is_recording()
    });
    let saved = live.last_saved().unwrap().to_owned();
    assert!(saved.starts_with("saved "), "{saved}");
    let csv = new_recording(directory.path(), &[]);
    let rows = check_recording(&csv, true);
    // Device 1's tare during the recording: its baselines changed from a set of the recording.
    let state =
        RecordedDeviceState::read(Path::new(&format!("{}.dev1.device.json", csv.display())))
            .unwrap();
    let baselines = &state.pads[0].baselines;
    assert!(baselines.len() >= 2, "{baselines:?}");
    let tared_from = baselines.last().unwrap().from_sequence;
    assert!(
        rows.iter()
            .any(|row| row.device == 1 && row.sequence >= tared_from),
        "the tare's baselines apply from set {tared_from}"
    );
    for device in &live.view().devices {
        assert!(device.state.accounting.received() > 100);
        assert_eq!(device.state.accounting.lost_on_link(), 0);
    }

    // A second recording (a second later: the name has the second), ended by quitting.
    std::thread::sleep(Duration::from_millis(1100));
    live.press('r');
    assert!(live.is_recording());
    tick_for(&mut live, Duration::from_millis(800));
    let (view, saved) = live.finish();
    let saved = saved.unwrap();
    assert!(saved.starts_with("saved "), "{saved}");
    assert!(view.recording.is_none());
    let second_csv = new_recording(directory.path(), &[csv]);
    check_recording(&second_csv, false);
    first.stop();
    second.stop();
}

/// With a pad shown in the detailed view the tare key tares that pad only: the recording's state
/// has new baselines for it and none for the device's other pad.
#[test]
fn the_tare_key_tares_only_the_pad_shown_in_detail() {
    let config = sim_device::scene_config(None, Some(2), Some(1.0), 3).unwrap();
    let simulator = sim_device::SimulatorThread::start(config, Some(60.0)).unwrap();
    let directory = tempfile::tempdir().unwrap();
    let port = simulator.path().to_string_lossy().into_owned();
    let mut args = ViewArgs::for_ports(vec![port], false);
    args.record_dir = directory.path().to_path_buf();
    args.tare_sets = 8;
    let mut live = LiveView::new(&args, None).unwrap();
    live.tick();
    tick_until(&mut live, Duration::from_secs(10), |live| {
        live.view().every_device_has(10)
    });
    assert_eq!(live.view().pad_in_detail(), None);
    live.press('1');
    assert_eq!(live.view().pad_in_detail(), Some((0, 1)));
    assert!(live.press('r'));
    tick_for(&mut live, Duration::from_millis(300));
    live.press('t');
    assert!(
        live.view().devices[0]
            .state
            .status
            .starts_with("tare of pad 1 running"),
        "{}",
        live.view().devices[0].state.status
    );
    tick_for(&mut live, Duration::from_millis(1000));
    live.press('r');
    tick_until(&mut live, Duration::from_secs(5), |live| {
        !live.is_recording()
    });
    let csv = new_recording(directory.path(), &[]);
    let state =
        RecordedDeviceState::read(Path::new(&format!("{}.dev0.device.json", csv.display())))
            .unwrap();
    assert_eq!(state.pads.len(), 2);
    assert_eq!(
        state.pads[0].baselines.len(),
        1,
        "pad 0 keeps the baselines of its tare at power-on: {:?}",
        state.pads[0].baselines
    );
    assert!(
        state.pads[1].baselines.len() >= 2,
        "pad 1 was tared: {:?}",
        state.pads[1].baselines
    );
    live.press('a');
    assert_eq!(live.view().pad_in_detail(), None);
    drop(live.finish());
    simulator.stop();
}

/// A device that goes away is said so, ends a recording (saved with what it has), and is
/// looked for again.
#[test]
fn a_device_that_goes_away_ends_the_recording_and_is_looked_for_again() {
    let (first, second) = two_simulators();
    let directory = tempfile::tempdir().unwrap();
    let ports = [first.path(), second.path()]
        .map(|path| path.to_string_lossy().into_owned())
        .to_vec();
    let mut args = ViewArgs::for_ports(ports, false);
    args.record_dir = directory.path().to_path_buf();
    let mut live = LiveView::new(&args, None).unwrap();
    live.tick();
    tick_until(&mut live, Duration::from_secs(10), |live| {
        live.view().every_device_has(10)
    });
    live.press('r');
    tick_for(&mut live, Duration::from_millis(500));
    second.stop();
    tick_until(&mut live, Duration::from_secs(10), |live| {
        !live.view().devices[1].state.connected && !live.is_recording()
    });
    let saved = live.last_saved().unwrap().to_owned();
    assert!(saved.starts_with("saved "), "{saved}");
    let status = &live.view().devices[1].state.status;
    assert!(
        status.contains("connection lost") || status.contains("waiting for"),
        "{status}"
    );
    let text = render_devices_to_string(live.view(), 100, 30);
    println!("{text}");
    assert!(text.contains("dev 1: disconnected"), "{text}");
    assert!(text.contains("dev 0: connected"), "{text}");
    let csv = new_recording(directory.path(), &[]);
    let rows = read_rows(&csv);
    assert!(rows.iter().any(|row| row.device == 1));
    assert!(Path::new(&format!("{}.dev0.device.json", csv.display())).exists());
    assert!(Path::new(&format!("{}.dev1.device.json", csv.display())).exists());
    let (view, _) = live.finish();
    assert!(view.devices[0].state.connected);
    first.stop();
}
