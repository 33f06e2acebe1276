//! Encoded sizes: the worst case of every frame equals its `MAX_ENCODED_LEN`, random frames never
//! exceed it, and device frames fit one 64-byte USB packet (the exceptions are named here: long
//! calibration replies, and sample frames with force and centre of pressure, which take two).

mod common;

use common::*;
use proptest::prelude::*;
use wire::{
    needs_zero_length_packet, CountersFrame, DeviceFrame, EventFrame, Frame, InfoFrame, ReplyFrame,
    ReplyPayload, Request, SampleFrame, Tier, MAX_FRAME_ENCODED_LEN, MAX_PAYLOAD_LEN,
    USB_FULL_SPEED_PACKET_LEN,
};

/// Encoded length (delimiter included) below which a frame is one short USB packet: sent alone
/// it ends the transfer and needs no zero-length packet.
const ONE_SHORT_PACKET: usize = USB_FULL_SPEED_PACKET_LEN - 1;

#[test]
fn worst_case_of_every_frame_has_the_documented_length() {
    let sample = encode(&DeviceFrame::Sample(worst_case_sample()));
    assert_eq!(sample.len(), SampleFrame::MAX_ENCODED_LEN);
    assert_eq!(sample.len(), 76);

    let info = encode(&DeviceFrame::Info(worst_case_info()));
    assert_eq!(info.len(), InfoFrame::MAX_ENCODED_LEN);
    assert_eq!(info.len(), 39);

    let counters = encode(&DeviceFrame::Counters(worst_case_counters()));
    assert_eq!(counters.len(), CountersFrame::MAX_ENCODED_LEN);
    assert_eq!(counters.len(), 36);

    let event = encode(&DeviceFrame::Event(worst_case_event()));
    assert_eq!(event.len(), EventFrame::MAX_ENCODED_LEN);
    assert_eq!(event.len(), 23);

    let reply = encode(&DeviceFrame::Reply(worst_case_reply()));
    assert_eq!(reply.len(), ReplyFrame::MAX_ENCODED_LEN);
    assert_eq!(reply.len(), DeviceFrame::MAX_ENCODED_LEN);
    assert_eq!(reply.len(), 156);

    let reply_len = |payload: ReplyPayload| {
        encode(&DeviceFrame::Reply(ReplyFrame {
            request_id: u16::MAX,
            result: Ok(payload),
        }))
        .len()
    };
    let other_replies = [
        reply_len(ReplyPayload::Ack),
        reply_len(ReplyPayload::Info(worst_case_info())),
        reply_len(ReplyPayload::Counters(worst_case_counters())),
        reply_len(ReplyPayload::ModelTier(Tier::Polynomial)),
        reply_len(ReplyPayload::Baseline(worst_case_baseline())),
        reply_len(ReplyPayload::PadInfo(worst_case_pad_info())),
    ];
    assert_eq!(other_replies[1], 44, "the Info reply");
    assert_eq!(other_replies[5], 72, "the PadInfo reply is the longest");
    assert_eq!(
        other_replies.iter().max(),
        Some(&ReplyFrame::MAX_ENCODED_LEN_WITHOUT_CALIBRATION)
    );

    let request = encode(&worst_case_request());
    assert_eq!(request.len(), Request::MAX_ENCODED_LEN);
    assert_eq!(request.len(), 155);

    assert_eq!(MAX_FRAME_ENCODED_LEN, 156);
    assert_eq!(Frame::MAX_ENCODED_LEN, MAX_FRAME_ENCODED_LEN);
    assert_eq!(MAX_PAYLOAD_LEN, 154);
    // Below 254 bytes, COBS adds exactly one code byte: no frame needs an `FF` run.
    const { assert!(MAX_PAYLOAD_LEN < 254) };
}

#[test]
fn device_frames_fit_one_short_usb_packet_except_long_calibration_replies_and_samples() {
    for frame in [
        DeviceFrame::Info(worst_case_info()),
        DeviceFrame::Counters(worst_case_counters()),
        DeviceFrame::Event(worst_case_event()),
        DeviceFrame::Reply(ReplyFrame {
            request_id: u16::MAX,
            result: Ok(ReplyPayload::Info(worst_case_info())),
        }),
        DeviceFrame::Reply(ReplyFrame {
            request_id: u16::MAX,
            result: Ok(ReplyPayload::Counters(worst_case_counters())),
        }),
        DeviceFrame::Reply(ReplyFrame {
            request_id: u16::MAX,
            result: Ok(ReplyPayload::Baseline(worst_case_baseline())),
        }),
    ] {
        let len = encode(&frame).len();
        assert!(len <= ONE_SHORT_PACKET, "{frame:?} is {len} bytes");
        assert!(!needs_zero_length_packet(len));
    }

    let points = ReplyFrame::CALIBRATION_POINTS_IN_ONE_PACKET;
    assert_eq!(points, 4);
    let fits = DeviceFrame::Reply(ReplyFrame {
        request_id: u16::MAX,
        result: Ok(ReplyPayload::Calibration(calibration_record_with_points(
            points,
        ))),
    });
    assert!(encode(&fits).len() <= ONE_SHORT_PACKET);
    // PROTOCOL.md section 8: "Reply (Calibration, up to 4 points)".
    assert_eq!(encode(&fits).len(), 60);
    let too_long = DeviceFrame::Reply(ReplyFrame {
        request_id: u16::MAX,
        result: Ok(ReplyPayload::Calibration(calibration_record_with_points(
            points + 1,
        ))),
    });
    assert!(encode(&too_long).len() > ONE_SHORT_PACKET);
}

proptest! {
    #![proptest_config(config(3000))]

    #[test]
    fn random_sample_frames_fit_two_packets_and_one_without_a_summary(sample in sample_frame()) {
        let len = encode(&DeviceFrame::Sample(sample)).len();
        prop_assert!(len <= SampleFrame::MAX_ENCODED_LEN);
        prop_assert!(len < 2 * USB_FULL_SPEED_PACKET_LEN);
        let mut without = sample;
        without.summary.force_n = None;
        without.summary.centre_of_pressure_mm = None;
        // Without force and centre a frame is one packet: short, or exactly 64 bytes
        // (followed by a zero-length packet).
        prop_assert!(encode(&DeviceFrame::Sample(without)).len() <= USB_FULL_SPEED_PACKET_LEN);
    }

    #[test]
    fn random_device_frames_stay_within_their_bound(frame in device_frame()) {
        let len = encode(&frame).len();
        let bound = match &frame {
            DeviceFrame::Info(_) => InfoFrame::MAX_ENCODED_LEN,
            DeviceFrame::Sample(_) => SampleFrame::MAX_ENCODED_LEN,
            DeviceFrame::Counters(_) => CountersFrame::MAX_ENCODED_LEN,
            DeviceFrame::Event(_) => EventFrame::MAX_ENCODED_LEN,
            DeviceFrame::Reply(ReplyFrame { result: Ok(ReplyPayload::Calibration(record)), .. })
                if record.calibration.points.len() > ReplyFrame::CALIBRATION_POINTS_IN_ONE_PACKET =>
            {
                ReplyFrame::MAX_ENCODED_LEN
            }
            // Since version 5 a PadInfo reply carries the pad's geometry: two packets.
            DeviceFrame::Reply(ReplyFrame { result: Ok(ReplyPayload::PadInfo(_)), .. }) => {
                ReplyFrame::MAX_ENCODED_LEN_WITHOUT_CALIBRATION
            }
            DeviceFrame::Reply(_) => ONE_SHORT_PACKET,
        };
        prop_assert!(len <= bound, "{} > {} for {:?}", len, bound, frame);
        prop_assert!(len <= DeviceFrame::MAX_ENCODED_LEN);
    }

    #[test]
    fn random_requests_stay_within_their_bound(request in request()) {
        prop_assert!(encode(&request).len() <= Request::MAX_ENCODED_LEN);
    }
}
