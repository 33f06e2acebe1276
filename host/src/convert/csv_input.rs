//! Where a CSV input's cells are and how one row becomes a model input. Column names may carry
//! a prefix (`pad1_`), so that the columns of one pad of a multi-pad recording are read like
//! those of a single-pad file.

use model_core::{SampleInput, TaxelFlags, TaxelReading, TAXEL_COUNT};

use super::pad_run::ACQUISITION_FLAGS;
use crate::csv_format::{
    find_column, find_columns, parse_flag_names, parse_number, parse_time_s, CsvDialect,
    CAPACITANCE_COLUMNS, FLAGS_COLUMNS, TEMPERATURE_COLUMN, TIME_COLUMN,
};
use crate::recording::SEQUENCE_COLUMN;

/// Where the cells of a CSV input are: the six columns the model needs, and in a recording
/// also the sequence number and the flags the acquisition set.
#[derive(Debug, Clone)]
pub(super) struct CsvColumns {
    /// The prefix of the column names (empty for a single-pad file).
    pub(super) prefix: String,
    /// time_s, temp_c, c11_pf..c22_pf.
    pub(super) needed: [usize; 6],
    /// The sequence number, unprefixed (one per row).
    pub(super) sequence: Option<usize>,
    /// flags11..flags22, when all four are there.
    pub(super) flags: Option<[usize; TAXEL_COUNT]>,
    /// Fields of the header.
    pub(super) field_count: usize,
    /// How the file is written.
    pub(super) dialect: CsvDialect,
}

impl CsvColumns {
    /// The columns of a single-pad file.
    pub(super) fn find(header: &csv::StringRecord, dialect: CsvDialect) -> anyhow::Result<Self> {
        Self::find_prefixed(header, dialect, "")
    }

    /// The columns named `prefix` + the single-pad names.
    pub(super) fn find_prefixed(
        header: &csv::StringRecord,
        dialect: CsvDialect,
        prefix: &str,
    ) -> anyhow::Result<Self> {
        let wanted = [
            TIME_COLUMN,
            TEMPERATURE_COLUMN,
            CAPACITANCE_COLUMNS[0],
            CAPACITANCE_COLUMNS[1],
            CAPACITANCE_COLUMNS[2],
            CAPACITANCE_COLUMNS[3],
        ]
        .map(|name| format!("{prefix}{name}"));
        let flag_names = FLAGS_COLUMNS.map(|name| format!("{prefix}{name}"));
        let needed =
            find_columns(header, wanted.each_ref().map(String::as_str)).map_err(|missing| {
                if header.iter().all(|field| field.trim().is_empty()) {
                    anyhow::anyhow!("the file is empty: it has no header row")
                } else {
                    anyhow::anyhow!(
                        "the header lacks the column(s) {} (found: {})",
                        missing.join(", "),
                        shortened(&header.iter().collect::<Vec<_>>().join(","))
                    )
                }
            })?;
        Ok(Self {
            prefix: prefix.to_owned(),
            needed,
            sequence: find_column(header, SEQUENCE_COLUMN),
            flags: find_columns(header, flag_names.each_ref().map(String::as_str)).ok(),
            field_count: header.len(),
            dialect,
        })
    }
}

/// At most 80 characters of a text that goes into a message.
pub(super) fn shortened(text: &str) -> String {
    const LIMIT: usize = 80;
    if text.chars().count() <= LIMIT {
        text.to_owned()
    } else {
        format!("{}…", text.chars().take(LIMIT).collect::<String>())
    }
}

/// One CSV row read as a model input, with its sequence number if the file has them.
pub(super) struct ParsedRow {
    /// The model input.
    pub(super) input: SampleInput,
    /// The sequence number, when the file has them.
    pub(super) sequence: Option<u32>,
}

/// Parses one CSV record into a model input, or says why it cannot.
pub(super) fn parse_sample(
    record: &csv::StringRecord,
    columns: &CsvColumns,
) -> Result<ParsedRow, String> {
    if record.len() != columns.field_count {
        return Err(format!(
            "expected {} fields, found {}",
            columns.field_count,
            record.len()
        ));
    }
    let decimal_comma = columns.dialect.decimal_comma;
    let cell = |index: usize| record.get(index).unwrap_or("");
    let prefix = &columns.prefix;
    let time_s = parse_time_s(cell(columns.needed[0]), decimal_comma)
        .map_err(|error| format!("{prefix}{error}"))?;
    let temperature_c = parse_number(cell(columns.needed[1]), decimal_comma)
        .map_err(|error| format!("{prefix}{TEMPERATURE_COLUMN}: {error}"))?
        .map(|value| value as f32)
        .filter(|value| !value.is_nan());
    let mut readings = [TaxelReading::Unavailable; TAXEL_COUNT];
    for (taxel, reading) in readings.iter_mut().enumerate() {
        let value = parse_number(cell(columns.needed[2 + taxel]), decimal_comma)
            .map_err(|error| format!("{prefix}{}: {error}", CAPACITANCE_COLUMNS[taxel]))?;
        if let Some(capacitance_pf) = value {
            *reading = TaxelReading::CapacitancePf(capacitance_pf as f32);
        }
    }
    let sequence = match columns.sequence {
        Some(index) => Some(cell(index).trim().parse::<u32>().map_err(|_| {
            format!(
                "{SEQUENCE_COLUMN}: '{}' is not a sequence number",
                cell(index).trim()
            )
        })?),
        None => None,
    };
    let mut input = SampleInput::new(readings, temperature_c);
    if let Some(flag_columns) = columns.flags {
        // A recording's flags say which readings the acquisition already knew to be bad.
        for (taxel, column) in flag_columns.iter().enumerate() {
            let flags = parse_flag_names(cell(*column))
                .map_err(|name| format!("{prefix}{}: unknown flag '{name}'", FLAGS_COLUMNS[taxel]))?
                .intersection(ACQUISITION_FLAGS);
            input.reading_flags[taxel] = flags;
            if flags.contains(TaxelFlags::CONVERTER_ERROR) {
                input.readings[taxel] = TaxelReading::Unavailable;
            }
        }
    }
    // The plausibility rule wants a non-negative time in microseconds.
    let input = if time_s >= 0.0 {
        input.at_time_us((time_s * 1.0e6) as u64)
    } else {
        input
    };
    Ok(ParsedRow { input, sequence })
}
