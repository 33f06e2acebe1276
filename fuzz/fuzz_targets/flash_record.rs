//! Arbitrary bytes as a record body, and as a flash region for the store's page and record
//! parser: either the bytes themselves, or a region the store wrote (records for several pads)
//! edited as the bytes say (bit flips, erased ranges, cleared bits). Never a panic; anything that
//! loads is a valid calibration (in an edited region, one that was saved for that pad or for
//! every pad); a save over it that succeeds loads back.
#![no_main]

use calibration_store::PadRecord;
use calibration_store::{
    decode_body, encode_body, CalibrationStore, LoadOutcome, RamFlash, RecordScope, MAX_BODY_LEN,
    MAX_PADS,
};
use libfuzzer_sys::fuzz_target;
use model_core::{CalibrationSpec, PadGeometry, PadRole, TaxelGeometry};

const SIZE: usize = 4096;
const PAGE: usize = 2048;

type Flash = RamFlash<SIZE, PAGE>;

fn block_on<T>(future: impl core::future::Future<Output = T>) -> T {
    embassy_futures::block_on(future)
}

/// A valid record that differs with `id`: calibration, role and electrode area.
fn spec(id: u32) -> PadRecord {
    let mut spec = CalibrationSpec {
        id,
        ..CalibrationSpec::default()
    };
    spec.taxels[(id % 4) as usize].parasitic_pf = (id % 100) as f32 * 0.01;
    let area_mm2 = 1.0 + (id % 97) as f32;
    let taxels = PadGeometry::ARTICLE
        .taxels()
        .map(|taxel| TaxelGeometry::new(taxel.x_mm, taxel.y_mm, area_mm2));
    PadRecord {
        calibration: spec,
        role: PadRole::ALL[(id % 5) as usize],
        geometry: PadGeometry::new(taxels).unwrap(),
    }
}

fuzz_target!(|bytes: &[u8]| {
    if let Ok(spec) = decode_body(bytes) {
        assert!(model_core::Calibration::new(&spec.calibration).is_ok());
        assert!(PadGeometry::new(*spec.geometry.taxels()).is_ok());
        let mut body = [0u8; MAX_BODY_LEN];
        let length = encode_body(&spec, &mut body).unwrap();
        assert_eq!(decode_body(&body[..length]), Ok(spec));
    }
    let Some((&mode, rest)) = bytes.split_first() else {
        return;
    };
    let (flash, saved) = if mode & 1 == 0 {
        let mut image = [0xFFu8; SIZE];
        let length = rest.len().min(SIZE);
        image[..length].copy_from_slice(&rest[..length]);
        (Flash::from_bytes(image), None)
    } else {
        let (flash, saved) = written_then_edited(mode, rest);
        (flash, Some(saved))
    };
    let Ok(mut store) = CalibrationStore::new(flash, 0..SIZE as u32) else {
        return;
    };
    for pad in 0..=MAX_PADS {
        if let LoadOutcome::Stored(spec) = block_on(store.load(pad)) {
            assert!(model_core::Calibration::new(&spec.calibration).is_ok());
            if let Some(saved) = &saved {
                assert!(
                    saved
                        .iter()
                        .any(|(scope, saved)| scope.covers(pad) && *saved == spec),
                    "pad {pad} loaded a calibration never saved for it"
                );
            }
        }
    }
    let new = spec(0xFEED);
    let pad = mode % MAX_PADS;
    if block_on(store.save_for(RecordScope::Pad(pad), &new)).is_ok() {
        assert_eq!(block_on(store.load(pad)), LoadOutcome::Stored(new.clone()));
    }
    if block_on(store.save(&new)).is_ok() {
        for pad in 0..=MAX_PADS {
            assert_eq!(block_on(store.load(pad)), LoadOutcome::Stored(new.clone()));
        }
    }
});

/// A region the store wrote (up to 15 saves, for pads or every pad, as `mode` and the first
/// bytes say), then edited four bytes of `rest` at a time: an operation, an address (two
/// bytes) and a value.
fn written_then_edited(mode: u8, rest: &[u8]) -> (Flash, Vec<(RecordScope, PadRecord)>) {
    let mut flash = Flash::new();
    let mut saved = Vec::new();
    let save_count = usize::from(mode >> 4);
    let (scopes, edits) = rest.split_at(save_count.min(rest.len()));
    for (id, &scope_byte) in (1..).zip(scopes) {
        let scope = if scope_byte >= MAX_PADS {
            RecordScope::EveryPad
        } else {
            RecordScope::Pad(scope_byte)
        };
        let spec = spec(id);
        if block_on(
            CalibrationStore::new(&mut flash, 0..SIZE as u32)
                .unwrap()
                .save_for(scope, &spec),
        )
        .is_ok()
        {
            saved.push((scope, spec));
        }
    }
    let bytes = flash.as_bytes_mut();
    for edit in edits.chunks_exact(4) {
        let address = usize::from(u16::from_le_bytes([edit[1], edit[2]])) % SIZE;
        let value = edit[3];
        match edit[0] % 3 {
            0 => bytes[address] ^= 1 << (value % 8),
            1 => {
                let end = (address + usize::from(value) * 4).min(SIZE);
                bytes[address..end].fill(0xFF);
            }
            _ => bytes[address] &= value,
        }
    }
    (flash, saved)
}
