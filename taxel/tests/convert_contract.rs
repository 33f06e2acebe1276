//! The `taxel convert` contract, run through the binary on temporary files: the output is the
//! input's rows, in order, with their identity, times, temperature and capacitances kept and
//! their pressures, flags, force, centre of pressure, partial and contact computed again; rows
//! that cannot be read are named by line and left out (status 3); the output is written under a
//! temporary name and renamed when complete, and may not be the input; each device's recorded
//! state beside the recording is used unless options replace it.
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use std::io::Write;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use model_core::{
    Calibration, CalibrationSpec, CurvePoint, PadModel, SampleInput, TaxelFlags, TaxelReading,
    TAXEL_COUNT,
};
use support::{encoded, sample, taxel_binary};
use taxel_host::device_state::{BaselineChange, RecordedDeviceState, RecordedPadState};
use taxel_host::schema::{header, PadReading, PadRow, RowReader, RowWriter};
use wire::{DeviceFrame, TemperatureSource};

/// 4.5 pF unloaded; dC/C0 of the article's table at 10 kPa.
const LOADED_10_KPA_PF: f32 = 4.5 * 1.0829;

/// A reading at `time_us` with these capacitances and temperature; its outputs empty.
fn reading(
    time_us: u64,
    temperature_c: Option<f32>,
    capacitance_pf: [Option<f32>; TAXEL_COUNT],
) -> PadReading {
    let temperature_source = if temperature_c.is_some() {
        TemperatureSource::Tmp117
    } else {
        TemperatureSource::None
    };
    PadReading::unconverted(time_us, temperature_c, temperature_source, capacitance_pf)
}

/// Device `device` pad `pad`'s row of set `sequence`.
fn pad_row(device: u32, pad: u8, sequence: u32, reading: Option<PadReading>) -> PadRow {
    PadRow {
        host_time_us: 1_700_000_000_123_456 + u64::from(sequence) * 10_000,
        device,
        pad,
        sequence,
        sync_error_us: Some(1_250),
        reading,
        marker: String::new(),
    }
}

/// Device 0 pad 0's row of set `sequence` at `time_s` and 25 °C.
fn row(sequence: u32, time_s: f64, capacitance_pf: [f32; TAXEL_COUNT]) -> PadRow {
    pad_row(
        0,
        0,
        sequence,
        Some(reading(
            (time_s * 1e6) as u64,
            Some(25.0),
            capacitance_pf.map(Some),
        )),
    )
}

fn recording(rows: &[PadRow]) -> Vec<u8> {
    let mut writer = RowWriter::new(Vec::new()).unwrap();
    for row in rows {
        writer.write(row).unwrap();
    }
    writer.into_inner()
}

/// The rows of a recording; panics on a row that cannot be read.
fn read_rows(bytes: &[u8]) -> Vec<PadRow> {
    let mut reader = RowReader::new(bytes).unwrap();
    let mut rows = Vec::new();
    while let Some(row) = reader.next_row() {
        rows.push(row.unwrap());
    }
    rows
}

/// The cells of every line (header included).
fn cells(bytes: &[u8]) -> Vec<Vec<String>> {
    csv::ReaderBuilder::new()
        .has_headers(false)
        .from_reader(bytes)
        .records()
        .map(|record| record.unwrap().iter().map(str::to_owned).collect())
        .collect()
}

/// `taxel convert input.csv -o output.csv EXTRA...` on `input` in `directory`: the output, and
/// the output's rows (empty when there is no output file).
fn run(directory: &Path, input: &[u8], extra_arguments: &[&str]) -> (Output, Vec<PadRow>) {
    let input_path = directory.join("input.csv");
    let output_path = directory.join("output.csv");
    let _ = std::fs::remove_file(&output_path);
    std::fs::write(&input_path, input).unwrap();
    let output = Command::new(taxel_binary())
        .arg("convert")
        .arg(&input_path)
        .arg("-o")
        .arg(&output_path)
        .args(extra_arguments)
        .output()
        .unwrap();
    let rows = std::fs::read(&output_path)
        .map(|bytes| read_rows(&bytes))
        .unwrap_or_default();
    (output, rows)
}

fn output_bytes(directory: &Path) -> Vec<u8> {
    std::fs::read(directory.join("output.csv")).unwrap()
}

fn pressure(rows: &[PadRow], row: usize, taxel: usize) -> f64 {
    f64::from(rows[row].reading.as_ref().unwrap().pressure_kpa[taxel].unwrap())
}

fn flags(rows: &[PadRow], row: usize, taxel: usize) -> TaxelFlags {
    rows[row].reading.as_ref().unwrap().flags[taxel]
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

fn leftovers(directory: &Path) -> Vec<String> {
    std::fs::read_dir(directory)
        .unwrap()
        .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.contains(".partial"))
        .collect()
}

/// Two pads of one device and a second device, with a missing frame: what the outputs of each
/// say is given wrong on purpose (`convert` must compute them again).
fn two_pads_and_two_devices(with_wrong_outputs: bool) -> Vec<PadRow> {
    let mut rows = vec![
        row(1, 0.00, [4.5; 4]),
        pad_row(0, 1, 1, Some(reading(2_000, Some(26.0), [Some(4.6); 4]))),
        pad_row(1, 0, 7, Some(reading(5_000, Some(24.0), [Some(4.4); 4]))),
        row(2, 0.01, [LOADED_10_KPA_PF, 4.5, 4.5, 4.5]),
        pad_row(0, 1, 2, None),
        pad_row(
            1,
            0,
            8,
            Some(reading(
                15_000,
                Some(24.0),
                [Some(4.4), Some(4.4 * 1.0829), Some(4.4), Some(4.4)],
            )),
        ),
        row(3, 0.02, [4.5, LOADED_10_KPA_PF, 4.5, 4.5]),
        pad_row(
            0,
            1,
            3,
            Some(reading(
                22_000,
                Some(26.0),
                [Some(4.6), Some(4.6), Some(4.6 * 1.0829), Some(4.6)],
            )),
        ),
    ];
    rows[0].marker = "tare, \"unloaded\"".to_owned();
    rows[5].sync_error_us = None;
    if with_wrong_outputs {
        for row in &mut rows {
            if let Some(reading) = &mut row.reading {
                reading.pressure_kpa = [Some(99.0), None, Some(-3.0), Some(1e6)];
                reading.flags = [TaxelFlags::SHORTED | TaxelFlags::NOT_TARED; TAXEL_COUNT];
                reading.force_n = Some(7.0);
                reading.centre_of_pressure_mm = Some([1.0, -1.0]);
                reading.partial = true;
            }
        }
    }
    rows
}

/// Replaces the old test of the header's order and the kept time text: the output is the
/// schema, one row per input row in order, every cell of identity, time, temperature and
/// capacitance as the input spelled it, and the outputs computed again (they do not depend on
/// what the input said), each pad of each device tared on its own first row.
#[test]
fn the_output_is_the_input_rows_with_their_outputs_computed_again() {
    let directory = tempfile::tempdir().unwrap();
    let input = recording(&two_pads_and_two_devices(true));
    let (output, rows) = run(directory.path(), &input, &[]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let converted = output_bytes(directory.path());
    assert!(
        converted.starts_with(format!("{}\n", header().join(",")).as_bytes()),
        "{}",
        String::from_utf8_lossy(&converted)
    );
    let (input_cells, output_cells) = (cells(&input), cells(&converted));
    assert_eq!(input_cells.len(), output_cells.len(), "one row per row");
    for (line, (before, after)) in input_cells.iter().zip(&output_cells).enumerate() {
        assert_eq!(
            before[..12],
            after[..12],
            "line {}: kept as written",
            line + 1
        );
        assert_eq!(before[25], after[25], "line {}: the marker", line + 1);
    }
    let messages = stderr(&output);
    assert!(
        messages.contains("device 0 pad 0, device 0 pad 1, device 1 pad 0 had no recorded state"),
        "{messages}"
    );
    assert!(messages.contains("1 pad frames were missing"), "{messages}");

    // Each pad's first row is its tare.
    for first in [0, 1, 2] {
        let reading = rows[first].reading.unwrap();
        assert_eq!(reading.pressure_kpa, [None; 4], "row {first}");
        assert_eq!(reading.flags, [TaxelFlags::NOT_TARED; 4], "row {first}");
        assert_eq!(reading.force_n, None);
    }
    assert!((pressure(&rows, 3, 0) - 10.0).abs() < 0.01);
    assert_eq!(pressure(&rows, 3, 1), 0.0);
    assert_eq!(flags(&rows, 3, 0), TaxelFlags::empty());
    assert_eq!(rows[4].reading, None, "a missing frame stays missing");
    assert!(
        (pressure(&rows, 5, 1) - 10.0).abs() < 0.01,
        "device 1's own tare"
    );
    assert!((pressure(&rows, 6, 1) - 10.0).abs() < 0.01);
    assert_eq!(pressure(&rows, 6, 0), 0.0);
    assert!(
        (pressure(&rows, 7, 2) - 10.0).abs() < 0.01,
        "pad 1's own tare"
    );
    for index in [3, 5, 6, 7] {
        let reading = rows[index].reading.unwrap();
        assert!(reading.force_n.unwrap() > 0.0, "row {index}: {reading:?}");
        assert!(reading.centre_of_pressure_mm.is_some());
        assert!(!reading.partial);
    }

    // What the input said about its outputs changes nothing (but a pad's first contact bit,
    // the state its stream started in: a recording can start during a contact).
    let (output, _) = run(
        directory.path(),
        &recording(&two_pads_and_two_devices(false)),
        &[],
    );
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(output_bytes(directory.path()), converted);
    // Converting the output again gives it back.
    let (output, _) = run(directory.path(), &converted, &[]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(output_bytes(directory.path()), converted);
}

#[test]
fn faulted_taxels_have_empty_pressure_and_flags_saying_why() {
    let directory = tempfile::tempdir().unwrap();
    let mut acquisition_flagged = row(4, 30.0, [4.5; 4]);
    if let Some(reading) = &mut acquisition_flagged.reading {
        // The acquisition's flags come from the device, not the model: they are kept.
        reading.flags[1] = TaxelFlags::CONVERTER_ERROR;
        reading.flags[2] = TaxelFlags::STUCK | TaxelFlags::SHORTED;
        reading.flags[3] = TaxelFlags::SATURATED;
    }
    let input = recording(&[
        row(1, 0.0, [4.5; 4]),
        pad_row(
            0,
            0,
            2,
            Some(reading(
                1_000_000,
                None,
                [Some(-0.3), Some(0.4), Some(4.3), Some(10.0)],
            )),
        ),
        pad_row(
            0,
            0,
            3,
            Some(reading(
                12_000_000,
                Some(70.0),
                [Some(4.5), Some(4.5), Some(4.5), None],
            )),
        ),
        acquisition_flagged,
    ]);
    let (output, rows) = run(directory.path(), &input, &[]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let row_2 = rows[1].reading.unwrap();
    assert_eq!(row_2.temperature_c, None, "missing temperature stays empty");
    assert_eq!(row_2.pressure_kpa[..2], [None, None]);
    let missing = TaxelFlags::TEMPERATURE_MISSING;
    assert_eq!(row_2.flags[0], TaxelFlags::SHORTED | missing);
    assert_eq!(row_2.flags[1], TaxelFlags::OPEN | missing);
    assert_eq!(
        row_2.pressure_kpa[2],
        Some(0.0),
        "below the baseline reads 0 kPa"
    );
    assert_eq!(row_2.flags[2], TaxelFlags::BELOW_BASELINE | missing);
    assert_eq!(row_2.flags[3], TaxelFlags::OVER_RANGE | missing);
    assert_eq!(row_2.pressure_kpa[3], Some(50.0));
    assert!(row_2.partial, "faulted taxels left out of the force");
    let row_3 = rows[2].reading.unwrap();
    assert_eq!(
        row_3.flags[3],
        TaxelFlags::TEMPERATURE_OUT_OF_RANGE | TaxelFlags::CONVERTER_ERROR
    );
    assert_eq!(row_3.pressure_kpa[3], None);
    assert_eq!(row_3.capacitance_pf[3], None, "an empty cell stays empty");
    assert_eq!(row_3.flags[0], TaxelFlags::TEMPERATURE_OUT_OF_RANGE);
    let row_4 = rows[3].reading.unwrap();
    assert_eq!(row_4.flags[0], TaxelFlags::empty());
    assert_eq!(row_4.pressure_kpa[0], Some(0.0));
    for (taxel, kept) in [
        (1, TaxelFlags::CONVERTER_ERROR),
        (2, TaxelFlags::STUCK),
        (3, TaxelFlags::SATURATED),
    ] {
        assert!(
            row_4.flags[taxel].contains(kept),
            "{:?}",
            row_4.flags[taxel]
        );
        assert!(
            !row_4.flags[taxel].contains(TaxelFlags::SHORTED),
            "a model flag is computed again"
        );
        assert_eq!(
            row_4.pressure_kpa[taxel], None,
            "a faulted taxel has no pressure"
        );
    }
}

/// The contract for rows that cannot be read changed from "written with empty cells" to "left
/// out": each is named with its line number and reason, every other row is converted, and the
/// status is 3.
#[test]
fn bad_rows_are_reported_with_line_numbers_and_left_out() {
    let directory = tempfile::tempdir().unwrap();
    let good = |sequence: u32, capacitance_pf: f32| {
        let text = String::from_utf8(recording(&[row(
            sequence,
            f64::from(sequence) * 0.1,
            [capacitance_pf, 4.5, 4.5, 4.5],
        )]))
        .unwrap();
        text.lines().nth(1).unwrap().to_owned()
    };
    let with_cell = |sequence: u32, column: usize, text: &str| {
        let mut cells: Vec<String> = good(sequence, 4.5).split(',').map(str::to_owned).collect();
        cells[column] = text.to_owned();
        cells.join(",")
    };
    let input = [
        header().join(","),
        good(1, 4.5),
        with_cell(2, 9, "abc"),
        good(3, 4.5)
            .split(',')
            .take(10)
            .collect::<Vec<_>>()
            .join(","),
        good(4, LOADED_10_KPA_PF),
        with_cell(5, 3, "x"),
        good(6, 4.5) + ",9",
        good(7, LOADED_10_KPA_PF),
    ]
    .join("\n")
        + "\n";
    let (output, rows) = run(directory.path(), input.as_bytes(), &[]);
    assert_eq!(output.status.code(), Some(3));
    let messages = stderr(&output);
    for line in ["line 3:", "line 4:", "line 6:", "line 7:"] {
        assert!(messages.contains(line), "{line} missing in {messages}");
    }
    for line in ["line 2:", "line 5:", "line 8:"] {
        assert!(!messages.contains(line), "{line} in {messages}");
    }
    assert!(messages.contains("c12_pf 'abc'"), "{messages}");
    assert!(messages.contains("seq 'x'"), "{messages}");
    assert!(
        messages.contains("4 rows could not be read (left out); 3 rows converted"),
        "{messages}"
    );
    let sequences: Vec<u32> = rows.iter().map(|row| row.sequence).collect();
    assert_eq!(sequences, [1, 4, 7], "only the rows that were read");
    assert!(
        (pressure(&rows, 1, 0) - 10.0).abs() < 0.01,
        "good rows still converted"
    );
    assert!((pressure(&rows, 2, 0) - 10.0).abs() < 0.01);
}

/// Replaces the test of free column order and ignored extra columns (the schema has one shape):
/// a header in another order or with another column is refused as a whole, with the header that
/// is expected; quoting (of every cell, header included) and a UTF-8 byte-order mark, which
/// spreadsheets add, change nothing.
#[test]
fn the_header_must_be_the_schema_and_quotes_and_a_byte_order_mark_are_read() {
    let directory = tempfile::tempdir().unwrap();
    let mut rows = vec![
        row(1, 0.0, [4.5, 4.4, 4.6, 4.3]),
        row(2, 0.5, [LOADED_10_KPA_PF, 4.6, 4.7, 4.3]),
    ];
    rows[0].marker = "tare, unloaded".to_owned();
    rows[1].marker = "pressed \"hard\"".to_owned();
    let plain = recording(&rows);
    let mut quoted = csv::WriterBuilder::new()
        .quote_style(csv::QuoteStyle::Always)
        .from_writer(b"\xef\xbb\xbf".to_vec());
    for line in cells(&plain) {
        quoted.write_record(&line).unwrap();
    }
    let quoted = quoted.into_inner().unwrap();
    assert!(quoted.starts_with(b"\xef\xbb\xbf\"host_time_s\",\"device\""));

    let (first_output, first) = run(directory.path(), &plain, &[]);
    assert_eq!(
        first_output.status.code(),
        Some(0),
        "{}",
        stderr(&first_output)
    );
    let first_bytes = output_bytes(directory.path());
    let (second_output, second) = run(directory.path(), &quoted, &[]);
    assert_eq!(
        second_output.status.code(),
        Some(0),
        "{}",
        stderr(&second_output)
    );
    assert_eq!(first, second);
    assert_eq!(output_bytes(directory.path()), first_bytes);
    assert_eq!(first[1].marker, "pressed \"hard\"");
    assert!((pressure(&first, 1, 0) - 10.0).abs() < 0.01);

    let text = String::from_utf8(plain).unwrap();
    let mut reordered = header();
    reordered.swap(8, 9);
    let with_extra = format!("{},note", header().join(","));
    for other_header in [reordered.join(","), with_extra] {
        let mut lines: Vec<&str> = text.lines().collect();
        lines[0] = &other_header;
        let (output, rows) = run(directory.path(), lines.join("\n").as_bytes(), &[]);
        let messages = stderr(&output);
        assert_eq!(output.status.code(), Some(1), "{messages}");
        assert!(
            messages.contains("the header is not a taxel recording's")
                && messages.contains(&format!("expected {}", header().join(","))),
            "{messages}"
        );
        assert!(rows.is_empty());
        assert!(!directory.path().join("output.csv").exists());
    }
}

#[test]
fn tare_rows_average_the_first_rows() {
    let directory = tempfile::tempdir().unwrap();
    // Still rows: a spread of 4 fF, within what converter noise explains.
    let input = recording(&[
        row(1, 0.0, [4.498, 4.5, 4.5, 4.5]),
        row(2, 1.0, [4.5, 4.5, 4.5, 4.5]),
        row(3, 2.0, [4.502, 4.5, 4.5, 4.5]),
        row(4, 3.0, [LOADED_10_KPA_PF, 4.5, 4.5, 4.5]),
    ]);
    let (output, rows) = run(directory.path(), &input, &["--tare-rows", "3"]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    for index in 0..3 {
        assert_eq!(flags(&rows, index, 0), TaxelFlags::NOT_TARED);
    }
    assert!((pressure(&rows, 3, 0) - 10.0).abs() < 0.01);
    let (_, one_row_tare) = run(directory.path(), &input, &[]);
    // Tared on 4.498 pF alone, 4.873 pF is dC/C0 = 0.08338 instead of 0.0829: about 0.06 kPa
    // more at Table 1's 0.0083 /kPa.
    let one_row = pressure(&one_row_tare, 3, 0);
    assert!((0.04..0.08).contains(&(one_row - 10.0)), "{one_row}");
    let (output, never) = run(directory.path(), &input, &["--tare-rows", "10"]);
    assert_eq!(output.status.code(), Some(0));
    assert!(
        stderr(&output).contains("device 0 pad 0: the tare never finished"),
        "{}",
        stderr(&output)
    );
    assert_eq!(flags(&never, 3, 0), TaxelFlags::NOT_TARED);
    assert_eq!(never[3].reading.unwrap().pressure_kpa, [None; 4]);
}

#[test]
fn a_tare_over_rows_that_are_not_still_is_refused_with_the_reason() {
    let directory = tempfile::tempdir().unwrap();
    // c11 drifts by 0.1 pF per row during the tare (pressed or moving): 81 fF of spread.
    let input = recording(&[
        row(1, 0.0, [4.4, 4.5, 4.5, 4.5]),
        row(2, 1.0, [4.5, 4.5, 4.5, 4.5]),
        row(3, 2.0, [4.6, 4.5, 4.5, 4.5]),
        row(4, 3.0, [LOADED_10_KPA_PF, 4.5, 4.5, 4.5]),
    ]);
    let (output, rows) = run(directory.path(), &input, &["--tare-rows", "3"]);
    assert_eq!(output.status.code(), Some(0));
    assert_eq!(flags(&rows, 3, 0), TaxelFlags::NOT_TARED);
    assert!(
        pressure(&rows, 3, 1).abs() < 0.01,
        "the still taxels are tared"
    );
    let warning = stderr(&output);
    assert!(
        warning.contains("taxel c11 could not be tared")
            && warning.contains("the pad was not still"),
        "{warning}"
    );
}

#[test]
fn tier_changes_the_inversion() {
    let directory = tempfile::tempdir().unwrap();
    let input = recording(&[
        row(1, 0.0, [4.5; 4]),
        row(2, 1.0, [LOADED_10_KPA_PF, 4.5, 4.5, 4.5]),
    ]);
    let (output, linear) = run(directory.path(), &input, &["--tier", "linear"]);
    assert_eq!(output.status.code(), Some(0));
    // The secant to the top point: 50 kPa * 0.0829 / 0.2563.
    assert!((pressure(&linear, 1, 0) - 50.0 * 0.0829 / 0.2563).abs() < 0.01);
    let (_, piecewise) = run(directory.path(), &input, &["--tier", "piecewise-linear"]);
    assert!((pressure(&piecewise, 1, 0) - 10.0).abs() < 0.01);
    let (output, _) = run(directory.path(), &input, &["--tier", "cubic"]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("monotone-cubic"));
}

/// A calibration whose curve is the article's with every dC/C0 doubled.
fn doubled_calibration() -> Calibration {
    let mut spec = CalibrationSpec::default();
    for taxel in &mut spec.taxels {
        taxel.points = model_core::ARTICLE_TABLE_1
            .iter()
            .map(|point| CurvePoint::new(point.pressure_kpa, point.relative_change * 2.0))
            .collect();
    }
    Calibration::new(&spec).unwrap()
}

#[test]
fn calibration_file_replaces_the_curve() {
    let directory = tempfile::tempdir().unwrap();
    let calibration_path = directory.path().join("double.json");
    taxel_host::calibration_file::write(&calibration_path, &doubled_calibration()).unwrap();
    let doubled_pf = 4.5 * (1.0 + 2.0 * 0.0829);
    let input = recording(&[
        row(1, 0.0, [4.5; 4]),
        row(2, 1.0, [doubled_pf, LOADED_10_KPA_PF, 4.5, 4.5]),
    ]);
    let calibration_argument = calibration_path.to_str().unwrap();
    let (output, rows) = run(
        directory.path(),
        &input,
        &["--calibration", calibration_argument],
    );
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert!((pressure(&rows, 1, 0) - 10.0).abs() < 0.01);
    assert!(pressure(&rows, 1, 1) < 6.0);
    std::fs::write(&calibration_path, "{\"format\": \"other\"}").unwrap();
    let (output, _) = run(
        directory.path(),
        &input,
        &["--calibration", calibration_argument],
    );
    assert_eq!(output.status.code(), Some(1));
    assert!(stderr(&output).contains("not a calibration file"));
    assert!(!directory.path().join("output.csv").exists());
}

/// Device 0's recorded state beside the recording (`input.csv.dev0.device.json`) gives its
/// calibration, tier and baselines from the first row on; device 1 has none and is converted
/// with the defaults; `--no-device-state` ignores the state, and options replace its parts.
#[test]
fn each_device_is_converted_with_its_recorded_state_unless_told_otherwise() {
    let directory = tempfile::tempdir().unwrap();
    let calibration = doubled_calibration();
    // Baselines tared at 4.6 pF and 25 °C with the doubled curve.
    let mut model = PadModel::new(calibration.clone());
    model.start_tare(1);
    model.process(&SampleInput::new(
        [TaxelReading::CapacitancePf(4.6); TAXEL_COUNT],
        Some(25.0),
    ));
    let mut state = RecordedDeviceState::new(&support::info(1));
    let mut pad = RecordedPadState::new(&wire::testing::pad_info_frame(0), &calibration).unwrap();
    pad.baselines = vec![BaselineChange {
        from_sequence: 0,
        taxels: model.baseline_records(),
    }];
    assert!(pad.baselines[0].taxels.iter().all(Option::is_some));
    state.add_pad(pad);
    state
        .write(&directory.path().join("input.csv.dev0.device.json"))
        .unwrap();
    let loaded_pf = 4.6 * (1.0 + 2.0 * 0.0829);
    let input = recording(&[
        row(1, 0.0, [4.6; 4]),
        pad_row(1, 0, 1, Some(reading(0, Some(25.0), [Some(4.5); 4]))),
        row(2, 1.0, [loaded_pf, 4.6, 4.6, 4.6]),
        pad_row(
            1,
            0,
            2,
            Some(reading(
                1_000_000,
                Some(25.0),
                [Some(LOADED_10_KPA_PF), Some(4.5), Some(4.5), Some(4.5)],
            )),
        ),
    ]);

    let (output, rows) = run(directory.path(), &input, &[]);
    let messages = stderr(&output);
    assert_eq!(output.status.code(), Some(0), "{messages}");
    assert!(
        messages.contains("converting with the device state in")
            && messages.contains("input.csv.dev0.device.json"),
        "{messages}"
    );
    assert!(
        messages.contains("device 1 pad 0 had no recorded state")
            && !messages.contains("device 0 pad 0 had no"),
        "{messages}"
    );
    assert_eq!(
        pressure(&rows, 0, 0),
        0.0,
        "tared by the recorded baselines"
    );
    assert_eq!(flags(&rows, 0, 0), TaxelFlags::empty());
    assert!((pressure(&rows, 2, 0) - 10.0).abs() < 0.01, "{:?}", rows[2]);
    assert_eq!(
        flags(&rows, 1, 0),
        TaxelFlags::NOT_TARED,
        "device 1: defaults"
    );
    assert!((pressure(&rows, 3, 0) - 10.0).abs() < 0.01);

    let (output, ignored) = run(directory.path(), &input, &["--no-device-state"]);
    let messages = stderr(&output);
    assert_eq!(output.status.code(), Some(0), "{messages}");
    assert!(
        !messages.contains("converting with the device state"),
        "{messages}"
    );
    assert!(messages.contains("device 0 pad 0, device 1 pad 0 had no recorded state"));
    assert_eq!(flags(&ignored, 0, 0), TaxelFlags::NOT_TARED);
    // The default curve, tared on 4.6 pF: dC/C0 = 0.1658, about 23 kPa.
    assert!(pressure(&ignored, 2, 0) > 20.0, "{:?}", ignored[2]);

    let (output, linear) = run(directory.path(), &input, &["--tier", "linear"]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    // The recorded baselines and calibration, another tier: the secant of the doubled curve.
    assert!(
        (pressure(&linear, 2, 0) - 50.0 * 0.0829 / 0.2563).abs() < 0.01,
        "{:?}",
        linear[2]
    );
    let (output, retared) = run(directory.path(), &input, &["--tare-rows", "1"]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(flags(&retared, 0, 0), TaxelFlags::NOT_TARED);
    assert!((pressure(&retared, 2, 0) - 10.0).abs() < 0.01);
}

/// Replaces the test of missing columns being named: any other shape is refused as a whole,
/// saying what was expected and what was found, and nothing is written.
#[test]
fn a_file_of_another_shape_is_refused_with_the_expected_header() {
    let directory = tempfile::tempdir().unwrap();
    let (output, _) = run(directory.path(), b"time_s,c11_pf,c12_pf\n0,4.5,4.5\n", &[]);
    assert_eq!(output.status.code(), Some(1));
    let messages = stderr(&output);
    assert!(
        messages.contains(&format!("expected {}", header().join(",")))
            && messages.contains("found time_s,c11_pf,c12_pf")
            && messages.contains("earlier versions are not read"),
        "{messages}"
    );
    assert!(!directory.path().join("output.csv").exists());
    assert!(leftovers(directory.path()).is_empty());
}

#[test]
fn raw_log_is_decoded_and_garbage_is_counted() {
    let directory = tempfile::tempdir().unwrap();
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
            (Some(1.0), LOADED_10_KPA_PF, 0),
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
    let text = cells(&output.stdout);
    assert_eq!(text[0].join(","), header().join(","));
    assert_eq!(
        text[1][0], "1.000000",
        "a raw log's host time is its device time"
    );
    assert_eq!(text[2][0], "1.002500");
    let rows = read_rows(&output.stdout);
    assert_eq!(rows.len(), 2);
    assert_eq!(rows[1].sequence, 2);
    assert_eq!(rows[1].sync_error_us, None);
    let reading = rows[1].reading.unwrap();
    assert_eq!(reading.temperature_c, Some(23.5));
    assert!((pressure(&rows, 1, 0) - 10.0).abs() < 0.01);
    assert_eq!(
        reading.flags[1],
        TaxelFlags::CONVERTER_ERROR,
        "acquisition flags are kept"
    );
    assert_eq!(reading.flags[3], TaxelFlags::STUCK);
    assert_eq!(reading.pressure_kpa[2], Some(0.0));
    let messages = stderr(&output);
    assert!(
        messages.contains("2 undecodable frames (17 bytes)"),
        "{messages}"
    );
}

/// The output is written under a temporary name beside it and renamed over it when complete:
/// while the conversion runs the old file is untouched and a `.partial` file is being written;
/// a run that fails or is killed leaves the old file as it was; a finished run replaces the file
/// (a new file renamed into place: another link to the old one keeps the old bytes).
#[test]
fn the_output_is_written_under_a_temporary_name_then_renamed() {
    let directory = tempfile::tempdir().unwrap();
    let output_path = directory.path().join("out.csv");
    let old_link = directory.path().join("old-link.csv");
    std::fs::write(&output_path, "precious\n").unwrap();
    std::fs::hard_link(&output_path, &old_link).unwrap();
    let input = recording(&[row(1, 0.0, [4.5; 4]), row(2, 1.0, [4.6; 4])]);
    let (header_line, rows) = input.split_at(input.iter().position(|&b| b == b'\n').unwrap() + 1);

    let convert_stdin = || {
        Command::new(taxel_binary())
            .current_dir(directory.path())
            .args(["convert", "-", "-o", "out.csv"])
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let wait_for_partial = || {
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            let partial = leftovers(directory.path());
            if !partial.is_empty() {
                return partial;
            }
            assert!(Instant::now() < deadline, "no temporary file appeared");
            std::thread::sleep(Duration::from_millis(20));
        }
    };

    // Killed half-way: the old file is untouched.
    let mut killed = convert_stdin();
    killed
        .stdin
        .as_mut()
        .unwrap()
        .write_all(header_line)
        .unwrap();
    wait_for_partial();
    killed.kill().unwrap();
    killed.wait().unwrap();
    assert_eq!(std::fs::read_to_string(&output_path).unwrap(), "precious\n");
    for name in leftovers(directory.path()) {
        std::fs::remove_file(directory.path().join(name)).unwrap();
    }

    // Half-way, then finished.
    let mut child = convert_stdin();
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(header_line).unwrap();
    stdin.flush().unwrap();
    let partial = wait_for_partial();
    assert_eq!(partial.len(), 1);
    assert!(partial[0].starts_with(".out.csv."), "{partial:?}");
    assert_eq!(std::fs::read_to_string(&output_path).unwrap(), "precious\n");
    stdin.write_all(rows).unwrap();
    drop(stdin);
    let finished = child.wait_with_output().unwrap();
    assert_eq!(
        finished.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&finished.stderr)
    );
    assert_eq!(read_rows(&std::fs::read(&output_path).unwrap()).len(), 2);
    assert_eq!(
        std::fs::read_to_string(&old_link).unwrap(),
        "precious\n",
        "a new file was renamed into place, the old one was not rewritten"
    );
    assert!(leftovers(directory.path()).is_empty());

    // A run that fails after it began writing (a recording without rows) leaves it as it was.
    let before = std::fs::read(&output_path).unwrap();
    std::fs::write(directory.path().join("empty.csv"), header_line).unwrap();
    let output = Command::new(taxel_binary())
        .current_dir(directory.path())
        .args(["convert", "empty.csv", "-o", "out.csv"])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    assert!(stderr(&output).contains("the recording has no rows"));
    assert_eq!(std::fs::read(&output_path).unwrap(), before);
    assert!(leftovers(directory.path()).is_empty());
}

/// The output may not be the input, however it is named; the input is left as it was.
#[test]
fn the_output_may_not_be_the_input() {
    let directory = tempfile::tempdir().unwrap();
    let input = recording(&[row(1, 0.0, [4.5; 4])]);
    std::fs::write(directory.path().join("rec.csv"), &input).unwrap();
    std::fs::write(directory.path().join("rec.csv.dev0.raw"), b"raw bytes").unwrap();
    std::fs::hard_link(
        directory.path().join("rec.csv"),
        directory.path().join("hard.csv"),
    )
    .unwrap();
    std::os::unix::fs::symlink("rec.csv", directory.path().join("soft.csv")).unwrap();
    for arguments in [
        &["convert", "rec.csv", "-o", "rec.csv"][..],
        &["convert", "rec.csv", "-o", "./rec.csv"][..],
        &["convert", "rec.csv", "-o", "hard.csv"][..],
        &["convert", "rec.csv", "-o", "soft.csv"][..],
        &[
            "convert",
            "--raw",
            "rec.csv.dev0.raw",
            "-o",
            "rec.csv.dev0.raw",
        ][..],
    ] {
        let output = Command::new(taxel_binary())
            .current_dir(directory.path())
            .args(arguments)
            .output()
            .unwrap();
        let messages = stderr(&output);
        assert_eq!(output.status.code(), Some(1), "{arguments:?}: {messages}");
        assert!(
            messages.contains("is the input"),
            "{arguments:?}: {messages}"
        );
        assert_eq!(
            std::fs::read(directory.path().join("rec.csv")).unwrap(),
            input
        );
        assert_eq!(
            std::fs::read(directory.path().join("rec.csv.dev0.raw")).unwrap(),
            b"raw bytes"
        );
        assert!(leftovers(directory.path()).is_empty());
    }
}

/// The exit status says what happened: 0 every row converted, 3 some rows left out, 1 nothing
/// converted (an error), 2 a wrong command line.
#[test]
fn exit_statuses_say_what_happened() {
    let directory = tempfile::tempdir().unwrap();
    let good = recording(&[row(1, 0.0, [4.5; 4]), row(2, 1.0, [4.6; 4])]);
    let mut with_bad_row = good.clone();
    with_bad_row.extend_from_slice(b"1,0,0,3\n");
    for (input, arguments, status) in [
        (&good[..], &[][..], 0),
        (&with_bad_row[..], &[][..], 3),
        (&b"time_s\n0\n"[..], &[][..], 1),
        (&good[..], &["--tare-rows", "0"][..], 2),
        (&good[..], &["--tier", "none"][..], 2),
        (&good[..], &["--no-such-option"][..], 2),
    ] {
        let (output, _) = run(directory.path(), input, arguments);
        assert_eq!(
            output.status.code(),
            Some(status),
            "{arguments:?}: {}",
            stderr(&output)
        );
        assert!(!stderr(&output).contains("panicked"));
    }
    let output = Command::new(taxel_binary())
        .arg("convert")
        .output()
        .unwrap();
    assert_eq!(
        output.status.code(),
        Some(2),
        "no input: {}",
        stderr(&output)
    );
}
