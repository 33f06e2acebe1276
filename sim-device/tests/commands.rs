//! Every command of the protocol, sent to the simulated device (the firmware's own command
//! handling) through the real encoder and decoder, with its reply and its effect.

// Test helpers may unwrap and panic: a failure is the test failing.
#![allow(clippy::unwrap_used, clippy::panic)]

use sim_device::testing::Host;
use sim_device::{MemoryPort, SceneFile, SimulatedDevice, SimulatedDeviceConfig};
use wire::{
    CalibrationSource, Command, DeviceEvent, DeviceFrame, DeviceFrameDecoder, ErrorCode,
    EventFrame, ReplyPayload, Request, SampleFrame, SampleRate, TaxelCalibrationRecord, UseCase,
};

#[test]
fn info_and_counters_describe_the_device() {
    let mut host = Host::new();
    let info = host.info();
    assert_eq!(info.protocol_version, wire::PROTOCOL_VERSION);
    assert_eq!(&info.board_serial[..9], b"SIMULATED");
    // Factory calibrated: the simulated pad's own curve is in its flash.
    assert_eq!(info.calibration_source, CalibrationSource::Flash);
    assert_eq!(info.rate, SampleRate::Sps400);
    assert_eq!(info.model_tier, model_core::Tier::MonotoneCubic);
    assert!(info.streaming && !info.text_mode);
    assert!(matches!(
        host.request(Command::ReadCounters),
        Ok(ReplyPayload::Counters(_))
    ));
}

#[test]
fn streaming_stops_and_starts() {
    let mut host = Host::new();
    assert_eq!(host.request(Command::StopStreaming), Ok(ReplyPayload::Ack));
    host.samples.clear();
    host.steps(50);
    assert!(host.samples.is_empty());
    assert_eq!(host.request(Command::StartStreaming), Ok(ReplyPayload::Ack));
    host.steps(50);
    assert!(host.samples.len() >= 49);
}

#[test]
fn the_rate_changes_and_a_bad_rate_is_refused() {
    let mut host = Host::new();
    assert_eq!(
        host.request(Command::SetRate {
            rate: SampleRate::Sps200
        }),
        Ok(ReplyPayload::Ack)
    );
    assert_eq!(host.info().rate, SampleRate::Sps200);
    host.samples.clear();
    host.steps(40);
    let spacing_us: Vec<u64> = host
        .samples
        .windows(2)
        .map(|pair| pair[1].timestamp_us - pair[0].timestamp_us)
        .collect();
    // Four conversions at 200 S/s: a sample set every 20 ms.
    let typical = spacing_us[spacing_us.len() / 2];
    assert!((19_000..22_000).contains(&typical), "{typical} us");
    // SetRate is command 4; 150 S/s is no rate.
    assert_eq!(
        host.request_with_varint(4, 150),
        Err(ErrorCode::InvalidArgument)
    );
    assert_eq!(host.request_with_varint(4, 100), Ok(ReplyPayload::Ack));
    assert_eq!(host.info().rate, SampleRate::Sps100);
}

/// A rate change (or setting the same rate) is not an error recovery: no re-initialisation is
/// counted and no ConverterReinitialised event is sent.
#[test]
fn setting_a_rate_is_not_counted_as_a_converter_reinitialisation() {
    let mut host = Host::new();
    let reinits = |host: &mut Host| match host.request(Command::ReadCounters) {
        Ok(ReplyPayload::Counters(counters)) => counters.converter_reinits,
        other => panic!("{other:?}"),
    };
    let before = reinits(&mut host);
    let mut events = 0;
    for rate in [
        SampleRate::Sps400,
        SampleRate::Sps400,
        SampleRate::Sps200,
        SampleRate::Sps200,
        SampleRate::Sps400,
    ] {
        assert_eq!(
            host.request(Command::SetRate { rate }),
            Ok(ReplyPayload::Ack)
        );
        events += host
            .steps(10)
            .iter()
            .filter(|frame| {
                matches!(
                    frame,
                    DeviceFrame::Event(EventFrame {
                        event: DeviceEvent::ConverterReinitialised { .. },
                        ..
                    })
                )
            })
            .count();
    }
    assert_eq!(reinits(&mut host), before);
    assert_eq!(events, 0);
}

/// Sample sets streamed at each rate after the change.
const SETS_PER_RATE: usize = 60;

/// Largest relative difference between the mean sample-set period in simulated time and the
/// period of four conversions at the rate set (the loop polls DONE every 500 us, so single
/// periods jitter by that much, but over 60 sets the mean follows the converter).
const SET_PERIOD_TOLERANCE: f64 = 0.02;

#[test]
fn every_supported_rate_streams_clean_sample_sets_at_that_rate() {
    let mut host = Host::new();
    // 400 S/s at boot, so every request below is a change.
    for rate in [SampleRate::Sps100, SampleRate::Sps200, SampleRate::Sps400] {
        let rate_sps = rate.sps();
        let reinits_before = match host.request(Command::ReadCounters) {
            Ok(ReplyPayload::Counters(counters)) => counters.converter_reinits,
            other => panic!("{other:?}"),
        };
        assert_eq!(
            host.request(Command::SetRate { rate }),
            Ok(ReplyPayload::Ack),
            "{rate_sps} S/s"
        );
        assert_eq!(host.info().rate, rate);

        host.samples.clear();
        let frames = host.steps(SETS_PER_RATE);
        let reinit_events = frames
            .iter()
            .filter(|frame| {
                matches!(
                    frame,
                    DeviceFrame::Event(EventFrame {
                        event: DeviceEvent::ConverterReinitialised { .. },
                        ..
                    })
                )
            })
            .count();
        assert_eq!(reinit_events, 0, "{rate_sps} S/s");
        assert_eq!(host.samples.len(), SETS_PER_RATE, "{rate_sps} S/s");
        for pair in host.samples.windows(2) {
            assert_eq!(pair[1].sequence, pair[0].sequence + 1, "{rate_sps} S/s");
        }
        for sample in &host.samples {
            for taxel in &sample.taxels {
                assert_eq!(
                    taxel.flags & wire::flags::CONVERTER_ERROR,
                    0,
                    "{rate_sps} S/s, sequence {}",
                    sample.sequence
                );
            }
        }

        let first = host.samples.first().unwrap().timestamp_us;
        let last = host.samples.last().unwrap().timestamp_us;
        let mean_period_us = (last - first) as f64 / (SETS_PER_RATE - 1) as f64;
        // Four conversions, one per taxel, make one sample set.
        let expected_period_us = 4.0 * 1e6 / f64::from(rate_sps);
        let relative_error = (mean_period_us / expected_period_us - 1.0).abs();
        assert!(
            relative_error <= SET_PERIOD_TOLERANCE,
            "{rate_sps} S/s: a set every {mean_period_us:.0} us, expected {expected_period_us:.0} us"
        );

        let reinits_after = match host.request(Command::ReadCounters) {
            Ok(ReplyPayload::Counters(counters)) => counters.converter_reinits,
            other => panic!("{other:?}"),
        };
        assert_eq!(reinits_after, reinits_before, "{rate_sps} S/s");
    }
}

#[test]
fn a_tare_replies_when_done_and_refuses_overlap_and_zero() {
    let mut host = Host::new();
    assert_eq!(
        host.request(Command::Tare {
            sample_sets: 0,
            pad: None
        }),
        Err(ErrorCode::InvalidArgument)
    );
    let mut encoded = [0u8; 64];
    let length = wire::encode_frame(
        &Request {
            request_id: 500,
            command: Command::Tare {
                sample_sets: 64,
                pad: None,
            },
        },
        &mut encoded,
    )
    .unwrap();
    host.send_bytes(&encoded[..length]);
    host.steps(2);
    assert_eq!(
        host.request(Command::Tare {
            sample_sets: 8,
            pad: None
        }),
        Err(ErrorCode::Busy)
    );
    let mut reply = None;
    for _ in 0..100 {
        for frame in host.steps(1) {
            if let DeviceFrame::Reply(frame) = frame {
                if frame.request_id == 500 {
                    reply = Some(frame.result);
                }
            }
        }
    }
    assert_eq!(reply, Some(Ok(ReplyPayload::Ack)));
}

/// A tare asked for while the demo scene presses c11 (0 -> 3 kPa over 3..4 s) is refused with
/// the reason; the same tare on the still pad a moment later succeeds.
#[test]
fn a_tare_while_the_pad_is_pressed_is_refused_as_not_still() {
    let mut host = Host::new();
    // Host::new ran 20 sets of 10 ms; run to 3.2 s, into the press.
    host.steps(300);
    let mut encoded = [0u8; 64];
    let length = wire::encode_frame(
        &Request {
            request_id: 600,
            command: Command::Tare {
                sample_sets: 32,
                pad: None,
            },
        },
        &mut encoded,
    )
    .unwrap();
    host.send_bytes(&encoded[..length]);
    // The pad's TareRefused names the moving taxel, C11, before the reply refuses the tare.
    let mut refused = None;
    let mut reply = None;
    for _ in 0..200 {
        for frame in host.steps(1) {
            match frame {
                DeviceFrame::Event(EventFrame {
                    event: DeviceEvent::TareRefused { pad, refused_mask },
                    ..
                }) => {
                    assert!(reply.is_none(), "the event comes before the reply");
                    refused = Some((pad.get(), refused_mask));
                }
                DeviceFrame::Reply(frame) if frame.request_id == 600 => reply = Some(frame.result),
                _ => {}
            }
        }
        if reply.is_some() {
            break;
        }
    }
    assert_eq!(reply, Some(Err(ErrorCode::TareNotStill)));
    let (pad, refused_mask) = refused.expect("a TareRefused event");
    assert_eq!(pad, 0);
    assert_eq!(
        refused_mask & 0b0001,
        0b0001,
        "C11 moved: {refused_mask:04b}"
    );
    // Held at 3 kPa from 4 s: still, so it tares (a deliberate tare under a static load).
    host.steps(100);
    assert_eq!(
        host.request(Command::Tare {
            sample_sets: 32,
            pad: None
        }),
        Ok(ReplyPayload::Ack)
    );
}

#[test]
fn tiers_and_use_cases_are_chosen_or_refused() {
    let mut host = Host::new();
    let table = model_core::Tier::Table;
    assert_eq!(
        host.request(Command::SetModelTier { tier: table }),
        Ok(ReplyPayload::Ack)
    );
    assert_eq!(host.info().model_tier, table);
    // A research tier is built only with model-core's feature `research-tiers`, which the
    // firmware leaves off (and `cargo test -p taxel-sim-device` too); a workspace-wide test run
    // turns it on for the host crates. Without it the device refuses the tier and keeps its own.
    let polynomial = model_core::Tier::Polynomial;
    if polynomial.is_built() {
        assert_eq!(
            host.request(Command::SetModelTier { tier: polynomial }),
            Ok(ReplyPayload::Ack)
        );
        assert_eq!(host.info().model_tier, polynomial);
    } else {
        for research in model_core::Tier::ALL
            .into_iter()
            .filter(|tier| tier.is_research())
        {
            assert_eq!(
                host.request(Command::SetModelTier { tier: research }),
                Err(ErrorCode::NotSupported),
                "{research:?}"
            );
            assert_eq!(host.info().model_tier, table);
        }
    }
    // SetModelTier is command 6; 99 is no tier.
    assert_eq!(
        host.request_with_varint(6, 99),
        Err(ErrorCode::InvalidArgument)
    );
    let glove = UseCase {
        pressure_max_kpa: 50.0,
        temperature_min_c: 25.0,
        temperature_max_c: 40.0,
        error_budget_kpa: 1.0,
    };
    let chosen = match host.request(Command::SetUseCase(glove)) {
        Ok(ReplyPayload::ModelTier(tier)) => tier,
        other => panic!("{other:?}"),
    };
    assert!(chosen.is_built(), "{chosen:?}");
    assert_eq!(host.info().model_tier, chosen);
    let too_hot = UseCase {
        temperature_max_c: 80.0,
        ..glove
    };
    assert_eq!(
        host.request(Command::SetUseCase(too_hot)),
        Err(ErrorCode::NotSupported)
    );
    let nonsense = UseCase {
        error_budget_kpa: f32::NAN,
        ..glove
    };
    assert_eq!(
        host.request(Command::SetUseCase(nonsense)),
        Err(ErrorCode::InvalidArgument)
    );
}

#[test]
fn a_calibration_is_read_written_saved_kept_across_a_reboot_and_restored() {
    let mut host = Host::new();
    let mut record = match host.request(Command::ReadCalibration {
        pad: wire::PadIndex::default(),
        taxel_index: 1,
    }) {
        Ok(ReplyPayload::Calibration(record)) => record,
        other => panic!("{other:?}"),
    };
    // The simulated pad's factory calibration, as the device reports it.
    let factory = host
        .device
        .simulation()
        .physics()
        .matching_calibration()
        .unwrap();
    let point_count = factory.taxels()[1].curve().points().len();
    assert_eq!(record.calibration.points.len(), point_count);
    assert_eq!(
        host.request(Command::ReadCalibration {
            pad: wire::PadIndex::default(),
            taxel_index: 9
        }),
        Err(ErrorCode::InvalidArgument)
    );
    record.calibration_id = 77;
    let top_relative_change = record.calibration.points[point_count - 1].1 + 0.01;
    record.calibration.points[point_count - 1].1 = top_relative_change;
    assert_eq!(
        host.request(Command::WriteCalibration(record.clone())),
        Ok(ReplyPayload::Ack)
    );
    let info = host.info();
    assert_eq!(
        (info.calibration_id, info.calibration_source),
        (77, CalibrationSource::Host)
    );
    let mut backwards: TaxelCalibrationRecord = record.clone();
    backwards.calibration.points[2].1 = backwards.calibration.points[1].1;
    assert_eq!(
        host.request(Command::WriteCalibration(backwards)),
        Err(ErrorCode::InvalidArgument)
    );

    assert_eq!(
        host.request(Command::SaveCalibration),
        Ok(ReplyPayload::Ack)
    );
    host.device.restart_mcu().unwrap();
    let info = host.info();
    assert_eq!(
        (info.calibration_id, info.calibration_source),
        (77, CalibrationSource::Flash)
    );
    match host.request(Command::ReadCalibration {
        pad: wire::PadIndex::default(),
        taxel_index: 1,
    }) {
        Ok(ReplyPayload::Calibration(read_back)) => {
            assert_eq!(
                read_back.calibration.points[point_count - 1].1,
                top_relative_change
            )
        }
        other => panic!("{other:?}"),
    }

    assert_eq!(
        host.request(Command::RestoreDefaults),
        Ok(ReplyPayload::Ack)
    );
    let info = host.info();
    assert_eq!(
        (info.calibration_id, info.calibration_source),
        (0, CalibrationSource::Defaults)
    );
}

/// The flags of taxel `taxel` in the last sample frame after `steps` more cycles.
fn latest_flags(host: &mut Host, taxel: usize, steps: usize) -> u16 {
    host.samples.clear();
    host.steps(steps);
    host.samples.last().unwrap().taxels[taxel].flags
}

/// A calibration's C0 (protocol version 2) is written and read over the wire, saved to flash and
/// kept across a reboot; a tare more than 5 % from it is flagged, a tare at it is not.
#[test]
fn a_calibrated_c0_is_carried_end_to_end_and_a_tare_far_from_it_is_flagged() {
    const FAR: u16 = wire::flags::BASELINE_FAR_FROM_CALIBRATION;
    let mut host = Host::new();
    let mut record = match host.request(Command::ReadCalibration {
        pad: wire::PadIndex::default(),
        taxel_index: 1,
    }) {
        Ok(ReplyPayload::Calibration(record)) => record,
        other => panic!("{other:?}"),
    };
    // The simulated pad's C0 - Cp of c12 at 25 °C; its tare reads about that.
    let true_c0_pf = host.device.simulation().physics().taxels[1].unloaded_pf;

    // Calibrated on a pad whose C0 was 10 % lower: the tared C0 is 10 % above it.
    let far_c0_pf = true_c0_pf / 1.1;
    record.calibration.unloaded_sensor_pf = Some(far_c0_pf);
    assert_eq!(
        host.request(Command::WriteCalibration(record.clone())),
        Ok(ReplyPayload::Ack)
    );
    assert_eq!(
        host.request(Command::Tare {
            sample_sets: 8,
            pad: None
        }),
        Ok(ReplyPayload::Ack)
    );
    assert_ne!(latest_flags(&mut host, 1, 5) & FAR, 0);
    assert_eq!(latest_flags(&mut host, 0, 1) & FAR, 0, "c11 has no C0");
    match host.request(Command::ReadCalibration {
        pad: wire::PadIndex::default(),
        taxel_index: 1,
    }) {
        Ok(ReplyPayload::Calibration(read_back)) => {
            assert_eq!(read_back.calibration.unloaded_sensor_pf, Some(far_c0_pf));
        }
        other => panic!("{other:?}"),
    }

    // Saved to flash (record format version 3) and read back after a reboot.
    record.calibration.unloaded_sensor_pf = Some(true_c0_pf);
    assert_eq!(
        host.request(Command::WriteCalibration(record.clone())),
        Ok(ReplyPayload::Ack)
    );
    assert_eq!(
        host.request(Command::SaveCalibration),
        Ok(ReplyPayload::Ack)
    );
    host.device.restart_mcu().unwrap();
    match host.request(Command::ReadCalibration {
        pad: wire::PadIndex::default(),
        taxel_index: 1,
    }) {
        Ok(ReplyPayload::Calibration(read_back)) => {
            assert_eq!(read_back.calibration, record.calibration);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(
        host.request(Command::Tare {
            sample_sets: 8,
            pad: None
        }),
        Ok(ReplyPayload::Ack)
    );
    assert_eq!(latest_flags(&mut host, 1, 5) & FAR, 0);

    // A C0 the wire can tell is no capacitance is refused before the model sees it, and one
    // beyond the converter's reach by the model.
    for refused in [0.0, -1.0, f32::NAN, 1.0e6] {
        record.calibration.unloaded_sensor_pf = Some(refused);
        assert_eq!(
            host.request(Command::WriteCalibration(record.clone())),
            Err(ErrorCode::InvalidArgument),
            "{refused}"
        );
    }
}

#[test]
fn text_mode_prints_a_header_and_csv_lines_and_binary_brings_frames_back() {
    let mut host = Host::new();
    let mut encoded = [0u8; 64];
    let length = wire::encode_frame(
        &Request {
            request_id: 600,
            command: Command::SetTextMode { enabled: true },
        },
        &mut encoded,
    )
    .unwrap();
    host.send_bytes(&encoded[..length]);
    let mut text = Vec::new();
    for _ in 0..10 {
        host.device.step(&mut host.link);
        text.extend(host.link.take_for_host(usize::MAX));
    }
    // The Ack comes as a binary frame, then the header, then one line per set.
    let mut decoder = DeviceFrameDecoder::new();
    let acknowledged = decoder.feed(&text).flatten().any(|frame| {
        matches!(frame, DeviceFrame::Reply(reply)
            if reply.request_id == 600 && reply.result == Ok(ReplyPayload::Ack))
    });
    assert!(acknowledged);
    let text = String::from_utf8_lossy(&text);
    assert!(
        text.contains(&format!("{}\r\n", wire::CSV_HEADER)),
        "{text}"
    );
    let lines: Vec<&str> = text
        .lines()
        .filter(|line| line.matches(',').count() == 12)
        .collect();
    assert!(lines.len() >= 10, "{text}");
    host.send_bytes(b"binary\n");
    host.samples.clear();
    host.steps(20);
    assert!(host.samples.len() >= 18);
}

#[test]
fn malformed_and_unknown_requests_are_answered_or_counted_never_fatal() {
    let mut host = Host::new();
    // A well-framed request whose command index is unknown: the id is readable, so it is answered.
    let mut payload = vec![wire::PROTOCOL_VERSION, wire::kind::REQUEST, 0x2A, 0x63];
    let crc = wire::crc16(&payload);
    payload.extend_from_slice(&crc.to_le_bytes());
    let mut framed = vec![0u8; 32];
    let length = cobs::encode(&payload, &mut framed);
    framed.truncate(length);
    framed.push(0);
    host.send_bytes(&framed);
    let mut answered = None;
    for frame in host.steps(5) {
        if let DeviceFrame::Reply(reply) = frame {
            answered = Some(reply);
        }
    }
    let reply = answered.unwrap();
    assert_eq!(
        (reply.request_id, reply.result),
        (0x2A, Err(ErrorCode::UnknownCommand))
    );
    host.send_bytes(&[0xFF; 300]);
    host.send_bytes(&[0x00, 0x01, 0x02, 0x00]);
    host.samples.clear();
    host.steps(20);
    assert!(host.samples.len() >= 18);
    assert!(matches!(
        host.request(Command::Info),
        Ok(ReplyPayload::Info(_))
    ));
}

fn calibration_records(host: &mut Host) -> Vec<TaxelCalibrationRecord> {
    (0..4)
        .map(|taxel_index| {
            match host.request(Command::ReadCalibration {
                pad: wire::PadIndex::default(),
                taxel_index,
            }) {
                Ok(ReplyPayload::Calibration(record)) => record,
                other => panic!("{other:?}"),
            }
        })
        .collect()
}

/// One default calibration: a board with erased flash, RestoreDefaults and the host all mean
/// model-core's `Calibration::default()`; the simulated pad's own curve comes from its flash.
#[test]
fn the_built_in_default_is_one_calibration_and_the_factory_one_is_in_flash() {
    let defaults = model_core::Calibration::default();
    let expected: Vec<TaxelCalibrationRecord> = (0..4)
        .map(|taxel| {
            device::calibration_record(&defaults, wire::PadIndex::default(), taxel).unwrap()
        })
        .collect();

    let mut host = Host::new();
    assert_eq!(host.info().calibration_source, CalibrationSource::Flash);
    assert_ne!(calibration_records(&mut host), expected);
    assert_eq!(
        host.request(Command::RestoreDefaults),
        Ok(ReplyPayload::Ack)
    );
    assert_eq!(calibration_records(&mut host), expected);

    let mut blank = Host::new();
    blank.device = SimulatedDevice::with_blank_flash(
        SimulatedDeviceConfig::new(SceneFile::default_scene().unwrap(), 1).with_seed(9),
    )
    .unwrap();
    blank.steps(20);
    assert_eq!(blank.info().calibration_source, CalibrationSource::Defaults);
    assert_eq!(calibration_records(&mut blank), expected);
}

fn baselines(host: &mut Host) -> Vec<Option<wire::BaselineWire>> {
    (0..4)
        .map(|taxel_index| {
            match host.request(Command::ReadBaseline {
                pad: wire::PadIndex::default(),
                taxel_index,
            }) {
                Ok(ReplyPayload::Baseline(reply)) => {
                    assert_eq!(reply.taxel_index, taxel_index);
                    reply.baseline
                }
                other => panic!("{other:?}"),
            }
        })
        .collect()
}

/// The boot tare and every later tare announce themselves with TareFinished, before the first
/// sample that uses them, and ReadBaseline returns what the model uses.
#[test]
fn baselines_are_read_back_and_every_tare_is_announced() {
    let mut host = Host::new();
    let boot = baselines(&mut host);
    assert!(boot.iter().all(Option::is_some), "{boot:?}");
    let model: Vec<Option<wire::BaselineWire>> = host
        .device
        .device_mut()
        .control()
        .pad(0)
        .unwrap()
        .baseline_records()
        .iter()
        .map(|record| record.as_ref().map(device::baseline_wire))
        .collect();
    assert_eq!(boot, model);
    assert_eq!(
        host.request(Command::ReadBaseline {
            pad: wire::PadIndex::default(),
            taxel_index: 4
        }),
        Err(ErrorCode::InvalidArgument)
    );

    // The demo scene is still before 3 s: a new tare succeeds and is announced.
    assert_eq!(
        host.request(Command::Tare {
            sample_sets: 8,
            pad: None
        }),
        Ok(ReplyPayload::Ack)
    );
    let mut announced = false;
    let mut encoded = [0u8; 64];
    let length = wire::encode_frame(
        &Request {
            request_id: 600,
            command: Command::Tare {
                sample_sets: 4,
                pad: None,
            },
        },
        &mut encoded,
    )
    .unwrap();
    host.send_bytes(&encoded[..length]);
    let mut event_then_sample = false;
    for _ in 0..50 {
        for frame in host.steps(1) {
            match frame {
                DeviceFrame::Event(EventFrame {
                    event: DeviceEvent::TareFinished { tared_mask, pad },
                    ..
                }) => {
                    assert_eq!((pad.get(), tared_mask), (0, 0b1111));
                    announced = true;
                }
                DeviceFrame::Sample(_) if announced => event_then_sample = true,
                _ => {}
            }
        }
    }
    assert!(announced && event_then_sample);
    let after = baselines(&mut host);
    assert_ne!(after, boot, "a new tare gives new baselines");
}

/// A calibration has one id: every WriteCalibration replaces it, Info reports it, and
/// ReadCalibration returns it for every taxel (PROTOCOL.md 5.1).
#[test]
fn the_calibration_id_is_the_last_one_written_for_every_taxel() {
    let mut host = Host::new();
    let mut records = calibration_records(&mut host);
    records[0].calibration_id = 5;
    records[1].calibration_id = 6;
    for record in &records[..2] {
        assert_eq!(
            host.request(Command::WriteCalibration(record.clone())),
            Ok(ReplyPayload::Ack)
        );
    }
    assert_eq!(host.info().calibration_id, 6);
    for record in calibration_records(&mut host) {
        assert_eq!(record.calibration_id, 6);
    }
}

/// `dropped_sample_frames` counts exactly the sample frames produced while streaming that were
/// not sent (here: a host that never reads fills the output queue) — one per pad per set, so a
/// device of 3 pads counts 3 for a set it could not send; frames of other kinds that were
/// dropped are not in it.
#[test]
fn dropped_sample_frames_counts_the_sample_frames_that_were_not_sent() {
    for pads in [1u32, 3] {
        dropped_frames_of_pads(pads);
    }
}

fn dropped_frames_of_pads(pads: u32) {
    let mut device = SimulatedDevice::new(
        SimulatedDeviceConfig::new(SceneFile::default_scene().unwrap(), pads as usize).with_seed(4),
    )
    .unwrap();
    let mut port = MemoryPort::new(2_000);
    let steps = 300u32;
    for _ in 0..steps {
        device.step(&mut port);
    }
    let counters = device.device_mut().host_counters();
    let bytes = port.take_for_host(usize::MAX);
    let mut decoder = DeviceFrameDecoder::new();
    let samples: Vec<SampleFrame> = decoder
        .feed(&bytes)
        .flatten()
        .filter_map(|frame| match frame {
            DeviceFrame::Sample(sample) => Some(sample),
            _ => None,
        })
        .collect();
    assert!(counters.sample_frames_dropped > 200, "{counters:?}");
    // A step is one sample set of every pad: each pad's frame is in the port or counted.
    assert_eq!(
        samples.len() as u32 + counters.sample_frames_dropped,
        steps * pads,
        "{pads} pads: every frame is either in the port or counted"
    );
    assert!(counters.frames_dropped_no_host > counters.sample_frames_dropped);
    let control = device.device_mut().control();
    let frame = device::counters_frame(&control.counters(), &counters);
    assert_eq!(frame.dropped_sample_frames, counters.sample_frames_dropped);
}
