//! The hex examples in docs/PROTOCOL.md are the encoder's real output: each example's payload
//! (before COBS) and frame (on the wire) blocks are compared with what this crate produces, and
//! the frame is decoded back with an independent COBS decoder written from the document.

// Test helpers may panic: a failure is the test failing.
#![allow(clippy::panic)]

mod common;

use common::*;
use wire::{
    Command, DeviceFrame, ErrorCode, PadIndex, ReplyFrame, ReplyPayload, Request, SampleRate,
    TaxelCalibrationRecord, TaxelCalibrationWire, Tier, WireMessage,
};

const PROTOCOL: &str = include_str!("../../docs/PROTOCOL.md");

/// The examples, by the name used in the document.
fn examples() -> Vec<(&'static str, Vec<u8>)> {
    vec![
        (
            "request-info",
            encode(&Request {
                request_id: 1,
                command: Command::Info,
            }),
        ),
        (
            "request-set-rate",
            encode(&Request {
                request_id: 2,
                command: Command::SetRate {
                    rate: SampleRate::Sps200,
                },
            }),
        ),
        (
            "reply-ack",
            encode(&DeviceFrame::Reply(ReplyFrame {
                request_id: 2,
                result: Ok(ReplyPayload::Ack),
            })),
        ),
        (
            "reply-error",
            encode(&DeviceFrame::Reply(ReplyFrame {
                request_id: 3,
                result: Err(ErrorCode::InvalidArgument),
            })),
        ),
        (
            "request-tare-pad",
            encode(&Request {
                request_id: 3,
                command: Command::Tare {
                    sample_sets: 64,
                    pad: Some(pad(1)),
                },
            }),
        ),
        ("sample", encode(&DeviceFrame::Sample(example_sample()))),
        (
            "request-write-calibration",
            encode(&Request {
                request_id: 4,
                command: Command::WriteCalibration(TaxelCalibrationRecord {
                    pad: pad(2),
                    taxel_index: 1,
                    calibration_id: 7,
                    calibration: TaxelCalibrationWire {
                        points: [(0.0, 0.0), (10.0, 0.0829)].into_iter().collect(),
                        parasitic_pf: 1.25,
                        unloaded_sensor_pf: Some(4.5),
                    },
                }),
            }),
        ),
    ]
}

/// COBS decoding as the document describes it, independent of the `cobs` crate.
fn reference_cobs_decode(frame: &[u8]) -> Vec<u8> {
    let encoded = &frame[..frame.len() - 1];
    let mut payload = Vec::new();
    let mut index = 0;
    while index < encoded.len() {
        let code = usize::from(encoded[index]);
        assert_ne!(code, 0);
        payload.extend_from_slice(&encoded[index + 1..index + code]);
        index += code;
        if code != 0xFF && index < encoded.len() {
            payload.push(0);
        }
    }
    payload
}

fn hex(bytes: &[u8]) -> String {
    bytes
        .iter()
        .map(|byte| format!("{byte:02X}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The hex bytes of the fenced block that follows `<!-- example NAME PART -->`.
fn document_block(name: &str, part: &str) -> Option<Vec<u8>> {
    let marker = format!("<!-- example {name} {part} -->");
    let after = &PROTOCOL[PROTOCOL.find(&marker)? + marker.len()..];
    let block = after.split("```").nth(1)?;
    let block = block.strip_prefix("text").unwrap_or(block);
    block
        .split_whitespace()
        .map(|token| u8::from_str_radix(token, 16).ok())
        .collect()
}

#[test]
fn document_examples_are_the_encoder_output() {
    let mut report = String::new();
    for (name, frame) in examples() {
        let payload = reference_cobs_decode(&frame);
        let crc_start = payload.len() - 2;
        assert_eq!(
            wire::crc16(&payload[..crc_start]).to_le_bytes(),
            payload[crc_start..]
        );
        assert_eq!(reference_cobs_encode(&payload), frame[..frame.len() - 1]);
        for (part, expected) in [("payload", &payload), ("frame", &frame)] {
            if document_block(name, part).as_ref() != Some(expected) {
                report.push_str(&format!("{name} {part}:\n{}\n", hex(expected)));
            }
        }
    }
    assert!(
        report.is_empty(),
        "docs/PROTOCOL.md differs; expected\n{report}"
    );
}

#[test]
fn document_crc_check_value_matches() {
    assert!(PROTOCOL.contains("CRC-16/IBM-SDLC"));
    assert!(PROTOCOL.contains("0x906E"));
    assert_eq!(wire::crc16(b"123456789"), 0x906E);
}

#[test]
fn document_states_the_longest_payload_of_this_version() {
    let sentence = format!("payload of this version is {} bytes", wire::MAX_PAYLOAD_LEN);
    assert!(
        PROTOCOL.replace('\n', " ").contains(&sentence),
        "docs/PROTOCOL.md section 2.1 should say: {sentence}"
    );
}

#[test]
fn document_kind_table_matches() {
    for (frame, kind) in [
        ("Info", wire::kind::INFO),
        ("Sample", wire::kind::SAMPLE),
        ("Counters", wire::kind::COUNTERS),
        ("Reply", wire::kind::REPLY),
        ("Event", wire::kind::EVENT),
        ("Request", wire::kind::REQUEST),
    ] {
        let row = format!("| `0x{kind:02X}` | {frame} |");
        assert!(PROTOCOL.contains(&row), "missing row {row}");
    }
    let request = Request {
        request_id: 0,
        command: Command::Info,
    };
    assert_eq!(request.kind(), wire::kind::REQUEST);
}

/// The number in the second column of the section-8 row whose first column is `frame`.
fn size_table_entry(frame: &str) -> usize {
    let row = format!("| {frame} | ");
    let line = PROTOCOL
        .lines()
        .find(|line| line.starts_with(&row))
        .unwrap_or_else(|| panic!("no size row {row}"));
    line[row.len()..]
        .split('|')
        .next()
        .and_then(|cell| cell.trim().parse().ok())
        .unwrap_or_else(|| panic!("no number in {line}"))
}

fn reply_len(request_id: u16, payload: ReplyPayload) -> usize {
    encode(&DeviceFrame::Reply(ReplyFrame {
        request_id,
        result: Ok(payload),
    }))
    .len()
}

#[test]
fn document_size_table_is_the_encoder_worst_case() {
    let other_replies = [
        reply_len(u16::MAX, ReplyPayload::Ack),
        encode(&DeviceFrame::Reply(ReplyFrame {
            request_id: u16::MAX,
            result: Err(ErrorCode::TareNotStill),
        }))
        .len(),
        reply_len(u16::MAX, ReplyPayload::Info(worst_case_info())),
        reply_len(u16::MAX, ReplyPayload::Counters(worst_case_counters())),
        reply_len(u16::MAX, ReplyPayload::ModelTier(Tier::Polynomial)),
        reply_len(u16::MAX, ReplyPayload::Baseline(worst_case_baseline())),
    ];
    let calibration = |points| {
        reply_len(
            u16::MAX,
            ReplyPayload::Calibration(calibration_record_with_points(points)),
        )
    };
    let rows = [
        (
            "Sample",
            encode(&DeviceFrame::Sample(worst_case_sample())).len(),
        ),
        ("Info", encode(&DeviceFrame::Info(worst_case_info())).len()),
        (
            "Counters",
            encode(&DeviceFrame::Counters(worst_case_counters())).len(),
        ),
        (
            "Event",
            encode(&DeviceFrame::Event(worst_case_event())).len(),
        ),
        (
            "Reply (Ack, error, Info, Counters, ModelTier, Baseline)",
            other_replies.into_iter().max().unwrap_or(0),
        ),
        (
            "Reply (PadInfo)",
            reply_len(u16::MAX, ReplyPayload::PadInfo(worst_case_pad_info())),
        ),
        ("Reply (Calibration, up to 4 points)", calibration(4)),
        ("Reply (Calibration, 5–16 points)", calibration(16)),
        (
            "Request (WriteCalibration with 16 points)",
            encode(&worst_case_request()).len(),
        ),
    ];
    for (frame, computed) in rows {
        assert_eq!(size_table_entry(frame), computed, "{frame}");
    }
}

/// Section 1.1's cases: a 5-point calibration with its C0, request id 3 and calibration id
/// 70 000 is exactly 64 bytes (13 points: 128), and its packets end with a zero-length packet;
/// the built-in 6-point default read with request id 1 is 66 bytes and needs none.
#[test]
fn calibration_replies_of_a_multiple_of_64_bytes_end_with_a_zero_length_packet() {
    let reply = |points: usize, unloaded_sensor_pf, request_id, calibration_id| {
        encode(&DeviceFrame::Reply(ReplyFrame {
            request_id,
            result: Ok(ReplyPayload::Calibration(TaxelCalibrationRecord {
                pad: PadIndex::default(),
                taxel_index: 0,
                calibration_id,
                calibration: TaxelCalibrationWire {
                    points: (0..points)
                        .map(|point| (10.0 * point as f32, 0.05 * point as f32))
                        .collect(),
                    parasitic_pf: 0.0,
                    unloaded_sensor_pf,
                },
            })),
        }))
    };
    let packets = |frame: &[u8]| {
        wire::usb_packets(frame)
            .map(<[u8]>::len)
            .collect::<Vec<_>>()
    };
    let five = reply(5, Some(4.5), 3, 70_000);
    assert_eq!(five.len(), 64);
    assert_eq!(packets(&five), [64, 0]);
    let thirteen = reply(13, Some(4.5), 3, 70_000);
    assert_eq!(thirteen.len(), 128);
    assert_eq!(packets(&thirteen), [64, 64, 0]);
    let default = reply(6, None, 1, 0);
    assert_eq!(default.len(), 66);
    assert_eq!(packets(&default), [64, 2]);
    assert!(PROTOCOL.contains("a 5-point calibration that records C0, with request id 3 "));
}

/// The sample example obeys the rules it illustrates: a faulted taxel has no pressure, and a
/// pressure is within [0, top of the calibration]; section 9's line is its text form.
#[test]
fn the_sample_example_obeys_the_document() {
    let sample = example_sample();
    for taxel in &sample.taxels {
        assert_eq!(
            taxel.pressure_kpa.is_some(),
            taxel.flags & wire::flags::FAULT_MASK == 0,
            "{taxel:?}"
        );
        if let Some(pressure_kpa) = taxel.pressure_kpa {
            assert!((0.0..=50.0).contains(&pressure_kpa), "{pressure_kpa}");
        }
    }
    let mut line = heapless::String::<{ wire::CSV_LINE_MAX_LEN }>::new();
    wire::format_csv_line(&sample, &mut line).unwrap();
    let marker = "<!-- example csv-line -->\n```text\n";
    let start = PROTOCOL.find(marker).unwrap() + marker.len();
    let documented = &PROTOCOL[start..start + PROTOCOL[start..].find('\n').unwrap()];
    assert_eq!(documented, line.trim_end());
}

/// Section 9's rule for text mode: at a boundary, a second byte of 03 starts a binary frame (to
/// the next 00), anything else a line (to the next newline).
#[test]
fn lines_and_frames_are_told_apart_by_the_documented_rule() {
    let mut line = heapless::String::<{ wire::CSV_LINE_MAX_LEN }>::new();
    wire::format_csv_line(&example_sample(), &mut line).unwrap();
    let reply = encode(&DeviceFrame::Reply(ReplyFrame {
        // Request id 10 is the byte 0A (newline) in the body.
        request_id: 10,
        result: Ok(ReplyPayload::ModelTier(Tier::Polynomial)),
    }));
    assert!(reply.contains(&b'\n'));
    let mut stream = Vec::new();
    stream.extend(wire::CSV_HEADER.as_bytes());
    stream.extend(b"\r\n");
    stream.extend(line.as_bytes());
    stream.extend(&reply);
    stream.extend(line.as_bytes());
    let (mut lines, mut frames, mut rest) = (Vec::new(), Vec::new(), stream.as_slice());
    while !rest.is_empty() {
        let end_byte = if rest.get(1) == Some(&wire::PROTOCOL_VERSION) {
            0x00
        } else {
            b'\n'
        };
        let end = rest.iter().position(|&byte| byte == end_byte).unwrap() + 1;
        let (chunk, tail) = rest.split_at(end);
        if end_byte == 0 {
            frames.push(chunk.to_vec());
        } else {
            lines.push(String::from_utf8(chunk.to_vec()).unwrap());
        }
        rest = tail;
    }
    assert_eq!(frames, [reply]);
    assert_eq!(lines.len(), 3);
    assert!(lines[0].starts_with("seq,") && lines[2] == line.as_str());
}
