//! `taxel calibrate` on synthetic reference loads with a known truth: the written curve points
//! and C0, the leave-one-out numbers, the calibration file round trip, a tare far from the
//! calibrated C0 flagged by `taxel convert`, and refused data sets. The reference loads are
//! `taxel calibrate`'s own table; the recordings converted are of the recording schema
//! (`taxel_host::schema`), written with its row writer and read back with its reader.
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use std::fmt::Write as _;
use std::path::Path;
use std::process::{Command, Output};
use std::time::Duration;

use model_core::{CalibrationCurve, TaxelFlags, TaxelInverses, TemperatureLaw};
use support::{ack, taxel_binary, FakeDevice, SplitMix64};
use taxel_host::calibration_file;
use taxel_host::calibration_transfer::upload;
use taxel_host::device_link::DeviceLink;
use taxel_host::schema::{header, PadReading, PadRow, RowReader, RowWriter};
use wire::{Command as WireCommand, TemperatureSource};

const GAINS: [f64; 4] = [1.0, 0.92, 1.08, 1.15];
const UNLOADED_SENSOR_PF: [f64; 4] = [4.5, 4.3, 4.7, 4.4];
const PARASITIC_PF: f64 = 0.8;
const TEMPERATURES_C: [f64; 4] = [22.0, 25.0, 31.0, 37.0];
const NOISE_PF: f64 = 0.0005;
const REPEATS: usize = 3;

/// The truth: the article's reference curve, scaled per taxel.
fn true_relative_change(taxel: usize, pressure_kpa: f64) -> f64 {
    let inverses = TaxelInverses::new(&CalibrationCurve::article_default());
    GAINS[taxel] * f64::from(inverses.relative_change_at(pressure_kpa as f32))
}

fn measured_pf(taxel: usize, relative_change: f64, temperature_c: f64) -> f64 {
    let ratio =
        f64::from(TemperatureLaw::article_default().permittivity_ratio(temperature_c as f32));
    PARASITIC_PF + ratio * UNLOADED_SENSOR_PF[taxel] * (1.0 + relative_change)
}

fn levels_kpa() -> Vec<f64> {
    (0..=10).map(|step| f64::from(step) * 5.0).collect()
}

fn synthetic_loads(seed: u64) -> String {
    let mut noise = SplitMix64(seed);
    let mut text = String::from("temp_c,pressure_kpa,c11_pf,c12_pf,c21_pf,c22_pf,operator\n");
    let mut row = 0;
    for repeat in 0..REPEATS {
        for pressure_kpa in levels_kpa() {
            let temperature_c = TEMPERATURES_C[row % TEMPERATURES_C.len()];
            row += 1;
            let _ = write!(text, "{temperature_c},{pressure_kpa}");
            for taxel in 0..4 {
                let capacitance_pf = measured_pf(
                    taxel,
                    true_relative_change(taxel, pressure_kpa),
                    temperature_c,
                ) + NOISE_PF * noise.symmetric();
                let _ = write!(text, ",{capacitance_pf:.7}");
            }
            let _ = writeln!(text, ",run {repeat}");
        }
    }
    text
}

fn calibrate(directory: &Path, loads: &str, extra_arguments: &[&str]) -> Output {
    let loads_path = directory.join("loads.csv");
    std::fs::write(&loads_path, loads).unwrap();
    Command::new(taxel_binary())
        .arg("calibrate")
        .arg(&loads_path)
        .arg("-o")
        .arg(directory.join("calibration.json"))
        .args(extra_arguments)
        .output()
        .unwrap()
}

/// One sample set of a recording: device time s, temperature °C, the four capacitances pF.
type RecordedSet = (u64, f64, [f64; 4]);

/// A recording of the recording schema as `taxel record` writes it for one pad (device 0, pad 0):
/// one row per set, the host time the device time (no sync error), sequence numbers from 0, and
/// the capacitances and temperature of each set (the pressures are what `taxel convert`
/// computes).
fn recording(sets: &[RecordedSet]) -> Vec<u8> {
    let mut writer = RowWriter::new(Vec::new()).unwrap();
    for (sequence, &(time_s, temperature_c, capacitance_pf)) in sets.iter().enumerate() {
        let time_us = time_s * 1_000_000;
        writer
            .write(&PadRow {
                host_time_us: time_us,
                device: 0,
                pad: 0,
                sequence: u32::try_from(sequence).unwrap(),
                sync_error_us: None,
                reading: Some(PadReading {
                    device_time_us: time_us,
                    temperature_c: Some(temperature_c as f32),
                    temperature_source: TemperatureSource::Tmp117,
                    capacitance_pf: capacitance_pf.map(|value| Some(value as f32)),
                    pressure_kpa: [None; 4],
                    flags: [TaxelFlags::empty(); 4],
                    force_n: None,
                    centre_of_pressure_mm: None,
                    partial: false,
                    contact: false,
                }),
                marker: String::new(),
            })
            .unwrap();
    }
    writer.into_inner()
}

/// Reads `taxel convert`'s output: it has the schema's header, and every row (one pad, a reading
/// in each) is returned.
fn converted_rows(output: &[u8]) -> Vec<PadRow> {
    let text = std::str::from_utf8(output).unwrap();
    assert_eq!(text.lines().next(), Some(header().join(",").as_str()));
    let mut reader = RowReader::new(output).unwrap();
    let mut rows = Vec::new();
    while let Some(row) = reader.next_row() {
        let row = row.unwrap();
        assert_eq!((row.device, row.pad), (0, 0), "{row:?}");
        assert!(row.reading.is_some(), "{row:?}");
        rows.push(row);
    }
    rows
}

/// The converted pressure of `taxel` in `row`, kPa (`None`: empty).
fn pressure_kpa_of(row: &PadRow, taxel: usize) -> Option<f64> {
    row.reading
        .as_ref()
        .and_then(|reading| reading.pressure_kpa[taxel])
        .map(f64::from)
}

/// The converted flags of `taxel` in `row`.
fn flags(row: &PadRow, taxel: usize) -> TaxelFlags {
    row.reading
        .as_ref()
        .map_or(TaxelFlags::empty(), |reading| reading.flags[taxel])
}

/// The table row of one taxel and tier: fit max, loo max, loo rms, folds.
fn table_row(stdout: &str, taxel: &str, tier: &str) -> (String, String, String, String) {
    let line = stdout
        .lines()
        .find(|line| {
            let mut words = line.split_whitespace();
            words.next() == Some(taxel) && words.next() == Some(tier)
        })
        .unwrap_or_else(|| panic!("no row for {taxel} {tier} in\n{stdout}"));
    let words: Vec<String> = line.split_whitespace().map(str::to_owned).collect();
    (
        words[2].clone(),
        words[3].clone(),
        words[4].clone(),
        words[5].clone(),
    )
}

#[test]
fn recovers_the_known_curve_and_reports_leave_one_out_errors() {
    let directory = tempfile::tempdir().unwrap();
    let output = calibrate(
        directory.path(),
        &synthetic_loads(7),
        &["--id", "7", "--parasitic-pf", "0.8"],
    );
    let stdout = String::from_utf8(output.stdout).unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let calibration = calibration_file::read(&directory.path().join("calibration.json")).unwrap();
    assert_eq!(calibration.id(), 7);
    let levels = levels_kpa();
    for (taxel, taxel_calibration) in calibration.taxels().iter().enumerate() {
        assert_eq!(taxel_calibration.parasitic_pf(), 0.8);
        let points = taxel_calibration.curve().points();
        assert_eq!(points.len(), levels.len());
        for (point, pressure_kpa) in points.iter().zip(&levels) {
            assert_eq!(f64::from(point.pressure_kpa), *pressure_kpa);
            let truth = true_relative_change(taxel, *pressure_kpa);
            let error = f64::from(point.relative_change) - truth;
            // 0.5 fF of noise on ~4.5 pF, averaged over three repeats and referred to C0.
            assert!(
                error.abs() < 2.5e-4,
                "taxel {taxel} at {pressure_kpa} kPa: {error}"
            );
        }

        // Leave-one-out of the piecewise-linear tier, computed here independently: each interior
        // point is predicted on the chord between its neighbours.
        let errors: Vec<f64> = (1..points.len() - 1)
            .map(|index| {
                let (before, point, after) = (points[index - 1], points[index], points[index + 1]);
                let slope = f64::from(after.pressure_kpa - before.pressure_kpa)
                    / f64::from(after.relative_change - before.relative_change);
                f64::from(before.pressure_kpa)
                    + slope * f64::from(point.relative_change - before.relative_change)
                    - f64::from(point.pressure_kpa)
            })
            .collect();
        let max = errors.iter().map(|error| error.abs()).fold(0.0, f64::max);
        let rms =
            (errors.iter().map(|error| error * error).sum::<f64>() / errors.len() as f64).sqrt();
        let name = ["c11", "c12", "c21", "c22"][taxel];
        let (fit_max, loo_max, loo_rms, folds) = table_row(&stdout, name, "piecewise-linear");
        assert!((fit_max.parse::<f64>().unwrap()).abs() < 1e-3, "{fit_max}");
        assert!(
            (loo_max.parse::<f64>().unwrap() - max).abs() < 2e-4,
            "{loo_max} vs {max}"
        );
        assert!(
            (loo_rms.parse::<f64>().unwrap() - rms).abs() < 2e-4,
            "{loo_rms} vs {rms}"
        );
        assert_eq!(folds, "9/9");
        // The reference cubic predicts the left-out levels of a smooth curve better than chords,
        // and the single-secant tier is far off between the ends.
        let (_, cubic_max, _, _) = table_row(&stdout, name, "monotone-cubic");
        assert!(
            cubic_max.parse::<f64>().unwrap() < max,
            "{cubic_max} vs {max}"
        );
        let (linear_fit, _, _, _) = table_row(&stdout, name, "linear");
        assert!(linear_fit.parse::<f64>().unwrap() > 5.0, "{linear_fit}");
    }
}

#[test]
fn calibration_converts_recordings_back_to_the_true_pressure() {
    let directory = tempfile::tempdir().unwrap();
    let output = calibrate(
        directory.path(),
        &synthetic_loads(11),
        &["--parasitic-pf", "0.8"],
    );
    assert!(output.status.success());
    let pressures_kpa = [0.0, 12.5, 27.0, 44.0];
    let sets: Vec<RecordedSet> = pressures_kpa
        .iter()
        .enumerate()
        .map(|(row, pressure_kpa)| {
            let temperature_c = [25.0, 40.0, 18.0, 33.0][row];
            // Rows a minute apart: the pad can change by 22 °C in that time (a jump of 15 °C
            // from one row to the next would be flagged implausible).
            let capacitance_pf = std::array::from_fn(|taxel| {
                measured_pf(
                    taxel,
                    true_relative_change(taxel, *pressure_kpa),
                    temperature_c,
                )
            });
            (row as u64 * 60, temperature_c, capacitance_pf)
        })
        .collect();
    let recording_path = directory.path().join("recording.csv");
    std::fs::write(&recording_path, recording(&sets)).unwrap();
    let output = Command::new(taxel_binary())
        .arg("convert")
        .arg(&recording_path)
        .arg("--calibration")
        .arg(directory.path().join("calibration.json"))
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let rows = converted_rows(&output.stdout);
    assert_eq!(rows.len(), pressures_kpa.len());
    // The first row is the tare (a recording without a device state is tared on its first
    // readable row).
    for (row, pressure_kpa) in pressures_kpa.iter().enumerate().skip(1) {
        for taxel in 0..4 {
            let converted = pressure_kpa_of(&rows[row], taxel).unwrap_or_else(|| {
                panic!(
                    "taxel {taxel} at {pressure_kpa} kPa has no pressure: {:?}",
                    rows[row]
                )
            });
            assert!(
                (converted - pressure_kpa).abs() < 0.1,
                "taxel {taxel} at {pressure_kpa} kPa read {converted}"
            );
        }
    }
}

/// Runs `taxel convert` on `recording` (a recording of the schema) with the calibration in
/// `directory`, tared on its first `tare_rows` rows; returns its output (the schema's CSV).
fn convert(directory: &Path, recording: &[u8], tare_rows: usize) -> Vec<u8> {
    let recording_path = directory.join("recording.csv");
    std::fs::write(&recording_path, recording).unwrap();
    let output = Command::new(taxel_binary())
        .arg("convert")
        .arg(&recording_path)
        .arg("--calibration")
        .arg(directory.join("calibration.json"))
        .arg("--tare-rows")
        .arg(tare_rows.to_string())
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    output.stdout
}

/// A recording of the calibrated pad whose sensor capacitance is `scale` times the true C0: two
/// unloaded rows (the tare) and two loaded ones, at 25 and 31 °C.
fn recording_with_c0_scaled(scale: f64) -> Vec<u8> {
    let sets: Vec<RecordedSet> = [(0.0, 25.0), (0.0, 25.0), (20.0, 25.0), (35.0, 31.0)]
        .into_iter()
        .enumerate()
        .map(|(row, (pressure_kpa, temperature_c))| {
            let ratio = f64::from(
                TemperatureLaw::article_default().permittivity_ratio(temperature_c as f32),
            );
            let capacitance_pf = std::array::from_fn(|taxel| {
                let sensor_pf = scale
                    * UNLOADED_SENSOR_PF[taxel]
                    * (1.0 + true_relative_change(taxel, pressure_kpa));
                PARASITIC_PF + ratio * sensor_pf
            });
            (row as u64 * 60, temperature_c, capacitance_pf)
        })
        .collect();
    recording(&sets)
}

/// The C0 - Cp that `taxel calibrate` measures at 25 °C goes into the file, per taxel; a
/// recording whose tare is 10 % above it is flagged `baseline_far_from_calibration` on every
/// tared row, one at it is not.
#[test]
fn the_calibrated_c0_is_written_and_a_tare_far_from_it_is_flagged() {
    let directory = tempfile::tempdir().unwrap();
    let output = calibrate(
        directory.path(),
        &synthetic_loads(5),
        &["--parasitic-pf", "0.8"],
    );
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let path = directory.path().join("calibration.json");
    let value: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let calibration = calibration_file::read(&path).unwrap();
    for (taxel, taxel_calibration) in calibration.taxels().iter().enumerate() {
        let written = value["calibration"]["taxels"][taxel]["unloaded_sensor_pf"]
            .as_f64()
            .unwrap();
        // 0.5 fF of noise on each of three unloaded rows.
        assert!(
            (written - UNLOADED_SENSOR_PF[taxel]).abs() < 1e-3,
            "taxel {taxel}: {written} pF"
        );
        assert_eq!(taxel_calibration.unloaded_sensor_pf(), Some(written as f32));
    }

    // The upload carries each taxel's C0 in its WriteCalibration (through the wire encoder and
    // the request decoder).
    let mut link = DeviceLink::new(FakeDevice::new(Box::new(|request| vec![ack(request)])));
    // The fake device answers every request with Ack: its pad count is given, not asked for.
    link.set_pad_count(1);
    upload(
        &mut link,
        &calibration,
        false,
        Duration::from_secs(5),
        &mut |_| {},
    )
    .unwrap();
    let requests = &link.port().requests;
    assert_eq!(requests.len(), 4);
    for (request, taxel_calibration) in requests.iter().zip(calibration.taxels()) {
        let WireCommand::WriteCalibration(record) = &request.command else {
            panic!("expected WriteCalibration, got {:?}", request.command);
        };
        assert!(taxel_calibration.unloaded_sensor_pf().is_some());
        assert_eq!(
            record.calibration.unloaded_sensor_pf,
            taxel_calibration.unloaded_sensor_pf()
        );
    }

    let far_output = convert(directory.path(), &recording_with_c0_scaled(1.1), 2);
    let far = converted_rows(&far_output);
    let at = converted_rows(&convert(
        directory.path(),
        &recording_with_c0_scaled(1.0),
        2,
    ));
    assert_eq!((far.len(), at.len()), (4, 4));
    // The flag is written by its documented name in the schema's flags columns (after the
    // header and the two tare rows).
    let far_text = String::from_utf8(far_output).unwrap();
    let flag_columns: Vec<usize> = ["flags11", "flags12", "flags21", "flags22"]
        .iter()
        .map(|name| header().iter().position(|column| column == name).unwrap())
        .collect();
    for line in far_text.lines().skip(1 + 2) {
        let cells: Vec<&str> = line.split(',').collect();
        for &column in &flag_columns {
            assert!(
                cells[column]
                    .split('|')
                    .any(|name| name == "baseline_far_from_calibration"),
                "{line}"
            );
        }
    }
    // The two tare rows come first; every tared row after them is compared.
    for (far_row, at_row) in far.iter().zip(&at).skip(2) {
        for taxel in 0..4 {
            assert!(
                flags(far_row, taxel).contains(TaxelFlags::BASELINE_FAR_FROM_CALIBRATION),
                "{far_row:?}"
            );
            assert!(
                !flags(at_row, taxel).contains(TaxelFlags::BASELINE_FAR_FROM_CALIBRATION),
                "{at_row:?}"
            );
        }
        // The pressures are still reported, and without the flag they are the true ones.
        let truth = [20.0, 35.0][usize::from(at_row.host_time_us == 180_000_000)];
        for taxel in 0..4 {
            let read = pressure_kpa_of(at_row, taxel).unwrap();
            assert!(
                (read - truth).abs() < 0.1,
                "taxel {taxel}: {read} vs {truth}"
            );
        }
        assert!(
            (0..4).all(|taxel| pressure_kpa_of(far_row, taxel).is_some()),
            "{far_row:?}"
        );
    }
}

#[test]
fn calibration_file_round_trips() {
    let directory = tempfile::tempdir().unwrap();
    let output = calibrate(directory.path(), &synthetic_loads(3), &["--id", "99"]);
    assert!(output.status.success());
    let path = directory.path().join("calibration.json");
    let text = std::fs::read_to_string(&path).unwrap();
    let value: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(value["format"], "taxel-calibration");
    assert_eq!(value["version"], 1);
    assert_eq!(value["calibration"]["id"], 99);
    let calibration = calibration_file::read(&path).unwrap();
    assert_eq!(calibration_file::to_json(&calibration).unwrap(), text);
    assert_eq!(calibration_file::from_json(&text).unwrap(), calibration);
}

#[test]
fn refuses_a_non_monotone_data_set() {
    let directory = tempfile::tempdir().unwrap();
    let loads = "pressure_kpa,c11_pf,c12_pf,c21_pf,c22_pf\n\
                 0,4.5,4.5,4.5,4.5\n\
                 10,4.9,4.9,4.9,4.9\n\
                 20,5.2,5.2,5.2,5.2\n\
                 30,5.4,5.4,5.1,5.4\n\
                 0,4.5,4.5,4.5,4.5\n";
    let output = calibrate(directory.path(), loads, &[]);
    assert_eq!(output.status.code(), Some(1));
    let messages = String::from_utf8_lossy(&output.stderr);
    assert!(messages.contains("taxel c21 is not monotone"), "{messages}");
    assert!(messages.contains("at 30 kPa"), "{messages}");
    assert!(!directory.path().join("calibration.json").exists());
}

#[test]
fn refuses_data_without_unloaded_rows_or_with_bad_rows() {
    let directory = tempfile::tempdir().unwrap();
    let output = calibrate(
        directory.path(),
        "pressure_kpa,c11_pf,c12_pf,c21_pf,c22_pf\n10,4.9,4.9,4.9,4.9\n20,5.2,5.2,5.2,5.2\n",
        &[],
    );
    assert_eq!(output.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&output.stderr).contains("no rows at pressure 0"));
    let output = calibrate(
        directory.path(),
        "pressure_kpa,c11_pf,c12_pf,c21_pf,c22_pf\n0,4.5,4.5,4.5,4.5\n10,4.9,x,4.9,4.9\n",
        &[],
    );
    assert_eq!(output.status.code(), Some(1));
    let messages = String::from_utf8_lossy(&output.stderr);
    assert!(messages.contains("line 3: c12_pf"), "{messages}");
}
