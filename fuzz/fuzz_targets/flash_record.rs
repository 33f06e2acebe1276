//! Arbitrary bytes as a stored calibration record and as a whole flash region: never a panic,
//! anything that loads is a valid calibration, and a save over it that succeeds loads back.
#![no_main]

use calibration_store::{decode_record, CalibrationStore, LoadOutcome, RamFlash, RecordScope};
use libfuzzer_sys::fuzz_target;
use model_core::CalibrationSpec;

const SIZE: usize = 4096;
const PAGE: usize = 2048;

fuzz_target!(|bytes: &[u8]| {
    if let Ok(spec) = decode_record(bytes) {
        assert!(model_core::Calibration::new(&spec).is_ok());
    }
    let mut image = [0xFFu8; SIZE];
    let length = bytes.len().min(SIZE);
    image[..length].copy_from_slice(&bytes[..length]);
    let Ok(mut store) =
        CalibrationStore::new(RamFlash::<SIZE, PAGE>::from_bytes(image), 0..SIZE as u32)
    else {
        return;
    };
    for pad in 0..=calibration_store::MAX_PADS {
        if let LoadOutcome::Stored(spec) = embassy_futures::block_on(store.load(pad)) {
            assert!(model_core::Calibration::new(&spec).is_ok());
        }
    }
    let saved = CalibrationSpec {
        id: 0xFEED,
        ..CalibrationSpec::default()
    };
    let pad = bytes
        .first()
        .map_or(0, |byte| byte % calibration_store::MAX_PADS);
    if embassy_futures::block_on(store.save_for(RecordScope::Pad(pad), &saved)).is_ok() {
        assert_eq!(
            embassy_futures::block_on(store.load(pad)),
            LoadOutcome::Stored(saved.clone())
        );
    }
    if embassy_futures::block_on(store.save(&saved)).is_ok() {
        for pad in 0..calibration_store::MAX_PADS {
            assert_eq!(
                embassy_futures::block_on(store.load(pad)),
                LoadOutcome::Stored(saved.clone())
            );
        }
    }
});
