//! Every pad's own state in a recording: a device of several pads whose pad 1 runs another
//! calibration than pad 0 is recorded, the device-state file (`NAME.csv.dev<n>.device.json`)
//! holds each pad's calibration, tier and baselines (a tare's new baselines in the history of
//! the pad that reported it), and `taxel convert` gives every pad's own pressures back. A
//! device-state file that lacks a pad's state still converts, and says which pad was
//! converted without it.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;
use support::{info, FakeDevice, SimulatorProcess};

use std::io::{BufReader, Write};
use std::path::Path;
use std::process::{Command, Output};
use std::sync::Arc;
use std::time::{Duration, Instant};

use model_core::{BaselineRecord, Calibration, TAXEL_COUNT};
use taxel_host::calibration_transfer::{pull, pull_baselines, upload_to_pads};
use taxel_host::device_link::DeviceLink;
use taxel_host::device_state::{BaselineChange, RecordedDeviceState, RecordedPadState};
use taxel_host::schema::{PadReading, PadRow, RowReader, RowWriter};
use taxel_host::session::{DeviceSession, SessionConfig, SessionEvent};
use wire::{
    Command as WireCommand, DeviceEvent, DeviceFrame, EventFrame, PadIndex, PadInfoFrame,
    ReplyFrame, ReplyPayload, TaxelBaselineWire, TemperatureSource,
};

/// Largest pressure difference allowed between the device and `convert`, kPa (as in
/// `device_agreement.rs`: the recording holds the tared capacitance's two exact parts summed to
/// one f32).
const AGREEMENT_KPA: f64 = 2.0e-4;

/// The id of the calibration the tests give pad 1.
const PAD_1_CALIBRATION_ID: u32 = 4242;

fn taxel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_taxel"))
}

fn pad(index: u8) -> PadIndex {
    PadIndex::new(index).unwrap()
}

fn run(command: &mut Command) -> (Output, String) {
    let output = command.output().unwrap();
    let messages = String::from_utf8_lossy(&output.stderr).into_owned();
    (output, messages)
}

/// A calibration unlike `calibration`: every curve point's pressure scaled by 0.8 (so every
/// pressure of the same capacitance is 20 % lower), with its own id.
fn another_calibration(calibration: &Calibration) -> Calibration {
    let mut spec = calibration.to_spec();
    spec.id = PAD_1_CALIBRATION_ID;
    for taxel in spec.taxels.iter_mut() {
        for point in taxel.points.iter_mut() {
            point.pressure_kpa *= 0.8;
        }
    }
    Calibration::new(&spec).unwrap()
}

/// Every row of a recording of the schema.
fn read_rows(path: &Path) -> Vec<PadRow> {
    let file = BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = RowReader::new(file).unwrap();
    let mut rows = Vec::new();
    while let Some(row) = reader.next_row() {
        rows.push(row.unwrap());
    }
    rows
}

/// Per pad: how many pressures of `converted` were compared with `recorded`'s (the device's),
/// and the largest difference, kPa. A pressure missing (faulted) must be missing in both.
fn pad_differences(recorded: &Path, converted: &Path, pads: usize) -> Vec<(usize, f64)> {
    let recorded = read_rows(recorded);
    let converted = read_rows(converted);
    assert_eq!(recorded.len(), converted.len());
    let mut differences = vec![(0usize, 0.0f64); pads];
    for (device, host) in recorded.iter().zip(&converted) {
        assert_eq!(
            (device.device, device.pad, device.sequence),
            (host.device, host.pad, host.sequence),
            "the same rows in the same order"
        );
        let (Some(device_reading), Some(host_reading)) = (&device.reading, &host.reading) else {
            assert_eq!(
                device.reading, host.reading,
                "a missing frame stays missing"
            );
            continue;
        };
        let (compared, worst_kpa) = &mut differences[usize::from(device.pad)];
        for (taxel, (device_kpa, host_kpa)) in device_reading
            .pressure_kpa
            .iter()
            .zip(&host_reading.pressure_kpa)
            .enumerate()
        {
            match (device_kpa, host_kpa) {
                (Some(device_kpa), Some(host_kpa)) => {
                    *worst_kpa =
                        worst_kpa.max((f64::from(*device_kpa) - f64::from(*host_kpa)).abs());
                    *compared += 1;
                }
                (None, None) => {}
                _ => panic!(
                    "pad {} set {} taxel {taxel}: device {device_kpa:?}, host {host_kpa:?}",
                    device.pad, device.sequence
                ),
            }
        }
    }
    differences
}

/// Through the binaries: `calibration push --pad 1` gives pad 1 a calibration of its own,
/// `calibration pull --pad N` reads each pad's back, `record` keeps both pads' calibrations in
/// the device state, and `convert` gives both pads' device pressures back. Converting with
/// pad 0's calibration for both pads does not: pad 1's pressures are then more than 1 kPa off.
#[test]
fn a_pad_with_its_own_calibration_is_recorded_and_converted_with_it() {
    let directory = tempfile::tempdir().unwrap();
    let mut simulator =
        SimulatorProcess::start(directory.path(), "port", &["--speed", "4", "--pads", "2"]);
    let port = simulator.port.clone();
    let pad_0_file = directory.path().join("pad0.json");
    let (output, messages) = run(taxel()
        .args(["calibration", "pull", &port, "-o"])
        .arg(&pad_0_file));
    assert!(output.status.success(), "{messages}");
    assert!(messages.contains("of pad 0"), "{messages}");
    let pad_0_calibration = taxel_host::calibration_file::read(&pad_0_file).unwrap();
    assert_eq!(pad_0_calibration.id(), sim_device::FACTORY_CALIBRATION_ID);
    let pad_1_file = directory.path().join("pad1.json");
    taxel_host::calibration_file::write(&pad_1_file, &another_calibration(&pad_0_calibration))
        .unwrap();
    let (output, messages) = run(taxel()
        .args(["calibration", "push"])
        .arg(&pad_1_file)
        .args([&port, "--pad", "1"]));
    assert!(output.status.success(), "{messages}");
    assert!(messages.contains("to pad 1 of"), "{messages}");
    assert!(
        !messages.contains("WriteCalibration for taxel"),
        "{messages}"
    );
    let (output, messages) = run(taxel()
        .args(["calibration", "push"])
        .arg(&pad_1_file)
        .args([&port, "--pad", "2"]));
    assert!(!output.status.success());
    assert!(messages.contains("there is no pad 2"), "{messages}");
    for (pad, id) in [
        ("0", sim_device::FACTORY_CALIBRATION_ID),
        ("1", PAD_1_CALIBRATION_ID),
    ] {
        let pulled = directory.path().join(format!("pulled{pad}.json"));
        let (output, messages) = run(taxel()
            .args(["calibration", "pull", &port, "--pad", pad, "-o"])
            .arg(&pulled));
        assert!(output.status.success(), "{messages}");
        assert_eq!(
            taxel_host::calibration_file::read(&pulled).unwrap().id(),
            id
        );
    }

    let recording = directory.path().join("rec.csv");
    let (output, messages) = run(taxel()
        .args(["record", &port, "--samples", "800", "-o"])
        .arg(&recording));
    simulator.stop();
    assert!(output.status.success(), "{messages}");
    let state_path = directory.path().join("rec.csv.dev0.device.json");
    let state = RecordedDeviceState::read(&state_path).unwrap();
    assert_eq!(state.pad_count, 2);
    let pad_0 = &state.pads[0];
    assert_eq!(pad_0.calibration.id, sim_device::FACTORY_CALIBRATION_ID);
    assert_eq!(state.pads.len(), 2);
    let pad_1 = &state.pads[1];
    assert_eq!(pad_1.pad, 1);
    assert_eq!(pad_1.calibration.id, PAD_1_CALIBRATION_ID);
    assert_eq!(
        pad_1.calibration().unwrap(),
        another_calibration(&pad_0_calibration)
    );
    assert_eq!(pad_1.tier, pad_0.tier);
    assert_eq!(pad_1.baselines.len(), 1);
    assert!(pad_1.baselines[0].taxels.iter().all(Option::is_some));
    assert!(state.pads_without_state().is_empty());

    let converted = directory.path().join("converted.csv");
    let (output, messages) = run(taxel()
        .arg("convert")
        .arg(&recording)
        .arg("-o")
        .arg(&converted));
    assert!(output.status.success(), "{messages}");
    assert!(
        messages.contains(&format!(
            "converting with the device state in {}",
            state_path.display()
        )),
        "{messages}"
    );
    assert!(!messages.contains("no recorded state"), "{messages}");
    let differences = pad_differences(&recording, &converted, 2);
    for (pad, (compared, worst_kpa)) in differences.iter().enumerate() {
        eprintln!("pad {pad}: {compared} pressures, largest difference {worst_kpa:e} kPa");
        assert!(*compared > 4 * 600, "pad {pad}: {compared} compared");
        assert!(*worst_kpa <= AGREEMENT_KPA, "pad {pad}: {worst_kpa} kPa");
    }

    // Pad 0's calibration for both pads misses pad 1's pressures: the test can tell.
    let with_pad_0s = directory.path().join("with-pad-0s.csv");
    let (output, messages) = run(taxel()
        .arg("convert")
        .arg(&recording)
        .arg("--calibration")
        .arg(&pad_0_file)
        .arg("-o")
        .arg(&with_pad_0s));
    assert!(output.status.success(), "{messages}");
    let differences = pad_differences(&recording, &with_pad_0s, 2);
    assert!(differences[0].1 <= AGREEMENT_KPA, "{differences:?}");
    assert!(differences[1].1 > 1.0, "{differences:?}");
}

/// In process, through the host library's recording pipeline (a `DeviceSession` following the
/// device's state, the `Worker`, the `Recorder`): a simulated device of two pads, pad 1 with a
/// calibration of its own, tared in the middle of a recording. Each pad's TareFinished brings
/// that pad's new baselines into that pad's history (the ones the device reports for it
/// afterwards), and the conversion gives both pads' device pressures, before and after the
/// tare — which it does not without the tare's change in the history.
#[test]
fn a_tare_during_a_recording_lands_in_each_pads_own_history() {
    use std::sync::atomic::{AtomicBool, Ordering};

    use sim_device::{PtyPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
    use taxel_host::device_link::open_serial;
    use taxel_host::host_clock::UnixClock;
    use taxel_host::recorder::{Recorder, RecordingPaths};
    use taxel_host::worker::{EventQueue, Overflow, Worker, WorkerEvent};

    /// Sets recorded before the tare, and in all.
    const BEFORE_TARE: u64 = 60;
    const SETS: u64 = 400;

    let directory = tempfile::tempdir().unwrap();
    let mut device = SimulatedDevice::new(
        SimulatedDeviceConfig::new(SceneFile::default_scene().unwrap(), 2)
            .with_seed(11)
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
    let mut link = DeviceLink::new(open_serial(&path, Duration::from_millis(20)).unwrap().port);
    let timeout = Duration::from_secs(2);
    let (info, _) = link.synchronise(timeout).unwrap();
    assert_eq!(info.pad_count, 2);
    let pad_0_calibration = pull(&mut link, pad(0), info.calibration_id, timeout).unwrap();
    upload_to_pads(
        &mut link,
        &another_calibration(&pad_0_calibration),
        Some(pad(1)),
        false,
        timeout,
        &mut |_| {},
    )
    .unwrap();
    let config = SessionConfig {
        request_timeout: timeout,
        follow_state: true,
    };
    let mut session = DeviceSession::open(link, config).unwrap();
    assert_eq!(
        session.state().unwrap().pads[1].calibration.id,
        PAD_1_CALIBRATION_ID
    );
    let csv_path = directory.path().join("tare.csv");
    let clock = UnixClock::new();
    let mut recorder = Recorder::create(
        RecordingPaths {
            csv: Some(csv_path.clone()),
            mcap: None,
        },
        1,
        clock,
        Some(SETS),
    )
    .unwrap();
    session.link_mut().set_raw_log(recorder.raw_log(0).unwrap());
    session.start().unwrap();
    let queue = Arc::new(EventQueue::new(100_000, Overflow::Wait));
    let worker = Worker::start(vec![session], Arc::clone(&queue), Arc::new(clock)).unwrap();
    // The demo scene is still for its first 3 s, then presses taxel C11: record 60 sets, tare
    // (still), record 340 more (pressed at the end, where the tare's baselines matter).
    let mut tare_reply = None;
    let mut tares_finished = Vec::new();
    let mut baseline_events = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(60);
    while !recorder.is_complete() || tares_finished.len() < 2 {
        assert!(Instant::now() < deadline, "{:?}", recorder.sets_taken());
        let Some(arrived) = queue.pop_until(Instant::now() + Duration::from_millis(100)) else {
            continue;
        };
        match &arrived.event {
            WorkerEvent::Session(SessionEvent::Device(EventFrame {
                event: DeviceEvent::TareFinished { pad, .. },
                ..
            })) if tare_reply.is_some() => tares_finished.push(*pad),
            WorkerEvent::Session(SessionEvent::Baselines { pad, change }) => {
                baseline_events.push((*pad, change.clone()));
            }
            WorkerEvent::Session(SessionEvent::BaselinesUnread { pad, reason }) => {
                panic!("pad {}: {reason}", pad.get())
            }
            WorkerEvent::Ended(end) => panic!("the device ended: {:?}", end.reason),
            _ => {}
        }
        recorder.take(arrived).unwrap();
        if tare_reply.is_none() && recorder.sets_taken()[0] >= BEFORE_TARE {
            tare_reply = Some(
                worker
                    .send(
                        0,
                        WireCommand::Tare {
                            sample_sets: 8,
                            pad: None,
                        },
                        timeout,
                    )
                    .unwrap(),
            );
        }
    }
    assert!(matches!(
        tare_reply.unwrap().recv().unwrap(),
        Ok(ReplyPayload::Ack)
    ));
    tares_finished.sort_unstable();
    assert_eq!(tares_finished, [pad(0), pad(1)]);
    let reported: Vec<_> = worker
        .run(0, move |session| {
            [pad(0), pad(1)].map(|pad| pull_baselines(session.link_mut(), pad, timeout).unwrap())
        })
        .unwrap()
        .recv()
        .unwrap()
        .to_vec();
    for mut session in worker.finish().into_iter().flatten() {
        if let Some(mut raw) = session.link_mut().take_raw_log() {
            raw.flush().unwrap();
        }
    }
    for arrived in queue.drain() {
        recorder.take(arrived).unwrap();
    }
    device_stop.store(true, Ordering::Relaxed);
    device_thread.join().unwrap();
    let summary = recorder.finish().unwrap();
    assert_eq!(summary.devices[0].sets, SETS);
    let rows = read_rows(&csv_path);
    assert_eq!(rows.len() as u64, 2 * SETS);
    // The set the tare was asked after: the 60th recorded.
    let asked_after = rows
        .iter()
        .filter(|row| row.pad == 0)
        .nth(BEFORE_TARE as usize - 1)
        .unwrap()
        .sequence;
    let state_path = directory.path().join("tare.csv.dev0.device.json");
    let state = RecordedDeviceState::read(&state_path).unwrap();
    for (pad_index, reported) in (0u8..).zip(&reported) {
        let history = state.pad_state(pad_index).unwrap().baselines;
        // The recording may start before the boot tare ends (then that tare is a change too);
        // the commanded tare is the last change, after set 60.
        assert!(history.len() >= 2, "pad {pad_index}: {history:?}");
        let last = &history[history.len() - 1];
        let before = &history[history.len() - 2];
        assert!(last.from_sequence > before.from_sequence, "pad {pad_index}");
        assert!(last.from_sequence > asked_after, "pad {pad_index}");
        assert_ne!(last.taxels, before.taxels, "pad {pad_index}");
        assert_eq!(&last.taxels, reported, "pad {pad_index}");
        // The change the session reported for this pad, and for no other.
        let events: Vec<&BaselineChange> = baseline_events
            .iter()
            .filter(|(pad, _)| pad.get() == pad_index)
            .map(|(_, change)| change)
            .collect();
        assert_eq!(events.last().copied(), Some(last), "pad {pad_index}");
    }

    let converted = directory.path().join("converted.csv");
    let (output, messages) = run(taxel()
        .arg("convert")
        .arg(&csv_path)
        .arg("-o")
        .arg(&converted));
    assert!(output.status.success(), "{messages}");
    for (pad, (compared, worst_kpa)) in pad_differences(&csv_path, &converted, 2).iter().enumerate()
    {
        assert!(*compared > 4 * 180, "pad {pad}: {compared} compared");
        assert!(*worst_kpa <= AGREEMENT_KPA, "pad {pad}: {worst_kpa} kPa");
    }

    // Without the tare's change in the history, the pressed sets after it are not the
    // device's: the test can tell.
    let without_tare = directory.path().join("without-tare.csv");
    std::fs::copy(&csv_path, &without_tare).unwrap();
    let mut truncated = state.clone();
    for pad in &mut truncated.pads {
        pad.baselines.pop();
    }
    truncated
        .write(&directory.path().join("without-tare.csv.dev0.device.json"))
        .unwrap();
    let converted = directory.path().join("converted-without-tare.csv");
    let (output, messages) = run(taxel()
        .arg("convert")
        .arg(&without_tare)
        .arg("-o")
        .arg(&converted));
    assert!(output.status.success(), "{messages}");
    let differences = pad_differences(&without_tare, &converted, 2);
    assert!(
        differences
            .iter()
            .all(|(_, worst_kpa)| *worst_kpa > AGREEMENT_KPA),
        "{differences:?}"
    );
}

/// A baseline record whose capacitance tells the pad, the taxel and the tare apart.
fn baseline(pad: u8, taxel: u8, tare: u8) -> BaselineRecord {
    device::baseline_record(&wire::BaselineWire {
        offset_pf: 4.0 + f32::from(pad),
        fine_pf: 0.1 * f32::from(taxel) + 0.01 * f32::from(tare),
        temperature_c: 25.0,
    })
}

/// Answers what a session following the state asks of a device of two pads: its Info, every
/// pad's calibration and PadInfo (pad 1 with calibration id 9, set by the host, tier linear),
/// and baselines — each pad's own, a new one after each time its four taxels were read.
fn two_pad_device() -> FakeDevice {
    let mut spec = Calibration::default().to_spec();
    spec.id = 9;
    let pad_1_calibration = Calibration::new(&spec).unwrap();
    let mut baseline_reads = [0u32; 2];
    FakeDevice::new(Box::new(move |request| {
        let payload = match request.command {
            WireCommand::Info => ReplyPayload::Info(info(2)),
            WireCommand::ReadCalibration { pad, taxel_index } => {
                let calibration = if pad.get() == 1 {
                    pad_1_calibration.clone()
                } else {
                    Calibration::default()
                };
                ReplyPayload::Calibration(
                    device::calibration_record(&calibration, pad, taxel_index).unwrap(),
                )
            }
            WireCommand::ReadBaseline { pad, taxel_index } => {
                let reads = &mut baseline_reads[usize::from(pad.get())];
                let tare = (*reads / TAXEL_COUNT as u32) as u8;
                *reads += 1;
                ReplyPayload::Baseline(TaxelBaselineWire {
                    pad,
                    taxel_index,
                    baseline: Some(device::baseline_wire(&baseline(
                        pad.get(),
                        taxel_index,
                        tare,
                    ))),
                })
            }
            // Pad 0 as the Info frame says; pad 1 with a calibration and tier of its own.
            WireCommand::PadInfo { pad } => ReplyPayload::PadInfo(PadInfoFrame {
                temperature_sensor: wire::TemperatureSensor::DieOnly,
                calibration_id: if pad.get() == 0 { 0 } else { 9 },
                calibration_source: wire::CalibrationSource::Host,
                model_tier: if pad.get() == 0 {
                    wire::Tier::MonotoneCubic
                } else {
                    wire::Tier::Linear
                },
                ..wire::testing::pad_info_frame(pad.get())
            }),
            _ => ReplyPayload::Ack,
        };
        vec![DeviceFrame::Reply(ReplyFrame {
            request_id: request.request_id,
            result: Ok(payload),
        })]
    }))
}

/// The session's events until nothing more comes.
fn events(session: &mut DeviceSession<FakeDevice>) -> Vec<SessionEvent> {
    let mut events = Vec::new();
    while let Some(event) = session
        .next_event(Instant::now() + Duration::from_millis(50))
        .unwrap()
    {
        events.push(event);
    }
    events
}

fn baseline_changes(events: &[SessionEvent]) -> Vec<(PadIndex, BaselineChange)> {
    events
        .iter()
        .filter_map(|event| match event {
            SessionEvent::Baselines { pad, change } => Some((*pad, change.clone())),
            _ => None,
        })
        .collect()
}

/// The requests per pad, through the one stream loop (`DeviceSession` following the state):
/// PadInfo for the pads after pad 0, and each pad's calibration and baselines; a TareFinished
/// of pad 1 reads pad 1's baselines, which apply from pad 1's next frame (not pad 0's), once,
/// in pad 1's history only.
#[test]
fn every_pads_state_is_read_and_a_tare_is_followed_on_its_own_pad() {
    let link = DeviceLink::new(two_pad_device());
    let config = SessionConfig {
        request_timeout: Duration::from_secs(2),
        follow_state: true,
    };
    let mut session = DeviceSession::open(link, config).unwrap();
    let state = session.state().unwrap().clone();
    let pad_0 = state.pad_state(0).unwrap();
    assert_eq!(pad_0.calibration.id, 0);
    assert_eq!(pad_0.tier, "monotone-cubic");
    let pad_1 = state.pad_state(1).unwrap();
    assert_eq!(pad_1.calibration.id, 9);
    assert_eq!(pad_1.tier, "linear");
    let first_baselines = |pad: u8| -> [Option<BaselineRecord>; TAXEL_COUNT] {
        std::array::from_fn(|taxel| Some(baseline(pad, taxel as u8, 0)))
    };
    for pad in 0..2u8 {
        assert_eq!(
            state.pad_state(pad).unwrap().baselines,
            [BaselineChange {
                from_sequence: 0,
                taxels: first_baselines(pad)
            }]
        );
    }
    session.start().unwrap();

    let requests_before = session.link_mut().port().requests.len();
    session
        .link_mut()
        .port_mut()
        .send(&DeviceFrame::Event(EventFrame {
            timestamp_us: 5,
            event: DeviceEvent::TareFinished {
                pad: pad(1),
                tared_mask: 0b1111,
            },
        }));
    let seen = events(&mut session);
    assert!(
        matches!(
            seen.as_slice(),
            [SessionEvent::Device(EventFrame {
                event: DeviceEvent::TareFinished { .. },
                ..
            })]
        ),
        "{seen:?}"
    );
    let after_event: Vec<WireCommand> = session.link_mut().port().requests[requests_before..]
        .iter()
        .map(|request| request.command.clone())
        .collect();
    assert_eq!(after_event.len(), TAXEL_COUNT, "{after_event:?}");
    assert!(after_event.iter().all(|command| matches!(
        command,
        WireCommand::ReadBaseline { pad, .. } if pad.get() == 1
    )));

    // Pad 0's frame of set 7 takes no pad 1 baselines; pad 1's does.
    let mut frame = support::sample(7, 70, [(Some(0.0), 4.5, 0); 4]);
    session
        .link_mut()
        .port_mut()
        .send(&DeviceFrame::Sample(frame));
    assert!(baseline_changes(&events(&mut session)).is_empty());
    frame.pad = pad(1);
    session
        .link_mut()
        .port_mut()
        .send(&DeviceFrame::Sample(frame));
    let changes = baseline_changes(&events(&mut session));
    let expected = BaselineChange {
        from_sequence: 7,
        taxels: std::array::from_fn(|taxel| Some(baseline(1, taxel as u8, 1))),
    };
    assert_eq!(changes, [(pad(1), expected.clone())]);
    // Once: the next set takes none.
    for pad_index in 0..2 {
        let mut next = support::sample(8, 80, [(Some(0.0), 4.5, 0); 4]);
        next.pad = pad(pad_index);
        session
            .link_mut()
            .port_mut()
            .send(&DeviceFrame::Sample(next));
    }
    assert!(baseline_changes(&events(&mut session)).is_empty());
    let state = session.state().unwrap();
    assert_eq!(
        state.pad_state(0).unwrap().baselines,
        [BaselineChange {
            from_sequence: 0,
            taxels: first_baselines(0)
        }],
        "pad 0's history is untouched"
    );
    assert_eq!(
        state.pad_state(1).unwrap().baselines,
        [
            BaselineChange {
                from_sequence: 0,
                taxels: first_baselines(1)
            },
            expected
        ]
    );
}

/// A device-state file that describes pad 0 only (`pad_count` 2 and no `other_pads`, as
/// `taxel record` wrote before every pad's state was recorded) beside a recording of two pads:
/// it converts, pad 0 with its recorded calibration, pad 1 (which has no recorded state) with
/// the built-in one and a tare on its first row, and stderr names pad 1 as converted without
/// a state of its own.
#[test]
fn a_pad_without_a_recorded_state_converts_with_the_defaults_and_says_so() {
    let directory = tempfile::tempdir().unwrap();
    let csv_path = directory.path().join("rec.csv");
    let mut writer = RowWriter::new(std::fs::File::create(&csv_path).unwrap()).unwrap();
    for sequence in 0..5u32 {
        // Unloaded on the first set, then dC/C0 = 0.0829: 10 kPa on the article's curve.
        let capacitance_pf = if sequence == 0 { 4.5 } else { 4.87305 };
        for pad in 0..2u8 {
            writer
                .write(&PadRow {
                    host_time_us: 1_700_000_000_000_000 + u64::from(sequence) * 10_000,
                    device: 0,
                    pad,
                    sequence,
                    sync_error_us: Some(500),
                    reading: Some(PadReading::unconverted(
                        100_000 * u64::from(sequence),
                        Some(25.0),
                        TemperatureSource::Tmp117,
                        [Some(capacitance_pf), Some(4.5), Some(4.5), Some(4.5)],
                    )),
                    marker: String::new(),
                })
                .unwrap();
        }
    }
    writer.into_inner().flush().unwrap();
    // Pad 0's state only, with a calibration of its own (20 % lower pressures).
    let mut state = RecordedDeviceState::new(&info(2));
    state.add_pad(
        RecordedPadState::new(
            &wire::testing::pad_info_frame(0),
            &another_calibration(&Calibration::default()),
        )
        .unwrap(),
    );
    assert_eq!(state.pads_without_state(), [1]);
    state
        .write(&directory.path().join("rec.csv.dev0.device.json"))
        .unwrap();
    let converted = directory.path().join("converted.csv");
    let (output, messages) = run(taxel()
        .arg("convert")
        .arg(&csv_path)
        .arg("-o")
        .arg(&converted));
    assert_eq!(output.status.code(), Some(0), "{messages}");
    assert!(
        messages.contains("device 0 pad 1 had no recorded state"),
        "{messages}"
    );
    assert!(!messages.contains("pad 0 had"), "{messages}");
    let rows = read_rows(&converted);
    assert_eq!(rows.len(), 10);
    for row in rows.iter().filter(|row| row.sequence > 0) {
        let kpa = row.reading.unwrap().pressure_kpa[0].unwrap();
        let expected = if row.pad == 0 { 8.0 } else { 10.0 };
        assert!(
            (kpa - expected).abs() < 0.01,
            "pad {} set {}: {kpa} kPa, not {expected}",
            row.pad,
            row.sequence
        );
    }
}
