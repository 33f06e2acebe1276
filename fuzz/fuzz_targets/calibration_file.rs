//! Arbitrary text as a calibration file: never a panic; whatever is accepted is a valid
//! calibration.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    if let Ok(text) = std::str::from_utf8(bytes) {
        if let Ok(calibration) = taxel_host::calibration_file::from_json(text) {
            assert!(model_core::Calibration::new(&calibration.to_spec()).is_ok());
        }
    }
});
