//! The hex examples in docs/PROTOCOL.md are the encoder's real output: each example's payload
//! (before COBS) and frame (on the wire) blocks are compared with what this crate produces, and
//! the frame is decoded back with an independent COBS decoder written from the document.

mod common;

use common::*;
use wire::{
    Command, DeviceFrame, ErrorCode, ReplyFrame, ReplyPayload, Request, TaxelCalibrationRecord,
    TaxelCalibrationWire, WireMessage,
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
                command: Command::SetRate { rate_sps: 200 },
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
        ("sample", encode(&DeviceFrame::Sample(example_sample()))),
        (
            "request-write-calibration",
            encode(&Request {
                request_id: 4,
                command: Command::WriteCalibration(TaxelCalibrationRecord {
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
