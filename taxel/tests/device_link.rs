//! The device link over in-memory streams: decoding with garbage between frames, request and
//! reply matching, timeouts, refusals, the calibration upload, and recording to CSV.
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use std::time::Duration;

use model_core::{Calibration, CalibrationSpec, CurvePoint};
use support::{ack, encoded, sample, ChunkedReader, FakeDevice};
use taxel_host::calibration_transfer::upload;
use taxel_host::device_link::{DeviceLink, FrameReceiver, LinkError, RequestError};
use taxel_host::host_clock::UnixClock;
use taxel_host::pad_set::PadSet;
use taxel_host::recorder::{Recorder, RecordingPaths};
use taxel_host::session::SessionEvent;
use taxel_host::worker::{ArrivedEvent, WorkerEvent};
use wire::{
    Command, CountersFrame, DecodeError, DeviceEvent, DeviceFrame, ErrorCode, EventFrame,
    ReplyFrame, ReplyPayload, SampleRate, TemperatureSource, Tier,
};

fn frames_with_garbage() -> (Vec<DeviceFrame>, Vec<u8>, u64) {
    let frames = vec![
        DeviceFrame::Sample(sample(
            1,
            1_000,
            [
                (Some(12.5), 4.75, 0),
                (None, -0.25, 0x0005),
                (Some(0.0), 4.5, 0),
                (Some(1.0), 4.6, 0x0001),
            ],
        )),
        DeviceFrame::Event(EventFrame {
            timestamp_us: 1_500,
            event: DeviceEvent::TemperatureSourceChanged {
                pad: wire::PadIndex::default(),
                source: TemperatureSource::McuInternal,
            },
        }),
        DeviceFrame::Counters(CountersFrame {
            dropped_sample_frames: 2,
            ..CountersFrame::default()
        }),
        DeviceFrame::Sample(sample(2, 6_000, [(Some(3.0), 4.7, 0); 4])),
        DeviceFrame::Sample(sample(4, 16_000, [(None, 0.2, 0x0008); 4])),
    ];
    let mut corrupted = encoded(&frames[0]);
    corrupted[10] ^= 0x40;
    let truncated = encoded(&frames[3])[..20].to_vec();
    let mut bytes = Vec::new();
    let mut bad_chunks = 0;
    bytes.extend(b"hello from a terminal\r\n\0");
    bad_chunks += 1;
    bytes.extend(encoded(&frames[0]));
    bytes.extend(&corrupted);
    bad_chunks += 1;
    bytes.extend(encoded(&frames[1]));
    bytes.extend([0, 0, 0]);
    bytes.extend(encoded(&frames[2]));
    bytes.extend(&truncated);
    bytes.push(0);
    bad_chunks += 1;
    bytes.extend(encoded(&frames[3]));
    bytes.extend([0xAB; 400]);
    bytes.push(0);
    bad_chunks += 1;
    bytes.extend(encoded(&frames[4]));
    (frames, bytes, bad_chunks)
}

#[test]
fn decodes_every_intact_frame_between_garbage_in_any_chunking() {
    let (frames, bytes, bad_chunks) = frames_with_garbage();
    for chunk_sizes in [vec![1], vec![7, 3, 64], vec![4096]] {
        let reader = ChunkedReader::new(bytes.clone(), chunk_sizes.clone());
        let mut link = DeviceLink::new(reader);
        let mut received = Vec::new();
        let end = loop {
            match link.next_frame() {
                Ok(Some(frame)) => received.push(frame),
                Ok(None) => {}
                Err(error) => break error,
            }
        };
        assert!(matches!(end, LinkError::Disconnected), "{end:?}");
        assert_eq!(received, frames, "chunks {chunk_sizes:?}");
        let statistics = link.statistics();
        assert_eq!(statistics.frames_decoded, frames.len() as u64);
        assert_eq!(statistics.frames_rejected, bad_chunks);
        assert_eq!(statistics.bytes_received, bytes.len() as u64);
        let good_bytes: u64 = frames.iter().map(|frame| encoded(frame).len() as u64).sum();
        // Every byte is in a decoded frame, a rejected frame, or one of the three lone delimiters.
        assert_eq!(
            statistics.bytes_rejected + 3,
            bytes.len() as u64 - good_bytes
        );
    }
}

#[test]
fn receiver_reports_the_decode_error_and_a_trailing_partial_frame() {
    let frame = DeviceFrame::Sample(sample(9, 9, [(Some(1.0), 4.5, 0); 4]));
    let mut corrupted = encoded(&frame);
    // 23.5 °C is 0x41BC0000: flipping a bit of its 0xBC byte leaves valid COBS and breaks the CRC.
    let temperature_byte = corrupted.iter().position(|&byte| byte == 0xBC).unwrap();
    corrupted[temperature_byte] ^= 0x01;
    let mut receiver = FrameReceiver::new();
    let mut frames = Vec::new();
    receiver.push_bytes(&corrupted, &mut frames);
    assert!(frames.is_empty());
    assert_eq!(receiver.statistics().last_error, Some(DecodeError::Crc));
    receiver.push_bytes(&encoded(&frame)[..10], &mut frames);
    receiver.finish();
    assert_eq!(receiver.statistics().frames_rejected, 2);
    assert_eq!(
        receiver.statistics().bytes_rejected,
        corrupted.len() as u64 + 10
    );
}

#[test]
fn request_waits_for_its_own_reply_and_keeps_other_frames_in_order() {
    let device = FakeDevice::new(Box::new(|request| {
        vec![
            DeviceFrame::Sample(sample(1, 10, [(Some(1.0), 4.5, 0); 4])),
            DeviceFrame::Reply(ReplyFrame {
                request_id: request.request_id.wrapping_add(100),
                result: Ok(ReplyPayload::Ack),
            }),
            DeviceFrame::Sample(sample(2, 20, [(Some(2.0), 4.5, 0); 4])),
            DeviceFrame::Reply(ReplyFrame {
                request_id: request.request_id,
                result: Ok(ReplyPayload::ModelTier(Tier::Saturating)),
            }),
            DeviceFrame::Sample(sample(3, 30, [(Some(3.0), 4.5, 0); 4])),
        ]
    }));
    let mut link = DeviceLink::new(device);
    let use_case = wire::UseCase {
        pressure_max_kpa: 40.0,
        temperature_min_c: 10.0,
        temperature_max_c: 40.0,
        error_budget_kpa: 0.5,
    };
    let reply = link
        .request(Command::SetUseCase(use_case), Duration::from_secs(5))
        .unwrap();
    assert_eq!(reply, ReplyPayload::ModelTier(Tier::Saturating));
    let mut sequences = Vec::new();
    let mut other_replies = 0;
    while let Ok(Some(frame)) = link.next_frame() {
        match frame {
            DeviceFrame::Sample(sample) => sequences.push(sample.sequence),
            DeviceFrame::Reply(_) => other_replies += 1,
            other => panic!("unexpected {other:?}"),
        }
    }
    assert_eq!(sequences, [1, 2, 3]);
    assert_eq!(other_replies, 1);
    let requests = &link.port().requests;
    assert_eq!(requests.len(), 1);
    assert_eq!(requests[0].command, Command::SetUseCase(use_case));
}

#[test]
fn refusal_and_silence_are_told_apart() {
    let device = FakeDevice::new(Box::new(|request| match request.command {
        Command::SetRate { .. } => vec![DeviceFrame::Reply(ReplyFrame {
            request_id: request.request_id,
            result: Err(ErrorCode::InvalidArgument),
        })],
        _ => Vec::new(),
    }));
    let mut link = DeviceLink::new(device);
    let refused = link.request(
        Command::SetRate {
            rate: SampleRate::Sps200,
        },
        Duration::from_secs(5),
    );
    assert!(matches!(
        refused,
        Err(RequestError::Refused(ErrorCode::InvalidArgument))
    ));
    let silent = link.request(Command::ReadCounters, Duration::from_millis(20));
    assert!(
        matches!(silent, Err(RequestError::Timeout { request_id: 2, .. })),
        "{silent:?}"
    );
}

fn calibration_with_distinct_taxels() -> Calibration {
    let mut spec = CalibrationSpec {
        id: 42,
        ..CalibrationSpec::default()
    };
    for (taxel, taxel_spec) in spec.taxels.iter_mut().enumerate() {
        let gain = 1.0 + 0.1 * taxel as f32;
        taxel_spec.points = model_core::ARTICLE_TABLE_1
            .iter()
            .map(|point| CurvePoint::new(point.pressure_kpa, point.relative_change * gain))
            .collect();
        taxel_spec.parasitic_pf = 0.5 * taxel as f32;
    }
    Calibration::new(&spec).unwrap()
}

#[test]
fn upload_writes_every_taxel_then_saves() {
    let calibration = calibration_with_distinct_taxels();
    let device = FakeDevice::new(Box::new(|request| vec![ack(request)]));
    let mut link = DeviceLink::new(device);
    // The fake device answers every request with Ack: its pad count is given, not asked for.
    link.set_pad_count(1);
    let mut messages = Vec::new();
    upload(
        &mut link,
        &calibration,
        true,
        Duration::from_secs(5),
        &mut |message| messages.push(message.to_owned()),
    )
    .unwrap();
    let requests = &link.port().requests;
    assert_eq!(requests.len(), 5);
    for (taxel, request) in requests[..4].iter().enumerate() {
        let Command::WriteCalibration(record) = &request.command else {
            panic!("expected WriteCalibration, got {:?}", request.command);
        };
        assert_eq!(usize::from(record.taxel_index), taxel);
        assert_eq!(record.calibration_id, 42);
        assert_eq!(record.check(), Ok(()));
        let expected: Vec<(f32, f32)> = calibration.taxels()[taxel]
            .curve()
            .points()
            .iter()
            .map(|point| (point.pressure_kpa, point.relative_change))
            .collect();
        assert_eq!(record.calibration.points.as_slice(), expected.as_slice());
        assert_eq!(record.calibration.parasitic_pf, 0.5 * taxel as f32);
    }
    assert_eq!(requests[4].command, Command::SaveCalibration);
    let ids: Vec<u16> = requests.iter().map(|request| request.request_id).collect();
    assert_eq!(ids, [1, 2, 3, 4, 5]);
    assert_eq!(messages.len(), 5);
}

#[test]
fn upload_stops_at_the_first_refusal() {
    let calibration = calibration_with_distinct_taxels();
    let device = FakeDevice::new(Box::new(|request| match &request.command {
        Command::WriteCalibration(record) if record.taxel_index == 2 => {
            vec![DeviceFrame::Reply(ReplyFrame {
                request_id: request.request_id,
                result: Err(ErrorCode::InvalidArgument),
            })]
        }
        _ => vec![ack(request)],
    }));
    let mut link = DeviceLink::new(device);
    link.set_pad_count(1);
    let error = upload(
        &mut link,
        &calibration,
        true,
        Duration::from_secs(5),
        &mut |_| {},
    )
    .unwrap_err();
    let text = format!("{error:#}");
    assert!(text.contains("taxel c21"), "{text}");
    assert!(text.contains("InvalidArgument"), "{text}");
    assert_eq!(link.port().requests.len(), 3);
}

/// Worker events of one device: sets 1, 2 and 4 of one pad (3 was lost), then its end.
fn recorded_events() -> Vec<ArrivedEvent> {
    let set = |sequence: u32, arrival_us: u64| ArrivedEvent {
        device: 0,
        arrival_us,
        event: WorkerEvent::Session(SessionEvent::Set {
            set: PadSet {
                sequence,
                pads: vec![Some(support::sample(
                    sequence,
                    u64::from(sequence) * 10_000,
                    [
                        (Some(12.5), 4.75, 0),
                        (None, 4.5, 4),
                        (Some(0.0), 4.5, 0),
                        (Some(1.0), 4.6, 0),
                    ],
                ))],
            },
            sets_missing_before: u64::from(sequence == 4),
        }),
    };
    vec![set(1, 100), set(2, 200), set(4, 400)]
}

#[test]
fn the_recorder_writes_every_set_it_is_given_in_the_schema() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("rec.csv");
    let paths = RecordingPaths {
        csv: Some(path.clone()),
        mcap: None,
    };
    let mut recorder = Recorder::create(paths, 1, UnixClock::new(), None).unwrap();
    for event in recorded_events() {
        recorder.take(event).unwrap();
    }
    let summary = recorder.finish().unwrap();
    assert_eq!(summary.devices[0].sets, 3);
    assert_eq!(
        summary.devices[0].stamped_at_arrival, 3,
        "no clock estimate from three sets"
    );
    let text = std::fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], taxel_host::schema::header().join(","));
    let sequences: Vec<&str> = lines[1..]
        .iter()
        .map(|line| line.split(',').nth(3).unwrap())
        .collect();
    assert_eq!(sequences, ["1", "2", "4"]);
    let cells: Vec<&str> = lines[1].split(',').collect();
    assert_eq!(
        &cells[8..20],
        ["4.75", "4.5", "4.5", "4.6", "12.5", "", "0", "1", "", "shorted", "", ""]
    );
    assert_eq!(cells[5], "", "stamped at its arrival: no sync error");
}

#[test]
fn a_full_disk_stops_the_recording_with_an_error_naming_the_file() {
    let paths = RecordingPaths {
        csv: Some(std::path::PathBuf::from("/dev/full")),
        mcap: None,
    };
    let mut recorder = Recorder::create(paths, 1, UnixClock::new(), None).unwrap();
    let mut result = Ok(());
    for event in recorded_events().into_iter().cycle().take(10_000) {
        result = recorder.take(event).and_then(|()| recorder.flush());
        if result.is_err() {
            break;
        }
    }
    let text = format!("{:#}", result.unwrap_err());
    assert!(text.contains("writing the CSV"), "{text}");
    assert!(text.to_lowercase().contains("no space"), "{text}");
}

/// A fresh link asks the device how many pads it has, and the calibration goes to every pad.
#[test]
fn upload_asks_for_the_pad_count_and_writes_every_pad() {
    let calibration = calibration_with_distinct_taxels();
    let device = FakeDevice::new(Box::new(|request| match &request.command {
        Command::Info => vec![DeviceFrame::Reply(ReplyFrame {
            request_id: request.request_id,
            result: Ok(ReplyPayload::Info(support::info(2))),
        })],
        _ => vec![ack(request)],
    }));
    let mut link = DeviceLink::new(device);
    upload(
        &mut link,
        &calibration,
        false,
        Duration::from_secs(5),
        &mut |_| {},
    )
    .unwrap();
    let pads: Vec<u8> = link
        .port()
        .requests
        .iter()
        .filter_map(|request| match &request.command {
            Command::WriteCalibration(record) => Some(record.pad.get()),
            _ => None,
        })
        .collect();
    assert_eq!(pads, [0, 0, 0, 0, 1, 1, 1, 1]);
}
