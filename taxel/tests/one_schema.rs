//! One recording schema for every case, through the binaries: `taxel record` of a one-pad
//! device, of a several-pad device and of several devices at once writes the same header;
//! `taxel convert` and `taxel plot` read each; re-processing with the recorded device states
//! gives the device's pressures, flags, force, centre of pressure and contact exactly; `--samples
//! N` records N sets of each device into the CSV and the MCAP file alike; `--wide` is an export
//! of one row per set.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

use support::{taxel_binary, SimulatorProcess};
use taxel_host::schema::{header, PadRow, RowReader};

fn taxel(arguments: &[&str]) -> std::process::Output {
    let output = Command::new(taxel_binary())
        .args(arguments)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "taxel {arguments:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

fn rows(path: &Path) -> Vec<PadRow> {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = RowReader::new(file).unwrap();
    let mut rows = Vec::new();
    while let Some(row) = reader.next_row() {
        rows.push(row.unwrap());
    }
    rows
}

fn first_line(path: &Path) -> String {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .to_owned()
}

/// Records `samples` sets of each simulator into `name`.csv and `name`.mcap.
fn record(
    directory: &Path,
    name: &str,
    ports: &[&str],
    samples: u64,
) -> (std::path::PathBuf, std::path::PathBuf) {
    let csv = directory.join(format!("{name}.csv"));
    let mcap = directory.join(format!("{name}.mcap"));
    let samples = samples.to_string();
    let mut arguments = vec!["record"];
    arguments.extend(ports);
    arguments.extend([
        "-o",
        csv.to_str().unwrap(),
        "--mcap",
        mcap.to_str().unwrap(),
        "--samples",
        samples.as_str(),
    ]);
    taxel(&arguments);
    (csv, mcap)
}

/// The messages of each topic in an MCAP file.
fn topic_counts(path: &Path) -> HashMap<String, usize> {
    let bytes = std::fs::read(path).unwrap();
    let mut counts = HashMap::new();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        *counts
            .entry(message.unwrap().channel.topic.clone())
            .or_insert(0) += 1;
    }
    counts
}

/// Converts `csv` with its device states and checks every row equals the device's; returns the
/// rows in contact and the changes of contact compared.
fn assert_reprocessed_equal(csv: &Path) -> (usize, usize) {
    let converted = csv.with_extension("converted.csv");
    taxel(&[
        "convert",
        csv.to_str().unwrap(),
        "-o",
        converted.to_str().unwrap(),
    ]);
    assert_eq!(first_line(&converted), header().join(","));
    let recorded = rows(csv);
    let again = rows(&converted);
    assert_eq!(recorded.len(), again.len());
    let mut compared = 0;
    for (recorded, again) in recorded.iter().zip(&again) {
        assert_eq!(
            (recorded.device, recorded.pad, recorded.sequence),
            (again.device, again.pad, again.sequence)
        );
        let (Some(device), Some(host)) = (&recorded.reading, &again.reading) else {
            assert_eq!(recorded.reading, again.reading);
            continue;
        };
        assert_eq!(device.pressure_kpa, host.pressure_kpa, "{recorded:?}");
        assert_eq!(device.flags, host.flags, "{recorded:?}");
        assert_eq!(device.force_n, host.force_n, "{recorded:?}");
        assert_eq!(
            device.centre_of_pressure_mm, host.centre_of_pressure_mm,
            "{recorded:?}"
        );
        assert_eq!(device.partial, host.partial, "{recorded:?}");
        assert_eq!(device.contact, host.contact, "{recorded:?}");
        compared += 1;
    }
    assert!(compared > 0);
    let in_contact = recorded
        .iter()
        .filter(|row| row.reading.as_ref().is_some_and(|reading| reading.contact))
        .count();
    let mut changes = 0;
    let mut last: HashMap<(u32, u8), bool> = HashMap::new();
    for row in &recorded {
        if let Some(reading) = &row.reading {
            let before = last.insert((row.device, row.pad), reading.contact);
            changes += usize::from(before.is_some_and(|before| before != reading.contact));
        }
    }
    (in_contact, changes)
}

/// The device's contact, through presses that start and end during the recording and a
/// recording that starts during a contact, is what re-processing with the device's state gives,
/// set by set.
#[test]
fn reprocessing_gives_the_devices_contact_set_by_set() {
    let directory = tempfile::tempdir().unwrap();
    // The demo scene presses C11 with 3 kPa (0.075 N, above the 0.05 N threshold) from 4 to
    // 8 s, slides a press across the pad from 9 to 16 s, presses the whole pad from 18 to 30 s
    // and again from 30 s: 20 s recorded from anywhere in its first 25 s hold several changes.
    let simulator = SimulatorProcess::start(directory.path(), "sim.txt", &["--speed", "10"]);
    let (csv, _) = record(
        directory.path(),
        "presses",
        &[simulator.port.as_str()],
        2000,
    );
    let (in_contact, changes) = assert_reprocessed_equal(&csv);
    assert!(in_contact > 100, "{in_contact} rows in contact");
    assert!(changes >= 2, "{changes} changes of contact");
    // A recording that starts in the middle of a contact: its first rows say so, and the
    // re-processing follows from there.
    let rows = rows(&csv);
    let first_in_contact = rows
        .iter()
        .position(|row| row.reading.as_ref().is_some_and(|reading| reading.contact))
        .unwrap();
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header_line = lines.next().unwrap();
    let tail: Vec<&str> = lines.skip(first_in_contact + 20).collect();
    let cut = directory.path().join("cut.csv");
    std::fs::write(&cut, format!("{header_line}\n{}\n", tail.join("\n"))).unwrap();
    std::fs::copy(
        directory.path().join("presses.csv.dev0.device.json"),
        directory.path().join("cut.csv.dev0.device.json"),
    )
    .unwrap();
    let (in_contact, _) = assert_reprocessed_equal(&cut);
    assert!(in_contact > 0);
}

#[test]
fn every_case_writes_one_schema_that_convert_and_plot_read_and_reprocessing_reproduces() {
    let directory = tempfile::tempdir().unwrap();
    let one_pad = SimulatorProcess::start(directory.path(), "one.txt", &["--speed", "5"]);
    let three_pads = SimulatorProcess::start(
        directory.path(),
        "three.txt",
        &["--speed", "5", "--pads", "3"],
    );
    let gripper = SimulatorProcess::start(
        directory.path(),
        "gripper.txt",
        &["--speed", "5", "--scene", "gripper"],
    );
    let cases: [(&str, Vec<&str>, Vec<usize>); 3] = [
        ("one", vec![one_pad.port.as_str()], vec![1]),
        ("three", vec![three_pads.port.as_str()], vec![3]),
        (
            "both",
            vec![one_pad.port.as_str(), gripper.port.as_str()],
            vec![1, 2],
        ),
    ];
    for (name, ports, pads) in cases {
        let (csv, mcap) = record(directory.path(), name, &ports, 150);
        assert_eq!(first_line(&csv), header().join(","), "{name}");
        let recorded = rows(&csv);
        for (device, pads) in pads.iter().enumerate() {
            let device_rows: Vec<&PadRow> = recorded
                .iter()
                .filter(|row| row.device as usize == device)
                .collect();
            assert_eq!(device_rows.len(), 150 * pads, "{name}: device {device}");
            for pad in 0..*pads {
                let sequences: Vec<u32> = device_rows
                    .iter()
                    .filter(|row| usize::from(row.pad) == pad)
                    .map(|row| row.sequence)
                    .collect();
                assert_eq!(sequences.len(), 150);
                assert!(sequences.windows(2).all(|pair| pair[1] == pair[0] + 1));
            }
            assert!(directory
                .path()
                .join(format!("{name}.csv.dev{device}.raw"))
                .exists());
            assert!(directory
                .path()
                .join(format!("{name}.csv.dev{device}.device.json"))
                .exists());
        }
        // The MCAP file holds the same sets: a pressure cloud and a wrench per pad per set.
        let counts = topic_counts(&mcap);
        for (device, pads) in pads.iter().enumerate() {
            for pad in 0..*pads {
                let topic = format!("/taxel/device{device}/pad{pad}/pressure");
                assert_eq!(counts.get(&topic), Some(&150), "{name}: {topic}");
            }
        }
        assert_reprocessed_equal(&csv);
        let picture = directory.path().join(format!("{name}.svg"));
        taxel(&[
            "plot",
            csv.to_str().unwrap(),
            "-o",
            picture.to_str().unwrap(),
        ]);
        let svg = std::fs::read_to_string(&picture).unwrap();
        if pads.iter().sum::<usize>() > 1 {
            assert!(svg.contains("Device 0 pad 0"), "{name}: a panel per pad");
        }
        let wide = directory.path().join(format!("{name}.wide.csv"));
        taxel(&[
            "convert",
            csv.to_str().unwrap(),
            "--wide",
            "-o",
            wide.to_str().unwrap(),
        ]);
        let wide_rows = std::fs::read_to_string(&wide).unwrap().lines().count() - 1;
        assert_eq!(
            wide_rows,
            150 * pads.len(),
            "{name}: one row per set of each device"
        );
    }
}

#[test]
fn a_raw_log_converts_into_the_schema_with_its_device_state() {
    let directory = tempfile::tempdir().unwrap();
    let device = SimulatorProcess::start(
        directory.path(),
        "port.txt",
        &["--speed", "5", "--pads", "2"],
    );
    let (csv, _) = record(directory.path(), "rec", &[device.port.as_str()], 120);
    let raw = directory.path().join("rec.csv.dev0.raw");
    let converted = directory.path().join("raw.csv");
    taxel(&[
        "convert",
        "--raw",
        raw.to_str().unwrap(),
        "-o",
        converted.to_str().unwrap(),
    ]);
    let from_raw = rows(&converted);
    let recorded = rows(&csv);
    // The raw log holds every frame received, the CSV the 120 sets recorded: each recorded row
    // is among the raw log's, with the same outputs.
    for row in &recorded {
        let found = from_raw
            .iter()
            .find(|raw_row| raw_row.pad == row.pad && raw_row.sequence == row.sequence)
            .unwrap();
        let (Some(recorded), Some(converted)) = (&row.reading, &found.reading) else {
            panic!("a missing frame")
        };
        assert_eq!(recorded.pressure_kpa, converted.pressure_kpa);
        assert_eq!(recorded.force_n, converted.force_n);
    }
}

#[test]
fn a_file_of_another_shape_is_refused_by_name() {
    let directory = tempfile::tempdir().unwrap();
    let old = directory.path().join("old.csv");
    std::fs::write(
        &old,
        "seq,time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n1,0.0,25,4.5,4.5,4.5,4.5\n",
    )
    .unwrap();
    for command in ["convert", "plot"] {
        let mut arguments = vec![command, old.to_str().unwrap()];
        let picture = directory.path().join("p.svg");
        if command == "plot" {
            arguments.extend(["-o", picture.to_str().unwrap()]);
        }
        let output = Command::new(taxel_binary())
            .args(&arguments)
            .output()
            .unwrap();
        assert!(!output.status.success());
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            stderr.contains("not a taxel recording"),
            "{command}: {stderr}"
        );
        assert!(stderr.contains("earlier versions"), "{command}: {stderr}");
    }
}
