//! Device and host agree: a recording of the simulated device, converted with the defaults,
//! gives the device's own pressures, because the recording carries the calibration, tier and
//! baselines the device used (`rec.csv.device.json`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;
use support::SimulatorProcess;

use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

/// Largest pressure difference allowed between the device and `convert`, kPa. The device
/// converts the converter's raw code split in two exact f32 parts; the recording holds their
/// sum rounded to f32 (half an ulp at 6 pF is 2.4e-7 pF, 5e-8 in dC/C0), which the flattest part
/// of a curve (0.002 per kPa at its top) turns into 2.5e-5 kPa; the rest of the arithmetic is
/// the same code in the same order.
const AGREEMENT_KPA: f64 = 2.0e-4;

fn taxel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_taxel"))
}

fn read_rows(path: &PathBuf) -> (Vec<String>, Vec<Vec<String>>) {
    let mut reader = csv::Reader::from_path(path).unwrap();
    let header = reader
        .headers()
        .unwrap()
        .iter()
        .map(str::to_owned)
        .collect();
    let rows = reader
        .records()
        .map(|record| record.unwrap().iter().map(str::to_owned).collect())
        .collect();
    (header, rows)
}

#[test]
fn a_recording_converted_with_the_defaults_gives_the_device_pressures() {
    let directory = tempfile::tempdir().unwrap();
    let mut simulator = SimulatorProcess::start(directory.path(), "port", &["--speed", "10"]);
    let port = simulator.port.clone();
    // The simulator streams before anybody listens: let it buffer stale data first.
    std::thread::sleep(Duration::from_millis(500));
    let recording = directory.path().join("rec.csv");
    let output = taxel()
        .args(["record", &port, "--samples", "1500", "-o"])
        .arg(&recording)
        .output()
        .unwrap();
    let record_messages = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{record_messages}");
    assert!(
        record_messages.contains("0 lost on the link"),
        "{record_messages}"
    );
    assert!(directory.path().join("rec.csv.device.json").exists());

    let converted = directory.path().join("converted.csv");
    let output = taxel()
        .arg("convert")
        .arg(&recording)
        .arg("-o")
        .arg(&converted)
        .output()
        .unwrap();
    let messages = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{messages}");
    assert!(
        messages.contains("the device's calibration recorded with it"),
        "convert says which calibration it used: {messages}"
    );
    simulator.stop();

    let (recorded_header, recorded) = read_rows(&recording);
    let (converted_header, converted) = read_rows(&converted);
    assert_eq!(recorded.len(), 1500);
    assert_eq!(converted.len(), recorded.len());
    let column = |header: &[String], name: &str| header.iter().position(|h| h == name).unwrap();
    let mut compared = 0u64;
    let mut worst_kpa = 0.0f64;
    for (row, (device, host)) in recorded.iter().zip(&converted).enumerate() {
        for name in ["p11_kpa", "p12_kpa", "p21_kpa", "p22_kpa"] {
            let device_cell = &device[column(&recorded_header, name)];
            let host_cell = &host[column(&converted_header, name)];
            match (device_cell.parse::<f64>(), host_cell.parse::<f64>()) {
                (Ok(device_kpa), Ok(host_kpa)) => {
                    worst_kpa = worst_kpa.max((device_kpa - host_kpa).abs());
                    compared += 1;
                }
                _ => assert_eq!(
                    device_cell.is_empty(),
                    host_cell.is_empty(),
                    "row {row} {name}: device '{device_cell}', host '{host_cell}'"
                ),
            }
        }
    }
    eprintln!("{compared} pressures compared; largest difference {worst_kpa:e} kPa");
    assert!(compared > 4 * 1000, "{compared} pressures compared");
    assert!(
        worst_kpa <= AGREEMENT_KPA,
        "device and convert differ by up to {worst_kpa} kPa"
    );
}

/// A tare in the middle of a recording: the device announces it (TareFinished), the recorder
/// reads the new baselines and notes from which sample they apply, and the conversion switches
/// baselines there: it still gives the device's pressures, before and after.
#[test]
fn a_tare_during_a_recording_is_followed_by_the_conversion() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;

    use sim_device::{PtyPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
    use taxel_host::device_link::{open_serial, DeviceLink};
    use taxel_host::record::record_accounted;
    use taxel_host::recording::{read_device_state, Recording};
    use taxel_host::stream_accounting::StreamAccounting;

    let directory = tempfile::tempdir().unwrap();
    let mut device = SimulatedDevice::new(SimulatedDeviceConfig {
        scene: SceneFile::default_scene().unwrap(),
        seed: 5,
        speed: Some(20.0),
        topology: sim_device::pads_topology(1),
        bus_frequency_hz: sim_device::BUS_FREQUENCY_HZ,
    })
    .unwrap();
    let mut port = PtyPort::open().unwrap();
    let path = port.path().to_string_lossy().into_owned();
    let device_stop = Arc::new(AtomicBool::new(false));
    let device_thread = {
        let stop = Arc::clone(&device_stop);
        std::thread::spawn(move || device.run(&mut port, Some(60.0), &stop))
    };
    let mut link = DeviceLink::new(open_serial(&path, Duration::from_millis(100)).unwrap().port);
    let timeout = Duration::from_secs(2);
    let (info, _) = link.synchronise(timeout).unwrap();
    let state = read_device_state(&mut link, &info, timeout).unwrap();
    let csv_path = directory.path().join("tare.csv");
    let (mut recording, _) = Recording::create(&csv_path, None).unwrap();
    recording.set_device_state(state);
    let mut accounting = StreamAccounting::new();
    let stop = AtomicBool::new(false);
    let flush = Duration::from_millis(200);
    // The demo scene is still for its first 3 s: record 100 sets, tare, record 150 more.
    record_accounted(
        &mut link,
        &mut recording,
        &mut accounting,
        &stop,
        Some(100),
        flush,
        &mut |_| {},
    )
    .unwrap();
    link.send(wire::Command::Tare { sample_sets: 8 }).unwrap();
    record_accounted(
        &mut link,
        &mut recording,
        &mut accounting,
        &stop,
        Some(150),
        flush,
        &mut |_| {},
    )
    .unwrap();
    device_stop.store(true, Ordering::Relaxed);
    device_thread.join().unwrap();
    let files = recording.finish(None).unwrap();
    let device_state =
        taxel_host::recording::RecordedDeviceState::read(&files.device_state.unwrap()).unwrap();
    // The recording may start before the boot tare ends (then that tare is a change too); the
    // commanded tare is the last change, after sample 100.
    let changes = &device_state.baselines;
    assert!(changes.len() >= 2, "{changes:?}");
    let last = &changes[changes.len() - 1];
    assert!(last.from_sequence > changes[changes.len() - 2].from_sequence);
    assert_ne!(last.taxels, changes[changes.len() - 2].taxels);
    assert!(last.taxels.iter().all(Option::is_some));

    let converted = directory.path().join("converted.csv");
    let output = taxel()
        .arg("convert")
        .arg(&csv_path)
        .arg("-o")
        .arg(&converted)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let (recorded_header, recorded) = read_rows(&csv_path);
    let (converted_header, converted) = read_rows(&converted);
    assert_eq!(recorded.len(), 250);
    let column = |header: &[String], name: &str| header.iter().position(|h| h == name).unwrap();
    let mut compared = 0;
    for (device, host) in recorded.iter().zip(&converted) {
        for name in ["p11_kpa", "p12_kpa", "p21_kpa", "p22_kpa"] {
            let device_cell = &device[column(&recorded_header, name)];
            let host_cell = &host[column(&converted_header, name)];
            if let (Ok(device_kpa), Ok(host_kpa)) =
                (device_cell.parse::<f64>(), host_cell.parse::<f64>())
            {
                assert!((device_kpa - host_kpa).abs() <= AGREEMENT_KPA);
                compared += 1;
            } else {
                assert_eq!(
                    device_cell.is_empty(),
                    host_cell.is_empty(),
                    "{name}: device {device:?}, host {host:?}"
                );
            }
        }
    }
    assert!(compared > 900, "{compared}");
}

/// `taxel calibration pull` writes the calibration the simulated device uses (its factory
/// calibration, from its flash) as a calibration file, and it is the simulated pad's own.
#[test]
fn calibration_pull_writes_the_device_calibration() {
    let directory = tempfile::tempdir().unwrap();
    let mut simulator = SimulatorProcess::start(directory.path(), "port", &["--speed", "10"]);
    let port = simulator.port.clone();
    let pulled = directory.path().join("pulled.json");
    let output = taxel()
        .args(["calibration", "pull", &port, "-o"])
        .arg(&pulled)
        .output()
        .unwrap();
    simulator.stop();
    let messages = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{messages}");
    assert!(messages.contains("from flash"), "{messages}");
    let calibration = taxel_host::calibration_file::read(&pulled).unwrap();
    assert_eq!(calibration.id(), sim_device::FACTORY_CALIBRATION_ID);
    let truth = sim_device::SimulatedDevice::new(sim_device::SimulatedDeviceConfig {
        scene: sim_device::SceneFile::default_scene().unwrap(),
        seed: 1,
        speed: None,
        topology: sim_device::pads_topology(1),
        bus_frequency_hz: sim_device::BUS_FREQUENCY_HZ,
    })
    .unwrap()
    .simulation()
    .physics()
    .matching_calibration()
    .unwrap();
    for (pulled_taxel, true_taxel) in calibration.taxels().iter().zip(truth.taxels()) {
        assert_eq!(pulled_taxel.curve().points(), true_taxel.curve().points());
        assert_eq!(pulled_taxel.parasitic_pf(), true_taxel.parasitic_pf());
    }
}
