//! Every pad's own state in a recording: a device of several pads whose pad 1 runs another
//! calibration than pad 0 is recorded, the device-state file holds each pad's calibration, tier
//! and baselines (a tare's new baselines in the history of the pad that reported it), and
//! `taxel convert` gives every pad's own pressures back. An older device-state file that holds
//! pad 0's state only still converts, with pad 0's state for every pad and a warning.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;
use support::{info, FakeDevice, SimulatorProcess};

use std::path::Path;
use std::process::{Command, Output};
use std::time::Duration;

use model_core::{BaselineRecord, Calibration, TAXEL_COUNT};
use taxel_host::calibration_transfer::{pull, pull_baselines, upload_to_pads};
use taxel_host::device_link::DeviceLink;
use taxel_host::recording::{
    read_device_state, BaselineChange, BaselineFollower, RecordedDeviceState, SampleSink,
};
use wire::{
    Command as WireCommand, DeviceEvent, DeviceFrame, EventFrame, PadIndex, PadInfoFrame,
    ReplyFrame, ReplyPayload, SampleFrame, TaxelBaselineWire,
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

/// A CSV file as its header and rows.
fn read_rows(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
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

/// Per pad: how many pressures of `converted` were compared with `recorded`'s (the device's),
/// and the largest difference, kPa. Empty cells must be empty in both.
fn pad_differences(recorded: &Path, converted: &Path, pads: usize) -> Vec<(usize, f64)> {
    let (recorded_header, recorded) = read_rows(recorded);
    let (converted_header, converted) = read_rows(converted);
    assert_eq!(recorded.len(), converted.len());
    let column = |header: &[String], name: &str| {
        header
            .iter()
            .position(|cell| cell == name)
            .unwrap_or_else(|| panic!("no column {name}"))
    };
    (0..pads)
        .map(|pad| {
            let mut compared = 0;
            let mut worst_kpa = 0.0f64;
            for (device, host) in recorded.iter().zip(&converted) {
                for taxel in ["p11_kpa", "p12_kpa", "p21_kpa", "p22_kpa"] {
                    let name = format!("pad{pad}_{taxel}");
                    let device_cell = &device[column(&recorded_header, &name)];
                    let host_cell = &host[column(&converted_header, &name)];
                    match (device_cell.parse::<f64>(), host_cell.parse::<f64>()) {
                        (Ok(device_kpa), Ok(host_kpa)) => {
                            worst_kpa = worst_kpa.max((device_kpa - host_kpa).abs());
                            compared += 1;
                        }
                        _ => assert_eq!(
                            device_cell.is_empty(),
                            host_cell.is_empty(),
                            "{name}: device '{device_cell}', host '{host_cell}'"
                        ),
                    }
                }
            }
            (compared, worst_kpa)
        })
        .collect()
}

/// Through the binaries: `calibration push --pad 1` gives pad 1 a calibration of its own,
/// `calibration pull --pad N` reads each pad's back, `record` keeps both pads' calibrations in
/// the device state, and `convert` gives both pads' device pressures back. Converting with
/// pad 0's calibration for both (what `convert` did before every pad's state was recorded) does
/// not.
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
    let state = RecordedDeviceState::read(&directory.path().join("rec.csv.device.json")).unwrap();
    assert_eq!(state.pad_count, 2);
    assert_eq!(state.calibration.id, sim_device::FACTORY_CALIBRATION_ID);
    assert_eq!(state.other_pads.len(), 1);
    let pad_1 = &state.other_pads[0];
    assert_eq!(pad_1.pad, 1);
    assert_eq!(pad_1.calibration.id, PAD_1_CALIBRATION_ID);
    assert_eq!(pad_1.tier, state.tier);
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
    assert!(!messages.contains("may differ"), "{messages}");
    assert!(
        messages.contains("with its own recorded calibration, tier, baselines"),
        "{messages}"
    );
    assert!(
        messages.contains(&format!("calibration id {PAD_1_CALIBRATION_ID}")),
        "{messages}"
    );
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

/// In process: a simulated device of two pads, pad 1 with a calibration of its own, tared in
/// the middle of a recording. Each pad's TareFinished brings that pad's new baselines into that
/// pad's history (the ones the device reports for it afterwards), and the conversion gives both
/// pads' device pressures, before and after the tare.
#[test]
fn a_tare_during_a_recording_lands_in_each_pads_own_history() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;

    use sim_device::{PtyPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
    use taxel_host::device_link::open_serial;
    use taxel_host::record::record_accounted;
    use taxel_host::recording::Recording;
    use taxel_host::stream_accounting::StreamAccounting;

    let directory = tempfile::tempdir().unwrap();
    let mut device = SimulatedDevice::new(SimulatedDeviceConfig {
        scene: SceneFile::default_scene().unwrap(),
        seed: 11,
        speed: Some(20.0),
        topology: sim_device::pads_topology(2),
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
    let state = read_device_state(&mut link, &info, timeout).unwrap();
    assert_eq!(state.other_pads[0].calibration.id, PAD_1_CALIBRATION_ID);
    let csv_path = directory.path().join("tare.csv");
    let (mut recording, _) = Recording::create_with_pads(&csv_path, None, 2).unwrap();
    recording.set_device_state(state);
    let mut accounting = StreamAccounting::new();
    let stop = AtomicBool::new(false);
    let flush = Duration::from_millis(200);
    // The demo scene is still for its first 3 s: record 60 sets, tare, record 200 more.
    record_accounted(
        &mut link,
        &mut recording,
        &mut accounting,
        &stop,
        Some(60),
        flush,
        &mut |_| {},
    )
    .unwrap();
    link.send(WireCommand::Tare { sample_sets: 8 }).unwrap();
    record_accounted(
        &mut link,
        &mut recording,
        &mut accounting,
        &stop,
        Some(200),
        flush,
        &mut |_| {},
    )
    .unwrap();
    let reported: Vec<_> = [pad(0), pad(1)]
        .into_iter()
        .map(|pad| pull_baselines(&mut link, pad, timeout).unwrap())
        .collect();
    device_stop.store(true, Ordering::Relaxed);
    device_thread.join().unwrap();
    let files = recording.finish(None).unwrap();
    let state = RecordedDeviceState::read(&files.device_state.unwrap()).unwrap();
    for (pad, reported) in (0u8..).zip(&reported) {
        let history = state.pad_state(pad).unwrap().baselines;
        // The recording may start before the boot tare ends (then that tare is a change too);
        // the commanded tare is the last change, after set 60.
        assert!(history.len() >= 2, "pad {pad}: {history:?}");
        let last = &history[history.len() - 1];
        let before = &history[history.len() - 2];
        assert!(last.from_sequence > before.from_sequence, "pad {pad}");
        assert_ne!(last.taxels, before.taxels, "pad {pad}");
        assert_eq!(&last.taxels, reported, "pad {pad}");
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
}

/// A baseline record whose capacitance tells the pad and taxel apart.
fn baseline(pad: u8, taxel: u8) -> BaselineRecord {
    device::baseline_record(&wire::BaselineWire {
        offset_pf: 4.0 + f32::from(pad),
        fine_pf: 0.1 * f32::from(taxel),
        temperature_c: 25.0,
    })
}

/// Answers what `read_device_state` and the baseline follower ask of a device of two pads:
/// pad 1 with calibration id 9, set by the host, tier linear.
fn two_pad_device() -> FakeDevice {
    let mut spec = Calibration::default().to_spec();
    spec.id = 9;
    let pad_1_calibration = Calibration::new(&spec).unwrap();
    FakeDevice::new(Box::new(move |request| {
        let payload = match request.command {
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
                ReplyPayload::Baseline(TaxelBaselineWire {
                    pad,
                    taxel_index,
                    baseline: Some(device::baseline_wire(&baseline(pad.get(), taxel_index))),
                })
            }
            WireCommand::PadInfo { pad } => ReplyPayload::PadInfo(PadInfoFrame {
                pad,
                channel: Some(pad.get()),
                temperature_sensor: wire::TemperatureSensor::DieOnly,
                calibration_id: 9,
                calibration_source: wire::CalibrationSource::Host,
                model_tier: wire::Tier::Linear,
            }),
            _ => ReplyPayload::Ack,
        };
        vec![DeviceFrame::Reply(ReplyFrame {
            request_id: request.request_id,
            result: Ok(payload),
        })]
    }))
}

/// Collects the baseline changes given to it, with their pads.
#[derive(Default)]
struct ChangeLog(Vec<(PadIndex, BaselineChange)>);

impl SampleSink for ChangeLog {
    fn write_sample(&mut self, _: &SampleFrame) -> anyhow::Result<()> {
        Ok(())
    }

    fn flush(&mut self) -> anyhow::Result<()> {
        Ok(())
    }

    fn baselines_changed(&mut self, pad: PadIndex, change: BaselineChange) {
        self.0.push((pad, change));
    }
}

/// The requests per pad: PadInfo for the pads after pad 0, and each pad's calibration and
/// baselines; a TareFinished of pad 1 reads pad 1's baselines, which apply from pad 1's next
/// frame (not pad 0's).
#[test]
fn every_pads_state_is_read_and_a_tare_is_followed_on_its_own_pad() {
    let mut link = DeviceLink::new(two_pad_device());
    let timeout = Duration::from_secs(2);
    let state = read_device_state(&mut link, &info(2), timeout).unwrap();
    assert_eq!(state.calibration.id, 0);
    assert_eq!(state.tier, "monotone-cubic");
    let pad_1 = state.pad_state(1).unwrap();
    assert_eq!(pad_1.calibration.id, 9);
    assert_eq!(pad_1.tier, "linear");
    for pad in 0..2u8 {
        let expected: [Option<BaselineRecord>; TAXEL_COUNT] =
            std::array::from_fn(|taxel| Some(baseline(pad, taxel as u8)));
        assert_eq!(
            state.pad_state(pad).unwrap().baselines,
            [BaselineChange {
                from_sequence: 0,
                taxels: expected
            }]
        );
    }

    let mut follower = BaselineFollower::default();
    let event = EventFrame {
        timestamp_us: 5,
        event: DeviceEvent::TareFinished {
            pad: pad(1),
            tared_mask: 0b1111,
        },
    };
    follower.on_event(&mut link, &event, timeout).unwrap();
    let requests: Vec<WireCommand> = link
        .port()
        .requests
        .iter()
        .map(|request| request.command.clone())
        .collect();
    let after_event = &requests[requests.len() - TAXEL_COUNT..];
    assert!(after_event.iter().all(|command| matches!(
        command,
        WireCommand::ReadBaseline { pad, .. } if pad.get() == 1
    )));
    let mut log = ChangeLog::default();
    let mut frame = support::sample(7, 70, [(Some(0.0), 4.5, 0); 4]);
    follower.before_sample(&mut log, &frame);
    assert!(log.0.is_empty(), "pad 0's frame takes no pad 1 baselines");
    frame.pad = pad(1);
    follower.before_sample(&mut log, &frame);
    follower.before_sample(&mut log, &frame);
    assert_eq!(log.0.len(), 1);
    let (changed_pad, change) = &log.0[0];
    assert_eq!(*changed_pad, pad(1));
    assert_eq!(change.from_sequence, 7);
    assert_eq!(change.taxels[2], Some(baseline(1, 2)));
}

/// A device-state file of two pads as `taxel record` wrote it before every pad's state was
/// recorded (pad 0's state and `pad_count`, no `other_pads`): it still converts, with pad 0's
/// calibration and tare for pad 1, and says pad 1's pressures may differ from the device's.
#[test]
fn an_older_device_state_of_two_pads_converts_with_pad_0s_state_and_says_so() {
    let directory = tempfile::tempdir().unwrap();
    let csv_path = directory.path().join("old.csv");
    let pad_columns = |pad: usize| {
        ["time_s", "temp_c", "c11_pf", "c12_pf", "c21_pf", "c22_pf"]
            .map(|name| format!("pad{pad}_{name}"))
            .join(",")
    };
    let mut text = format!("seq,{},{}\n", pad_columns(0), pad_columns(1));
    for sequence in 0..5 {
        let capacitance_pf = if sequence == 0 { 4.5 } else { 4.87305 };
        text.push_str(&format!(
            "{sequence},0.{sequence},25,{c},4.5,4.5,4.5,0.{sequence},25,{c},4.5,4.5,4.5\n",
            c = capacitance_pf
        ));
    }
    std::fs::write(&csv_path, text).unwrap();
    let old_state = serde_json::json!({
        "format": "taxel-recording-device-state",
        "version": 1,
        "firmware": "3.0.0",
        "protocol_version": 3,
        "board_serial": "070707070707070707070707",
        "calibration_source": "built-in defaults",
        "tier": "monotone-cubic",
        "converter_rate_sps": 400,
        "calibration": Calibration::default().to_spec(),
        "baselines": [],
        "pad_count": 2
    });
    std::fs::write(
        directory.path().join("old.csv.device.json"),
        serde_json::to_string_pretty(&old_state).unwrap(),
    )
    .unwrap();
    let converted = directory.path().join("converted.csv");
    let (output, messages) = run(taxel()
        .arg("convert")
        .arg(&csv_path)
        .arg("-o")
        .arg(&converted));
    assert_eq!(output.status.code(), Some(0), "{messages}");
    assert!(messages.contains("for each of the 2 pads"), "{messages}");
    assert!(
        messages.contains(
            "pad 0's calibration, tier and baselines are used for pad 1, whose pressures may differ from the device's"
        ),
        "{messages}"
    );
    let (header, rows) = read_rows(&converted);
    let column = |name: &str| header.iter().position(|cell| cell == name).unwrap();
    assert_eq!(rows.len(), 5);
    for row in &rows[1..] {
        let pad_0: f64 = row[column("pad0_p11_kpa")].parse().unwrap();
        assert!((pad_0 - 10.0).abs() < 0.01, "{pad_0}");
        assert_eq!(row[column("pad1_p11_kpa")], row[column("pad0_p11_kpa")]);
    }
}
