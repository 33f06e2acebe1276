//! The per-pad commands on a simulated device with several pads: PadInfo describes where each
//! pad is, calibration and baseline commands address one pad, each pad's saved calibration
//! survives a reboot, and a pad index the device does not have is refused.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic)]

mod support;

use support::Host;
use wire::{
    CalibrationSource, Command, ErrorCode, PadIndex, PadInfoFrame, ReplyPayload, TemperatureSensor,
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
