//! The per-pad commands on a simulated device with several pads: PadInfo describes where each
//! pad is, calibration, baseline and tare commands address one pad, each pad's saved
//! calibration survives a reboot, and a pad index the device does not have is refused.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic)]

use sensor_sim::{Keyframe, ScriptedScene};
use sim_device::testing::Host;
use sim_device::{SceneFile, SimulatedDeviceConfig};
use wire::{
    CalibrationSource, Command, DeviceEvent, ErrorCode, PadIndex, PadInfoFrame, ReplyPayload,
    TaxelBaselineWire, TemperatureSensor, UseCase,
};

fn pad(index: u8) -> PadIndex {
    PadIndex::new(index).unwrap()
}

fn pad_info(host: &mut Host, index: u8) -> PadInfoFrame {
    match host.request(Command::PadInfo { pad: pad(index) }) {
        Ok(ReplyPayload::PadInfo(info)) => info,
        other => panic!("pad {index}: {other:?}"),
    }
}

#[test]
fn pad_info_says_where_every_pad_is() {
    let mut host = Host::with_pads(3);
    assert_eq!(host.info().pad_count, 3);
    for index in 0..3 {
        let info = pad_info(&mut host, index);
        assert_eq!(info.pad, pad(index));
        // pads_topology puts pad k on channel k, with the TMP117 on the main bus at 0x48.
        assert_eq!(info.channel, Some(index));
        assert_eq!(
            info.temperature_sensor,
            TemperatureSensor::SharedTmp117 { address: 0x48 }
        );
        assert_eq!(info.calibration_source, CalibrationSource::Flash);
        assert_eq!(info.calibration_id, sim_device::FACTORY_CALIBRATION_ID);
    }
    assert_eq!(
        host.request(Command::PadInfo { pad: pad(3) }),
        Err(ErrorCode::InvalidArgument)
    );
    // Beyond the wire's eight pads, the typed argument itself is refused.
    assert_eq!(
        host.request_with_varint(14, 8),
        Err(ErrorCode::InvalidArgument)
    );
}

#[test]
fn the_single_pad_board_has_its_pad_on_the_bus_itself() {
    let mut host = Host::new();
    let info = pad_info(&mut host, 0);
    assert_eq!(info.channel, None);
    assert_eq!(
        info.temperature_sensor,
        TemperatureSensor::SharedTmp117 { address: 0x48 }
    );
}

#[test]
fn a_calibration_written_to_one_pad_changes_that_pad_only() {
    let mut host = Host::with_pads(2);
    let read = |host: &mut Host, index: u8| match host.request(Command::ReadCalibration {
        pad: pad(index),
        taxel_index: 1,
    }) {
        Ok(ReplyPayload::Calibration(record)) => record,
        other => panic!("{other:?}"),
    };
    let mut record = read(&mut host, 1);
    assert_eq!(record.pad, pad(1));
    record.calibration_id = 77;
    record.calibration.parasitic_pf += 0.5;
    assert_eq!(
        host.request(Command::WriteCalibration(record.clone())),
        Ok(ReplyPayload::Ack)
    );
    assert_eq!(read(&mut host, 1), record);
    assert_ne!(read(&mut host, 0).calibration_id, 77);
    let (first, second) = (pad_info(&mut host, 0), pad_info(&mut host, 1));
    assert_eq!(first.calibration_source, CalibrationSource::Flash);
    assert_eq!(
        (second.calibration_id, second.calibration_source),
        (77, CalibrationSource::Host)
    );
    // Saved, each pad keeps its own calibration over a reboot.
    assert_eq!(
        host.request(Command::SaveCalibration),
        Ok(ReplyPayload::Ack)
    );
    assert_eq!(
        pad_info(&mut host, 1).calibration_source,
        CalibrationSource::Flash
    );
    host.device.restart_mcu().unwrap();
    host.steps(20);
    assert_eq!(read(&mut host, 1), record);
    let (first, second) = (pad_info(&mut host, 0), pad_info(&mut host, 1));
    assert_eq!(
        (first.calibration_id, first.calibration_source),
        (sim_device::FACTORY_CALIBRATION_ID, CalibrationSource::Flash)
    );
    assert_eq!(
        (second.calibration_id, second.calibration_source),
        (77, CalibrationSource::Flash)
    );
    // A pad the device does not have.
    record.pad = pad(2);
    assert_eq!(
        host.request(Command::WriteCalibration(record)),
        Err(ErrorCode::InvalidArgument)
    );
    assert_eq!(
        host.request(Command::ReadBaseline {
            pad: pad(2),
            taxel_index: 0
        }),
        Err(ErrorCode::InvalidArgument)
    );
    match host.request(Command::ReadBaseline {
        pad: pad(1),
        taxel_index: 0,
    }) {
        Ok(ReplyPayload::Baseline(baseline)) => {
            assert_eq!(baseline.pad, pad(1));
            assert!(baseline.baseline.is_some(), "tared at boot");
        }
        other => panic!("{other:?}"),
    }
}

/// A use case one pad's calibration cannot serve (it was calibrated to 20 kPa only, the use
/// case needs 50) is refused, and no pad's tier changes; within 20 kPa each pad chooses on its
/// own calibration.
#[test]
fn every_pad_must_fit_a_use_case_and_each_chooses_its_own_tier() {
    let mut host = Host::with_pads(2);
    for taxel_index in 0..4 {
        let mut record = match host.request(Command::ReadCalibration {
            pad: pad(1),
            taxel_index,
        }) {
            Ok(ReplyPayload::Calibration(record)) => record,
            other => panic!("{other:?}"),
        };
        record.calibration_id = 88;
        record
            .calibration
            .points
            .retain(|&(pressure_kpa, _)| pressure_kpa <= 20.0);
        assert!(record.calibration.points.len() >= 2);
        assert_eq!(
            host.request(Command::WriteCalibration(record)),
            Ok(ReplyPayload::Ack)
        );
    }
    let tiers = |host: &mut Host| [pad_info(host, 0).model_tier, pad_info(host, 1).model_tier];
    let before = tiers(&mut host);
    let full_range = UseCase {
        pressure_max_kpa: 50.0,
        temperature_min_c: 25.0,
        temperature_max_c: 40.0,
        error_budget_kpa: 1.0,
    };
    assert_eq!(
        host.request(Command::SetUseCase(full_range)),
        Err(ErrorCode::NotSupported)
    );
    assert_eq!(tiers(&mut host), before);
    let light_touch = UseCase {
        pressure_max_kpa: 15.0,
        ..full_range
    };
    let first = match host.request(Command::SetUseCase(light_touch)) {
        Ok(ReplyPayload::ModelTier(tier)) => tier,
        other => panic!("{other:?}"),
    };
    assert_eq!(tiers(&mut host)[0], first);
    assert_eq!(host.info().model_tier, first);
}

/// Each pad's calibration is saved under its multiplexer channel: when the pad on channel 1 is
/// unplugged at the next boot, the pad on channel 2 becomes the second pad found and still
/// boots on its own calibration.
#[test]
fn a_saved_calibration_follows_its_pads_channel_when_another_pad_is_missing() {
    let mut scene = sim_device::SceneFile::default_scene().unwrap();
    let default_pad = scene.pads[0].clone();
    let mut unplugged = default_pad.clone();
    unplugged.faults.push(sim_device::SceneFault {
        kind: sim_device::FaultKind::Unplugged,
        taxel: 0,
        start_s: 2.0,
        end_s: 1000.0,
    });
    scene.pads = vec![default_pad.clone(), unplugged, default_pad];
    let mut host = Host::with_scene(scene, 3);
    for (index, id) in [(0u8, 100u32), (1, 101), (2, 102)] {
        for taxel_index in 0..4 {
            let mut record = match host.request(Command::ReadCalibration {
                pad: pad(index),
                taxel_index,
            }) {
                Ok(ReplyPayload::Calibration(record)) => record,
                other => panic!("{other:?}"),
            };
            record.calibration_id = id;
            record.calibration.parasitic_pf += 0.1 * f32::from(index);
            assert_eq!(
                host.request(Command::WriteCalibration(record)),
                Ok(ReplyPayload::Ack)
            );
        }
    }
    assert_eq!(
        host.request(Command::SaveCalibration),
        Ok(ReplyPayload::Ack)
    );
    while host.device.simulation().now_us() < 2_500_000 {
        host.steps(10);
    }
    host.device.restart_mcu().unwrap();
    host.steps(20);
    assert_eq!(host.info().pad_count, 2);
    let (first, second) = (pad_info(&mut host, 0), pad_info(&mut host, 1));
    assert_eq!(
        (
            first.channel,
            first.calibration_id,
            first.calibration_source
        ),
        (Some(0), 100, CalibrationSource::Flash)
    );
    assert_eq!(
        (
            second.channel,
            second.calibration_id,
            second.calibration_source
        ),
        (Some(2), 102, CalibrationSource::Flash)
    );
}

/// The glove's palm leaves the factory with its larger geometry: PadInfo reports it and the
/// device's force is its pressures times those areas. SetPadGeometry gives a pad another one
/// (refused when it is not a geometry or the pad does not exist), which SaveCalibration keeps
/// over a reboot.
#[test]
fn each_pad_has_its_own_geometry_reported_used_and_kept() {
    use model_core::{PadGeometry, PadRole, TaxelGeometry};
    use sim_device::SceneFile;
    use wire::{DeviceFrame, PadGeometryRecord};

    let scene = SceneFile::built_in("glove").unwrap();
    let pads = scene.pads.len();
    let mut host = Host::with_scene(scene.clone(), pads);
    let palm = (pads - 1) as u8;
    let info = pad_info(&mut host, palm);
    assert_eq!(info.role, PadRole::Palm);
    assert_eq!(&info.taxels, scene.pads[pads - 1].geometry.taxels());
    assert!(info.taxels.iter().all(|taxel| taxel.area_mm2 == 96.0));
    assert_eq!((info.taxels[0].x_mm, info.taxels[0].y_mm), (-6.5, 4.5));
    let thumb = pad_info(&mut host, 0);
    assert_eq!(thumb.role, PadRole::Fingertip);
    assert_eq!(&thumb.taxels, PadGeometry::ARTICLE.taxels());
    // Force = Σ pressure × area over the palm's own electrodes, as the device sends it.
    let mut compared = 0;
    for frame in host.run_until_s(6.0) {
        let DeviceFrame::Sample(sample) = frame else {
            continue;
        };
        let (Some(force_n), false) = (sample.summary.force_n, sample.summary.partial) else {
            continue;
        };
        if sample.pad.get() != palm {
            continue;
        }
        let expected_n: f32 = sample
            .taxels
            .iter()
            .zip(&info.taxels)
            .map(|(taxel, place)| taxel.pressure_kpa.unwrap() * place.area_mm2 * 1e-3)
            .sum();
        assert!((force_n - expected_n).abs() <= 1e-4 * expected_n.max(1.0));
        compared += usize::from(expected_n > 0.5);
    }
    assert!(compared > 10, "{compared} loaded palm frames");

    // Another geometry for pad 1: long and narrow, kept over a reboot once saved.
    let narrow = [(-2.0, 6.0), (2.0, 6.0), (-2.0, -6.0), (2.0, -6.0)]
        .map(|(x, y)| TaxelGeometry::new(x, y, 12.0));
    let set = |pad, taxels| {
        Command::SetPadGeometry(PadGeometryRecord {
            pad: self::pad(pad),
            role: PadRole::GripperJaw,
            taxels,
        })
    };
    let mut same_place = narrow;
    same_place[3] = same_place[0];
    assert_eq!(
        host.request(set(1, same_place)),
        Err(ErrorCode::InvalidArgument)
    );
    assert_eq!(
        host.request(set(pads as u8, narrow)),
        Err(ErrorCode::InvalidArgument)
    );
    assert_eq!(host.request(set(1, narrow)), Ok(ReplyPayload::Ack));
    assert_eq!(pad_info(&mut host, 1).taxels, narrow);
    assert_eq!(pad_info(&mut host, 1).role, PadRole::GripperJaw);
    host.device.restart_mcu().unwrap();
    host.steps(20);
    assert_eq!(
        pad_info(&mut host, 1).taxels,
        *PadGeometry::ARTICLE.taxels(),
        "not saved: the reboot brings back the saved geometry"
    );
    assert_eq!(host.request(set(1, narrow)), Ok(ReplyPayload::Ack));
    assert_eq!(
        host.request(Command::SaveCalibration),
        Ok(ReplyPayload::Ack)
    );
    host.device.restart_mcu().unwrap();
    host.steps(20);
    assert_eq!(pad_info(&mut host, 1).taxels, narrow);
    assert_eq!(pad_info(&mut host, 1).role, PadRole::GripperJaw);
    assert_eq!(pad_info(&mut host, palm).role, PadRole::Palm);
}

/// Every taxel's baseline of pad `index`.
fn baselines(host: &mut Host, index: u8) -> Vec<TaxelBaselineWire> {
    (0..4)
        .map(|taxel_index| {
            match host.request(Command::ReadBaseline {
                pad: pad(index),
                taxel_index,
            }) {
                Ok(ReplyPayload::Baseline(baseline)) => baseline,
                other => panic!("pad {index} taxel {taxel_index}: {other:?}"),
            }
        })
        .collect()
}

/// Both pads unloaded for the tare at boot, then 5 kPa on every taxel from 1.2 s on, held still.
fn held_press(_pad: usize) -> ScriptedScene {
    let keyframe = |time_s, pressure_kpa| Keyframe {
        time_s,
        pressure_kpa: [pressure_kpa; 4],
        temperature_c: 25.0,
    };
    ScriptedScene::new(vec![
        keyframe(0.0, 0.0),
        keyframe(1.0, 0.0),
        keyframe(1.2, 5.0),
        keyframe(10.0, 5.0),
    ])
    .unwrap()
}

/// The last sample of pad `index` that `host` decoded: its pressures, kPa.
fn last_pressures_kpa(host: &Host, index: u8) -> [f32; 4] {
    let sample = host
        .samples
        .iter()
        .rev()
        .find(|sample| sample.pad == pad(index))
        .unwrap();
    sample
        .taxels
        .map(|taxel| taxel.pressure_kpa.unwrap_or(f32::NAN))
}

/// Both pads pressed and held; a tare of pad 1 takes the held load as pad 1's zero and leaves
/// pad 0 alone: its baselines, its pressure and its events.
#[test]
fn a_tare_of_one_pad_tares_that_pad_only() {
    let mut host = Host::with_config(SimulatedDeviceConfig::new(
        SceneFile::default_scene().unwrap(),
        2,
    ));
    for index in 0..2 {
        let scene = held_press(index);
        host.device
            .simulation()
            .set_pad_scene(index, move |time_us: u64| {
                scene.point_at_s(time_us as f64 / 1e6)
            })
            .unwrap();
    }
    host.run_until_s(2.0);
    let (pad_0_before, pad_1_before) = (baselines(&mut host, 0), baselines(&mut host, 1));
    assert!(pad_0_before
        .iter()
        .chain(&pad_1_before)
        .all(|taxel| taxel.baseline.is_some()));
    for index in 0..2 {
        for pressure_kpa in last_pressures_kpa(&host, index) {
            assert!(
                (pressure_kpa - 5.0).abs() < 0.5,
                "pad {index}: {pressure_kpa} kPa"
            );
        }
    }

    let (reply, events) = host.request_with_events(Command::Tare {
        sample_sets: 16,
        pad: Some(pad(1)),
    });
    assert_eq!(reply, Ok(ReplyPayload::Ack));
    assert_eq!(
        events,
        [DeviceEvent::TareFinished {
            pad: pad(1),
            tared_mask: 0b1111
        }]
    );
    host.steps(8);
    assert_eq!(baselines(&mut host, 0), pad_0_before, "pad 0 was not tared");
    let pad_1_after = baselines(&mut host, 1);
    for (before, after) in pad_1_before.iter().zip(&pad_1_after) {
        let (Some(before), Some(after)) = (before.baseline, after.baseline) else {
            panic!("pad 1 lost a baseline: {before:?} {after:?}");
        };
        // The held load raised the capacitance pad 1 was tared at.
        assert!(
            after.offset_pf + after.fine_pf > before.offset_pf + before.fine_pf + 0.01,
            "{before:?} -> {after:?}"
        );
    }
    for pressure_kpa in last_pressures_kpa(&host, 0) {
        assert!(
            (pressure_kpa - 5.0).abs() < 0.5,
            "pad 0: {pressure_kpa} kPa"
        );
    }
    for pressure_kpa in last_pressures_kpa(&host, 1) {
        assert!(pressure_kpa.abs() < 0.5, "pad 1: {pressure_kpa} kPa");
    }

    // Every pad, as before version 6: pad 0 is tared too.
    let (reply, events) = host.request_with_events(Command::Tare {
        sample_sets: 16,
        pad: None,
    });
    assert_eq!(reply, Ok(ReplyPayload::Ack));
    let mut tared: Vec<u8> = events
        .iter()
        .filter_map(|event| match event {
            DeviceEvent::TareFinished { pad, .. } => Some(pad.get()),
            _ => None,
        })
        .collect();
    tared.sort_unstable();
    assert_eq!(tared, [0, 1]);
    assert_ne!(baselines(&mut host, 0), pad_0_before);
}

#[test]
fn a_tare_of_a_pad_the_device_lacks_is_refused_and_tares_nothing() {
    let mut host = Host::with_pads(2);
    let before = [baselines(&mut host, 0), baselines(&mut host, 1)];
    for index in [2, 7] {
        let (reply, events) = host.request_with_events(Command::Tare {
            sample_sets: 8,
            pad: Some(pad(index)),
        });
        assert_eq!(reply, Err(ErrorCode::InvalidArgument));
        assert!(events.is_empty(), "{events:?}");
    }
    host.steps(40);
    assert_eq!([baselines(&mut host, 0), baselines(&mut host, 1)], before);
    // Nothing is left pending: the next tare is not Busy.
    assert_eq!(
        host.request(Command::Tare {
            sample_sets: 8,
            pad: Some(pad(0)),
        }),
        Ok(ReplyPayload::Ack)
    );
}
