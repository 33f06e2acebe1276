//! End to end, as a user meets it: the simulated device (the firmware's acquisition, model and
//! protocol code over the simulated converter) on a pseudo-terminal, opened by the host tool's
//! real serial code path, streamed by the host library's session (the one stream loop every
//! consumer builds on), recorded in the recording schema, read back, and the recording compared
//! with the scripted scene.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic)]

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use model_core::TaxelFlags;
use sim_device::{PtyPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use taxel_host::device_link::{open_serial, DeviceLink};
use taxel_host::schema::{header, PadReading, PadRow, RowReader, RowWriter};
use taxel_host::session::{DeviceSession, SessionConfig, SessionEvent};

/// Largest difference between a recorded pressure and the scene, kPa. The scene is the
/// simulator's own truth: its physics does not use the pressure model, and the device converts
/// with the simulated pad's factory calibration (the true curve every 5 kPa), whose monotone
/// cubic is up to 0.065 kPa off the true curve between points. On top: converter noise (1 fF rms
/// at 400 S/s, 0.1 kPa at the flat top of the curve), the TMP117's one-second conversion lag
/// while the scene warms at 0.67 °C/s (about 0.1 kPa), and the 10 ms a sample set takes while
/// pressures ramp at up to 15 kPa/s (0.15 kPa).
const SAMPLE_TOLERANCE_KPA: f64 = 0.5;
/// Largest RMS difference over the whole recording, kPa (measured: 0.076 kPa with seed 3).
const RMS_TOLERANCE_KPA: f64 = 0.1;
/// However the stream ends, the recording ends by then (the scene lasts a few seconds at the
/// simulator's speed).
const RECORDING_DEADLINE: Duration = Duration::from_secs(120);

fn unix_now_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |since| {
            u64::try_from(since.as_micros()).unwrap_or(u64::MAX)
        })
}

/// What the session's stream gave, besides the rows.
#[derive(Debug, Default)]
struct Streamed {
    sets: u64,
    sets_missing: u64,
    missing_frames: u64,
    ended_by: String,
}

/// Records one device from `path` until it goes away: a session over the serial link, every
/// sample set it closes written as the schema's rows (one per pad), stamped with its arrival on
/// the host clock (no clock mapping here: `sync_error_ms` stays empty).
fn record(path: &str) -> (Vec<u8>, Streamed) {
    let opened = open_serial(path, Duration::from_millis(100)).unwrap();
    let mut session =
        DeviceSession::open(DeviceLink::new(opened.port), SessionConfig::default()).unwrap();
    assert_eq!(session.pad_count(), 1);
    session.start().unwrap();
    let mut rows = RowWriter::new(Vec::new()).unwrap();
    let mut streamed = Streamed::default();
    let mut write_set = |event: SessionEvent, rows: &mut RowWriter<Vec<u8>>| {
        let SessionEvent::Set {
            set,
            sets_missing_before,
        } = event
        else {
            return;
        };
        streamed.sets += 1;
        streamed.sets_missing += sets_missing_before;
        let host_time_us = unix_now_us();
        for (pad, frame) in set.pads.iter().enumerate() {
            streamed.missing_frames += u64::from(frame.is_none());
            let row = PadRow {
                host_time_us,
                device: 0,
                pad: u8::try_from(pad).unwrap(),
                sequence: set.sequence,
                sync_error_us: None,
                reading: frame.as_ref().map(PadReading::from_frame),
                marker: String::new(),
            };
            rows.write(&row).unwrap();
        }
    };
    let deadline = Instant::now() + RECORDING_DEADLINE;
    // Recording ends when the device goes away at the end of the scene (as an unplug would).
    let ended_by = loop {
        assert!(
            Instant::now() < deadline,
            "the stream did not end; {} sets so far",
            rows.rows()
        );
        match session.next_event(Instant::now() + Duration::from_millis(200)) {
            Ok(Some(event)) => write_set(event, &mut rows),
            Ok(None) => {}
            Err(error) => break error.to_string(),
        }
    };
    if let Some(event) = session.close_open_set() {
        write_set(event, &mut rows);
    }
    assert_eq!(
        streamed.sets_missing,
        session.accounting().sequence_gap_sets(),
        "the sets the session says are missing are the accounting's"
    );
    streamed.ended_by = ended_by;
    (rows.into_inner(), streamed)
}

#[test]
fn a_recording_of_the_simulated_device_matches_its_scene() {
    let scene = SceneFile::default_scene().unwrap();
    let period_s = scene.period_s();
    let truth = scene.pads[0].scene.clone();
    let mut device = SimulatedDevice::new(
        SimulatedDeviceConfig::new(scene, 1)
            .with_seed(3)
            .with_speed(Some(25.0)),
    )
    .unwrap();
    let mut port = PtyPort::open().unwrap();
    let path = port.path().to_string_lossy().into_owned();
    let device_stop = Arc::new(AtomicBool::new(false));
    let device_thread = {
        let stop = Arc::clone(&device_stop);
        thread::spawn(move || device.run(&mut port, Some(period_s), &stop))
    };

    let recorded = std::panic::catch_unwind(|| record(&path));
    device_stop.store(true, Ordering::Relaxed);
    device_thread.join().unwrap();
    let (bytes, streamed) = recorded.unwrap_or_else(|panic| std::panic::resume_unwind(panic));

    // The recording is read back through the schema's reader: every row must be readable.
    let first_line = bytes.split(|&byte| byte == b'\n').next().unwrap();
    assert_eq!(first_line, header().join(",").as_bytes());
    let mut reader = RowReader::new(bytes.as_slice()).unwrap();
    let (mut rows, mut compared, mut squared) = (0u64, 0u64, 0.0f64);
    let mut shorted_rows = 0u64;
    let mut previous_sequence: Option<u32> = None;
    let mut gaps = 0u64;
    let mut previous_host_us = 0u64;
    while let Some(row) = reader.next_row() {
        let row = row.unwrap();
        rows += 1;
        assert_eq!((row.device, row.pad), (0, 0));
        assert!(
            row.host_time_us >= previous_host_us,
            "host times go forward"
        );
        previous_host_us = row.host_time_us;
        if let Some(previous) = previous_sequence {
            assert!(row.sequence > previous, "sets in order");
            gaps += u64::from(row.sequence - previous - 1);
        }
        previous_sequence = Some(row.sequence);
        let reading = row
            .reading
            .unwrap_or_else(|| panic!("set {}: the pad's frame is missing", row.sequence));
        let time_s = reading.device_time_us as f64 / 1e6;
        // The device tares on its first 16 sets; those carry no pressure.
        if time_s < 0.3 {
            continue;
        }
        let expected = truth.point_at_s(time_s);
        for taxel in 0..4 {
            let flags = reading.flags[taxel];
            let pressure = reading.pressure_kpa[taxel];
            let in_short = taxel == 1 && (68.05..70.95).contains(&time_s);
            if in_short {
                assert!(
                    pressure.is_none(),
                    "t {time_s}: a shorted taxel must carry no pressure: {pressure:?}"
                );
                assert!(flags.contains(TaxelFlags::SHORTED), "t {time_s}: {flags:?}");
                shorted_rows += 1;
                continue;
            }
            if (67.95..71.1).contains(&time_s) && taxel == 1 {
                continue;
            }
            let Some(pressure) = pressure else {
                panic!("t {time_s} taxel {taxel}: no pressure, flags {flags:?}");
            };
            let error = f64::from(pressure) - f64::from(expected.pressure_kpa[taxel]);
            assert!(
                error.abs() < SAMPLE_TOLERANCE_KPA,
                "t {time_s} taxel {taxel}: {pressure} kPa vs scene {} kPa ({flags:?})",
                expected.pressure_kpa[taxel]
            );
            squared += error * error;
            compared += 1;
        }
    }
    let rms = (squared / compared.max(1) as f64).sqrt();
    println!("{rows} rows, {compared} pressures compared, RMS {rms:.4} kPa, {shorted_rows} shorted cells, {gaps} sets missing, {streamed:?}");
    assert_eq!(rows, streamed.sets, "one row per set of the one pad");
    assert_eq!(streamed.missing_frames, 0);
    assert_eq!(
        gaps, streamed.sets_missing,
        "the recording's gaps are the stream's"
    );
    // One pass of the scene at about 100 sets per second.
    assert!(rows as f64 > 0.95 * period_s * 100.0, "{rows} rows");
    assert!(gaps as f64 <= 0.01 * rows as f64, "{gaps} sets missing");
    assert!(rms < RMS_TOLERANCE_KPA, "RMS {rms}");
    assert!(shorted_rows > 250, "{shorted_rows}");
}

/// `taxel calibrate --upload --save` as it runs against a board: a fitted calibration goes to
/// the simulated device over the pseudo-terminal, is saved in its flash, and is what the device
/// reports and loads after its MCU reboots.
#[test]
fn a_calibration_uploaded_and_saved_over_the_serial_path_survives_a_reboot() {
    use model_core::{Calibration, CalibrationSpec};
    use taxel_host::calibration_transfer::upload;
    use wire::{CalibrationSource, Command, ReplyPayload};

    let mut device = SimulatedDevice::new(
        SimulatedDeviceConfig::new(SceneFile::default_scene().unwrap(), 1)
            .with_seed(4)
            .with_speed(Some(20.0)),
    )
    .unwrap();
    let mut port = PtyPort::open().unwrap();
    let path = port.path().to_string_lossy().into_owned();
    let stop = Arc::new(AtomicBool::new(false));
    let reboot = Arc::new(AtomicBool::new(false));
    let device_thread = {
        let (stop, reboot) = (Arc::clone(&stop), Arc::clone(&reboot));
        thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                if reboot.swap(false, Ordering::Relaxed) {
                    device.restart_mcu().unwrap();
                }
                device.step(&mut port);
            }
        })
    };
    let opened = open_serial(&path, Duration::from_millis(50)).unwrap();
    let mut link = DeviceLink::new(opened.port);
    let mut spec = CalibrationSpec {
        id: 4242,
        ..CalibrationSpec::default()
    };
    for (taxel, calibration) in spec.taxels.iter_mut().enumerate() {
        calibration.parasitic_pf = 1.0 + 0.1 * taxel as f32;
    }
    let calibration = Calibration::new(&spec).unwrap();
    let timeout = Duration::from_secs(5);
    upload(&mut link, &calibration, true, timeout, &mut |_| {}).unwrap();

    let info = |link: &mut DeviceLink<_>| match link.request(Command::Info, timeout) {
        Ok(ReplyPayload::Info(info)) => info,
        other => panic!("{other:?}"),
    };
    let before = info(&mut link);
    assert_eq!(
        (before.calibration_id, before.calibration_source),
        (4242, CalibrationSource::Flash)
    );
    // Something only RAM holds: a calibration written but not saved. A reboot must lose it.
    let mut unsaved =
        device::calibration_record(&calibration, wire::PadIndex::default(), 0).unwrap();
    unsaved.calibration_id = 999;
    assert_eq!(
        link.request(Command::WriteCalibration(unsaved), timeout)
            .ok(),
        Some(ReplyPayload::Ack)
    );
    assert_eq!(info(&mut link).calibration_id, 999);
    let last_sequence_before = latest_sequence(&mut link);
    reboot.store(true, Ordering::Relaxed);
    // The reboot restarts the acquisition's numbering: wait for a sample numbered below the
    // last one seen before it.
    let deadline = std::time::Instant::now() + timeout;
    loop {
        assert!(
            std::time::Instant::now() < deadline,
            "no sample from after a reboot"
        );
        if let Ok(Some(wire::DeviceFrame::Sample(sample))) = link.next_frame() {
            if sample.sequence < last_sequence_before {
                break;
            }
        }
    }
    let after = info(&mut link);
    assert_eq!(
        (after.calibration_id, after.calibration_source),
        (4242, CalibrationSource::Flash)
    );
    let read = Command::ReadCalibration {
        pad: wire::PadIndex::default(),
        taxel_index: 3,
    };
    match link.request(read, timeout) {
        Ok(ReplyPayload::Calibration(record)) => {
            assert!((record.calibration.parasitic_pf - 1.3).abs() < 1e-6);
        }
        other => panic!("{other:?}"),
    }
    stop.store(true, Ordering::Relaxed);
    device_thread.join().unwrap();
}

/// The sequence number of the newest sample frame the link has or receives next.
fn latest_sequence<P: std::io::Read + std::io::Write>(link: &mut DeviceLink<P>) -> u32 {
    let mut latest = None;
    for _ in 0..10_000 {
        match link.next_frame() {
            Ok(Some(wire::DeviceFrame::Sample(sample))) => latest = Some(sample.sequence),
            Ok(None) if latest.is_some() => break,
            _ => {}
        }
    }
    latest.unwrap()
}
