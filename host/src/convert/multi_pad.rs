//! Converting a recording of several pads: a CSV file in the pad-prefixed layout of
//! [`crate::pad_set`] (recognised from its header), or a raw log whose device state says how
//! many pads there are. Each pad runs through a model of its own with its own calibration, tier
//! and baselines ([`ConvertOptions::pad_options`]: the ones recorded for it, or pad 0's when the
//! device state describes pad 0 only, as files written before per-pad read-back do), and the
//! output is `seq`, then per pad `pad<n>_time_s,pad<n>_temp_c,pad<n>_p11_kpa..,pad<n>_flags11..`.
//!
//! A pad whose frame is missing from a set has every input cell empty; its output cells are all
//! empty too, and it is counted, not reported as a bad row. A pad whose cells cannot be read
//! makes the row a bad row (its time kept when readable, its other cells empty).

use std::io::{Read, Write};

use anyhow::{bail, Context};
use model_core::TAXEL_COUNT;
use wire::DeviceFrame;

use super::csv_input::{parse_sample, shortened, CsvColumns};
use super::pad_run::{frame_input, PadRun};
use super::{
    as_written, csv_writer, ensure_samples_decoded, next_record, read_frames, readable_time,
    BadRow, ConvertOptions, ConvertSummary,
};
use crate::csv_format::{
    format_optional, format_time_us, CsvDialect, FLAGS_COLUMNS, PRESSURE_COLUMNS,
    TEMPERATURE_COLUMN, TIME_COLUMN,
};
use crate::pad_set::{pad_column, pad_prefix, PadSet, PadSetAssembler, MAX_PAD_COUNT};
use crate::recording::SEQUENCE_COLUMN;

/// The output columns of one pad, without their prefix.
pub fn pad_output_columns() -> Vec<&'static str> {
    let mut columns = vec![TIME_COLUMN, TEMPERATURE_COLUMN];
    columns.extend(PRESSURE_COLUMNS);
    columns.extend(FLAGS_COLUMNS);
    columns
}

/// The output header for `pad_count` pads: `seq`, then every pad's [`pad_output_columns`]
/// prefixed `pad<n>_`.
pub fn output_header(pad_count: u8) -> Vec<String> {
    let mut header = vec![SEQUENCE_COLUMN.to_owned()];
    for pad in 0..usize::from(pad_count) {
        header.extend(
            pad_output_columns()
                .into_iter()
                .map(|name| pad_column(pad, name)),
        );
    }
    header
}

/// The pad index of a pad-prefixed column name (`pad12_x` gives 12), `None` for others.
fn column_pad(name: &str) -> Option<u32> {
    let rest = name
        .trim_start_matches('\u{feff}')
        .trim()
        .strip_prefix("pad")?;
    let (digits, _) = rest.split_once('_')?;
    if digits.is_empty() || !digits.chars().all(|c| c.is_ascii_digit()) {
        return None;
    }
    // More digits than any index needs are still a pad column, and too large.
    Some(digits.parse::<u32>().unwrap_or(u32::MAX))
}

/// How many pads a header's pad-prefixed columns name; `None` when it has none (a single-pad
/// file). The pads must be 0, 1, ... with each pad's columns together and in pad order.
pub fn header_pad_count(header: &csv::StringRecord) -> anyhow::Result<Option<u8>> {
    let mut pads: Vec<u32> = Vec::new();
    for name in header.iter() {
        let Some(pad) = column_pad(name) else {
            continue;
        };
        if pad >= u32::from(MAX_PAD_COUNT) {
            bail!(
                "the header's column '{}' names pad {pad}: a device has at most {MAX_PAD_COUNT} pads (0 to {})",
                shortened(name.trim()),
                MAX_PAD_COUNT - 1
            );
        }
        match pads.last() {
            Some(&last) if pad == last => {}
            Some(&last) if pad < last || pads.contains(&pad) => bail!(
                "the header's pads are out of order: a column of pad {pad} ('{}') comes after pad {last}'s; a recording has each pad's columns together, pad 0 first",
                shortened(name.trim())
            ),
            _ => pads.push(pad),
        }
    }
    if pads.is_empty() {
        return Ok(None);
    }
    for (expected, &pad) in (0u32..).zip(&pads) {
        if pad != expected {
            bail!(
                "the header has columns of pad {pad} but none of pad {expected}: a recording has the columns of pads 0 to n-1"
            );
        }
    }
    Ok(Some(pads.len() as u8))
}

/// One run per pad, each with its pad's options; an error names the pad.
fn pad_runs(options: &ConvertOptions, pad_count: u8) -> anyhow::Result<Vec<PadRun>> {
    (0..usize::from(pad_count))
        .map(|pad| PadRun::new(&options.pad_options(pad)).with_context(|| format!("pad {pad}")))
        .collect()
}

/// Converts a CSV recording of `pad_count` pads whose header was read (see the module
/// documentation).
pub(super) fn convert_csv<R: Read, W: Write>(
    mut reader: csv::Reader<R>,
    header: &csv::StringRecord,
    dialect: CsvDialect,
    pad_count: u8,
    output: W,
    options: &ConvertOptions,
) -> anyhow::Result<ConvertSummary> {
    let sequence_column = crate::csv_format::find_column(header, SEQUENCE_COLUMN)
        .with_context(|| {
            format!("the header has pad-prefixed columns but lacks the column {SEQUENCE_COLUMN}, which numbers the sample sets")
        })?;
    let columns = (0..usize::from(pad_count))
        .map(|pad| CsvColumns::find_prefixed(header, dialect, &pad_prefix(pad)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut runs = pad_runs(options, pad_count)?;
    let mut writer = csv_writer(output);
    writer.write_record(output_header(pad_count))?;
    let mut summary = ConvertSummary {
        dialect: (dialect != CsvDialect::default()).then_some(dialect),
        pad_count,
        ..ConvertSummary::default()
    };
    let empty_pad = vec![String::new(); pad_output_columns().len()];
    let mut record = csv::StringRecord::new();
    while let Some((line, readable)) = next_record(&mut reader, &mut record)? {
        let mut reasons = Vec::new();
        if let Err(reason) = readable {
            reasons.push(reason);
        } else if record.len() != header.len() {
            reasons.push(format!(
                "expected {} fields, found {}",
                header.len(),
                record.len()
            ));
        }
        let sequence_cell = record.get(sequence_column).unwrap_or("").trim();
        let sequence = sequence_cell.parse::<u32>();
        if reasons.is_empty() && sequence.is_err() {
            reasons.push(format!(
                "{SEQUENCE_COLUMN}: '{}' is not a sequence number",
                shortened(sequence_cell)
            ));
        }
        let row_unreadable = !reasons.is_empty();
        let mut cells = vec![if row_unreadable {
            String::new()
        } else {
            sequence_cell.to_owned()
        }];
        for (pad_columns, run) in columns.iter().zip(runs.iter_mut()) {
            let time_cell = record.get(pad_columns.needed[0]).unwrap_or("");
            if row_unreadable {
                // No pad of a row that cannot be read as a whole is converted.
                cells.push(readable_time(time_cell, dialect));
                cells.extend(empty_pad.iter().skip(1).cloned());
                continue;
            }
            if pad_is_missing(&record, pad_columns) {
                summary.missing_pad_frames += 1;
                cells.extend(empty_pad.iter().cloned());
                continue;
            }
            match parse_sample(&record, pad_columns) {
                Ok(row) => {
                    let temperature_cell = record.get(pad_columns.needed[1]).unwrap_or("");
                    cells.push(as_written(time_cell, dialect));
                    cells.push(as_written(temperature_cell, dialect));
                    cells.extend(run.cells(sequence.as_ref().ok().copied(), &row.input));
                }
                Err(reason) => {
                    reasons.push(reason);
                    cells.push(readable_time(time_cell, dialect));
                    cells.extend(empty_pad.iter().skip(1).cloned());
                }
            }
        }
        writer.write_record(&cells)?;
        if !reasons.is_empty() {
            summary.bad_rows.push(BadRow {
                line,
                reason: reasons.join("; "),
            });
        }
        summary.rows_written += 1;
    }
    if summary.rows_written == 0 {
        bail!("the file has a header but no data rows: nothing to convert");
    }
    writer.flush()?;
    summary.tare_warnings = pad_warnings(runs);
    Ok(summary)
}

/// Whether a pad's frame is missing from a row: every cell of the pad the conversion reads is
/// empty, its time included.
fn pad_is_missing(record: &csv::StringRecord, columns: &CsvColumns) -> bool {
    let flags = columns.flags.iter().flatten();
    columns
        .needed
        .iter()
        .chain(flags)
        .all(|&index| record.get(index).is_none_or(|cell| cell.trim().is_empty()))
}

/// Every pad's tare warnings, each saying its pad.
fn pad_warnings(runs: Vec<PadRun>) -> Vec<String> {
    runs.into_iter()
        .enumerate()
        .flat_map(|(pad, run)| {
            run.warnings()
                .into_iter()
                .map(move |warning| format!("pad {pad}: {warning}"))
        })
        .collect()
}

/// Converts a raw log of [`ConvertOptions::pad_count`] pads: every sample set becomes a row,
/// frames gathered as `taxel record` gathers them.
pub(super) fn convert_raw<R: Read, W: Write>(
    input: R,
    output: W,
    options: &ConvertOptions,
) -> anyhow::Result<ConvertSummary> {
    let pad_count = options.pad_count.clamp(1, MAX_PAD_COUNT);
    let mut runs = pad_runs(options, pad_count)?;
    let mut writer = csv_writer(output);
    writer.write_record(output_header(pad_count))?;
    let mut summary = ConvertSummary {
        pad_count,
        ..ConvertSummary::default()
    };
    let mut assembler = PadSetAssembler::new(pad_count);
    let mut write_set = |set: PadSet, summary: &mut ConvertSummary| -> anyhow::Result<()> {
        let mut cells = vec![set.sequence.to_string()];
        for (frame, run) in set.pads.iter().zip(runs.iter_mut()) {
            let Some(frame) = frame else {
                summary.missing_pad_frames += 1;
                cells.extend(std::iter::repeat_n(String::new(), 2 + 2 * TAXEL_COUNT));
                continue;
            };
            let input = frame_input(frame);
            cells.push(format_time_us(frame.timestamp_us));
            cells.push(format_optional(input.temperature_c));
            cells.extend(run.cells(Some(set.sequence), &input));
        }
        writer.write_record(&cells)?;
        summary.rows_written += 1;
        Ok(())
    };
    let statistics = read_frames(input, Some(pad_count), |frame| {
        if let DeviceFrame::Sample(sample) = frame {
            for set in assembler.push(sample) {
                write_set(set, &mut summary)?;
            }
        }
        Ok(())
    })?;
    if let Some(set) = assembler.finish() {
        write_set(set, &mut summary)?;
    }
    summary.undecodable_frames = statistics.frames_rejected;
    summary.undecodable_bytes = statistics.bytes_rejected;
    summary.frames_of_other_pads = statistics.samples_beyond_pad_count;
    ensure_samples_decoded(summary.rows_written, &statistics)?;
    writer.flush()?;
    summary.tare_warnings = pad_warnings(runs);
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(names: &[&str]) -> csv::StringRecord {
        csv::StringRecord::from(names.to_vec())
    }

    #[test]
    fn a_row_with_the_wrong_field_count_converts_no_pad() {
        let input = "seq,pad0_time_s,pad0_temp_c,pad0_c11_pf,pad0_c12_pf,pad0_c21_pf,pad0_c22_pf,\
                     pad1_time_s,pad1_temp_c,pad1_c11_pf,pad1_c12_pf,pad1_c21_pf,pad1_c22_pf\n\
                     1,0.1,25,4.5,4.5,4.5,4.5,0.2,25,4.6,4.6,4.6,4.6\n\
                     2,0.3,25,4.5,4.5,4.5,4.5,0.4,25,4.6,4.6,4.6,4.6,9\n\
                     x,0.5,25,4.5,4.5,4.5,4.5,,,,,,\n\
                     4,0.7,25,4.5,4.5,4.5,4.5,,,,,,\n";
        let mut output = Vec::new();
        let summary =
            super::super::convert_csv(input.as_bytes(), &mut output, &ConvertOptions::default())
                .unwrap();
        let text = String::from_utf8(output).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 5);
        assert_eq!(
            lines[1],
            "1,0.1,25,,,,,not_tared,not_tared,not_tared,not_tared,\
             0.2,25,,,,,not_tared,not_tared,not_tared,not_tared"
        );
        assert_eq!(lines[2], ",0.3,,,,,,,,,,0.4,,,,,,,,,");
        assert_eq!(lines[3], ",0.5,,,,,,,,,,,,,,,,,,,");
        assert_eq!(lines[4], "4,0.7,25,0,0,0,0,,,,,,,,,,,,,,");
        let reasons: Vec<(u64, &str)> = summary
            .bad_rows
            .iter()
            .map(|row| (row.line, row.reason.as_str()))
            .collect();
        assert_eq!(
            reasons,
            [
                (3, "expected 13 fields, found 14"),
                (4, "seq: 'x' is not a sequence number")
            ]
        );
        assert_eq!(summary.missing_pad_frames, 1);
        assert_eq!(summary.rows_written, 4);
    }

    #[test]
    fn the_pad_count_comes_from_the_prefixed_columns_in_order() {
        assert_eq!(
            header_pad_count(&header(&["time_s", "c11_pf"])).unwrap(),
            None
        );
        assert_eq!(
            header_pad_count(&header(&[
                "seq",
                "pad0_time_s",
                "pad0_c11_pf",
                "pad1_time_s"
            ]))
            .unwrap(),
            Some(2)
        );
        assert_eq!(
            header_pad_count(&header(&["padding_x", "pad_time_s", "seq"])).unwrap(),
            None,
            "only pad<digits>_ is a pad prefix"
        );
        let error = header_pad_count(&header(&["seq", "pad1_time_s", "pad0_time_s"])).unwrap_err();
        assert!(error.to_string().contains("out of order"), "{error}");
        let error =
            header_pad_count(&header(&["pad0_time_s", "pad1_time_s", "pad0_temp_c"])).unwrap_err();
        assert!(error.to_string().contains("out of order"), "{error}");
        let error = header_pad_count(&header(&["pad0_time_s", "pad2_time_s"])).unwrap_err();
        assert!(error.to_string().contains("none of pad 1"), "{error}");
        let error = header_pad_count(&header(&["pad0_time_s", "pad8_time_s"])).unwrap_err();
        assert!(error.to_string().contains("at most 8 pads"), "{error}");
        let error =
            header_pad_count(&header(&["pad0_time_s", "pad99999999999_time_s"])).unwrap_err();
        assert!(error.to_string().contains("at most 8 pads"), "{error}");
    }
}
