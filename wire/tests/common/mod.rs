//! Shared test helpers: a deterministic proptest configuration, strategies for every message
//! type (floats drawn from every bit pattern, NaN and infinities included) and worst cases.
#![allow(dead_code)]
#![allow(
    clippy::unwrap_used,
    reason = "test helpers: a failure is a test failure"
)]

use core::fmt::Debug;

use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed};
use wire::{
    decode_frame, encode_frame, CalibrationSource, Command, CountersFrame, DeviceEvent,
    DeviceFrame, ErrorCode, EventFrame, FirmwareVersion, FrameDecoder, InfoFrame, PadIndex,
    PadSummary, ReplyFrame, ReplyPayload, Request, SampleFrame, SampleRate, TaxelCalibrationRecord,
    TaxelCalibrationWire, TaxelSample, TemperatureSource, Tier, UseCase, WireMessage,
    CALIBRATION_POINTS_MAX, MAX_FRAME_ENCODED_LEN,
};

/// A fixed seed and no regression files, so every run draws the same cases.
pub fn config(cases: u32) -> Config {
    Config {
        cases,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(0x7A8E_2024),
        failure_persistence: None,
        ..Config::default()
    }
}

/// Any f32 bit pattern, with the special values made frequent.
pub fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => any::<u32>().prop_map(f32::from_bits),
        1 => prop::sample::select(vec![
            f32::NAN,
            -f32::NAN,
            f32::from_bits(0x7F80_0001),
            f32::from_bits(0xFFBF_FFFF),
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.0,
            -0.0,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            f32::from_bits(1),
        ]),
    ]
}

pub fn temperature_source() -> impl Strategy<Value = TemperatureSource> {
    prop::sample::select(vec![
        TemperatureSource::None,
        TemperatureSource::Tmp117,
        TemperatureSource::McuInternal,
        TemperatureSource::LastKnown,
    ])
}

pub fn taxel_sample(float: BoxedStrategy<f32>) -> impl Strategy<Value = TaxelSample> {
    (prop::option::of(float.clone()), float, any::<u16>()).prop_map(
        |(pressure_kpa, capacitance_pf, flags)| TaxelSample {
            pressure_kpa,
            capacitance_pf,
            flags,
        },
    )
}

pub fn pad_summary(float: BoxedStrategy<f32>) -> impl Strategy<Value = PadSummary> {
    (
        prop::option::of(float.clone()),
        prop::option::of(prop::array::uniform2(float)),
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(
            |(force_n, centre_of_pressure_mm, partial, contact)| PadSummary {
                force_n,
                centre_of_pressure_mm,
                partial,
                contact,
            },
        )
}

/// Pad `index` (0..=7).
pub fn pad(index: u8) -> PadIndex {
    PadIndex::new(index).unwrap()
}

pub fn pad_index() -> impl Strategy<Value = PadIndex> {
    (0..=PadIndex::MAX).prop_map(|index| PadIndex::new(index).unwrap())
}

pub fn sample_frame_with(float: BoxedStrategy<f32>) -> impl Strategy<Value = SampleFrame> {
    (
        pad_index(),
        any::<u32>(),
        any::<u64>(),
        prop::option::of(float.clone()),
        temperature_source(),
        prop::array::uniform4(taxel_sample(float.clone())),
        pad_summary(float),
    )
        .prop_map(
            |(pad, sequence, timestamp_us, temperature_c, temperature_source, taxels, summary)| {
                SampleFrame {
                    pad,
                    sequence,
                    timestamp_us,
                    temperature_c,
                    temperature_source,
                    taxels,
                    summary,
                }
            },
        )
}

pub fn sample_frame() -> impl Strategy<Value = SampleFrame> {
    sample_frame_with(any_f32().boxed())
}

pub fn calibration_source() -> impl Strategy<Value = CalibrationSource> {
    prop::sample::select(vec![
        CalibrationSource::Flash,
        CalibrationSource::Defaults,
        CalibrationSource::DefaultsAfterCorruptFlash,
        CalibrationSource::Host,
    ])
}

pub fn info_frame() -> impl Strategy<Value = InfoFrame> {
    (
        any::<u8>(),
        any::<[u8; 3]>(),
        any::<[u8; 12]>(),
        any::<u32>(),
        calibration_source(),
        sample_rate(),
        tier(),
        any::<bool>(),
        any::<bool>(),
        any::<u8>(),
        any::<u32>(),
    )
        .prop_map(
            |(
                protocol_version,
                [major, minor, patch],
                board_serial,
                calibration_id,
                calibration_source,
                rate,
                model_tier,
                streaming,
                text_mode,
                pad_count,
                clock_us_per_s,
            )| InfoFrame {
                protocol_version,
                firmware_version: FirmwareVersion {
                    major,
                    minor,
                    patch,
                },
                board_serial,
                calibration_id,
                calibration_source,
                rate,
                model_tier,
                streaming,
                text_mode,
                pad_count,
                clock_us_per_s,
            },
        )
}

pub fn counters_frame() -> impl Strategy<Value = CountersFrame> {
    any::<[u32; 6]>().prop_map(|values| CountersFrame {
        dropped_sample_frames: values[0],
        converter_reinits: values[1],
        i2c_errors: values[2],
        temperature_sensor_errors: values[3],
        frames_dropped_no_host: values[4],
        host_frames_rejected: values[5],
    })
}

pub fn calibration() -> impl Strategy<Value = TaxelCalibrationWire> {
    (
        prop::collection::vec((any_f32(), any_f32()), 0..=CALIBRATION_POINTS_MAX),
        any_f32(),
        prop::option::of(any_f32()),
    )
        .prop_map(
            |(points, parasitic_pf, unloaded_sensor_pf)| TaxelCalibrationWire {
                points: points.into_iter().collect(),
                parasitic_pf,
                unloaded_sensor_pf,
            },
        )
}

pub fn calibration_record() -> impl Strategy<Value = TaxelCalibrationRecord> {
    (pad_index(), any::<u8>(), any::<u32>(), calibration()).prop_map(
        |(pad, taxel_index, calibration_id, calibration)| TaxelCalibrationRecord {
            pad,
            taxel_index,
            calibration_id,
            calibration,
        },
    )
}

pub fn error_code() -> impl Strategy<Value = ErrorCode> {
    prop::sample::select(vec![
        ErrorCode::UnknownCommand,
        ErrorCode::Malformed,
        ErrorCode::InvalidArgument,
        ErrorCode::Busy,
        ErrorCode::FlashError,
        ErrorCode::NotSupported,
        ErrorCode::TareFailed,
        ErrorCode::TareNotStill,
    ])
}

pub fn reply_payload() -> impl Strategy<Value = ReplyPayload> {
    prop_oneof![
        Just(ReplyPayload::Ack),
        info_frame().prop_map(ReplyPayload::Info),
        counters_frame().prop_map(ReplyPayload::Counters),
        calibration_record().prop_map(ReplyPayload::Calibration),
        tier().prop_map(ReplyPayload::ModelTier),
        pad_info().prop_map(ReplyPayload::PadInfo),
    ]
}

pub fn temperature_sensor() -> impl Strategy<Value = wire::TemperatureSensor> {
    prop_oneof![
        any::<u8>().prop_map(|address| wire::TemperatureSensor::OwnTmp117 { address }),
        any::<u8>().prop_map(|address| wire::TemperatureSensor::SharedTmp117 { address }),
        Just(wire::TemperatureSensor::DieOnly),
    ]
}

pub fn pad_info() -> impl Strategy<Value = wire::PadInfoFrame> {
    (
        pad_index(),
        proptest::option::of(any::<u8>()),
        temperature_sensor(),
        any::<u32>(),
        calibration_source(),
        tier(),
        pad_role(),
        taxel_geometries(any_f32().boxed()),
    )
        .prop_map(
            |(
                pad,
                channel,
                temperature_sensor,
                calibration_id,
                calibration_source,
                model_tier,
                role,
                taxels,
            )| {
                wire::PadInfoFrame {
                    pad,
                    channel,
                    temperature_sensor,
                    calibration_id,
                    calibration_source,
                    model_tier,
                    role,
                    taxels,
                }
            },
        )
}

pub fn pad_role() -> impl Strategy<Value = wire::PadRole> {
    prop::sample::select(wire::PadRole::ALL.to_vec())
}

pub fn taxel_geometries(
    float: BoxedStrategy<f32>,
) -> impl Strategy<Value = [wire::TaxelGeometry; 4]> {
    prop::array::uniform4((float.clone(), float.clone(), float).prop_map(
        |(x_mm, y_mm, area_mm2)| wire::TaxelGeometry {
            x_mm,
            y_mm,
            area_mm2,
        },
    ))
}

pub fn pad_geometry_record() -> impl Strategy<Value = wire::PadGeometryRecord> {
    (pad_index(), pad_role(), taxel_geometries(any_f32().boxed()))
        .prop_map(|(pad, role, taxels)| wire::PadGeometryRecord { pad, role, taxels })
}

pub fn reply_frame() -> impl Strategy<Value = ReplyFrame> {
    (
        any::<u16>(),
        prop_oneof![reply_payload().prop_map(Ok), error_code().prop_map(Err)],
    )
        .prop_map(|(request_id, result)| ReplyFrame { request_id, result })
}

pub fn device_event() -> impl Strategy<Value = DeviceEvent> {
    prop_oneof![
        (pad_index(), any::<u32>()).prop_map(|(pad, reinit_count)| {
            DeviceEvent::ConverterReinitialised { pad, reinit_count }
        }),
        (pad_index(), temperature_source())
            .prop_map(|(pad, source)| DeviceEvent::TemperatureSourceChanged { pad, source }),
        Just(DeviceEvent::CalibrationFlashCorrupt),
        (pad_index(), any::<u8>())
            .prop_map(|(pad, tared_mask)| DeviceEvent::TareFinished { pad, tared_mask }),
        pad_index().prop_map(|pad| DeviceEvent::ContactStarted { pad }),
        pad_index().prop_map(|pad| DeviceEvent::ContactEnded { pad }),
        (pad_index(), any::<u8>())
            .prop_map(|(pad, refused_mask)| DeviceEvent::TareRefused { pad, refused_mask }),
    ]
}

pub fn event_frame() -> impl Strategy<Value = EventFrame> {
    (any::<u64>(), device_event()).prop_map(|(timestamp_us, event)| EventFrame {
        timestamp_us,
        event,
    })
}

pub fn device_frame() -> impl Strategy<Value = DeviceFrame> {
    prop_oneof![
        info_frame().prop_map(DeviceFrame::Info),
        sample_frame().prop_map(DeviceFrame::Sample),
        counters_frame().prop_map(DeviceFrame::Counters),
        reply_frame().prop_map(DeviceFrame::Reply),
        event_frame().prop_map(DeviceFrame::Event),
    ]
}

pub fn use_case() -> impl Strategy<Value = UseCase> {
    (any_f32(), any_f32(), any_f32(), any_f32()).prop_map(
        |(pressure_max_kpa, temperature_min_c, temperature_max_c, error_budget_kpa)| UseCase {
            pressure_max_kpa,
            temperature_min_c,
            temperature_max_c,
            error_budget_kpa,
        },
    )
}

pub fn sample_rate() -> impl Strategy<Value = SampleRate> {
    prop::sample::select(vec![
        SampleRate::Sps100,
        SampleRate::Sps200,
        SampleRate::Sps400,
    ])
}

pub fn tier() -> impl Strategy<Value = Tier> {
    prop::sample::select(Tier::ALL.to_vec())
}

pub fn command() -> impl Strategy<Value = Command> {
    prop_oneof![
        Just(Command::Info),
        Just(Command::ReadCounters),
        Just(Command::StartStreaming),
        Just(Command::StopStreaming),
        sample_rate().prop_map(|rate| Command::SetRate { rate }),
        (any::<u16>(), proptest::option::of(pad_index()))
            .prop_map(|(sample_sets, pad)| Command::Tare { sample_sets, pad }),
        tier().prop_map(|tier| Command::SetModelTier { tier }),
        use_case().prop_map(Command::SetUseCase),
        (pad_index(), any::<u8>())
            .prop_map(|(pad, taxel_index)| Command::ReadCalibration { pad, taxel_index }),
        calibration_record().prop_map(Command::WriteCalibration),
        Just(Command::SaveCalibration),
        Just(Command::RestoreDefaults),
        any::<bool>().prop_map(|enabled| Command::SetTextMode { enabled }),
        (pad_index(), any::<u8>())
            .prop_map(|(pad, taxel_index)| Command::ReadBaseline { pad, taxel_index }),
        pad_index().prop_map(|pad| Command::PadInfo { pad }),
        pad_geometry_record().prop_map(Command::SetPadGeometry),
    ]
}

pub fn request() -> impl Strategy<Value = Request> {
    (any::<u16>(), command()).prop_map(|(request_id, command)| Request {
        request_id,
        command,
    })
}

/// Encodes `message` into a new vector.
pub fn encode<M: WireMessage>(message: &M) -> Vec<u8> {
    let mut buffer = [0u8; MAX_FRAME_ENCODED_LEN];
    let len = encode_frame(message, &mut buffer).unwrap();
    buffer[..len].to_vec()
}

/// Encodes, checks the framing invariants, decodes with both the one-shot and the streaming
/// decoder, and checks that the result is bit-exact: same Debug text (field by field, -0.0
/// included) and the same bytes when encoded again (NaN payload bits included).
pub fn assert_round_trip<M: WireMessage + Debug>(message: &M) -> Vec<u8> {
    let encoded = encode(message);
    assert_eq!(
        encoded.last(),
        Some(&0),
        "frame must end with the delimiter"
    );
    assert!(
        !encoded[..encoded.len() - 1].contains(&0),
        "no 0x00 inside a frame"
    );

    let mut scratch = encoded.clone();
    let decoded: M = decode_frame(&mut scratch).unwrap();
    assert_eq!(format!("{decoded:?}"), format!("{message:?}"));
    assert_eq!(
        encode(&decoded),
        encoded,
        "re-encoding must give the same bytes"
    );

    let mut decoder = FrameDecoder::<MAX_FRAME_ENCODED_LEN, M>::new();
    let results: Vec<_> = decoder.feed(&encoded).collect();
    assert_eq!(results.len(), 1);
    let streamed = results.into_iter().next().unwrap().unwrap();
    assert_eq!(encode(&streamed), encoded);
    encoded
}

/// The sample frame with every optional value present and the largest integers.
pub fn worst_case_sample() -> SampleFrame {
    SampleFrame {
        pad: PadIndex::new(PadIndex::MAX).unwrap(),
        sequence: u32::MAX,
        timestamp_us: u64::MAX,
        temperature_c: Some(f32::MIN),
        temperature_source: TemperatureSource::LastKnown,
        taxels: [TaxelSample {
            pressure_kpa: Some(-f32::NAN),
            capacitance_pf: f32::NEG_INFINITY,
            flags: u16::MAX,
        }; 4],
        summary: PadSummary {
            force_n: Some(f32::MAX),
            centre_of_pressure_mm: Some([f32::MIN, f32::MAX]),
            partial: true,
            contact: true,
        },
    }
}

pub fn worst_case_info() -> InfoFrame {
    InfoFrame {
        protocol_version: u8::MAX,
        firmware_version: FirmwareVersion {
            major: u8::MAX,
            minor: u8::MAX,
            patch: u8::MAX,
        },
        board_serial: [0xFF; 12],
        calibration_id: u32::MAX,
        calibration_source: CalibrationSource::DefaultsAfterCorruptFlash,
        rate: SampleRate::Sps400,
        model_tier: Tier::ALL[Tier::ALL.len() - 1],
        streaming: true,
        text_mode: true,
        pad_count: u8::MAX,
        clock_us_per_s: u32::MAX,
    }
}

pub fn worst_case_counters() -> CountersFrame {
    CountersFrame {
        dropped_sample_frames: u32::MAX,
        converter_reinits: u32::MAX,
        i2c_errors: u32::MAX,
        temperature_sensor_errors: u32::MAX,
        frames_dropped_no_host: u32::MAX,
        host_frames_rejected: u32::MAX,
    }
}

/// The longest record with `point_count` points: every other field at its longest, an unloaded
/// capacitance included.
pub fn calibration_record_with_points(point_count: usize) -> TaxelCalibrationRecord {
    TaxelCalibrationRecord {
        pad: PadIndex::new(PadIndex::MAX).unwrap(),
        taxel_index: u8::MAX,
        calibration_id: u32::MAX,
        calibration: TaxelCalibrationWire {
            points: (0..point_count)
                .map(|index| (f32::MAX, index as f32))
                .collect(),
            parasitic_pf: f32::MAX,
            unloaded_sensor_pf: Some(f32::MAX),
        },
    }
}

pub fn worst_case_reply() -> ReplyFrame {
    ReplyFrame {
        request_id: u16::MAX,
        result: Ok(ReplyPayload::Calibration(calibration_record_with_points(
            CALIBRATION_POINTS_MAX,
        ))),
    }
}

pub fn worst_case_baseline() -> wire::TaxelBaselineWire {
    wire::TaxelBaselineWire {
        pad: PadIndex::new(PadIndex::MAX).unwrap(),
        taxel_index: u8::MAX,
        baseline: Some(wire::BaselineWire {
            offset_pf: f32::MAX,
            fine_pf: f32::MAX,
            temperature_c: f32::MAX,
        }),
    }
}

pub fn worst_case_pad_info() -> wire::PadInfoFrame {
    wire::PadInfoFrame {
        pad: PadIndex::new(PadIndex::MAX).unwrap(),
        channel: Some(u8::MAX),
        temperature_sensor: wire::TemperatureSensor::SharedTmp117 { address: u8::MAX },
        calibration_id: u32::MAX,
        calibration_source: CalibrationSource::DefaultsAfterCorruptFlash,
        model_tier: Tier::Polynomial,
        role: wire::PadRole::GripperJaw,
        taxels: [wire::TaxelGeometry {
            x_mm: f32::MAX,
            y_mm: f32::MIN,
            area_mm2: f32::NAN,
        }; 4],
    }
}

pub fn worst_case_event() -> EventFrame {
    EventFrame {
        timestamp_us: u64::MAX,
        event: DeviceEvent::ConverterReinitialised {
            pad: PadIndex::new(PadIndex::MAX).unwrap(),
            reinit_count: u32::MAX,
        },
    }
}

pub fn worst_case_request() -> Request {
    Request {
        request_id: u16::MAX,
        command: Command::WriteCalibration(calibration_record_with_points(CALIBRATION_POINTS_MAX)),
    }
}

/// An independent COBS encoder written from the algorithm's definition (not the `cobs` crate),
/// so that frames built with it check the crate against the specification.
pub fn reference_cobs_encode(payload: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8];
    let mut code_index = 0;
    let mut code = 1u8;
    for &byte in payload {
        if byte == 0 {
            out[code_index] = code;
            code_index = out.len();
            out.push(0);
            code = 1;
        } else {
            out.push(byte);
            code += 1;
            if code == 0xFF {
                out[code_index] = code;
                code_index = out.len();
                out.push(0);
                code = 1;
            }
        }
    }
    out[code_index] = code;
    out
}

/// A complete frame with any version, kind and body, CRC computed as the specification says
/// (CRC-16/IBM-SDLC over version, kind and body, appended little-endian).
pub fn raw_frame(version: u8, kind: u8, body: &[u8]) -> Vec<u8> {
    let mut payload = vec![version, kind];
    payload.extend_from_slice(body);
    let crc = wire::crc16(&payload);
    payload.extend_from_slice(&crc.to_le_bytes());
    let mut frame = reference_cobs_encode(&payload);
    frame.push(0);
    frame
}

/// The sample frame of PROTOCOL.md's examples and of the text-mode tests.
pub fn example_sample() -> SampleFrame {
    SampleFrame {
        pad: PadIndex::new(1).unwrap(),
        sequence: 1234,
        timestamp_us: 5_000_250,
        temperature_c: Some(23.5),
        temperature_source: TemperatureSource::Tmp117,
        taxels: [
            TaxelSample {
                pressure_kpa: Some(12.5),
                capacitance_pf: 4.75,
                flags: 0,
            },
            TaxelSample {
                pressure_kpa: None,
                capacitance_pf: -0.25,
                flags: wire::flags::SHORTED | wire::flags::BELOW_BASELINE,
            },
            TaxelSample {
                pressure_kpa: None,
                capacitance_pf: 4.5,
                flags: wire::flags::NOT_TARED,
            },
            TaxelSample {
                pressure_kpa: Some(0.0),
                capacitance_pf: 4.25,
                flags: wire::flags::BELOW_BASELINE,
            },
        ],
        summary: PadSummary {
            // Taxels 0 and 3 read (12.5 and 0 kPa on 25 mm² each); 1 and 2 are excluded.
            force_n: Some(0.3125),
            centre_of_pressure_mm: Some([-2.75, 2.75]),
            partial: true,
            contact: true,
        },
    }
}
