//! Device and host agree: a recording of the simulated device, converted with its recorded
//! state (`rec.csv.dev0.device.json`: the calibration, tier and baselines the device used, each
//! baseline with the set it applies from), gives the device's own pressures, flags, force,
//! centre of pressure and contact — exactly, bit for bit (contact once the device's detector
//! has changed within the recording: its history from before the recording is not recorded).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;
use support::SimulatorProcess;

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use taxel_host::schema::{PadRow, RowReader};

fn taxel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_taxel"))
}

/// The rows of a recording; panics on a row that cannot be read.
fn read_rows(path: &Path) -> Vec<PadRow> {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = RowReader::new(file).unwrap();
    let mut rows = Vec::new();
    while let Some(row) = reader.next_row() {
        rows.push(row.unwrap());
    }
    rows
}

/// Converts `recording` with its recorded state into `converted`; returns convert's messages.
fn convert(recording: &Path, converted: &Path) -> String {
    let output = taxel()
        .arg("convert")
        .arg(recording)
        .arg("-o")
        .arg(converted)
        .output()
        .unwrap();
    let messages = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{messages}");
    assert!(
        messages.contains("converting with the device state in")
            && messages.contains(".dev0.device.json"),
        "convert says which state it used: {messages}"
    );
    assert!(!messages.contains("had no recorded state"), "{messages}");
    messages
}

/// How many pressures and contact states were compared.
#[derive(Debug, Default)]
struct Agreement {
    pressures: u64,
    contacts: u64,
    /// Sets at the start of a pad whose contact was not compared (see [`assert_agree_exactly`]).
    contacts_before_the_first_change: u64,
}

/// Every row of the recording and of its conversion agree exactly: the same set of the same
/// pad, the device's readings kept, and every output the device computed computed again to the
/// same bits.
///
/// One exception, which the recorded state cannot remove: the contact detector's history from
/// before the first recorded set (a contact under way, or sets counted towards one) is not in
/// the recording, so a pad's contact is compared from the first change of contact the device
/// made within the recording, at least a debounce after its first set; from there the two
/// detectors have seen the same sets.
fn assert_agree_exactly(recorded: &[PadRow], converted: &[PadRow]) -> Agreement {
    use std::collections::HashMap;
    let debounce_sets = u64::from(model_core::ContactConfig::DEFAULT.debounce_sets());
    assert_eq!(converted.len(), recorded.len());
    let mut agreement = Agreement::default();
    // Per pad: sets seen, the device's last contact, whether contact is compared yet.
    let mut contact_history: HashMap<(u32, u8), (u64, Option<bool>, bool)> = HashMap::new();
    for (device, host) in recorded.iter().zip(converted) {
        assert_eq!(
            (
                device.host_time_us,
                device.device,
                device.pad,
                device.sequence
            ),
            (host.host_time_us, host.device, host.pad, host.sequence)
        );
        let (Some(device_reading), Some(host_reading)) = (&device.reading, &host.reading) else {
            assert_eq!(device.reading, host.reading, "set {}", device.sequence);
            continue;
        };
        let set = device.sequence;
        assert_eq!(
            device_reading.pressure_kpa.map(|kpa| kpa.map(f32::to_bits)),
            host_reading.pressure_kpa.map(|kpa| kpa.map(f32::to_bits)),
            "set {set}: device {:?}, host {:?}",
            device_reading.pressure_kpa,
            host_reading.pressure_kpa
        );
        assert_eq!(device_reading.flags, host_reading.flags, "set {set}");
        assert_eq!(device_reading.force_n, host_reading.force_n, "set {set}");
        assert_eq!(
            device_reading.centre_of_pressure_mm, host_reading.centre_of_pressure_mm,
            "set {set}"
        );
        assert_eq!(device_reading.partial, host_reading.partial, "set {set}");
        assert_eq!(
            (
                device_reading.device_time_us,
                device_reading.temperature_c,
                device_reading.capacitance_pf
            ),
            (
                host_reading.device_time_us,
                host_reading.temperature_c,
                host_reading.capacitance_pf
            ),
            "set {set}: the readings are kept"
        );
        let (seen, last_contact, compared) = contact_history
            .entry((device.device, device.pad))
            .or_insert((0, None, false));
        if *seen >= debounce_sets && last_contact.is_some_and(|last| last != device_reading.contact)
        {
            *compared = true;
        }
        *seen += 1;
        *last_contact = Some(device_reading.contact);
        if *compared {
            assert_eq!(device_reading.contact, host_reading.contact, "set {set}");
            agreement.contacts += 1;
        } else {
            agreement.contacts_before_the_first_change += 1;
        }
        agreement.pressures += device_reading
            .pressure_kpa
            .iter()
            .filter(|kpa| kpa.is_some())
            .count() as u64;
    }
    agreement
}

/// The old test allowed 2e-4 kPa between the device and `convert`; the recording now holds every
/// capacitance as the f32 the device's model used, so the agreement is exact.
#[test]
fn a_recording_converted_with_its_recorded_state_gives_the_device_outputs_exactly() {
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
    assert!(directory.path().join("rec.csv.dev0.device.json").exists());
    assert!(directory.path().join("rec.csv.dev0.raw").exists());

    let converted = directory.path().join("converted.csv");
    convert(&recording, &converted);
    simulator.stop();

    let recorded = read_rows(&recording);
    assert_eq!(recorded.len(), 1500);
    let agreement = assert_agree_exactly(&recorded, &read_rows(&converted));
    eprintln!("every output equal: {agreement:?}");
    assert!(agreement.pressures > 4 * 1000, "{agreement:?}");
    assert!(
        agreement.contacts > 1000,
        "the scene's presses start and end contacts: {agreement:?}"
    );
}

/// A tare in the middle of a recording: the device announces it (TareFinished), the session
/// reads the new baselines and notes from which set they apply, the recorder writes them into
/// the device's state, and the conversion switches baselines there: it still gives the device's
/// outputs exactly, before and after. Recorded as `taxel record` does, through the host
/// library's session, worker and recorder, with the tare requested through the worker.
#[test]
fn a_tare_during_a_recording_is_followed_by_the_conversion() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    use std::time::Instant;

    use sim_device::{PtyPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
    use taxel_host::device_link::{open_serial, DeviceLink};
    use taxel_host::device_state::RecordedDeviceState;
    use taxel_host::host_clock::UnixClock;
    use taxel_host::recorder::{Recorder, RecordingPaths};
    use taxel_host::session::{DeviceSession, SessionConfig};
    use taxel_host::worker::{EventQueue, Overflow, Worker, WorkerEvent};
    use wire::{Command as DeviceCommand, ReplyPayload};

    let directory = tempfile::tempdir().unwrap();
    let mut device = SimulatedDevice::new(
        SimulatedDeviceConfig::new(SceneFile::default_scene().unwrap(), 1)
            .with_seed(5)
            .with_speed(Some(20.0)),
    )
    .unwrap();
    let mut port = PtyPort::open().unwrap();
    let path = port.path().to_string_lossy().into_owned();
    let device_stop = Arc::new(AtomicBool::new(false));
    let device_thread = {
        let stop = Arc::clone(&device_stop);
        std::thread::spawn(move || device.run(&mut port, Some(60.0), &stop))
    };

    let csv_path = directory.path().join("tare.csv");
    let clock = UnixClock::new();
    let paths = RecordingPaths {
        csv: Some(csv_path.clone()),
        mcap: None,
    };
    // The demo scene is still for its first 3 s: record 100 sets, tare, record 150 more.
    let mut recorder = Recorder::create(paths, 1, clock, Some(250)).unwrap();
    let config = SessionConfig {
        request_timeout: Duration::from_secs(2),
        follow_state: true,
    };
    let opened = open_serial(&path, Duration::from_millis(20)).unwrap();
    let mut session = DeviceSession::open(DeviceLink::new(opened.port), config).unwrap();
    session.link_mut().set_raw_log(recorder.raw_log(0).unwrap());
    session.start().unwrap();
    let queue = Arc::new(EventQueue::new(100_000, Overflow::Wait));
    let worker = Worker::start(vec![session], Arc::clone(&queue), Arc::new(clock)).unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut tared = false;
    let mut baseline_events = 0;
    while !recorder.is_complete() {
        assert!(
            Instant::now() < deadline,
            "sets so far: {:?}",
            recorder.sets_taken()
        );
        if !tared && recorder.sets_taken()[0] >= 100 {
            let reply = worker
                .request(
                    0,
                    DeviceCommand::Tare {
                        sample_sets: 8,
                        pad: None,
                    },
                    Duration::from_secs(5),
                )
                .unwrap();
            assert_eq!(reply, ReplyPayload::Ack);
            tared = true;
        }
        if let Some(arrived) = queue.pop_until(Instant::now() + Duration::from_millis(100)) {
            match &arrived.event {
                WorkerEvent::Ended(end) => panic!("the device ended: {:?}", end.reason),
                WorkerEvent::Session(taxel_host::session::SessionEvent::Baselines { .. }) => {
                    baseline_events += 1;
                }
                _ => {}
            }
            recorder.take(arrived).unwrap();
        }
    }
    for mut session in worker.finish().into_iter().flatten() {
        if let Some(mut raw) = session.link_mut().take_raw_log() {
            raw.flush().unwrap();
        }
    }
    for arrived in queue.drain() {
        recorder.take(arrived).unwrap();
    }
    let summary = recorder.finish().unwrap();
    device_stop.store(true, Ordering::Relaxed);
    device_thread.join().unwrap();
    assert_eq!(summary.devices[0].sets, 250);
    assert!(baseline_events >= 1, "the tare's baselines were read");

    let state_path = directory.path().join("tare.csv.dev0.device.json");
    assert!(summary.files.contains(&state_path), "{:?}", summary.files);
    let device_state = RecordedDeviceState::read(&state_path).unwrap();
    // The recording may start before the boot tare ends (then that tare is a change too); the
    // commanded tare is the last change, after set 100 of the recording.
    let recorded = read_rows(&csv_path);
    assert_eq!(recorded.len(), 250);
    let changes = &device_state.pad_state(0).unwrap().baselines;
    assert!(changes.len() >= 2, "{changes:?}");
    let last = &changes[changes.len() - 1];
    assert!(last.from_sequence > changes[changes.len() - 2].from_sequence);
    assert!(last.from_sequence > recorded[100].sequence, "{changes:?}");
    assert!(last.from_sequence <= recorded[249].sequence, "{changes:?}");
    assert_ne!(last.taxels, changes[changes.len() - 2].taxels);
    assert!(last.taxels.iter().all(Option::is_some));

    let converted = directory.path().join("converted.csv");
    convert(&csv_path, &converted);
    let converted = read_rows(&converted);
    let agreement = assert_agree_exactly(&recorded, &converted);
    eprintln!("every output equal: {agreement:?}");
    assert!(agreement.pressures > 900, "{agreement:?}");
    // Both baselines were in use: pressures on either side of the change agree.
    let after = recorded
        .iter()
        .filter(|row| row.sequence >= last.from_sequence)
        .filter(|row| {
            row.reading
                .is_some_and(|reading| reading.pressure_kpa[0].is_some())
        })
        .count();
    assert!(after > 50, "{after} sets with pressures after the tare");
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
    let truth = sim_device::SimulatedDevice::new(
        sim_device::SimulatedDeviceConfig::new(sim_device::SceneFile::default_scene().unwrap(), 1)
            .with_seed(1),
    )
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
