//! Several pads end to end through the real host path: `taxel sim` runs the simulated board
//! (the firmware's discovery, acquisition and protocol code, a TCA9548A with one pad per
//! channel) on a pseudo-terminal, `taxel record` records it, and the pad-prefixed columns are
//! checked against the scene each pad plays (force = pressure x the article's 5 mm x 5 mm
//! electrodes, computed here).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;
use support::SimulatorProcess;

use std::collections::HashMap;
use std::process::Command;

use sim_device::SceneFile;

/// Four electrodes of 25 mm², as m².
const ELECTRODE_AREA_M2: f64 = 25e-6;
/// Each pressure within 0.5 kPa of the scene: 4 x 0.5 kPa x 25 mm².
const FORCE_TOLERANCE_N: f64 = 0.05;

fn taxel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_taxel"))
}

/// Records `sets` sample sets from a simulator started with `arguments`; the rows by column.
fn record(arguments: &[&str], sets: u32) -> Vec<HashMap<String, String>> {
    let directory = tempfile::tempdir().unwrap();
    let mut simulator = SimulatorProcess::start(
        directory.path(),
        "port",
        &[&["--speed", "4"], arguments].concat(),
    );
    let port = simulator.port.clone();
    let recording = directory.path().join("rec.csv");
    let output = taxel()
        .args(["record", &port, "--samples", &sets.to_string(), "-o"])
        .arg(&recording)
        .output()
        .unwrap();
    simulator.stop();
    let messages = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{messages}");
    let mut reader = csv::Reader::from_path(&recording).unwrap();
    let header: Vec<String> = reader
        .headers()
        .unwrap()
        .iter()
        .map(str::to_owned)
        .collect();
    reader
        .records()
        .map(|record| {
            let record = record.unwrap();
            header
                .iter()
                .cloned()
                .zip(record.iter().map(str::to_owned))
                .collect()
        })
        .collect()
}

/// Checks every complete pad cell group of every row against the scene: its force, and that a
/// pad whose four taxels read is not flagged partial. Returns how many pad samples it checked.
fn check_against_scene(rows: &[HashMap<String, String>], scene: &SceneFile, pads: usize) -> usize {
    let mut checked = 0;
    for row in rows {
        for pad in 0..pads {
            let cell = |name: &str| row.get(&format!("pad{pad}_{name}")).unwrap().clone();
            let time = cell("time_s");
            assert!(
                !time.is_empty(),
                "pad {pad} missing from row {:?}",
                row.get("seq")
            );
            let time_s: f64 = time.parse().unwrap();
            // The tare at boot and the press ramps: check where the pad is steady or unloaded.
            let all_read = ["p11_kpa", "p12_kpa", "p21_kpa", "p22_kpa"]
                .iter()
                .all(|name| !cell(name).is_empty());
            if time_s < 1.0 || !all_read {
                continue;
            }
            let period_s = scene.period_s();
            let scene_time_s = if scene.repeat {
                time_s % period_s
            } else {
                time_s
            };
            let pressures = scene
                .pad(pad)
                .unwrap()
                .scene
                .point_at_s(scene_time_s)
                .pressure_kpa;
            let expected_n: f64 = pressures
                .iter()
                .map(|kpa| f64::from(*kpa) * 1e3 * ELECTRODE_AREA_M2)
                .sum();
            let force_n: f64 = cell("force_n").parse().unwrap();
            assert!(
                (force_n - expected_n).abs() < FORCE_TOLERANCE_N,
                "pad {pad} at {time_s} s: {force_n} N recorded, scene {expected_n} N"
            );
            assert_eq!(cell("partial"), "0", "pad {pad} at {time_s} s");
            checked += 1;
        }
    }
    checked
}

#[test]
fn the_gripper_scene_is_recorded_pad_by_pad() {
    let rows = record(&["--scene", "gripper"], 600);
    assert_eq!(rows.len(), 600);
    let scene = SceneFile::built_in("gripper").unwrap();
    let checked = check_against_scene(&rows, &scene, 2);
    assert!(checked > 800, "{checked} pad samples checked");
    assert!(!rows[0].contains_key("pad2_time_s"));
}

#[test]
fn eight_pads_are_recorded_in_their_columns() {
    let rows = record(&["--pads", "8"], 300);
    assert_eq!(rows.len(), 300);
    let scene = SceneFile::default_scene().unwrap();
    let checked = check_against_scene(&rows, &scene, 8);
    assert!(checked > 8 * 200, "{checked} pad samples checked");
    // One sample set per row: every pad of a row carries the row's sequence number's set, read
    // within one converter cycle (10 ms at 400 S/s).
    for row in &rows {
        let times: Vec<f64> = (0..8)
            .map(|pad| row[&format!("pad{pad}_time_s")].parse().unwrap())
            .collect();
        let spread_s = times.iter().fold(f64::MIN, |a, b| a.max(*b))
            - times.iter().fold(f64::MAX, |a, b| a.min(*b));
        assert!(spread_s < 0.010, "pads of one set read {spread_s} s apart");
    }
}

/// Two devices with several pads each, recorded together: the long format has one row per
/// pad frame, and every device's every pad follows its own scene.
#[test]
fn two_devices_with_several_pads_are_recorded_on_one_timeline() {
    let directory = tempfile::tempdir().unwrap();
    let first_directory = directory.path().join("first");
    let second_directory = directory.path().join("second");
    std::fs::create_dir_all(&first_directory).unwrap();
    std::fs::create_dir_all(&second_directory).unwrap();
    let mut gripper = SimulatorProcess::start(
        &first_directory,
        "port",
        &["--speed", "4", "--scene", "gripper"],
    );
    let gripper_port = gripper.port.clone();
    let mut three =
        SimulatorProcess::start(&second_directory, "port", &["--speed", "4", "--pads", "3"]);
    let three_port = three.port.clone();
    let recording = directory.path().join("both.csv");
    let output = taxel()
        .args([
            "record",
            &gripper_port,
            &three_port,
            "--samples",
            "400",
            "-o",
        ])
        .arg(&recording)
        .output()
        .unwrap();
    gripper.stop();
    three.stop();
    let messages = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{messages}");
    let mut reader = csv::Reader::from_path(&recording).unwrap();
    let header: Vec<String> = reader
        .headers()
        .unwrap()
        .iter()
        .map(str::to_owned)
        .collect();
    let column = |name: &str| header.iter().position(|cell| cell == name).unwrap();
    let scenes = [
        SceneFile::built_in("gripper").unwrap(),
        SceneFile::default_scene().unwrap(),
    ];
    let mut frames = [[0usize; 3]; 2];
    let mut checked = 0;
    let mut previous_host_s = f64::MIN;
    for record in reader.records() {
        let record = record.unwrap();
        let device: usize = record[column("device")].parse().unwrap();
        let pad: usize = record[column("pad")].parse().unwrap();
        frames[device][pad] += 1;
        let host_s: f64 = record[column("host_time_s")].parse().unwrap();
        assert!(host_s >= previous_host_s, "rows out of host-time order");
        previous_host_s = host_s;
        let all_read = ["p11_kpa", "p12_kpa", "p21_kpa", "p22_kpa"]
            .iter()
            .all(|name| !record[column(name)].is_empty());
        let time_s: f64 = record[column("device_time_s")].parse().unwrap();
        if time_s < 1.0 || !all_read {
            continue;
        }
        let scene = &scenes[device];
        let scene_time_s = if scene.repeat {
            time_s % scene.period_s()
        } else {
            time_s
        };
        let pressures = scene
            .pad(pad)
            .unwrap()
            .scene
            .point_at_s(scene_time_s)
            .pressure_kpa;
        let expected_n: f64 = pressures
            .iter()
            .map(|kpa| f64::from(*kpa) * 1e3 * ELECTRODE_AREA_M2)
            .sum();
        let force_n: f64 = record[column("force_n")].parse().unwrap();
        assert!(
            (force_n - expected_n).abs() < FORCE_TOLERANCE_N,
            "device {device} pad {pad} at {time_s} s: {force_n} N, scene {expected_n} N"
        );
        checked += 1;
    }
    // 400 sample frames per device (the limit counts each device's frames): 200 sets of the
    // gripper's two pads; the three-pad board's frames are split between its pads.
    assert_eq!(frames[0][2], 0);
    // --samples counts sample sets of each device, however many pads it has.
    for count in frames[0][..2].iter().chain(&frames[1]) {
        assert!(count.abs_diff(400) <= 1, "{frames:?}");
    }
    assert!(checked > 400, "{checked} pad frames checked");
    // Each device's state holds every one of its pads' state.
    for (device, pad_count) in [(0, 2u8), (1, 3)] {
        let path = directory
            .path()
            .join(format!("both.csv.dev{device}.device.json"));
        let state = taxel_host::recording::RecordedDeviceState::read(&path).unwrap();
        assert_eq!(state.pad_count, pad_count, "device {device}");
        let pads: Vec<u8> = state.other_pads.iter().map(|pad| pad.pad).collect();
        assert_eq!(pads, (1..pad_count).collect::<Vec<_>>(), "device {device}");
        assert!(state.pads_without_state().is_empty(), "device {device}");
    }
}
