//! Arbitrary bytes from a host into the device's input parser: never a panic; every event is a
//! request with checkable arguments, an error reply, a counted rejection or a mode change.
#![no_main]

use device::{HostInput, HostInputEvent};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let mut input = HostInput::new();
    for &byte in bytes {
        if let Some(HostInputEvent::Request(request)) = input.push(byte) {
            let _ = request.command.check_arguments();
        }
    }
});
