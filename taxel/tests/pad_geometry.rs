//! A pad's geometry through the binaries: `taxel calibration geometry` reads what the simulated
//! glove's pads leave the factory with (the palm's 96 mm² electrodes, not square), sets another one and
//! saves it; a recording of the device carries each pad's geometry in its state, and `taxel
//! convert` computes the force with it, as the device does.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use std::process::Command;

use support::{taxel_binary, SimulatorProcess};
use taxel_host::device_state::RecordedDeviceState;
use taxel_host::schema::{PadRow, RowReader};

fn taxel(arguments: &[&str]) -> (bool, String, String) {
    let output = Command::new(taxel_binary())
        .args(arguments)
        .output()
        .unwrap();
    (
        output.status.success(),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

#[test]
fn a_pads_geometry_is_read_set_saved_recorded_and_converted_with() {
    let directory = tempfile::tempdir().unwrap();
    let glove = SimulatorProcess::start(
        directory.path(),
        "glove.txt",
        &["--speed", "5", "--scene", "glove"],
    );
    let port = glove.port.as_str();

    let (ok, palm, errors) = taxel(&["calibration", "geometry", port, "--pad", "5"]);
    assert!(ok, "{errors}");
    assert!(palm.starts_with("pad 5: palm"), "{palm}");
    assert!(
        palm.contains("c11: centre (-6.500, 4.500) mm, area 96.000 mm²"),
        "{palm}"
    );

    // A long narrow geometry for pad 1; two taxels in one place are refused.
    let narrow = [
        "--taxel=-2,6,12",
        "--taxel=2,6,12",
        "--taxel=-2,-6,12",
        "--taxel=2,-6,12",
    ];
    let mut arguments = vec![
        "calibration",
        "geometry",
        port,
        "--pad",
        "1",
        "--role",
        "finger",
    ];
    arguments.extend([
        "--taxel=-2,6,12",
        "--taxel=-2,6,12",
        "--taxel=1,1,1",
        "--taxel=2,2,2",
    ]);
    let (ok, _, errors) = taxel(&arguments);
    assert!(!ok);
    assert!(
        errors.contains("taxel 1") && errors.contains("taxel 0"),
        "{errors}"
    );
    let mut arguments = vec![
        "calibration",
        "geometry",
        port,
        "--pad",
        "1",
        "--role",
        "finger",
    ];
    arguments.extend(narrow);
    arguments.push("--save");
    let (ok, finger, errors) = taxel(&arguments);
    assert!(ok, "{errors}");
    assert!(finger.starts_with("pad 1: finger"), "{finger}");
    assert!(
        finger.contains("c22: centre (2.000, -6.000) mm, area 12.000 mm²"),
        "{finger}"
    );

    // A recording of a whole pass of the scene (14 s) holds every pad's geometry; converting it
    // gives the device's forces.
    let csv = directory.path().join("glove.csv");
    let (ok, _, errors) = taxel(&[
        "record",
        port,
        "-o",
        csv.to_str().unwrap(),
        "--samples",
        "1500",
    ]);
    assert!(ok, "{errors}");
    drop(glove);
    let state =
        RecordedDeviceState::read(&directory.path().join("glove.csv.dev0.device.json")).unwrap();
    let geometry_of = |pad: u8| state.pad_state(pad).unwrap().geometry;
    assert_eq!(geometry_of(5).taxels()[0].area_mm2, 96.0);
    assert_eq!(geometry_of(1).taxels()[3].y_mm, -6.0);
    assert_eq!(geometry_of(0).taxels()[0].area_mm2, 25.0);
    let converted = directory.path().join("converted.csv");
    let (ok, _, errors) = taxel(&[
        "convert",
        csv.to_str().unwrap(),
        "-o",
        converted.to_str().unwrap(),
    ]);
    assert!(ok, "{errors}");
    let rows = |path: &std::path::Path| -> Vec<PadRow> {
        let mut reader =
            RowReader::new(std::io::BufReader::new(std::fs::File::open(path).unwrap())).unwrap();
        std::iter::from_fn(|| reader.next_row().map(Result::unwrap)).collect()
    };
    let (recorded, again) = (rows(&csv), rows(&converted));
    assert_eq!(recorded.len(), again.len());
    let mut loaded_palm_rows = 0;
    for (recorded, again) in recorded.iter().zip(&again) {
        let (Some(device), Some(host)) = (&recorded.reading, &again.reading) else {
            continue;
        };
        assert_eq!(device.force_n, host.force_n, "{recorded:?}");
        assert_eq!(device.centre_of_pressure_mm, host.centre_of_pressure_mm);
        if recorded.pad == 5 && device.force_n.is_some_and(|force_n| force_n > 0.5) {
            // The palm's force is its pressures over 96 mm² electrodes.
            let expected_n: f32 = device
                .pressure_kpa
                .iter()
                .map(|kpa| kpa.unwrap() * 96.0 * 1e-3)
                .sum();
            assert!((device.force_n.unwrap() - expected_n).abs() < 1e-3 * expected_n);
            loaded_palm_rows += 1;
        }
    }
    assert!(
        loaded_palm_rows > 0,
        "the palm was pressed during the recording"
    );
}
