//! The command set: discriminants fixed by the protocol document, and the argument checks the
//! device applies before acting.

mod common;

use common::*;
use wire::{
    decode_frame, Command, DecodeError, ErrorCode, PadIndex, Request, RequestDecoder, SampleRate,
    TaxelCalibrationRecord, TaxelCalibrationWire, Tier, UseCase, COMMAND_COUNT, PROTOCOL_VERSION,
};

fn use_case() -> UseCase {
    UseCase {
        pressure_max_kpa: 50.0,
        temperature_min_c: 15.0,
        temperature_max_c: 35.0,
        error_budget_kpa: 0.5,
    }
}

fn record(points: &[(f32, f32)]) -> TaxelCalibrationRecord {
    TaxelCalibrationRecord {
        pad: pad(2),
        taxel_index: 3,
        calibration_id: 42,
        calibration: TaxelCalibrationWire {
            points: points.iter().copied().collect(),
            parasitic_pf: 1.5,
            unloaded_sensor_pf: Some(4.5),
        },
    }
}

const TABLE_1: [(f32, f32); 6] = [
    (0.0, 0.0),
    (10.0, 0.0829),
    (20.0, 0.1475),
    (30.0, 0.1981),
    (40.0, 0.2317),
    (50.0, 0.2563),
];

#[test]
fn command_discriminants_are_the_documented_ones() {
    let commands = [
        Command::Info,
        Command::ReadCounters,
        Command::StartStreaming,
        Command::StopStreaming,
        Command::SetRate {
            rate: SampleRate::Sps100,
        },
        Command::Tare {
            sample_sets: 1,
            pad: None,
        },
        Command::SetModelTier { tier: Tier::Linear },
        Command::SetUseCase(use_case()),
        Command::ReadCalibration {
            pad: PadIndex::default(),
            taxel_index: 0,
        },
        Command::WriteCalibration(record(&TABLE_1)),
        Command::SaveCalibration,
        Command::RestoreDefaults,
        Command::SetTextMode { enabled: true },
        Command::ReadBaseline {
            pad: PadIndex::default(),
            taxel_index: 0,
        },
        Command::PadInfo {
            pad: PadIndex::default(),
        },
        Command::SetPadGeometry(wire::PadGeometryRecord {
            pad: PadIndex::default(),
            role: wire::PadRole::Palm,
            taxels: *wire::PadGeometry::ARTICLE.taxels(),
        }),
    ];
    assert_eq!(commands.len() as u32, COMMAND_COUNT);
    for (discriminant, command) in commands.into_iter().enumerate() {
        let request = Request {
            request_id: 5,
            command,
        };
        let frame = encode(&request);
        let mut payload = frame.clone();
        // decode in place leaves the payload at the start of the buffer
        let decoded: Request = decode_frame(&mut payload).unwrap();
        assert_eq!(decoded, request);
        assert_eq!(payload[0], wire::PROTOCOL_VERSION);
        assert_eq!(payload[1], wire::kind::REQUEST);
        assert_eq!(payload[2], 5, "request id");
        assert_eq!(
            usize::from(payload[3]),
            discriminant,
            "{:?}",
            request.command
        );
    }
}

/// The taxel calibration record as PROTOCOL.md 6.2 lays it out: pad (version 3), taxel, id,
/// points, parasitic, then (since version 2) the unloaded capacitance as an option: `01` and the
/// f32, or `00`.
#[test]
fn the_calibration_record_ends_with_the_optional_unloaded_capacitance() {
    for unloaded_sensor_pf in [Some(4.5f32), None] {
        let mut written = record(&TABLE_1[..2]);
        written.calibration.unloaded_sensor_pf = unloaded_sensor_pf;
        let request = Request {
            request_id: 5,
            command: Command::WriteCalibration(written),
        };
        let mut payload = encode(&request);
        let decoded: Request = decode_frame(&mut payload).unwrap();
        assert_eq!(decoded, request);
        let mut expected = vec![
            wire::PROTOCOL_VERSION,
            wire::kind::REQUEST,
            5,
            9,
            2,
            3,
            42,
            2,
        ];
        for value in [0.0f32, 0.0, 10.0, 0.0829, 1.5] {
            expected.extend_from_slice(&value.to_le_bytes());
        }
        match unloaded_sensor_pf {
            Some(unloaded_pf) => {
                expected.push(1);
                expected.extend_from_slice(&unloaded_pf.to_le_bytes());
            }
            None => expected.push(0),
        }
        expected.extend_from_slice(&wire::crc16(&expected).to_le_bytes());
        assert_eq!(payload[..expected.len()], expected[..]);
    }
}

/// The request `id 5`, then `command`, then `argument` as a postcard varint, as a host of
/// another implementation could send it.
fn request_with_varint(command: u8, argument: u32) -> Result<Request, DecodeError> {
    let mut body = vec![5, command];
    let mut value = argument;
    loop {
        let byte = (value & 0x7F) as u8;
        value >>= 7;
        if value == 0 {
            body.push(byte);
            break;
        }
        body.push(byte | 0x80);
    }
    let frame = raw_frame(PROTOCOL_VERSION, wire::kind::REQUEST, &body);
    let mut decoder = RequestDecoder::new();
    let mut results: Vec<_> = decoder.feed(&frame).collect();
    assert_eq!(results.len(), 1);
    results.remove(0)
}

/// A request of `command` with `argument` decodes to `expected`, or, when that is `None`, is
/// refused where it is decoded with the error the device replies: InvalidArgument.
fn assert_decodes_to(command: u8, argument: u32, expected: Option<Command>) {
    let decoded = request_with_varint(command, argument);
    match expected {
        Some(command) => assert_eq!(
            decoded,
            Ok(Request {
                request_id: 5,
                command
            })
        ),
        None => assert_eq!(
            decoded,
            Err(DecodeError::InvalidRequest {
                request_id: 5,
                error: ErrorCode::InvalidArgument
            }),
            "command {command}, argument {argument}"
        ),
    }
}

#[test]
fn only_100_200_and_400_samples_per_second_are_rates() {
    for rate_sps in 0..=u16::MAX {
        let supported = matches!(rate_sps, 100 | 200 | 400);
        assert_eq!(SampleRate::from_sps(rate_sps).is_some(), supported);
        // SetRate is command 4; any other number is refused where it is decoded, with the
        // error the device replies.
        assert_decodes_to(
            4,
            u32::from(rate_sps),
            SampleRate::from_sps(rate_sps).map(|rate| Command::SetRate { rate }),
        );
    }
    for rate in [SampleRate::Sps100, SampleRate::Sps200, SampleRate::Sps400] {
        assert_eq!(SampleRate::from_sps(rate.sps()), Some(rate));
    }
}

#[test]
fn arguments_out_of_range_are_invalid() {
    let invalid = Err(ErrorCode::InvalidArgument);
    for pad in [None, PadIndex::new(7)] {
        assert_eq!(
            Command::Tare {
                sample_sets: 0,
                pad
            }
            .check_arguments(),
            invalid
        );
        assert_eq!(
            Command::Tare {
                sample_sets: 1,
                pad
            }
            .check_arguments(),
            Ok(())
        );
    }
    assert_eq!(
        Command::ReadCalibration {
            pad: PadIndex::default(),
            taxel_index: 3
        }
        .check_arguments(),
        Ok(())
    );
    assert_eq!(
        Command::ReadCalibration {
            pad: PadIndex::default(),
            taxel_index: 4
        }
        .check_arguments(),
        invalid
    );
    let geometry = |taxels| {
        Command::SetPadGeometry(wire::PadGeometryRecord {
            pad: PadIndex::default(),
            role: wire::PadRole::Fingertip,
            taxels,
        })
    };
    let article = *wire::PadGeometry::ARTICLE.taxels();
    assert_eq!(geometry(article).check_arguments(), Ok(()));
    let mut zero_area = article;
    zero_area[2].area_mm2 = 0.0;
    let mut same_place = article;
    same_place[1] = same_place[0];
    let mut not_finite = article;
    not_finite[3].x_mm = f32::NAN;
    for broken in [zero_area, same_place, not_finite] {
        assert_eq!(geometry(broken).check_arguments(), invalid, "{broken:?}");
    }
    assert_eq!(Command::SetUseCase(use_case()).check_arguments(), Ok(()));
    for broken in [
        UseCase {
            pressure_max_kpa: 0.0,
            ..use_case()
        },
        UseCase {
            pressure_max_kpa: f32::NAN,
            ..use_case()
        },
        UseCase {
            temperature_min_c: 35.0,
            ..use_case()
        },
        UseCase {
            temperature_max_c: f32::INFINITY,
            ..use_case()
        },
        UseCase {
            error_budget_kpa: -0.1,
            ..use_case()
        },
    ] {
        assert_eq!(
            Command::SetUseCase(broken).check_arguments(),
            invalid,
            "{broken:?}"
        );
    }
}

#[test]
fn calibration_writes_are_checked() {
    let invalid = Err(ErrorCode::InvalidArgument);
    assert_eq!(
        Command::WriteCalibration(record(&TABLE_1)).check_arguments(),
        Ok(())
    );
    assert_eq!(record(&TABLE_1[..2]).check(), Ok(()));
    assert_eq!(record(&TABLE_1[..1]).check(), invalid);
    assert_eq!(record(&[]).check(), invalid);

    let mut wrong_taxel = record(&TABLE_1);
    wrong_taxel.taxel_index = 4;
    assert_eq!(wrong_taxel.check(), invalid);

    let mut pressure_not_increasing = TABLE_1;
    pressure_not_increasing[3].0 = 20.0;
    assert_eq!(record(&pressure_not_increasing).check(), invalid);

    let mut change_not_increasing = TABLE_1;
    change_not_increasing[4].1 = 0.1;
    assert_eq!(record(&change_not_increasing).check(), invalid);

    let mut not_finite = TABLE_1;
    not_finite[5].1 = f32::NAN;
    assert_eq!(record(&not_finite).check(), invalid);

    let mut negative_parasitic = record(&TABLE_1);
    negative_parasitic.calibration.parasitic_pf = -1.0;
    assert_eq!(negative_parasitic.check(), invalid);

    for unloaded_pf in [0.0, -0.0, -4.5, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let mut bad_unloaded = record(&TABLE_1);
        bad_unloaded.calibration.unloaded_sensor_pf = Some(unloaded_pf);
        assert_eq!(bad_unloaded.check(), invalid, "{unloaded_pf}");
    }
    let mut no_unloaded = record(&TABLE_1);
    no_unloaded.calibration.unloaded_sensor_pf = None;
    assert_eq!(no_unloaded.check(), Ok(()));
}

#[test]
fn a_tier_is_one_of_the_ids_and_any_other_is_an_invalid_argument() {
    // SetModelTier is command 6.
    for id in 0..=u8::MAX {
        assert_decodes_to(
            6,
            u32::from(id),
            Tier::from_id(id).map(|tier| Command::SetModelTier { tier }),
        );
    }
}

#[test]
fn a_tare_names_its_pad_after_the_sample_sets_and_a_pad_above_7_is_an_invalid_argument() {
    // Tare (command 5), 300 sample sets (varint AC 02), then the pad as a postcard Option.
    let decode = |pad: &[u8]| {
        let mut body = vec![5u8, 5, 0xAC, 0x02];
        body.extend(pad);
        let frame = raw_frame(PROTOCOL_VERSION, wire::kind::REQUEST, &body);
        let mut decoder = RequestDecoder::new();
        let results: Vec<_> = decoder.feed(&frame).collect();
        results
    };
    let tare = |pad| {
        Ok(Request {
            request_id: 5,
            command: Command::Tare {
                sample_sets: 300,
                pad,
            },
        })
    };
    assert_eq!(decode(&[0]), [tare(None)]);
    assert_eq!(decode(&[1, 0]), [tare(PadIndex::new(0))]);
    assert_eq!(decode(&[1, 7]), [tare(PadIndex::new(7))]);
    let refused = |error| {
        [Err(DecodeError::InvalidRequest {
            request_id: 5,
            error,
        })]
    };
    assert_eq!(decode(&[1, 8]), refused(ErrorCode::InvalidArgument));
    // Not an Option tag, or the pad missing: the body is malformed (a version-5 tare had no pad).
    assert_eq!(decode(&[2, 0]), refused(ErrorCode::Malformed));
    assert_eq!(decode(&[1]), refused(ErrorCode::Malformed));
    assert_eq!(decode(&[]), refused(ErrorCode::Malformed));
}

#[test]
fn seventeen_points_that_fit_the_buffer_are_malformed_not_an_invalid_argument() {
    // WriteCalibration (command 9): taxel 0, calibration id 1, 17 points, parasitic 0 pF, no C0.
    let mut body = vec![5u8, 9, 0, 1, 17];
    for point in 0..17u8 {
        body.extend((f32::from(point) * 3.0).to_le_bytes());
        body.extend((f32::from(point) * 0.01).to_le_bytes());
    }
    body.extend(0.0f32.to_le_bytes());
    body.push(0);
    let frame = raw_frame(PROTOCOL_VERSION, wire::kind::REQUEST, &body);
    let mut decoder = RequestDecoder::new();
    let results: Vec<_> = decoder.feed(&frame).collect();
    assert_eq!(
        results,
        [Err(DecodeError::InvalidRequest {
            request_id: 5,
            error: ErrorCode::Malformed
        })]
    );
}

#[test]
fn commands_without_arguments_are_always_acceptable() {
    for command in [
        Command::Info,
        Command::ReadCounters,
        Command::StartStreaming,
        Command::StopStreaming,
        Command::SaveCalibration,
        Command::RestoreDefaults,
        Command::SetTextMode { enabled: false },
    ] {
        assert_eq!(command.check_arguments(), Ok(()));
    }
}
