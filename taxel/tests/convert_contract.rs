//! The `taxel convert` contract, run through the binary on temporary files.
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use std::path::Path;
use std::process::{Command, Output};

use model_core::{Calibration, CalibrationSpec, CurvePoint};
use support::{encoded, sample, taxel_binary};
use wire::DeviceFrame;

const HEADER: &str =
    "time_s,temp_c,p11_kpa,p12_kpa,p21_kpa,p22_kpa,flags11,flags12,flags21,flags22";

/// 4.5 pF unloaded; dC/C0 of the article's table at 10 kPa.
const LOADED_10_KPA_PF: f64 = 4.5 * 1.0829;

fn run(directory: &Path, input: &str, extra_arguments: &[&str]) -> (Output, Vec<Vec<String>>) {
    let input_path = directory.join("input.csv");
    let output_path = directory.join("output.csv");
    std::fs::write(&input_path, input).unwrap();
    let output = Command::new(taxel_binary())
        .arg("convert")
        .arg(&input_path)
        .arg("-o")
        .arg(&output_path)
        .args(extra_arguments)
        .output()
        .unwrap();
    let rows = std::fs::read_to_string(&output_path)
        .map(|text| parse_csv(&text))
        .unwrap_or_default();
    (output, rows)
}

fn parse_csv(text: &str) -> Vec<Vec<String>> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .from_reader(text.as_bytes());
    reader
        .records()
        .map(|record| record.unwrap().iter().map(str::to_owned).collect())
        .collect()
}

fn pressure(rows: &[Vec<String>], row: usize, taxel: usize) -> f64 {
    rows[row][2 + taxel].parse().unwrap()
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn header_order_and_values() {
    let directory = tempfile::tempdir().unwrap();
    let input = format!(
        "time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n\
         0.000,25.0,4.5,4.5,4.5,4.5\n\
         0.010,25.0,{LOADED_10_KPA_PF},4.5,4.5,4.5\n\
         0.020,25.0,4.5,{LOADED_10_KPA_PF},4.5,4.5\n"
    );
    let (output, rows) = run(directory.path(), &input, &[]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let text = std::fs::read_to_string(directory.path().join("output.csv")).unwrap();
    assert!(text.starts_with(&format!("{HEADER}\r\n")), "{text}");
    assert_eq!(rows.len(), 4);
    let times: Vec<&str> = rows[1..].iter().map(|row| row[0].as_str()).collect();
    assert_eq!(times, ["0.000", "0.010", "0.020"], "time_s text preserved");
    assert!(rows[1..].iter().all(|row| row[1] == "25.0"));
    assert_eq!(&rows[1][2..6], ["", "", "", ""]);
    assert_eq!(&rows[1][6..10], ["not_tared"; 4]);
    assert!((pressure(&rows, 2, 0) - 10.0).abs() < 0.01);
    assert_eq!(pressure(&rows, 2, 1), 0.0);
    assert_eq!(pressure(&rows, 3, 0), 0.0);
    assert!((pressure(&rows, 3, 1) - 10.0).abs() < 0.01);
    assert_eq!(&rows[2][6..10], ["", "", "", ""]);
}

#[test]
fn faulted_taxels_have_empty_pressure_and_flags_saying_why() {
    let directory = tempfile::tempdir().unwrap();
    let input = "time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n\
                 0,25,4.5,4.5,4.5,4.5\n\
                 1,,-0.3,0.4,4.3,10\n\
                 12,70,4.5,4.5,4.5,\n";
    let (output, rows) = run(directory.path(), input, &[]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(rows[2][1], "", "missing temperature stays empty");
    assert_eq!(&rows[2][2..4], ["", ""]);
    assert_eq!(rows[2][6], "shorted|temperature_missing");
    assert_eq!(rows[2][7], "open|temperature_missing");
    assert_eq!(rows[2][4], "0", "below the baseline reads 0 kPa");
    assert_eq!(rows[2][8], "below_baseline|temperature_missing");
    assert_eq!(rows[2][9], "over_range|temperature_missing");
    assert_eq!(pressure(&rows, 2, 3), 50.0);
    assert_eq!(rows[3][9], "temperature_out_of_range|converter_error");
    assert_eq!(rows[3][5], "");
    assert_eq!(rows[3][6], "temperature_out_of_range");
}

#[test]
fn bad_rows_are_reported_with_line_numbers_and_written_empty() {
    let directory = tempfile::tempdir().unwrap();
    let input = format!(
        "time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n\
         0.0,25,4.5,4.5,4.5,4.5\n\
         0.1,25,4.5,abc,4.5,4.5\n\
         0.2,25,4.5,4.5\n\
         0.3,25,{LOADED_10_KPA_PF},4.5,4.5,4.5\n\
         x,25,4.5,4.5,4.5,4.5\n\
         0.5,25,4.5,4.5,4.5,4.5,9\n"
    );
    let (output, rows) = run(directory.path(), &input, &[]);
    assert_eq!(output.status.code(), Some(3));
    let messages = stderr(&output);
    for line in ["line 3:", "line 4:", "line 6:", "line 7:"] {
        assert!(messages.contains(line), "{line} missing in {messages}");
    }
    assert!(!messages.contains("line 2:") && !messages.contains("line 5:"));
    assert!(messages.contains("abc"), "{messages}");
    assert_eq!(rows.len(), 7, "one output row per input row");
    let empty_rest = vec![String::new(); 9];
    assert_eq!(rows[2][0], "0.1");
    assert_eq!(rows[2][1..], empty_rest[..]);
    assert_eq!(rows[3][0], "0.2");
    assert_eq!(rows[3][1..], empty_rest[..]);
    assert_eq!(rows[5][0], "", "an unreadable time is not kept");
    assert_eq!(rows[6][0], "0.5");
    assert_eq!(rows[6][1..], empty_rest[..]);
    assert!(
        (pressure(&rows, 4, 0) - 10.0).abs() < 0.01,
        "good rows still converted"
    );
}

#[test]
fn column_order_is_free_extra_columns_are_ignored_and_quotes_are_read() {
    let directory = tempfile::tempdir().unwrap();
    let canonical = format!(
        "time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n\
         0.0,24.0,4.5,4.4,4.6,4.3\n\
         0.5,30.5,{LOADED_10_KPA_PF},4.6,4.7,4.3\n"
    );
    let shuffled = format!(
        "note,c22_pf,c21_pf,\"time_s\",seq,c12_pf,temp_c,c11_pf\n\
         \"tare, unloaded\",4.3,4.6,0.0,1,4.4,24.0,\"4.5\"\n\
         \"pressed \"\"hard\"\"\",4.3,4.7,\"0.5\",2,4.6,30.5,{LOADED_10_KPA_PF}\n"
    );
    let (first_output, first) = run(directory.path(), &canonical, &[]);
    let (second_output, second) = run(directory.path(), &shuffled, &[]);
    assert_eq!(first_output.status.code(), Some(0));
    assert_eq!(
        second_output.status.code(),
        Some(0),
        "{}",
        stderr(&second_output)
    );
    assert_eq!(first, second);
    assert_eq!(first[0].join(","), HEADER);
}

#[test]
fn tare_rows_average_the_first_rows() {
    let directory = tempfile::tempdir().unwrap();
    // Still rows: a spread of 1.6 fF, within what converter noise explains.
    let input = format!(
        "time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n\
         0,25,4.498,4.5,4.5,4.5\n\
         1,25,4.5,4.5,4.5,4.5\n\
         2,25,4.502,4.5,4.5,4.5\n\
         3,25,{LOADED_10_KPA_PF},4.5,4.5,4.5\n"
    );
    let (output, rows) = run(directory.path(), &input, &["--tare-rows", "3"]);
    assert_eq!(output.status.code(), Some(0));
    for row in &rows[1..4] {
        assert_eq!(row[6], "not_tared");
    }
    assert!((pressure(&rows, 4, 0) - 10.0).abs() < 0.01);
    let (_, one_row_tare) = run(directory.path(), &input, &[]);
    // Tared on 4.498 pF alone, 4.873 pF is dC/C0 = 0.08338 instead of 0.0829: about 0.06 kPa
    // more at Table 1's 0.0083 /kPa.
    let one_row = pressure(&one_row_tare, 4, 0);
    assert!((0.04..0.08).contains(&(one_row - 10.0)), "{one_row}");
    let (output, never) = run(directory.path(), &input, &["--tare-rows", "10"]);
    assert_eq!(output.status.code(), Some(0));
    assert!(stderr(&output).contains("tare never finished"));
    assert_eq!(never[4][6], "not_tared");
}

#[test]
fn a_tare_over_rows_that_are_not_still_is_refused_with_the_reason() {
    let directory = tempfile::tempdir().unwrap();
    // c11 drifts by 0.1 pF per row during the tare (pressed or moving): 82 fF of spread.
    let input = format!(
        "time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n\
         0,25,4.4,4.5,4.5,4.5\n\
         1,25,4.5,4.5,4.5,4.5\n\
         2,25,4.6,4.5,4.5,4.5\n\
         3,25,{LOADED_10_KPA_PF},4.5,4.5,4.5\n"
    );
    let (output, rows) = run(directory.path(), &input, &["--tare-rows", "3"]);
    assert_eq!(output.status.code(), Some(0));
    assert_eq!(rows[4][6], "not_tared");
    assert!(
        (pressure(&rows, 4, 1)).abs() < 0.01,
        "the still taxels are tared"
    );
    let warning = stderr(&output);
    assert!(
        warning.contains("c11") && warning.contains("the pad was not still"),
        "{warning}"
    );
}

#[test]
fn tier_changes_the_inversion() {
    let directory = tempfile::tempdir().unwrap();
    let input = format!(
        "time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n\
         0,25,4.5,4.5,4.5,4.5\n\
         1,25,{LOADED_10_KPA_PF},4.5,4.5,4.5\n"
    );
    let (output, linear) = run(directory.path(), &input, &["--tier", "linear"]);
    assert_eq!(output.status.code(), Some(0));
    // The secant to the top point: 50 kPa * 0.0829 / 0.2563.
    assert!((pressure(&linear, 2, 0) - 50.0 * 0.0829 / 0.2563).abs() < 0.01);
    let (_, piecewise) = run(directory.path(), &input, &["--tier", "piecewise-linear"]);
    assert!((pressure(&piecewise, 2, 0) - 10.0).abs() < 0.01);
    let (output, _) = run(directory.path(), &input, &["--tier", "cubic"]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("monotone-cubic"));
}

#[test]
fn calibration_file_replaces_the_curve() {
    let directory = tempfile::tempdir().unwrap();
    let mut spec = CalibrationSpec::default();
    for taxel in &mut spec.taxels {
        taxel.points = model_core::ARTICLE_TABLE_1
            .iter()
            .map(|point| CurvePoint::new(point.pressure_kpa, point.relative_change * 2.0))
            .collect();
    }
    let calibration = Calibration::new(&spec).unwrap();
    let calibration_path = directory.path().join("double.json");
    taxel_host::calibration_file::write(&calibration_path, &calibration).unwrap();
    let doubled_pf = 4.5 * (1.0 + 2.0 * 0.0829);
    let input = format!(
        "time_s,temp_c,c11_pf,c12_pf,c21_pf,c22_pf\n\
         0,25,4.5,4.5,4.5,4.5\n\
         1,25,{doubled_pf},{LOADED_10_KPA_PF},4.5,4.5\n"
    );
    let calibration_argument = calibration_path.to_str().unwrap();
    let (output, rows) = run(
        directory.path(),
        &input,
        &["--calibration", calibration_argument],
    );
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert!((pressure(&rows, 2, 0) - 10.0).abs() < 0.01);
    assert!(pressure(&rows, 2, 1) < 6.0);
    std::fs::write(&calibration_path, "{\"format\": \"other\"}").unwrap();
    let (output, _) = run(
        directory.path(),
        &input,
        &["--calibration", calibration_argument],
    );
    assert_eq!(output.status.code(), Some(1));
    assert!(stderr(&output).contains("not a calibration file"));
}

#[test]
fn missing_columns_fail_with_their_names() {
    let directory = tempfile::tempdir().unwrap();
    let (output, _) = run(directory.path(), "time_s,c11_pf,c12_pf\n0,4.5,4.5\n", &[]);
    assert_eq!(output.status.code(), Some(1));
    let messages = stderr(&output);
    assert!(
        messages.contains("temp_c") && messages.contains("c22_pf"),
        "{messages}"
    );
}

#[test]
fn raw_log_is_decoded_and_garbage_is_counted() {
    let directory = tempfile::tempdir().unwrap();
    let loaded_pf = LOADED_10_KPA_PF as f32;
    let mut bytes = Vec::new();
    bytes.extend(encoded(&DeviceFrame::Sample(sample(
        1,
        1_000_000,
        [(None, 4.5, 0x80); 4],
    ))));
    bytes.extend(b"garbage\0");
    bytes.extend(encoded(&DeviceFrame::Sample(sample(
        2,
        1_002_500,
        [
            (Some(1.0), loaded_pf, 0),
            (None, 4.5, 0x0100),
            (Some(0.0), 4.5, 0),
            (None, 4.5, 0x0200),
        ],
    ))));
    bytes.extend(&encoded(&DeviceFrame::Sample(sample(3, 3, [(None, 4.5, 0); 4])))[..9]);
    let raw_path = directory.path().join("recording.csv.raw");
    std::fs::write(&raw_path, &bytes).unwrap();
    let output = Command::new(taxel_binary())
        .args(["convert", "--raw"])
        .arg(&raw_path)
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let rows = parse_csv(&String::from_utf8(output.stdout.clone()).unwrap());
    assert_eq!(rows.len(), 3);
    assert_eq!(rows[1][0], "1.000000");
    assert_eq!(rows[2][0], "1.002500");
    assert_eq!(rows[2][1], "23.5");
    assert!((pressure(&rows, 2, 0) - 10.0).abs() < 0.01);
    assert_eq!(rows[2][7], "converter_error", "acquisition flags are kept");
    assert_eq!(rows[2][9], "stuck");
    assert_eq!(rows[2][4], "0");
    let messages = stderr(&output);
    assert!(
        messages.contains("2 undecodable frames (17 bytes)"),
        "{messages}"
    );
}
