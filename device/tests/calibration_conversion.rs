//! A taxel calibration between the model and the wire keeps everything it carries, the
//! calibrated C0 included, both ways.

// A failed unwrap is the test failing.
#![allow(clippy::unwrap_used)]

use device::{calibration_record, taxel_calibration_spec, CalibrationConversionError};
use model_core::{Calibration, CalibrationSpec};

fn calibration_with_c0() -> Calibration {
    let mut spec = CalibrationSpec {
        id: 12,
        ..CalibrationSpec::default()
    };
    for (taxel, taxel_spec) in spec.taxels.iter_mut().enumerate() {
        taxel_spec.parasitic_pf = 0.5 * taxel as f32;
        taxel_spec.unloaded_sensor_pf = (taxel != 2).then_some(4.25 + 0.125 * taxel as f32);
    }
    Calibration::new(&spec).unwrap()
}

#[test]
fn the_calibrated_c0_survives_the_wire_both_ways() {
    let calibration = calibration_with_c0();
    assert_eq!(calibration.id(), 12);
    for (taxel, expected) in calibration.taxels().iter().enumerate() {
        let pad = wire::PadIndex::new(3).unwrap();
        let record = calibration_record(&calibration, pad, taxel as u8).unwrap();
        assert_eq!(record.pad, pad);
        assert_eq!(
            record.calibration.unloaded_sensor_pf,
            expected.unloaded_sensor_pf()
        );
        assert_eq!(record.check(), Ok(()));
        assert_eq!(
            taxel_calibration_spec(&record.calibration),
            Ok(expected.to_spec())
        );
    }
    assert_eq!(calibration.taxels()[2].unloaded_sensor_pf(), None);
    assert_eq!(
        calibration_record(&calibration, wire::PadIndex::default(), 4),
        Err(CalibrationConversionError::NoSuchTaxel)
    );
}
