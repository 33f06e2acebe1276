//! Several pads end to end through the real host path: `taxel sim` runs the simulated board
//! (the firmware's discovery, acquisition and protocol code, a TCA9548A with one pad per
//! channel) on a pseudo-terminal, `taxel record` records it into the recording schema (a row
//! per pad per sample set), and every pad's rows are checked against the scene that pad plays
//! (force = pressure x the article's 5 mm x 5 mm electrodes, computed here). `--samples N`
//! gives N sets of every pad of every device.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;
use support::SimulatorProcess;

use std::collections::BTreeMap;
use std::io::BufReader;
use std::path::Path;
use std::process::Command;

use sim_device::SceneFile;
use taxel_host::device_state::RecordedDeviceState;
use taxel_host::schema::{PadReading, PadRow, RowReader};

/// Each pressure within 0.5 kPa of the scene: the force within 0.5 kPa times the pad's
/// electrode area (0.05 N on the article's pad).
const PRESSURE_TOLERANCE_KPA: f64 = 0.5;

fn taxel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_taxel"))
}

fn read_rows(path: &Path) -> Vec<PadRow> {
    let file = BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = RowReader::new(file).unwrap();
    let mut rows = Vec::new();
    while let Some(row) = reader.next_row() {
        rows.push(row.unwrap());
    }
    rows
}

/// Records `sets` sample sets from a simulator started with `arguments`; its rows.
fn record(arguments: &[&str], sets: u32) -> Vec<PadRow> {
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
    read_rows(&recording)
}

/// The rows of each (device, pad), in file order.
fn by_pad(rows: &[PadRow]) -> BTreeMap<(u32, u8), Vec<&PadRow>> {
    let mut pads: BTreeMap<(u32, u8), Vec<&PadRow>> = BTreeMap::new();
    for row in rows {
        pads.entry((row.device, row.pad)).or_default().push(row);
    }
    pads
}

/// Checks every pad's reading where its four taxels read against `scene`'s pad `pad`: its
/// force, and that it is not flagged partial. Returns whether it was checked (the tare at
/// boot and before the first second are left out).
fn check_against_scene(reading: &PadReading, scene: &SceneFile, pad: usize, what: &str) -> bool {
    let time_s = reading.device_time_us as f64 / 1e6;
    if time_s < 1.0 || reading.pressure_kpa.iter().any(Option::is_none) {
        return false;
    }
    let scene_time_s = if scene.repeat {
        time_s % scene.period_s()
    } else {
        time_s
    };
    let pad_scene = scene.pad(pad).unwrap();
    let pressures = pad_scene.scene.point_at_s(scene_time_s).pressure_kpa;
    // The electrode areas the scene gives the pad (the article's 25 mm² unless it says).
    let expected_n: f64 = pressures
        .iter()
        .zip(pad_scene.geometry.taxels())
        .map(|(kpa, taxel)| f64::from(*kpa) * 1e3 * f64::from(taxel.area_mm2) * 1e-6)
        .sum();
    let area_m2: f64 = pad_scene
        .geometry
        .taxels()
        .iter()
        .map(|taxel| f64::from(taxel.area_mm2) * 1e-6)
        .sum();
    let tolerance_n = PRESSURE_TOLERANCE_KPA * 1e3 * area_m2;
    let force_n = f64::from(reading.force_n.unwrap());
    assert!(
        (force_n - expected_n).abs() < tolerance_n,
        "{what} at {time_s} s: {force_n} N recorded, scene {expected_n} N"
    );
    assert!(!reading.partial, "{what} at {time_s} s: partial");
    true
}

/// Every pad of one device has exactly `sets` rows, the same consecutive sets, each with the
/// pad's frame; checks them against the scene. Returns how many pad samples it checked.
fn check_device(rows: &[PadRow], scene: &SceneFile, pads: usize, sets: usize) -> usize {
    let by_pad = by_pad(rows);
    let found: Vec<(u32, u8)> = by_pad.keys().copied().collect();
    let expected: Vec<(u32, u8)> = (0..pads).map(|pad| (0, pad as u8)).collect();
    assert_eq!(found, expected, "one device, pads 0 to {}", pads - 1);
    let pad_0_sequences: Vec<u32> = by_pad[&(0, 0)].iter().map(|row| row.sequence).collect();
    assert!(pad_0_sequences
        .windows(2)
        .all(|pair| pair[1] == pair[0] + 1));
    let mut checked = 0;
    for ((_, pad), pad_rows) in &by_pad {
        let sequences: Vec<u32> = pad_rows.iter().map(|row| row.sequence).collect();
        assert_eq!(pad_rows.len(), sets, "pad {pad}");
        assert_eq!(sequences, pad_0_sequences, "pad {pad}: the same sets");
        for row in pad_rows {
            let reading = row
                .reading
                .as_ref()
                .unwrap_or_else(|| panic!("pad {pad} missing from set {}", row.sequence));
            let what = format!("pad {pad}");
            if check_against_scene(reading, scene, usize::from(*pad), &what) {
                checked += 1;
            }
        }
    }
    checked
}

#[test]
fn the_gripper_scene_is_recorded_pad_by_pad() {
    let rows = record(&["--scene", "gripper"], 600);
    // Two pads, and no third: a row per pad per set.
    assert_eq!(rows.len(), 2 * 600);
    let scene = SceneFile::built_in("gripper").unwrap();
    let checked = check_device(&rows, &scene, 2, 600);
    assert!(checked > 800, "{checked} pad samples checked");
}

#[test]
fn eight_pads_are_recorded_in_their_rows() {
    let rows = record(&["--pads", "8"], 300);
    assert_eq!(rows.len(), 8 * 300);
    let scene = SceneFile::default_scene().unwrap();
    let checked = check_device(&rows, &scene, 8, 300);
    assert!(checked > 8 * 200, "{checked} pad samples checked");
    // One sample set per sequence number: every pad's frame of a set was read within one
    // converter cycle (10 ms at 400 S/s), and the set's rows share its host time.
    let mut sets: BTreeMap<u32, Vec<&PadRow>> = BTreeMap::new();
    for row in &rows {
        sets.entry(row.sequence).or_default().push(row);
    }
    assert_eq!(sets.len(), 300);
    for (sequence, set) in &sets {
        let times: Vec<u64> = set
            .iter()
            .map(|row| row.reading.unwrap().device_time_us)
            .collect();
        let spread_us = times.iter().max().unwrap() - times.iter().min().unwrap();
        assert!(
            spread_us < 10_000,
            "set {sequence}: pads read {spread_us} us apart"
        );
        assert!(
            set.iter()
                .all(|row| row.host_time_us == set[0].host_time_us),
            "set {sequence}: one host time"
        );
    }
}

/// Two devices with several pads each, recorded together: a row per pad per set of each
/// device, `--samples` sets of every pad of every device, and every device's every pad follows
/// its own scene.
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
    let rows = read_rows(&recording);
    let scenes = [
        SceneFile::built_in("gripper").unwrap(),
        SceneFile::default_scene().unwrap(),
    ];
    let pad_counts = [2usize, 3];
    let by_pad = by_pad(&rows);
    let found: Vec<(u32, u8)> = by_pad.keys().copied().collect();
    assert_eq!(found, [(0, 0), (0, 1), (1, 0), (1, 1), (1, 2)]);
    let mut checked = 0;
    for (&(device, pad), pad_rows) in &by_pad {
        // --samples counts sample sets of each device, however many pads it has: every pad of
        // every device has exactly that many rows, consecutive sets in host-time order.
        assert_eq!(pad_rows.len(), 400, "device {device} pad {pad}");
        assert!(
            pad_rows
                .windows(2)
                .all(|pair| pair[1].sequence == pair[0].sequence + 1
                    && pair[0].host_time_us <= pair[1].host_time_us),
            "device {device} pad {pad}"
        );
        for row in pad_rows {
            let reading = row.reading.as_ref().unwrap();
            let what = format!("device {device} pad {pad}");
            if check_against_scene(reading, &scenes[device as usize], usize::from(pad), &what) {
                checked += 1;
            }
        }
    }
    assert_eq!(rows.len(), 400 * pad_counts.iter().sum::<usize>());
    assert!(checked > 400, "{checked} pad frames checked");
    // Each device's state holds every one of its pads' state.
    for (device, pad_count) in [(0, 2u8), (1, 3)] {
        let path = directory
            .path()
            .join(format!("both.csv.dev{device}.device.json"));
        let state = RecordedDeviceState::read(&path).unwrap();
        assert_eq!(state.pad_count, pad_count, "device {device}");
        let pads: Vec<u8> = state.pads.iter().map(|pad| pad.pad).collect();
        assert_eq!(pads, (0..pad_count).collect::<Vec<_>>(), "device {device}");
        assert!(state.pads_without_state().is_empty(), "device {device}");
    }
}
