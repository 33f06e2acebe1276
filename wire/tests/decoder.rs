//! The streaming decoder: resynchronisation after garbage, truncation, corruption, oversize
//! frames and future versions; specific errors for each kind of damage; no panic on any input.

mod common;

use common::*;
use proptest::prelude::*;
use wire::{
    kind, Command, DecodeError, DeviceFrame, DeviceFrameDecoder, ErrorCode, Frame, FrameDecoder,
    ReplyFrame, Request, RequestDecoder, SampleFrame, PROTOCOL_VERSION,
};

fn sample_bytes(sequence: u32) -> Vec<u8> {
    let mut sample = worst_case_sample();
    sample.sequence = sequence;
    sample.taxels[1].pressure_kpa = Some(12.5);
    encode(&DeviceFrame::Sample(sample))
}

fn sequence_of(result: &Result<DeviceFrame, DecodeError>) -> Option<u32> {
    match result {
        Ok(DeviceFrame::Sample(sample)) => Some(sample.sequence),
        _ => None,
    }
}

fn decode_all(bytes: &[u8]) -> Vec<Result<DeviceFrame, DecodeError>> {
    let mut decoder = DeviceFrameDecoder::new();
    decoder.feed(bytes).collect()
}

#[test]
fn consecutive_frames_decode_and_repeated_delimiters_are_ignored() {
    let mut stream = vec![0, 0, 0];
    stream.extend(sample_bytes(1));
    stream.extend([0, 0]);
    stream.extend(sample_bytes(2));
    stream.extend(sample_bytes(3));
    let sequences: Vec<_> = decode_all(&stream).iter().map(sequence_of).collect();
    assert_eq!(sequences, [Some(1), Some(2), Some(3)]);
}

#[test]
fn garbage_costs_one_error_then_frames_decode() {
    let garbage: Vec<u8> = (1..=200u8).map(|byte| byte.wrapping_mul(37) | 1).collect();
    let mut stream = garbage.clone();
    stream.push(0);
    stream.extend(sample_bytes(10));
    // Garbage glued to the front of a frame costs that frame too: one error, not two.
    stream.extend(&garbage[..20]);
    stream.extend(sample_bytes(11));
    stream.extend(sample_bytes(12));
    let results = decode_all(&stream);
    assert_eq!(results.len(), 4);
    assert!(results[0].is_err());
    assert_eq!(sequence_of(&results[1]), Some(10));
    assert!(results[2].is_err());
    assert_eq!(sequence_of(&results[3]), Some(12));
}

#[test]
fn a_frame_joined_mid_stream_or_with_lost_bytes_costs_only_itself() {
    let frame = sample_bytes(20);
    for cut in 1..frame.len() - 1 {
        // Port opened mid-frame: only the tail arrives.
        let mut stream = frame[cut..].to_vec();
        stream.extend(sample_bytes(21));
        let results = decode_all(&stream);
        assert_eq!(results.len(), 2, "cut at {cut}");
        assert!(
            results[0].is_err(),
            "tail from {cut} decoded: {:?}",
            results[0]
        );
        assert_eq!(sequence_of(&results[1]), Some(21));

        // One byte lost in the middle of a frame.
        let mut stream = frame.clone();
        stream.remove(cut);
        stream.extend(sample_bytes(22));
        let results = decode_all(&stream);
        assert_eq!(results.len(), 2, "byte {cut} lost");
        assert!(results[0].is_err(), "frame without byte {cut} decoded");
        assert_eq!(sequence_of(&results[1]), Some(22));
    }
}

#[test]
fn every_single_bit_flip_is_rejected_and_the_next_frame_decodes() {
    let frames = [
        sample_bytes(30),
        encode(&DeviceFrame::Info(worst_case_info())),
        encode(&DeviceFrame::Reply(worst_case_reply())),
    ];
    for frame in &frames {
        for byte_index in 0..frame.len() - 1 {
            for bit in 0..8 {
                let mut stream = frame.clone();
                stream[byte_index] ^= 1 << bit;
                stream.extend(sample_bytes(31));
                let results = decode_all(&stream);
                let (damaged, last) = results.split_at(results.len() - 1);
                assert!(
                    !damaged.is_empty() && damaged.iter().all(Result::is_err),
                    "flip of bit {bit} in byte {byte_index} not detected: {damaged:?}"
                );
                assert_eq!(sequence_of(&last[0]), Some(31));
            }
        }
    }
}

#[test]
fn a_corrupted_body_is_reported_as_a_crc_error() {
    let mut payload_frame = sample_bytes(40);
    // A data byte, neither a COBS code byte nor the delimiter: the first byte of the temperature
    // (f32::MIN, little-endian FF FF 7F FF, no zero in it or next to it).
    let index = payload_frame
        .windows(4)
        .position(|window| window == f32::MIN.to_le_bytes())
        .unwrap();
    payload_frame[index] ^= 0x10;
    let results = decode_all(&payload_frame);
    assert_eq!(results, [Err(DecodeError::Crc)]);
}

#[test]
fn a_future_version_is_reported_then_the_next_frame_decodes() {
    let future = raw_frame(PROTOCOL_VERSION + 1, kind::SAMPLE, &[0xAB; 70]);
    let mut stream = future.clone();
    stream.extend(sample_bytes(50));
    stream.extend(raw_frame(0xFF, 0xEE, &[]));
    stream.extend(sample_bytes(51));
    let results = decode_all(&stream);
    assert_eq!(results.len(), 4);
    assert_eq!(
        results[0],
        Err(DecodeError::UnsupportedVersion {
            found: PROTOCOL_VERSION + 1,
            supported: PROTOCOL_VERSION
        })
    );
    assert_eq!(sequence_of(&results[1]), Some(50));
    assert_eq!(
        results[2],
        Err(DecodeError::UnsupportedVersion {
            found: 0xFF,
            supported: PROTOCOL_VERSION
        })
    );
    assert_eq!(sequence_of(&results[3]), Some(51));
}

/// Version 1 carried the taxel calibration record without `unloaded_sensor_pf`. Its frames, the
/// calibration ones above all, are reported as version 1 rather than read in the version-2
/// layout, in either direction.
#[test]
fn version_1_calibration_frames_are_refused_by_version() {
    // WriteCalibration, request id 7, taxel 0, id 1, points (0, 0) and (10, 0.1), parasitic 0:
    // the version-1 body, which ends where version 2 expects the option tag.
    let mut body = vec![7, 9, 0, 1, 2];
    for value in [0.0f32, 0.0, 10.0, 0.1, 0.0] {
        body.extend_from_slice(&value.to_le_bytes());
    }
    let refused = Err(DecodeError::UnsupportedVersion {
        found: 1,
        supported: PROTOCOL_VERSION,
    });
    let mut decoder = RequestDecoder::new();
    let results: Vec<_> = decoder.feed(&raw_frame(1, kind::REQUEST, &body)).collect();
    assert_eq!(results, [refused]);
    // The same body as a version-2 frame is not a request this side can read either: it never
    // passes for a calibration without a C0.
    let results: Vec<_> = decoder
        .feed(&raw_frame(PROTOCOL_VERSION, kind::REQUEST, &body))
        .collect();
    assert!(
        matches!(
            results[..],
            [Err(DecodeError::InvalidRequest {
                request_id: 7,
                error: ErrorCode::Malformed
            })]
        ),
        "{results:?}"
    );
    // The calibration reply: request id 7, Ok, Calibration, then the same record.
    let mut reply = vec![7, 0, 3];
    reply.extend_from_slice(&body[2..]);
    let results = decode_all(&raw_frame(1, kind::REPLY, &reply));
    assert_eq!(
        results,
        [Err(DecodeError::UnsupportedVersion {
            found: 1,
            supported: PROTOCOL_VERSION
        })]
    );
}

#[test]
fn each_kind_of_damage_has_its_own_error() {
    assert_eq!(
        decode_all(&[0x02, 0x01, 0x00]),
        [Err(DecodeError::TooShort)]
    );
    assert_eq!(decode_all(&[0x05, 0x01, 0x00]), [Err(DecodeError::Cobs)]);
    assert_eq!(
        decode_all(&raw_frame(PROTOCOL_VERSION, 0x7F, &[1, 2, 3])),
        [Err(DecodeError::UnknownKind(0x7F))]
    );
    assert_eq!(
        decode_all(&raw_frame(PROTOCOL_VERSION, kind::COUNTERS, &[1, 2, 3])),
        [Err(DecodeError::Postcard(
            postcard::Error::DeserializeUnexpectedEnd
        ))]
    );
    assert_eq!(
        decode_all(&raw_frame(
            PROTOCOL_VERSION,
            kind::COUNTERS,
            &[0, 0, 0, 0, 0, 0, 9]
        )),
        [Err(DecodeError::TrailingBytes)]
    );
    // Status byte, then pad byte, with their reserved bit 7 set.
    for reserved in [0, 1] {
        let mut body = vec![0x00, 0x00];
        body[reserved] = 0x80;
        body.extend([0; 12]);
        body.extend([0; 4 * 6]);
        assert!(matches!(
            decode_all(&raw_frame(PROTOCOL_VERSION, kind::SAMPLE, &body))[..],
            [Err(DecodeError::Postcard(_))]
        ));
        body[reserved] = 0x00;
        assert!(matches!(
            decode_all(&raw_frame(PROTOCOL_VERSION, kind::SAMPLE, &body))[..],
            [Ok(DeviceFrame::Sample(_))]
        ));
    }
}

#[test]
fn an_oversized_frame_is_reported_once_then_the_next_frame_decodes() {
    let mut decoder = FrameDecoder::<80, DeviceFrame>::new();
    let mut stream = vec![0x55; 1000];
    stream.push(0);
    stream.extend(sample_bytes(60));
    let results: Vec<_> = decoder.feed(&stream).collect();
    assert_eq!(results.len(), 2);
    assert_eq!(results[0], Err(DecodeError::Overflow));
    assert_eq!(sequence_of(&results[1]), Some(60));

    // A frame of exactly the buffer size (without delimiter) is accepted.
    let frame = sample_bytes(61);
    const LEN: usize = SampleFrame::MAX_ENCODED_LEN - 1;
    assert_eq!(frame.len(), LEN + 1);
    let mut exact = FrameDecoder::<LEN, DeviceFrame>::new();
    let results: Vec<_> = exact.feed(&frame).collect();
    assert_eq!(sequence_of(&results[0]), Some(61));
    let mut short = FrameDecoder::<{ LEN - 1 }, DeviceFrame>::new();
    let results: Vec<_> = short.feed(&frame).collect();
    assert_eq!(results, [Err(DecodeError::Overflow)]);
}

fn request_results(bytes: &[u8]) -> Vec<Result<Request, DecodeError>> {
    let mut decoder = RequestDecoder::new();
    decoder.feed(bytes).collect()
}

#[test]
fn device_side_answers_requests_it_cannot_parse_when_the_id_is_known() {
    // request id 300 = varint AC 02; command discriminant 16 does not exist.
    let unknown = raw_frame(PROTOCOL_VERSION, kind::REQUEST, &[0xAC, 0x02, 16]);
    let results = request_results(&unknown);
    let expected = DecodeError::InvalidRequest {
        request_id: 300,
        error: ErrorCode::UnknownCommand,
    };
    assert_eq!(results, [Err(expected.clone())]);
    assert_eq!(
        expected.error_reply(),
        Some(DeviceFrame::Reply(ReplyFrame {
            request_id: 300,
            result: Err(ErrorCode::UnknownCommand)
        }))
    );

    // SetRate (discriminant 4) without its argument.
    let truncated = raw_frame(PROTOCOL_VERSION, kind::REQUEST, &[7, 4]);
    assert_eq!(
        request_results(&truncated),
        [Err(DecodeError::InvalidRequest {
            request_id: 7,
            error: ErrorCode::Malformed
        })]
    );

    // Info (discriminant 0) followed by a stray byte.
    let trailing = raw_frame(PROTOCOL_VERSION, kind::REQUEST, &[8, 0, 1]);
    assert_eq!(
        request_results(&trailing),
        [Err(DecodeError::InvalidRequest {
            request_id: 8,
            error: ErrorCode::Malformed
        })]
    );

    // SetTextMode (discriminant 12) with a bool of 2.
    let bad_bool = raw_frame(PROTOCOL_VERSION, kind::REQUEST, &[9, 12, 2]);
    assert_eq!(
        request_results(&bad_bool),
        [Err(DecodeError::InvalidRequest {
            request_id: 9,
            error: ErrorCode::Malformed
        })]
    );

    // No readable request id: nobody to answer, a counted drop.
    let empty = raw_frame(PROTOCOL_VERSION, kind::REQUEST, &[]);
    let results = request_results(&empty);
    assert!(matches!(results[..], [Err(DecodeError::Postcard(_))]));
    assert_eq!(
        results[0].as_ref().err().and_then(DecodeError::error_reply),
        None
    );

    // Damaged frames are never answered.
    assert_eq!(DecodeError::Crc.error_reply(), None);
    assert_eq!(DecodeError::UnknownKind(kind::SAMPLE).error_reply(), None);

    // And the decoder still works afterwards.
    let mut stream = unknown;
    stream.extend(encode(&Request {
        request_id: 301,
        command: Command::StartStreaming,
    }));
    let results = request_results(&stream);
    assert_eq!(
        results[1],
        Ok(Request {
            request_id: 301,
            command: Command::StartStreaming
        })
    );
}

#[test]
fn device_frames_sent_to_the_device_are_unknown_kinds() {
    let bytes = sample_bytes(70);
    assert_eq!(
        request_results(&bytes),
        [Err(DecodeError::UnknownKind(kind::SAMPLE))]
    );
}

proptest! {
    #![proptest_config(config(3000))]

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let mut any_direction = FrameDecoder::<{ wire::MAX_FRAME_ENCODED_LEN }, Frame>::new();
        let mut tiny = FrameDecoder::<3, DeviceFrame>::new();
        let mut requests = RequestDecoder::new();
        for &byte in &bytes {
            let _ = any_direction.push(byte);
            let _ = tiny.push(byte);
            if let Some(Err(error)) = requests.push(byte) {
                let _ = error.error_reply();
            }
        }
        let _ = wire::decode_frame::<Frame>(&mut bytes.clone());
    }

    #[test]
    fn random_bodies_with_valid_crc_never_panic(
        version in prop_oneof![Just(PROTOCOL_VERSION), any::<u8>()],
        kind_byte in prop_oneof![
            prop::sample::select(vec![
                kind::INFO, kind::SAMPLE, kind::COUNTERS, kind::REPLY, kind::EVENT, kind::REQUEST,
            ]),
            any::<u8>(),
        ],
        body in prop::collection::vec(any::<u8>(), 0..160),
    ) {
        let frame = raw_frame(version, kind_byte, &body);
        let mut decoder = FrameDecoder::<{ wire::MAX_FRAME_ENCODED_LEN }, Frame>::new();
        let results: Vec<_> = decoder.feed(&frame).collect();
        if frame.len() <= wire::MAX_FRAME_ENCODED_LEN {
            prop_assert_eq!(results.len(), 1);
            if version != PROTOCOL_VERSION {
                prop_assert_eq!(
                    &results[0],
                    &Err(DecodeError::UnsupportedVersion { found: version, supported: PROTOCOL_VERSION })
                );
            }
        }
    }

    #[test]
    fn valid_frames_survive_any_garbage_prefix(
        garbage in prop::collection::vec(any::<u8>(), 0..300),
        frame in device_frame(),
    ) {
        let mut stream = garbage;
        stream.push(0);
        let encoded = encode(&frame);
        stream.extend(&encoded);
        let mut decoder = DeviceFrameDecoder::new();
        let results: Vec<_> = decoder.feed(&stream).collect();
        let last = results.last().cloned().unwrap().unwrap();
        prop_assert_eq!(encode(&last), encoded);
    }
}
