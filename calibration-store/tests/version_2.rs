//! Calibrations saved by the previous firmware (record format version 2, before the taxels carried
//! their calibrated C0) still load, as the same calibration with no C0: from records and from a
//! whole flash region exactly as that firmware's code wrote them (`tests/data/v2-*.bin`), and a
//! save over them continues their save counter. A version-2 record is checked like any other.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test helpers outside #[test] functions: a failure is a test failure"
)]

mod common;

use calibration_store::{
    decode_record, decode_saved_record, encode_record, LoadOutcome, RecordError, RecordScope,
    SavedRecord, MAX_RECORD_LEN, RECORD_FORMAT_VERSION,
};
use common::{
    block_on, config, reboot_and_load, small_store, spec, valid_spec, version_2_flash,
    version_2_flash_newest, without_c0, worst_case_spec,
};
use crc::{Crc, CRC_32_ISO_HDLC};
use heapless::Vec as BoundedVec;
use model_core::calibration::{
    Calibration, CalibrationError, CalibrationSpec, CurvePoint, FaultThresholds, PermittivityPoint,
    MAX_CURVE_POINTS, MAX_TEMPERATURE_POINTS, TAXEL_COUNT,
};
use proptest::prelude::*;
use serde::{Deserialize, Serialize};

/// `spec(7)` as the version-2 encoder wrote it, with save counter 41.
const V2_SPEC_7: &[u8] = include_bytes!("data/v2-record-spec-7.bin");
/// `worst_case_spec(u32::MAX)` of that time (no C0: the field did not exist) as the version-2
/// encoder wrote it, with save counter 0xA1B2_C3D4: the longest version-2 record.
const V2_WORST_CASE: &[u8] = include_bytes!("data/v2-record-worst-case.bin");

const INDEPENDENT_CRC: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

/// One taxel in the version-2 layout, written here from the old `TaxelCalibrationSpec`.
#[derive(Serialize, Deserialize)]
struct TaxelV2 {
    points: BoundedVec<CurvePoint, MAX_CURVE_POINTS>,
    parasitic_pf: f32,
}

/// The version-2 body, written here from the old `CalibrationSpec`.
#[derive(Serialize, Deserialize)]
struct SpecV2 {
    id: u32,
    taxels: [TaxelV2; TAXEL_COUNT],
    temperature_points: BoundedVec<PermittivityPoint, MAX_TEMPERATURE_POINTS>,
    characterised_min_c: f32,
    characterised_max_c: f32,
    thresholds: FaultThresholds,
}

/// A record as the version-2 encoder wrote it: `[02][save counter LE][version-2 body][CRC-32 LE]`.
/// Only a spec without C0 has a version-2 form.
fn version_2_record(spec: &CalibrationSpec, save_counter: u32) -> Vec<u8> {
    assert!(spec
        .taxels
        .iter()
        .all(|taxel| taxel.unloaded_sensor_pf.is_none()));
    let old = SpecV2 {
        id: spec.id,
        taxels: spec.taxels.clone().map(|taxel| TaxelV2 {
            points: taxel.points,
            parasitic_pf: taxel.parasitic_pf,
        }),
        temperature_points: spec.temperature_points.clone(),
        characterised_min_c: spec.characterised_min_c,
        characterised_max_c: spec.characterised_max_c,
        thresholds: spec.thresholds,
    };
    let mut body = [0u8; MAX_RECORD_LEN];
    let body = postcard::to_slice(&old, &mut body).unwrap();
    with_header_and_crc(2, save_counter, body)
}

/// The calibration a version-2 body holds, read with the old layout itself (as the previous
/// firmware read it), with no C0; None if that layout does not parse all of it or it does not
/// validate.
fn read_with_the_old_layout(body: &[u8]) -> Option<CalibrationSpec> {
    let (old, rest) = postcard::take_from_bytes::<SpecV2>(body).ok()?;
    if !rest.is_empty() {
        return None;
    }
    let mut spec = CalibrationSpec {
        id: old.id,
        temperature_points: old.temperature_points,
        characterised_min_c: old.characterised_min_c,
        characterised_max_c: old.characterised_max_c,
        thresholds: old.thresholds,
        ..CalibrationSpec::default()
    };
    for (taxel, old_taxel) in spec.taxels.iter_mut().zip(old.taxels) {
        taxel.points = old_taxel.points;
        taxel.parasitic_pf = old_taxel.parasitic_pf;
        taxel.unloaded_sensor_pf = None;
    }
    Calibration::new(&spec).ok().map(|_| spec)
}

fn with_header_and_crc(version: u8, save_counter: u32, body: &[u8]) -> Vec<u8> {
    let mut record = vec![version];
    record.extend_from_slice(&save_counter.to_le_bytes());
    record.extend_from_slice(body);
    let crc = INDEPENDENT_CRC.checksum(&record);
    record.extend_from_slice(&crc.to_le_bytes());
    record
}

fn record(spec: &CalibrationSpec, save_counter: u32) -> Vec<u8> {
    let mut buffer = [0u8; MAX_RECORD_LEN];
    let length = encode_record(spec, save_counter, &mut buffer).unwrap();
    buffer[..length].to_vec()
}

#[test]
fn the_previous_firmwares_records_load_as_the_same_calibration_without_c0() {
    assert_eq!(V2_SPEC_7[0], 2);
    assert!(spec(7)
        .taxels
        .iter()
        .all(|taxel| taxel.unloaded_sensor_pf.is_none()));
    assert_eq!(
        decode_saved_record(V2_SPEC_7),
        Ok(SavedRecord {
            scope: RecordScope::EveryPad,
            save_counter: 41,
            spec: spec(7)
        })
    );
    assert_eq!(V2_WORST_CASE.len(), 631);
    assert_eq!(
        decode_saved_record(V2_WORST_CASE),
        Ok(SavedRecord {
            scope: RecordScope::EveryPad,
            save_counter: 0xA1B2_C3D4,
            spec: without_c0(worst_case_spec(u32::MAX))
        })
    );
    // Written again, the calibration is a version-3 record: one `None` tag per taxel longer.
    let rewritten = record(&spec(7), 42);
    assert_eq!(rewritten[0], RECORD_FORMAT_VERSION);
    assert_eq!(rewritten.len(), V2_SPEC_7.len() + TAXEL_COUNT);
    assert_eq!(decode_record(&rewritten), Ok(spec(7)));
}

/// The layout this file writes is the previous firmware's, byte for byte, so the property test
/// below covers what that firmware could have saved.
#[test]
fn the_version_2_layout_written_here_is_the_previous_firmwares() {
    assert_eq!(version_2_record(&spec(7), 41), V2_SPEC_7);
    assert_eq!(
        version_2_record(&without_c0(worst_case_spec(u32::MAX)), 0xA1B2_C3D4),
        V2_WORST_CASE
    );
}

#[test]
fn a_version_2_record_is_checked_like_any_other() {
    for bit in 0..V2_SPEC_7.len() * 8 {
        let mut flipped = V2_SPEC_7.to_vec();
        flipped[bit / 8] ^= 1 << (bit % 8);
        assert!(decode_record(&flipped).is_err(), "bit {bit}");
    }
    for length in 0..V2_SPEC_7.len() {
        assert!(
            decode_record(&V2_SPEC_7[..length]).is_err(),
            "{length} bytes"
        );
    }
    let body = &V2_SPEC_7[5..V2_SPEC_7.len() - 4];
    let mut trailing = body.to_vec();
    trailing.push(0);
    assert_eq!(
        decode_record(&with_header_and_crc(2, 41, &trailing)),
        Err(RecordError::TrailingBytes)
    );
    let mut invalid = spec(7);
    invalid.taxels[2].points[3] = CurvePoint::new(1.0, 0.5);
    assert_eq!(
        decode_record(&version_2_record(&invalid, 41)),
        Err(RecordError::Invalid(
            CalibrationError::NotStrictlyIncreasing { taxel: 2, point: 3 }
        ))
    );
    // A version-3 body behind a version-2 byte is not read as a version-2 calibration.
    let mut with_c0 = spec(7);
    with_c0.taxels[0].unloaded_sensor_pf = Some(4.5);
    let version_3 = record(&with_c0, 41);
    assert!(decode_record(&with_header_and_crc(
        2,
        41,
        &version_3[5..version_3.len() - 4]
    ))
    .is_err());
}

#[test]
fn the_previous_firmwares_flash_loads_its_newest_calibration() {
    let mut flash = version_2_flash();
    assert_eq!(
        reboot_and_load(&mut flash),
        LoadOutcome::Stored(version_2_flash_newest())
    );
}

/// The previous firmware saved two records (save counters 0 and 1): the first version-3 save
/// gets 2, so it wins over both wherever the flash layer puts it.
#[test]
fn a_save_over_the_previous_firmwares_flash_continues_its_save_counter() {
    let mut flash = version_2_flash();
    let mut new = worst_case_spec(8);
    new.taxels[3].unloaded_sensor_pf = None;
    block_on(small_store(&mut flash).save(&new)).unwrap();
    assert_eq!(
        reboot_and_load(&mut flash),
        LoadOutcome::Stored(new.clone())
    );
    let expected = record(&new, 2);
    assert!(flash
        .as_bytes()
        .windows(expected.len())
        .any(|window| window == expected));
    for id in 9..30 {
        let saved = worst_case_spec(id);
        block_on(small_store(&mut flash).save(&saved)).unwrap();
        assert_eq!(reboot_and_load(&mut flash), LoadOutcome::Stored(saved));
    }
}

proptest! {
    #![proptest_config(config(1000))]

    /// Whatever calibration the previous firmware could have saved loads as that calibration.
    #[test]
    fn every_valid_version_2_record_loads_as_its_calibration(
        spec in valid_spec(),
        save_counter in any::<u32>(),
    ) {
        let spec = without_c0(spec);
        let record = version_2_record(&spec, save_counter);
        prop_assert!(record.len() <= MAX_RECORD_LEN);
        prop_assert_eq!(
            decode_saved_record(&record),
            Ok(SavedRecord {
                save_counter,
                scope: RecordScope::EveryPad,
                spec
            })
        );
    }

    /// A version-2 body with one byte changed loads exactly when the old layout reads it as a
    /// valid calibration, and as that calibration: reading by putting the `None` tags back is
    /// reading with the old layout.
    #[test]
    fn edited_version_2_bodies_load_as_the_old_layout_reads_them(
        spec in valid_spec(),
        position in any::<usize>(),
        value in any::<u8>(),
    ) {
        let record = version_2_record(&without_c0(spec), 0);
        let mut body = record[5..record.len() - 4].to_vec();
        let position = position % body.len();
        body[position] = value;
        let loaded = decode_record(&with_header_and_crc(2, 0, &body)).ok();
        prop_assert_eq!(loaded, read_with_the_old_layout(&body));
    }

    /// Random version-2 bodies behind a correct CRC reach the version-2 decoder and validation:
    /// never a panic, and loaded exactly when the old layout reads them as a valid calibration.
    #[test]
    fn random_version_2_bodies_never_panic(
        body in proptest::collection::vec(any::<u8>(), 0..=MAX_RECORD_LEN),
    ) {
        let loaded = decode_record(&with_header_and_crc(2, 0, &body)).ok();
        prop_assert_eq!(loaded, read_with_the_old_layout(&body));
    }
}
