//! Every frame and command survives encode -> decode bit-exactly, for random field values
//! including NaN (any payload), infinities and -0.0; and each direction's decoder refuses the
//! other direction's frames by kind.

mod common;

use common::*;
use proptest::prelude::*;
use wire::{decode_frame, kind, DecodeError, DeviceFrame, Frame, Request};

proptest! {
    #![proptest_config(config(3000))]

    #[test]
    fn sample_frames_round_trip(sample in sample_frame()) {
        assert_round_trip(&DeviceFrame::Sample(sample));
    }

    #[test]
    fn info_frames_round_trip(info in info_frame()) {
        assert_round_trip(&DeviceFrame::Info(info));
    }

    #[test]
    fn counters_frames_round_trip(counters in counters_frame()) {
        assert_round_trip(&DeviceFrame::Counters(counters));
    }

    #[test]
    fn reply_frames_round_trip(reply in reply_frame()) {
        assert_round_trip(&DeviceFrame::Reply(reply));
    }

    #[test]
    fn event_frames_round_trip(event in event_frame()) {
        assert_round_trip(&DeviceFrame::Event(event));
    }

    #[test]
    fn requests_round_trip(request in request()) {
        assert_round_trip(&request);
    }

    #[test]
    fn any_direction_frames_round_trip(
        frame in prop_oneof![
            device_frame().prop_map(Frame::Device),
            request().prop_map(Frame::Request),
        ]
    ) {
        let bytes = assert_round_trip(&frame);
        // The same bytes decode through the direction-specific decoder to the same message.
        match &frame {
            Frame::Device(device_frame) => {
                let decoded: DeviceFrame = decode_frame(&mut bytes.clone()).unwrap();
                prop_assert_eq!(encode(&decoded), encode(device_frame));
                let refused = decode_frame::<Request>(&mut bytes.clone());
                prop_assert_eq!(refused, Err(DecodeError::UnknownKind(device_frame.kind())));
            }
            Frame::Request(request) => {
                let decoded: Request = decode_frame(&mut bytes.clone()).unwrap();
                prop_assert_eq!(encode(&decoded), encode(request));
                let refused = decode_frame::<DeviceFrame>(&mut bytes.clone());
                prop_assert_eq!(refused, Err(DecodeError::UnknownKind(kind::REQUEST)));
            }
        }
    }
}

#[test]
fn sample_values_keep_their_exact_bits() {
    let bit_patterns = [
        0x7FC0_0000u32, // canonical quiet NaN
        0x7FC0_1234,    // quiet NaN with payload
        0x7F80_0001,    // signalling NaN
        0xFFFF_FFFF,    // negative NaN, all payload bits
        0x7F80_0000,    // +inf
        0xFF80_0000,    // -inf
        0x8000_0000,    // -0.0
        0x0000_0001,    // smallest subnormal
    ];
    for bits in bit_patterns {
        let value = f32::from_bits(bits);
        let mut sample = worst_case_sample();
        sample.temperature_c = Some(value);
        for taxel in &mut sample.taxels {
            taxel.pressure_kpa = Some(value);
            taxel.capacitance_pf = value;
        }
        let bytes = assert_round_trip(&DeviceFrame::Sample(sample));
        let decoded: DeviceFrame = decode_frame(&mut bytes.clone()).unwrap();
        let DeviceFrame::Sample(decoded) = decoded else {
            panic!("expected a sample frame, got {decoded:?}");
        };
        assert_eq!(decoded.temperature_c.map(f32::to_bits), Some(bits));
        for taxel in decoded.taxels {
            assert_eq!(taxel.pressure_kpa.map(f32::to_bits), Some(bits));
            assert_eq!(taxel.capacitance_pf.to_bits(), bits);
        }
    }
}

#[test]
fn a_faulted_pressure_stays_absent_and_is_not_sent() {
    let mut sample = worst_case_sample();
    sample.taxels[2].pressure_kpa = None;
    let with_fault = encode(&DeviceFrame::Sample(sample));
    let without_fault = encode(&DeviceFrame::Sample(worst_case_sample()));
    assert_eq!(with_fault.len() + 4, without_fault.len());
    let decoded: DeviceFrame = decode_frame(&mut with_fault.clone()).unwrap();
    let DeviceFrame::Sample(decoded) = decoded else {
        panic!("expected a sample frame, got {decoded:?}");
    };
    assert_eq!(decoded.taxels[2].pressure_kpa, None);
    assert!(decoded.taxels[1].pressure_kpa.is_some());
}
