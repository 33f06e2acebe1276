//! The record format: exact layout, worst-case length, typed errors, and that no corruption of a
//! valid record (bit flips, truncation, extension) or random input ever decodes or panics.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test helpers outside #[test] functions: a failure is a test failure"
)]

mod common;

use calibration_store::{
    decode_record, decode_saved_record, encode_record, encode_scoped_record, RecordError,
    RecordScope, SavedRecord, MAX_RECORD_LEN, PAD_RECORD_FORMAT_VERSION, RECORD_FORMAT_VERSION,
};
use common::{config, spec, valid_spec, worst_case_spec};
use crc::{Crc, CRC_32_ISO_HDLC};
use model_core::calibration::{Calibration, CalibrationError, CalibrationSpec, CurvePoint};
use proptest::prelude::*;

/// Re-declared here rather than taken from the crate, so a wrong algorithm there fails.
const INDEPENDENT_CRC: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

/// The save counter the tests that do not care about it use.
const COUNTER: u32 = 0x0102_0304;

fn encode(spec: &CalibrationSpec) -> Vec<u8> {
    encode_with_counter(spec, COUNTER)
}

fn encode_with_counter(spec: &CalibrationSpec, save_counter: u32) -> Vec<u8> {
    let mut buffer = [0u8; MAX_RECORD_LEN];
    let length = encode_record(spec, save_counter, &mut buffer).unwrap();
    buffer[..length].to_vec()
}

/// version + save counter + body + a correct CRC, whatever the body is.
fn record_with_body(version: u8, body: &[u8]) -> Vec<u8> {
    let mut record = vec![version];
    record.extend_from_slice(&COUNTER.to_le_bytes());
    record.extend_from_slice(body);
    let crc = INDEPENDENT_CRC.checksum(&record);
    record.extend_from_slice(&crc.to_le_bytes());
    record
}

#[test]
fn layout_is_version_save_counter_postcard_body_and_little_endian_crc32() {
    let spec = spec(7);
    let record = encode_with_counter(&spec, 0xA1B2_C3D4);
    let body = postcard_body(&spec);
    assert_eq!(record[0], 3);
    assert_eq!(RECORD_FORMAT_VERSION, 3);
    assert_eq!(&record[1..5], &[0xD4, 0xC3, 0xB2, 0xA1]);
    assert_eq!(&record[5..record.len() - 4], body.as_slice());
    let crc = INDEPENDENT_CRC.checksum(&record[..record.len() - 4]);
    assert_eq!(&record[record.len() - 4..], &crc.to_le_bytes());
    assert_eq!(INDEPENDENT_CRC.checksum(b"123456789"), 0xCBF4_3926);
    assert_eq!(
        decode_saved_record(&record),
        Ok(SavedRecord {
            save_counter: 0xA1B2_C3D4,
            scope: RecordScope::EveryPad,
            spec
        })
    );
}

/// Version 4, one pad's record: version 3 with the pad's index after the version byte.
#[test]
fn a_pad_record_is_version_four_then_the_pad_then_a_version_three_record() {
    let spec = spec(9);
    let mut buffer = [0u8; MAX_RECORD_LEN];
    let length =
        encode_scoped_record(RecordScope::Pad(6), &spec, 0x0A0B_0C0D, &mut buffer).unwrap();
    let record = &buffer[..length];
    let mut expected = vec![4, 6, 0x0D, 0x0C, 0x0B, 0x0A];
    expected.extend_from_slice(&postcard_body(&spec));
    let crc = INDEPENDENT_CRC.checksum(&expected);
    expected.extend_from_slice(&crc.to_le_bytes());
    assert_eq!(record, expected.as_slice());
    assert_eq!(PAD_RECORD_FORMAT_VERSION, 4);
    assert_eq!(
        decode_saved_record(record),
        Ok(SavedRecord {
            save_counter: 0x0A0B_0C0D,
            scope: RecordScope::Pad(6),
            spec: spec.clone()
        })
    );
    // The longest record is a pad's.
    let worst = worst_case_spec(u32::MAX);
    let length = encode_scoped_record(RecordScope::Pad(7), &worst, u32::MAX, &mut buffer).unwrap();
    assert_eq!(length, MAX_RECORD_LEN);
    // A pad index beyond the eighth is refused when writing and when reading.
    assert_eq!(
        encode_scoped_record(RecordScope::Pad(8), &spec, 0, &mut buffer),
        Err(RecordError::PadOutOfRange { pad: 8 })
    );
    let mut beyond = expected.clone();
    beyond[1] = 8;
    let crc_at = beyond.len() - 4;
    let crc = INDEPENDENT_CRC.checksum(&beyond[..crc_at]);
    beyond[crc_at..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(
        decode_saved_record(&beyond),
        Err(RecordError::PadOutOfRange { pad: 8 })
    );
}

/// Version 3: each taxel's `unloaded_sensor_pf` follows its `parasitic_pf` as a postcard
/// `Option<f32>` (`00`, or `01` and the f32 little-endian).
#[test]
fn a_calibrated_c0_round_trips_and_is_an_option_after_the_parasitic_capacitance() {
    let mut with_c0 = spec(7);
    let unloaded_pf = [4.5f32, 4.25, 4.75, 0.5];
    for (taxel, pf) in with_c0.taxels.iter_mut().zip(unloaded_pf) {
        taxel.unloaded_sensor_pf = Some(pf);
    }
    with_c0.taxels[2].unloaded_sensor_pf = None;
    let record = encode_with_counter(&with_c0, 5);
    assert_eq!(
        decode_saved_record(&record),
        Ok(SavedRecord {
            save_counter: 5,
            scope: RecordScope::EveryPad,
            spec: with_c0.clone()
        })
    );
    // 3 x 5 bytes for Some and 1 for None, where the spec without any has 4 x 1.
    assert_eq!(record.len(), encode(&spec(7)).len() + 12);
    for taxel in [0, 1, 3] {
        let parasitic_then_c0: Vec<u8> = with_c0.taxels[taxel]
            .parasitic_pf
            .to_le_bytes()
            .into_iter()
            .chain([1])
            .chain(unloaded_pf[taxel].to_le_bytes())
            .collect();
        assert!(
            record
                .windows(parasitic_then_c0.len())
                .any(|window| window == parasitic_then_c0),
            "taxel {taxel}"
        );
    }
    let mut out_of_range = with_c0;
    for refused in [0.0, -1.0, f32::NAN, f32::INFINITY, 1.0e6] {
        out_of_range.taxels[1].unloaded_sensor_pf = Some(refused);
        let mut buffer = [0u8; MAX_RECORD_LEN];
        assert_eq!(
            encode_record(&out_of_range, COUNTER, &mut buffer),
            Err(RecordError::Invalid(CalibrationError::UnloadedOutOfRange {
                taxel: 1
            })),
            "{refused}"
        );
        let body = postcard_body(&out_of_range);
        assert_eq!(
            decode_record(&record_with_body(RECORD_FORMAT_VERSION, &body)),
            Err(RecordError::Invalid(CalibrationError::UnloadedOutOfRange {
                taxel: 1
            })),
            "{refused}"
        );
    }
}

#[test]
fn the_save_counter_round_trips_at_its_extremes() {
    for save_counter in [0, 1, 0x7F, 0x80, u32::MAX] {
        let record = encode_with_counter(&spec(2), save_counter);
        let decoded = decode_saved_record(&record).unwrap();
        assert_eq!(decoded.save_counter, save_counter);
        assert_eq!(decode_record(&record), Ok(decoded.spec));
    }
}

/// Version 1 (no save counter) was never shipped: an intact version 1 record is refused.
#[test]
fn an_intact_version_1_record_is_refused() {
    let mut version_1 = vec![1u8];
    version_1.extend_from_slice(&postcard_body(&spec(3)));
    let crc = INDEPENDENT_CRC.checksum(&version_1);
    version_1.extend_from_slice(&crc.to_le_bytes());
    assert_eq!(
        decode_record(&version_1),
        Err(RecordError::UnsupportedVersion { found: 1 })
    );
}

/// postcard's `alloc` feature is off in the workspace: serialize into a large slice instead.
fn postcard_body(spec: &CalibrationSpec) -> Vec<u8> {
    let mut buffer = [0u8; 4096];
    postcard::to_slice(spec, &mut buffer).unwrap().to_vec()
}

#[test]
fn worst_case_spec_fills_max_record_len_exactly() {
    let worst = worst_case_spec(u32::MAX);
    let record = encode(&worst);
    // A record for every pad; one pad's record adds the pad's index.
    assert_eq!(record.len() + 1, MAX_RECORD_LEN);
    assert_eq!(MAX_RECORD_LEN, 652);
    assert!(worst
        .taxels
        .iter()
        .all(|taxel| taxel.unloaded_sensor_pf.is_some()));
    assert_eq!(decode_record(&record), Ok(worst));
}

#[test]
fn default_record_length_is_measured() {
    // One `None` tag per taxel more than the 259 bytes of version 2.
    assert_eq!(encode(&CalibrationSpec::default()).len(), 263);
}

#[test]
fn every_too_short_buffer_is_refused_without_writing_past_it() {
    let worst = worst_case_spec(u32::MAX);
    for length in 0..MAX_RECORD_LEN - 1 {
        let mut buffer = vec![0xA5u8; length];
        assert_eq!(
            encode_record(&worst, COUNTER, &mut buffer),
            Err(RecordError::BufferTooSmall),
            "buffer of {length} bytes"
        );
    }
    for length in 0..MAX_RECORD_LEN {
        let mut buffer = vec![0xA5u8; length];
        assert_eq!(
            encode_scoped_record(RecordScope::Pad(0), &worst, COUNTER, &mut buffer),
            Err(RecordError::BufferTooSmall),
            "buffer of {length} bytes"
        );
    }
}

#[test]
fn an_invalid_spec_is_refused_before_anything_is_written() {
    let mut invalid = spec(1);
    invalid.taxels[3].points.truncate(1);
    let mut buffer = [0x5Au8; MAX_RECORD_LEN];
    assert_eq!(
        encode_record(&invalid, COUNTER, &mut buffer),
        Err(RecordError::Invalid(CalibrationError::TooFewPoints {
            taxel: 3
        }))
    );
    assert!(buffer.iter().all(|&byte| byte == 0x5A));
}

#[test]
fn short_inputs_are_too_short() {
    for length in 0..=8 {
        assert_eq!(
            decode_record(&[3, 0, 0, 0, 0, 0, 0, 0, 0][..length]),
            Err(RecordError::TooShort),
            "{length} bytes"
        );
    }
}

#[test]
fn a_changed_byte_is_a_crc_error() {
    let mut record = encode(&spec(3));
    let middle = record.len() / 2;
    record[middle] ^= 0x40;
    assert_eq!(decode_record(&record), Err(RecordError::BadCrc));
}

#[test]
fn an_intact_record_of_another_version_is_refused_by_version() {
    let record = encode(&spec(3));
    for version in [0, 1, 5, 0xFF] {
        let other_version = record_with_body(version, &record[5..record.len() - 4]);
        assert_eq!(
            decode_record(&other_version),
            Err(RecordError::UnsupportedVersion { found: version })
        );
    }
}

#[test]
fn an_intact_record_with_a_garbage_body_is_a_postcard_error() {
    assert!(matches!(
        decode_record(&record_with_body(RECORD_FORMAT_VERSION, &[])),
        Err(RecordError::Postcard(_))
    ));
    assert!(matches!(
        decode_record(&record_with_body(RECORD_FORMAT_VERSION, &[0xFF; 40])),
        Err(RecordError::Postcard(_))
    ));
}

#[test]
fn an_intact_record_with_bytes_after_the_body_is_refused() {
    let record = encode(&spec(3));
    let mut body = record[5..record.len() - 4].to_vec();
    body.push(0);
    assert_eq!(
        decode_record(&record_with_body(RECORD_FORMAT_VERSION, &body)),
        Err(RecordError::TrailingBytes)
    );
}

#[test]
fn an_intact_record_that_does_not_validate_is_refused() {
    let mut invalid = spec(3);
    invalid.taxels[1].points[2] = CurvePoint::new(5.0, 0.01);
    let body = postcard_body(&invalid);
    assert_eq!(
        decode_record(&record_with_body(RECORD_FORMAT_VERSION, &body)),
        Err(RecordError::Invalid(
            CalibrationError::NotStrictlyIncreasing { taxel: 1, point: 2 }
        ))
    );
    let mut invalid = spec(3);
    invalid.thresholds.dead_band_relative = f32::NAN;
    let body = postcard_body(&invalid);
    assert_eq!(
        decode_record(&record_with_body(RECORD_FORMAT_VERSION, &body)),
        Err(RecordError::Invalid(CalibrationError::InvalidThresholds))
    );
}

fn flip(record: &[u8], bits: &[usize]) -> Vec<u8> {
    let mut flipped = record.to_vec();
    for &bit in bits {
        flipped[bit / 8] ^= 1 << (bit % 8);
    }
    flipped
}

#[test]
fn every_single_bit_flip_of_the_longest_record_is_caught() {
    let record = encode(&worst_case_spec(0x1234_5678));
    for bit in 0..record.len() * 8 {
        let flipped = flip(&record, &[bit]);
        let result = decode_record(&flipped);
        assert!(result.is_err(), "bit {bit}: {result:?}");
    }
}

#[test]
fn every_truncation_and_extension_of_a_record_is_caught() {
    for record in [encode(&spec(9)), encode(&worst_case_spec(9))] {
        for length in 0..record.len() {
            assert!(decode_record(&record[..length]).is_err(), "{length} bytes");
        }
        for extra in [0x00u8, 0xFF, 0x5A] {
            let mut extended = record.clone();
            extended.push(extra);
            assert!(decode_record(&extended).is_err());
        }
    }
}

proptest! {
    #![proptest_config(config(2000))]

    #[test]
    fn valid_specs_round_trip_within_max_record_len(spec in valid_spec()) {
        let record = encode(&spec);
        prop_assert!(record.len() <= MAX_RECORD_LEN);
        prop_assert_eq!(decode_record(&record), Ok(spec));
    }

    /// CRC-32 has a Hamming distance of at least 4 up to 91607 bits, so up to three flipped bits
    /// in a record of at most 5208 bits are always detected.
    #[test]
    fn up_to_three_bit_flips_never_decode(
        spec in valid_spec(),
        bit_seeds in proptest::collection::vec(any::<usize>(), 1..=3),
    ) {
        let record = encode(&spec);
        let bit_count = record.len() * 8;
        let mut bits: Vec<usize> = bit_seeds.iter().map(|seed| seed % bit_count).collect();
        bits.sort_unstable();
        bits.dedup();
        let result = decode_record(&flip(&record, &bits));
        prop_assert!(result.is_err(), "bits {:?}: {:?}", bits, result);
    }

    #[test]
    fn truncations_never_decode(spec in valid_spec(), cut in any::<usize>()) {
        let record = encode(&spec);
        let length = cut % record.len();
        prop_assert!(decode_record(&record[..length]).is_err());
    }

    #[test]
    fn random_bytes_never_decode_or_panic(
        bytes in proptest::collection::vec(any::<u8>(), 0..=MAX_RECORD_LEN + 8),
    ) {
        prop_assert!(decode_record(&bytes).is_err());
    }

    /// Random bodies behind a correct CRC and version reach postcard and validation: never a
    /// panic, and anything accepted validates.
    #[test]
    fn random_bodies_with_a_correct_crc_never_panic(
        body in proptest::collection::vec(any::<u8>(), 0..=MAX_RECORD_LEN),
    ) {
        let record = record_with_body(RECORD_FORMAT_VERSION, &body);
        if let Ok(spec) = decode_record(&record) {
            prop_assert!(Calibration::new(&spec).is_ok());
        }
    }

    /// Valid bodies with one byte changed behind a recomputed CRC: parse or validation errors,
    /// or (when the change lands in a value) a different spec that validates. Never a panic.
    #[test]
    fn edited_bodies_with_a_correct_crc_never_panic(
        spec in valid_spec(),
        position in any::<usize>(),
        value in any::<u8>(),
    ) {
        let record = encode(&spec);
        let mut body = record[5..record.len() - 4].to_vec();
        let position = position % body.len();
        body[position] = value;
        let edited = record_with_body(RECORD_FORMAT_VERSION, &body);
        if let Ok(decoded) = decode_record(&edited) {
            prop_assert!(Calibration::new(&decoded).is_ok());
        }
    }
}
