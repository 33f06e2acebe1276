//! Devices with several pads: synthetic streams of one sample frame per pad per set, encoded
//! with the wire crate and fed through the link, recorded one row per set, and converted back.
// Helpers outside #[test] functions unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;
use support::info;

use std::collections::HashMap;
use std::process::Command;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use model_core::{Calibration, PadModel, SampleInput, TaxelReading};
use support::{encoded, taxel_binary, ChunkedReader, SplitMix64};
use taxel_host::convert::{convert_csv, convert_raw, ConvertOptions};
use taxel_host::device_link::DeviceLink;
use taxel_host::record::{record_link, StopReason};
use taxel_host::record_rows::RecordRows;
use wire::{DeviceFrame, PadIndex, PadSummary, SampleFrame, TaxelSample, TemperatureSource};

/// A frame whose every value tells its pad and set apart: capacitance 4.5 + pad/10 +
/// taxel/100 + set/1000 pF, pressure 10 x pad + taxel + set/10 kPa, temperature 20 + pad °C,
/// taxel 3 of odd pads flagged below_baseline, force pad + 0.5 N, centre (pad, -set) mm.
fn frame(pad: u8, sequence: u32) -> SampleFrame {
    let set = sequence as f32;
    let pad_value = f32::from(pad);
    SampleFrame {
        pad: PadIndex::new(pad).unwrap(),
        sequence,
        timestamp_us: u64::from(sequence) * 10_000 + u64::from(pad) * 300,
        temperature_c: Some(20.0 + pad_value),
        temperature_source: if pad.is_multiple_of(2) {
            TemperatureSource::Tmp117
        } else {
            TemperatureSource::McuInternal
        },
        taxels: std::array::from_fn(|taxel| TaxelSample {
            pressure_kpa: Some(10.0 * pad_value + taxel as f32 + set / 10.0),
            capacitance_pf: 4.5 + pad_value / 10.0 + taxel as f32 / 100.0 + set / 1000.0,
            flags: if taxel == 3 && pad % 2 == 1 {
                0x0001
            } else {
                0
            },
        }),
        summary: PadSummary {
            force_n: Some(pad_value + 0.5),
            centre_of_pressure_mm: Some([pad_value, -set]),
            partial: pad == 2,
            contact: pad % 2 == 1,
        },
    }
}

/// The CSV rows by column name.
fn rows_by_name(text: &str) -> (Vec<String>, Vec<HashMap<String, String>>) {
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let header: Vec<String> = reader
        .headers()
        .unwrap()
        .iter()
        .map(str::to_owned)
        .collect();
    let rows = reader
        .records()
        .map(|record| {
            let record = record.unwrap();
            assert_eq!(record.len(), header.len());
            header
                .iter()
                .cloned()
                .zip(record.iter().map(str::to_owned))
                .collect()
        })
        .collect();
    (header, rows)
}

/// The recorded cells `frame(pad, sequence)` must give, by column name.
fn expected_cells(pad: u8, sequence: u32) -> Vec<(String, String)> {
    let frame = frame(pad, sequence);
    let mut cells: Vec<(String, String)> = vec![
        (
            "time_s".into(),
            taxel_host::csv_format::format_time_us(frame.timestamp_us),
        ),
        ("temp_c".into(), format!("{}", 20 + u32::from(pad))),
        (
            "temp_source".into(),
            if pad.is_multiple_of(2) {
                "tmp117"
            } else {
                "mcu_internal"
            }
            .into(),
        ),
        ("force_n".into(), format!("{}", f32::from(pad) + 0.5)),
        ("cop_x_mm".into(), format!("{}", f32::from(pad))),
        ("cop_y_mm".into(), format!("{}", -(sequence as f32))),
        ("partial".into(), if pad == 2 { "1" } else { "0" }.into()),
        (
            "contact".into(),
            if pad % 2 == 1 { "1" } else { "0" }.into(),
        ),
    ];
    for (taxel, name) in ["11", "12", "21", "22"].iter().enumerate() {
        let sample = frame.taxels[taxel];
        cells.push((format!("c{name}_pf"), format!("{}", sample.capacitance_pf)));
        cells.push((
            format!("p{name}_kpa"),
            format!("{}", sample.pressure_kpa.unwrap()),
        ));
        let flags = if sample.flags != 0 {
            "below_baseline"
        } else {
            ""
        };
        cells.push((format!("flags{name}"), flags.into()));
    }
    cells
        .into_iter()
        .map(|(name, value)| (format!("pad{pad}_{name}"), value))
        .collect()
}

fn assert_pad_recorded(row: &HashMap<String, String>, pad: u8, sequence: u32) {
    assert_eq!(row["seq"], sequence.to_string());
    for (column, value) in expected_cells(pad, sequence) {
        assert_eq!(row[&column], value, "{column} of set {sequence}");
    }
}

fn assert_pad_missing(row: &HashMap<String, String>, pad: u8) {
    let prefix = format!("pad{pad}_");
    let cells: Vec<_> = row
        .iter()
        .filter(|(name, _)| name.starts_with(&prefix))
        .collect();
    assert_eq!(cells.len(), 20);
    for (name, value) in cells {
        assert_eq!(value, "", "{name} of a missing frame");
    }
}

/// What a recording through the link gave.
struct Recorded {
    text: String,
    summary: taxel_host::record::RecordSummary,
    rows: u64,
    incomplete_rows: u64,
    missing_of_pad: Vec<u64>,
    beyond_pad_count: u64,
}

/// Records `frames` (after an Info of `pad_count` pads) through the link into a multi-pad CSV.
fn record(pad_count: u8, frames: &[DeviceFrame], limit: Option<u64>) -> Recorded {
    let mut bytes = encoded(&DeviceFrame::Info(info(pad_count)));
    for frame in frames {
        bytes.extend(encoded(frame));
    }
    let mut link = DeviceLink::new(ChunkedReader::new(bytes, vec![13, 64, 5]));
    let mut rows = RecordRows::from_writer(Vec::new(), pad_count).unwrap();
    let summary = record_link(
        &mut link,
        &mut rows,
        &AtomicBool::new(false),
        limit,
        Duration::from_secs(5),
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(link.pad_count(), Some(pad_count));
    rows.end_of_stream().unwrap();
    let recorded_rows = rows.rows();
    let incomplete_rows = rows.incomplete_rows();
    let missing_of_pad = (0..usize::from(pad_count))
        .map(|pad| rows.missing_of_pad(pad))
        .collect();
    let text = String::from_utf8(rows.finish().unwrap().into_inner().unwrap()).unwrap();
    Recorded {
        text,
        summary,
        rows: recorded_rows,
        incomplete_rows,
        missing_of_pad,
        beyond_pad_count: link.statistics().samples_beyond_pad_count,
    }
}

fn samples(frames: impl IntoIterator<Item = SampleFrame>) -> Vec<DeviceFrame> {
    frames.into_iter().map(DeviceFrame::Sample).collect()
}

#[test]
fn two_pads_land_in_their_columns_and_a_missing_frame_empties_only_its_pad() {
    let mut frames = Vec::new();
    for sequence in 1..=5 {
        for pad in 0..2 {
            // Pad 1's frame of set 2 and pad 0's of set 4 are lost.
            if (pad, sequence) != (1, 2) && (pad, sequence) != (0, 4) {
                frames.push(frame(pad, sequence));
            }
        }
    }
    // A frame of a pad the device does not have: a protocol violation, set aside.
    frames.insert(3, frame(5, 2));
    let recorded = record(2, &samples(frames), None);
    let (header, rows) = rows_by_name(&recorded.text);
    assert_eq!(header.len(), 1 + 2 * 20 + 1);
    assert_eq!(header[0], "seq");
    assert_eq!(header[1], "pad0_time_s");
    assert_eq!(header[21], "pad1_time_s");
    assert_eq!(header[41], "marker");
    assert_eq!(rows.len(), 5, "one row per sample set");
    for (index, row) in rows.iter().enumerate() {
        let sequence = index as u32 + 1;
        match sequence {
            2 => {
                assert_pad_recorded(row, 0, 2);
                assert_pad_missing(row, 1);
            }
            4 => {
                assert_pad_missing(row, 0);
                assert_pad_recorded(row, 1, 4);
            }
            _ => {
                assert_pad_recorded(row, 0, sequence);
                assert_pad_recorded(row, 1, sequence);
            }
        }
        assert_eq!(row["marker"], "");
    }
    assert_eq!(recorded.rows, 5);
    assert_eq!(recorded.incomplete_rows, 2);
    assert_eq!(recorded.missing_of_pad, [1, 1]);
    assert_eq!(recorded.beyond_pad_count, 1);
    let accounting = &recorded.summary.accounting;
    assert_eq!(recorded.summary.samples, 8, "frames received, every pad's");
    assert_eq!(accounting.received_of_pad(0), 4);
    assert_eq!(accounting.received_of_pad(1), 4);
    assert_eq!(accounting.sequence_gap_of_pad(0), 1);
    assert_eq!(accounting.sequence_gap_of_pad(1), 1);
    assert_eq!(accounting.lost_on_link(), 2);
    assert_eq!(
        recorded.summary.stop_reason,
        StopReason::Disconnected("the device closed the connection (unplugged?)".to_owned())
    );
}

#[test]
fn eight_pads_each_in_its_columns_with_one_pad_missing_a_set() {
    let mut frames = Vec::new();
    for sequence in 10..=12 {
        for pad in 0..8 {
            if (pad, sequence) != (5, 11) {
                frames.push(frame(pad, sequence));
            }
        }
    }
    let recorded = record(8, &samples(frames), None);
    let (header, rows) = rows_by_name(&recorded.text);
    assert_eq!(header.len(), 1 + 8 * 20 + 1);
    assert_eq!(header[1 + 7 * 20], "pad7_time_s");
    assert_eq!(rows.len(), 3);
    for (index, row) in rows.iter().enumerate() {
        let sequence = 10 + index as u32;
        for pad in 0..8 {
            if (pad, sequence) == (5, 11) {
                assert_pad_missing(row, pad);
            } else {
                assert_pad_recorded(row, pad, sequence);
            }
        }
    }
    assert_eq!(recorded.missing_of_pad, [0, 0, 0, 0, 0, 1, 0, 0]);
    let accounting = &recorded.summary.accounting;
    assert_eq!(accounting.sequence_gap_of_pad(5), 1);
    assert_eq!(
        (0..8)
            .map(|pad| accounting.sequence_gap_of_pad(pad))
            .sum::<u64>(),
        1
    );
    assert_eq!(accounting.received(), 23);
}

#[test]
fn a_missing_last_frame_of_the_stream_is_an_incomplete_row_not_a_complete_one() {
    let frames = samples([frame(0, 1), frame(1, 1), frame(2, 1), frame(0, 2)]);
    let recorded = record(3, &frames, None);
    let (_, rows) = rows_by_name(&recorded.text);
    assert_eq!(rows.len(), 2);
    assert_pad_recorded(&rows[1], 0, 2);
    assert_pad_missing(&rows[1], 1);
    assert_pad_missing(&rows[1], 2);
    assert_eq!(recorded.incomplete_rows, 1);
}

#[test]
fn the_sample_limit_counts_sample_sets() {
    let mut frames = Vec::new();
    for sequence in 1..=4 {
        for pad in 0..2 {
            frames.push(frame(pad, sequence));
        }
    }
    let recorded = record(2, &samples(frames.clone()), Some(2));
    assert_eq!(recorded.summary.stop_reason, StopReason::SampleLimit);
    let (_, rows) = rows_by_name(&recorded.text);
    assert_eq!(rows.len(), 2);
    assert_pad_recorded(&rows[1], 1, 2);
    // Set 2 lacks pad 1: the limit is reached when set 3 begins, and set 3 is not recorded.
    frames.remove(3);
    let recorded = record(2, &samples(frames), Some(2));
    assert_eq!(recorded.summary.stop_reason, StopReason::SampleLimit);
    let (_, rows) = rows_by_name(&recorded.text);
    assert_eq!(rows.len(), 2);
    assert_pad_recorded(&rows[1], 0, 2);
    assert_pad_missing(&rows[1], 1);
}

#[test]
fn a_single_pad_device_records_the_single_pad_layout_unchanged() {
    let frames = samples([frame(0, 1), frame(0, 2)]);
    let recorded = record(1, &frames, None);
    let lines: Vec<&str> = recorded.text.split("\r\n").collect();
    assert_eq!(
        lines[0],
        "seq,time_s,temp_c,temp_source,c11_pf,c12_pf,c21_pf,c22_pf,p11_kpa,p12_kpa,p21_kpa,p22_kpa,flags11,flags12,flags21,flags22,marker"
    );
    assert_eq!(
        lines[1],
        "1,0.010000,20,tmp117,4.501,4.511,4.521,4.531,0.1,1.1,2.1,3.1,,,,,"
    );
    assert_eq!(lines.len(), 4);
}

/// Frames of `pad_count` pads whose pressures are those the host model gives with the default
/// calibration and a tare on each pad's first set (as the device would compute them), with
/// capacitances that differ per pad and set; one frame of pad 1 is missing.
fn device_computed_frames(pad_count: u8) -> Vec<SampleFrame> {
    let mut noise = SplitMix64(11);
    let mut models: Vec<PadModel> = (0..pad_count)
        .map(|_| {
            let mut model = PadModel::new(Calibration::default());
            model.start_tare(1);
            model
        })
        .collect();
    let mut frames = Vec::new();
    for sequence in 0..40u32 {
        for pad in 0..pad_count {
            let load = if sequence == 0 {
                0.0
            } else {
                0.02 * f64::from(pad + 1) * (1.0 + (f64::from(sequence) * 0.3).sin())
            };
            let readings: [TaxelReading; 4] = std::array::from_fn(|taxel| {
                let unloaded = 4.5 + 0.05 * f64::from(pad) + 0.01 * taxel as f64;
                TaxelReading::CapacitancePf(
                    (unloaded * (1.0 + load / (taxel as f64 + 1.0)) + 0.0005 * noise.symmetric())
                        as f32,
                )
            });
            let timestamp_us = u64::from(sequence) * 10_000 + u64::from(pad) * 250;
            let input = SampleInput::new(readings, Some(24.0)).at_time_us(timestamp_us);
            let output = models[usize::from(pad)].process(&input);
            if (pad, sequence) == (1, 17) {
                continue;
            }
            frames.push(SampleFrame {
                pad: PadIndex::new(pad).unwrap(),
                sequence,
                timestamp_us,
                temperature_c: Some(24.0),
                temperature_source: TemperatureSource::Tmp117,
                taxels: std::array::from_fn(|taxel| TaxelSample {
                    pressure_kpa: output.taxels[taxel].pressure_kpa(),
                    capacitance_pf: match readings[taxel] {
                        TaxelReading::CapacitancePf(value) => value,
                        _ => f32::NAN,
                    },
                    flags: output.taxels[taxel].flags().bits(),
                }),
                summary: PadSummary::default(),
            });
        }
    }
    frames
}

fn assert_same_pressures(recorded_text: &str, converted_text: &str, pad_count: u8) {
    let (_, recorded) = rows_by_name(recorded_text);
    let (header, converted) = rows_by_name(converted_text);
    assert_eq!(header[0], "seq");
    assert_eq!(header.len(), 1 + usize::from(pad_count) * 10);
    assert_eq!(converted.len(), recorded.len());
    let mut compared = 0;
    for (device, host) in recorded.iter().zip(&converted) {
        assert_eq!(device["seq"], host["seq"]);
        for pad in 0..pad_count {
            let time = format!("pad{pad}_time_s");
            assert_eq!(device[&time], host[&time]);
            for name in ["p11_kpa", "p12_kpa", "p21_kpa", "p22_kpa"] {
                let column = format!("pad{pad}_{name}");
                let (device_cell, host_cell) = (&device[&column], &host[&column]);
                if device_cell.is_empty() || host_cell.is_empty() {
                    assert_eq!(device_cell, host_cell, "{column} of set {}", device["seq"]);
                    continue;
                }
                let device_kpa: f64 = device_cell.parse().unwrap();
                let host_kpa: f64 = host_cell.parse().unwrap();
                assert!(
                    (device_kpa - host_kpa).abs() < 1e-4,
                    "{column} of set {}: device {device_kpa}, host {host_kpa}",
                    device["seq"]
                );
                compared += 1;
            }
        }
    }
    assert!(compared > 4 * 30 * usize::from(pad_count), "{compared}");
}

#[test]
fn record_then_convert_gives_the_same_pressures_for_every_pad() {
    for pad_count in [2u8, 8] {
        let frames = samples(device_computed_frames(pad_count));
        let recorded = record(pad_count, &frames, None);
        assert_eq!(recorded.missing_of_pad[1], 1);
        let (_, recorded_rows) = rows_by_name(&recorded.text);
        let loaded = recorded_rows
            .iter()
            .filter(|row| {
                row["pad1_p11_kpa"]
                    .parse::<f64>()
                    .is_ok_and(|kpa| kpa > 1.0)
            })
            .count();
        assert!(
            loaded > 20,
            "the synthetic load reaches the pressures: {loaded}"
        );
        let mut converted = Vec::new();
        let summary = convert_csv(
            recorded.text.as_bytes(),
            &mut converted,
            &ConvertOptions::default(),
        )
        .unwrap();
        assert_eq!(summary.pad_count, pad_count);
        assert_eq!(summary.missing_pad_frames, 1);
        assert!(summary.bad_rows.is_empty(), "{:?}", summary.bad_rows);
        let converted = String::from_utf8(converted).unwrap();
        assert_same_pressures(&recorded.text, &converted, pad_count);
        let row_17 = converted.lines().nth(18).unwrap();
        assert!(row_17.starts_with("17,"), "{row_17}");

        // The raw log converts to the same rows when the pad count is known.
        let mut raw = Vec::new();
        for frame in &frames {
            raw.extend(encoded(frame));
        }
        let mut from_raw = Vec::new();
        let options = ConvertOptions {
            pad_count,
            ..ConvertOptions::default()
        };
        let summary = convert_raw(raw.as_slice(), &mut from_raw, &options).unwrap();
        assert_eq!(summary.missing_pad_frames, 1);
        assert_eq!(String::from_utf8(from_raw).unwrap(), converted);
    }
}

#[test]
fn a_raw_log_of_several_pads_without_its_pad_count_converts_pad_0_and_says_so() {
    let mut raw = Vec::new();
    for frame in samples(device_computed_frames(2)) {
        raw.extend(encoded(&frame));
    }
    let mut output = Vec::new();
    let summary = convert_raw(raw.as_slice(), &mut output, &ConvertOptions::default()).unwrap();
    assert_eq!(summary.rows_written, 40);
    assert_eq!(summary.frames_of_other_pads, 39);
}

fn convert_file(input: &str) -> std::process::Output {
    let directory = tempfile::tempdir().unwrap();
    let input_path = directory.path().join("input.csv");
    std::fs::write(&input_path, input).unwrap();
    Command::new(taxel_binary())
        .arg("convert")
        .arg(&input_path)
        .arg("-o")
        .arg(directory.path().join("output.csv"))
        .output()
        .unwrap()
}

#[test]
fn a_multi_pad_header_out_of_order_or_lacking_a_column_is_a_clear_error() {
    let pad = |n: usize| {
        ["time_s", "temp_c", "c11_pf", "c12_pf", "c21_pf", "c22_pf"]
            .map(|name| format!("pad{n}_{name}"))
            .join(",")
    };
    let row = "1,0.1,25,4.5,4.5,4.5,4.5,0.1,25,4.5,4.5,4.5,4.5
";
    let out_of_order = format!(
        "seq,{},{}
{row}",
        pad(1),
        pad(0)
    );
    let output = convert_file(&out_of_order);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("out of order"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let lacking = format!(
        "seq,{},{}
{row}",
        pad(0),
        pad(1).replace(",pad1_c12_pf", "")
    );
    let output = convert_file(&lacking);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("pad1_c12_pf"), "{stderr}");
    let without_seq = format!(
        "{},{}
{}",
        pad(0),
        pad(1),
        &row[2..]
    );
    let output = convert_file(&without_seq);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("lacks the column seq"), "{stderr}");
    let good = format!(
        "seq,{},{}
{row}2,0.2,25,4.5,4.5,abc,4.5,,,,,,
",
        pad(0),
        pad(1)
    );
    let output = convert_file(&good);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("line 3: pad0_c21_pf"), "{stderr}");
    assert!(stderr.contains("1 pad frames were missing"), "{stderr}");
}

#[test]
fn a_recording_file_of_two_pads_converts_with_its_device_state_from_csv_and_raw() {
    use std::io::Write;
    use taxel_host::recording::{RecordedDeviceState, Recording};
    let directory = tempfile::tempdir().unwrap();
    let csv_path = directory.path().join("rec.csv");
    let raw_path = directory.path().join("rec.csv.raw");
    let (mut recording, raw_writer) =
        Recording::create_with_pads(&csv_path, Some(&raw_path), 2).unwrap();
    let mut raw_writer = raw_writer.unwrap();
    recording.set_device_state(RecordedDeviceState::new(&info(2), &Calibration::default()));
    for frame in device_computed_frames(2) {
        raw_writer
            .write_all(&encoded(&DeviceFrame::Sample(frame)))
            .unwrap();
        recording.write_sample(&frame).unwrap();
    }
    let files = recording.finish(Some(raw_writer)).unwrap();
    assert_eq!(files.samples, 40);
    assert!(
        files.incomplete.as_deref().unwrap().contains("pad 1: 1"),
        "{:?}",
        files.incomplete
    );
    let state = std::fs::read_to_string(files.device_state.unwrap()).unwrap();
    assert!(state.contains("\"pad_count\": 2"), "{state}");
    let recorded = std::fs::read_to_string(&csv_path).unwrap();
    let mut converted = Vec::new();
    for raw in [false, true] {
        let output_path = directory.path().join(format!("out-{raw}.csv"));
        let mut command = Command::new(taxel_binary());
        command.arg("convert");
        if raw {
            command.arg("--raw").arg(&raw_path);
        } else {
            command.arg(&csv_path);
        }
        let output = command.arg("-o").arg(&output_path).output().unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(0), "{stderr}");
        assert!(stderr.contains("for each of the 2 pads"), "{stderr}");
        assert!(stderr.contains("1 pad frames were missing"), "{stderr}");
        let text = std::fs::read_to_string(&output_path).unwrap();
        assert_same_pressures(&recorded, &text, 2);
        converted.push(text);
    }
    assert_eq!(converted[0], converted[1]);
}
