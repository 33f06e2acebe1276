//! Arbitrary bytes into the host's frame decoder: never a panic, and every frame it accepts
//! re-encodes to bytes that decode to the same frame.
#![no_main]

use libfuzzer_sys::fuzz_target;
use wire::{encode_frame, DeviceFrame, DeviceFrameDecoder};

fuzz_target!(|bytes: &[u8]| {
    let mut decoder = DeviceFrameDecoder::new();
    let frames: Vec<DeviceFrame> = decoder.feed(bytes).filter_map(Result::ok).collect();
    for frame in frames {
        let mut encoded = [0u8; DeviceFrame::MAX_ENCODED_LEN];
        let length = encode_frame(&frame, &mut encoded).expect("an accepted frame re-encodes");
        let mut again = DeviceFrameDecoder::new();
        let decoded: Vec<_> = again.feed(&encoded[..length]).collect();
        assert_eq!(decoded.len(), 1);
        // Compare encodings, not values: NaN payloads make value equality useless.
        let mut re_encoded = [0u8; DeviceFrame::MAX_ENCODED_LEN];
        let frame_again = decoded
            .into_iter()
            .next()
            .and_then(Result::ok)
            .expect("decodes");
        let length_again = encode_frame(&frame_again, &mut re_encoded).expect("re-encodes");
        assert_eq!(&encoded[..length], &re_encoded[..length_again]);
    }
});
