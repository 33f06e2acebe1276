//! The record body: exact layout (version byte, postcard calibration, role, geometry),
//! worst-case length, typed errors, and that no truncation, extension or random input ever
//! decodes into anything but a calibration and a geometry that validate, or panics. (Bit flips are the record CRC's business: see
//! format.rs and power_loss.rs.)

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test helpers outside #[test] functions: a failure is a test failure"
)]

mod common;

use calibration_store::{
    decode_body, encode_body, PadRecord, RecordError, BODY_FORMAT_VERSION, MAX_BODY_LEN,
};
use common::{config, spec, valid_spec, with_layout, worst_case_spec};
use model_core::calibration::{Calibration, CalibrationError, CalibrationSpec, CurvePoint};
use model_core::{PadGeometry, PadRole};
use proptest::prelude::*;

fn encode(spec: &PadRecord) -> Vec<u8> {
    let mut buffer = [0u8; MAX_BODY_LEN];
    let length = encode_body(spec, &mut buffer).unwrap();
    buffer[..length].to_vec()
}

/// postcard's `alloc` feature is off in the workspace: serialize into a large slice instead.
fn postcard_body(spec: &CalibrationSpec) -> Vec<u8> {
    let mut buffer = [0u8; 4096];
    postcard::to_slice(spec, &mut buffer).unwrap().to_vec()
}

/// A record's body after the version byte, written out by hand: the postcard calibration, the
/// role's index (one byte) and each taxel's x, y and area as f32 little-endian.
fn record_bytes(record: &PadRecord) -> Vec<u8> {
    let mut bytes = postcard_body(&record.calibration);
    let role = PadRole::ALL
        .iter()
        .position(|role| *role == record.role)
        .unwrap();
    bytes.push(role as u8);
    for taxel in record.geometry.taxels() {
        for value in [taxel.x_mm, taxel.y_mm, taxel.area_mm2] {
            bytes.extend(value.to_le_bytes());
        }
    }
    bytes
}

/// The version byte, then whatever bytes.
fn with_version(version: u8, rest: &[u8]) -> Vec<u8> {
    let mut body = vec![version];
    body.extend_from_slice(rest);
    body
}

#[test]
fn layout_is_the_version_then_the_calibration_role_and_geometry() {
    for id in [7, 8, 9, 10, 11] {
        let record = spec(id);
        let body = encode(&record);
        assert_eq!(BODY_FORMAT_VERSION, 2);
        assert_eq!(body, with_version(2, &record_bytes(&record)));
        assert_eq!(decode_body(&body), Ok(record));
    }
}

#[test]
fn a_geometry_that_does_not_validate_is_refused() {
    let record = spec(7);
    let mut bytes = record_bytes(&record);
    // The last taxel's area, the body's last four bytes: 0 mm² is no electrode.
    let area_at = bytes.len() - 4;
    bytes[area_at..].copy_from_slice(&0.0f32.to_le_bytes());
    assert!(matches!(
        decode_body(&with_version(2, &bytes)),
        Err(RecordError::Postcard(_))
    ));
    // A role index beyond the five roles.
    let mut bytes = record_bytes(&record);
    let role_at = bytes.len() - 49;
    bytes[role_at] = 5;
    assert!(matches!(
        decode_body(&with_version(2, &bytes)),
        Err(RecordError::Postcard(_))
    ));
    assert_eq!(
        decode_body(&with_version(2, &record_bytes(&record))),
        Ok(record)
    );
}

/// Each taxel's `unloaded_sensor_pf` follows its `parasitic_pf` as a postcard `Option<f32>`
/// (`00`, or `01` and the f32 little-endian).
#[test]
fn a_calibrated_c0_round_trips_and_is_an_option_after_the_parasitic_capacitance() {
    let mut with_c0 = spec(7);
    let unloaded_pf = [4.5f32, 4.25, 4.75, 0.5];
    for (taxel, pf) in with_c0.calibration.taxels.iter_mut().zip(unloaded_pf) {
        taxel.unloaded_sensor_pf = Some(pf);
    }
    with_c0.calibration.taxels[2].unloaded_sensor_pf = None;
    let body = encode(&with_c0);
    assert_eq!(decode_body(&body), Ok(with_c0.clone()));
    // 3 x 5 bytes for Some and 1 for None, where the spec without any has 4 x 1.
    assert_eq!(body.len(), encode(&spec(7)).len() + 12);
    for taxel in [0, 1, 3] {
        let parasitic_then_c0: Vec<u8> = with_c0.calibration.taxels[taxel]
            .parasitic_pf
            .to_le_bytes()
            .into_iter()
            .chain([1])
            .chain(unloaded_pf[taxel].to_le_bytes())
            .collect();
        assert!(
            body.windows(parasitic_then_c0.len())
                .any(|window| window == parasitic_then_c0),
            "taxel {taxel}"
        );
    }
    let mut out_of_range = with_c0;
    for refused in [0.0, -1.0, f32::NAN, f32::INFINITY, 1.0e6] {
        out_of_range.calibration.taxels[1].unloaded_sensor_pf = Some(refused);
        let mut buffer = [0u8; MAX_BODY_LEN];
        let invalid = Err(RecordError::Invalid(CalibrationError::UnloadedOutOfRange {
            taxel: 1,
        }));
        assert_eq!(
            encode_body(&out_of_range, &mut buffer).map(|_| ()),
            invalid.clone(),
            "{refused}"
        );
        assert_eq!(
            decode_body(&with_version(2, &record_bytes(&out_of_range))).map(|_| ()),
            invalid,
            "{refused}"
        );
    }
}

#[test]
fn worst_case_spec_fills_max_body_len_exactly() {
    let worst = worst_case_spec(u32::MAX);
    let body = encode(&worst);
    assert_eq!(body.len(), MAX_BODY_LEN);
    assert_eq!(MAX_BODY_LEN, 692);
    assert!(worst
        .calibration
        .taxels
        .iter()
        .all(|taxel| taxel.unloaded_sensor_pf.is_some()));
    assert_eq!(decode_body(&body), Ok(worst));
}

#[test]
fn default_body_length_is_measured() {
    let default = PadRecord::new(CalibrationSpec::default());
    assert_eq!(default.geometry, PadGeometry::ARTICLE);
    assert_eq!(encode(&default).len(), 255 + 1 + 48);
}

#[test]
fn every_too_short_buffer_is_refused() {
    let worst = worst_case_spec(u32::MAX);
    for length in 0..MAX_BODY_LEN {
        let mut buffer = vec![0xA5u8; length];
        assert_eq!(
            encode_body(&worst, &mut buffer),
            Err(RecordError::BufferTooSmall),
            "buffer of {length} bytes"
        );
    }
}

#[test]
fn an_invalid_spec_is_refused_before_anything_is_written() {
    let mut invalid = spec(1);
    invalid.calibration.taxels[3].points.truncate(1);
    let mut buffer = [0x5Au8; MAX_BODY_LEN];
    assert_eq!(
        encode_body(&invalid, &mut buffer),
        Err(RecordError::Invalid(CalibrationError::TooFewPoints {
            taxel: 3
        }))
    );
    assert!(buffer.iter().all(|&byte| byte == 0x5A));
}

#[test]
fn empty_and_too_long_inputs_are_refused_by_length() {
    assert_eq!(decode_body(&[]), Err(RecordError::Empty));
    let mut long = encode(&worst_case_spec(1));
    long.resize(MAX_BODY_LEN + 1, 0);
    assert_eq!(decode_body(&long), Err(RecordError::TooLong));
}

#[test]
fn a_body_of_another_version_is_refused_by_version() {
    let calibration = record_bytes(&spec(3));
    for version in [0, 1, 3, 4, 0xFF] {
        assert_eq!(
            decode_body(&with_version(version, &calibration)),
            Err(RecordError::UnsupportedVersion { found: version })
        );
    }
}

#[test]
fn a_garbage_body_is_a_postcard_error() {
    assert!(matches!(decode_body(&[2]), Err(RecordError::Postcard(_))));
    assert!(matches!(
        decode_body(&with_version(2, &[0xFF; 40])),
        Err(RecordError::Postcard(_))
    ));
}

#[test]
fn bytes_after_the_calibration_are_refused() {
    let mut body = encode(&spec(3));
    body.push(0);
    assert_eq!(decode_body(&body), Err(RecordError::TrailingBytes));
}

#[test]
fn a_calibration_that_does_not_validate_is_refused() {
    let mut invalid = spec(3);
    invalid.calibration.taxels[1].points[2] = CurvePoint::new(5.0, 0.01);
    assert_eq!(
        decode_body(&with_version(2, &record_bytes(&invalid))),
        Err(RecordError::Invalid(
            CalibrationError::NotStrictlyIncreasing { taxel: 1, point: 2 }
        ))
    );
    let mut invalid = spec(3);
    invalid.calibration.thresholds.dead_band_relative = f32::NAN;
    assert_eq!(
        decode_body(&with_version(2, &record_bytes(&invalid))),
        Err(RecordError::Invalid(CalibrationError::InvalidThresholds))
    );
}

#[test]
fn every_truncation_and_extension_of_a_body_is_refused() {
    for body in [encode(&spec(9)), encode(&worst_case_spec(9))] {
        for length in 0..body.len() {
            assert!(decode_body(&body[..length]).is_err(), "{length} bytes");
        }
        for extra in [0x00u8, 0xFF, 0x5A] {
            let mut extended = body.clone();
            extended.push(extra);
            assert!(decode_body(&extended).is_err());
        }
    }
}

proptest! {
    #![proptest_config(config(2000))]

    #[test]
    fn valid_specs_round_trip_within_max_body_len(spec in valid_spec(), id in any::<u32>()) {
        let spec = with_layout(spec, id);
        let body = encode(&spec);
        prop_assert!(body.len() <= MAX_BODY_LEN);
        prop_assert_eq!(decode_body(&body), Ok(spec));
    }

    #[test]
    fn random_bytes_never_panic_and_anything_accepted_validates(
        bytes in proptest::collection::vec(any::<u8>(), 0..=MAX_BODY_LEN + 8),
    ) {
        if let Ok(record) = decode_body(&bytes) {
            prop_assert!(Calibration::new(&record.calibration).is_ok());
            prop_assert!(PadGeometry::new(*record.geometry.taxels()).is_ok());
        }
    }

    /// Random calibrations behind the right version reach postcard and validation: never a
    /// panic, and anything accepted validates.
    #[test]
    fn random_calibrations_behind_the_version_never_panic(
        rest in proptest::collection::vec(any::<u8>(), 0..=MAX_BODY_LEN),
    ) {
        if let Ok(record) = decode_body(&with_version(2, &rest)) {
            prop_assert!(Calibration::new(&record.calibration).is_ok());
            prop_assert!(PadGeometry::new(*record.geometry.taxels()).is_ok());
        }
    }

    /// Valid bodies with one byte changed: parse or validation errors, or (when the change lands
    /// in a value) a different calibration that validates. Never a panic.
    #[test]
    fn edited_bodies_never_panic(
        spec in valid_spec(),
        id in any::<u32>(),
        position in any::<usize>(),
        value in any::<u8>(),
    ) {
        let mut body = encode(&with_layout(spec, id));
        let position = 1 + position % (body.len() - 1);
        body[position] = value;
        if let Ok(decoded) = decode_body(&body) {
            prop_assert!(Calibration::new(&decoded.calibration).is_ok());
            prop_assert!(PadGeometry::new(*decoded.geometry.taxels()).is_ok());
        }
    }
}
