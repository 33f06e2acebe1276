//! Column names and cell formats shared by every CSV file the tool reads and writes: taxel
//! columns, flag cells (documented flag names joined by `|`), numbers with '.' as the decimal
//! separator whatever the locale, and device timestamps in seconds.

use std::io::{BufRead, Read};

use model_core::{TaxelFlags, TAXEL_COUNT};
use wire::TemperatureSource;

/// Capacitance columns in pad order (C11, C12, C21, C22), pF.
pub const CAPACITANCE_COLUMNS: [&str; TAXEL_COUNT] = ["c11_pf", "c12_pf", "c21_pf", "c22_pf"];

/// Pressure columns in pad order, kPa.
pub const PRESSURE_COLUMNS: [&str; TAXEL_COUNT] = ["p11_kpa", "p12_kpa", "p21_kpa", "p22_kpa"];

/// Flag columns in pad order.
pub const FLAGS_COLUMNS: [&str; TAXEL_COUNT] = ["flags11", "flags12", "flags21", "flags22"];

/// Taxel labels in pad order, for people (views, plots, tables).
pub const TAXEL_LABELS: [&str; TAXEL_COUNT] = ["C11", "C12", "C21", "C22"];

/// Time column, seconds.
pub const TIME_COLUMN: &str = "time_s";

/// Temperature column, °C; an empty cell means no temperature.
pub const TEMPERATURE_COLUMN: &str = "temp_c";

/// Separator between flag names in a flags cell.
pub const FLAG_SEPARATOR: char = '|';

/// The flags cell: documented flag names (see [`TaxelFlags::NAMES`]) in bit order joined by `|`;
/// empty when no flag is set. Bits without a documented name are written as `bit<n>`.
pub fn flag_names(flags: TaxelFlags) -> String {
    let mut names: Vec<String> = TaxelFlags::NAMES
        .iter()
        .filter(|(flag, _)| flags.contains(*flag))
        .map(|(_, name)| (*name).to_owned())
        .collect();
    let undocumented = flags.bits() & !TaxelFlags::all().bits();
    for bit in 0..u16::BITS {
        if undocumented & (1 << bit) != 0 {
            names.push(format!("bit{bit}"));
        }
    }
    names.join(&FLAG_SEPARATOR.to_string())
}

/// The flags cell of raw wire flag bits.
pub fn wire_flag_names(bits: u16) -> String {
    flag_names(TaxelFlags::from_bits_retain(bits))
}

/// Parses a flags cell written by [`flag_names`]; `Err` carries the first unknown name.
pub fn parse_flag_names(cell: &str) -> Result<TaxelFlags, String> {
    let mut flags = TaxelFlags::empty();
    for name in cell
        .split(FLAG_SEPARATOR)
        .map(str::trim)
        .filter(|name| !name.is_empty())
    {
        let flag = match TaxelFlags::from_documented_name(name) {
            Some(flag) => flag,
            None => name
                .strip_prefix("bit")
                .and_then(|bit| bit.parse::<u32>().ok())
                .and_then(|bit| 1u16.checked_shl(bit))
                .map(TaxelFlags::from_bits_retain)
                .ok_or_else(|| name.to_owned())?,
        };
        flags |= flag;
    }
    Ok(flags)
}

/// Flags in words for people: "not tared, below baseline"; empty when no flag is set.
pub fn flag_words(flags: TaxelFlags) -> String {
    flag_names(flags)
        .split(FLAG_SEPARATOR)
        .map(|name| name.replace('_', " "))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A number cell: the shortest decimal text that reads back as the same f32, always with '.'
/// as the decimal separator and never in exponent form; empty for NaN (an absent value never
/// looks like a number).
pub fn format_number(value: f32) -> String {
    if value.is_nan() {
        String::new()
    } else {
        format!("{value}")
    }
}

/// An optional number cell: empty for `None`.
pub fn format_optional(value: Option<f32>) -> String {
    value.map(format_number).unwrap_or_default()
}

/// A device timestamp in seconds with 6 decimals, exact (no floating point on the way).
pub fn format_time_us(timestamp_us: u64) -> String {
    format!(
        "{}.{:06}",
        timestamp_us / 1_000_000,
        timestamp_us % 1_000_000
    )
}

/// Parses a number cell (surrounding spaces ignored, '.' decimal separator). `Ok(None)` for an
/// empty cell, `Err` for anything that is not a number.
pub fn parse_optional_number(cell: &str) -> Result<Option<f64>, String> {
    let trimmed = cell.trim();
    if trimmed.is_empty() {
        return Ok(None);
    }
    trimmed.parse::<f64>().map(Some).map_err(|_| {
        let decimal_comma = trimmed.split_once(',').is_some_and(|(whole, fraction)| {
            !fraction.is_empty()
                && whole.trim_start_matches('-').chars().all(|c| c.is_ascii_digit())
                && fraction.chars().all(|c| c.is_ascii_digit())
        });
        if decimal_comma {
            format!(
                "'{trimmed}' is not a number: write decimals with '.', or separate the fields with ';' (then ',' decimals are read)"
            )
        } else {
            format!("'{}' is not a number", shortened_cell(trimmed))
        }
    })
}

/// The largest time a file may carry, s (about 31 years): anything beyond is corrupt data, and
/// drawing or modelling it would only waste time.
pub const MAX_TIME_S: f64 = 1.0e9;

/// Parses a time cell: a finite number of seconds within ±[`MAX_TIME_S`].
pub fn parse_time_s(cell: &str, decimal_comma: bool) -> Result<f64, String> {
    match parse_number(cell, decimal_comma)? {
        None => Err("time_s is empty".to_owned()),
        Some(time_s) if !time_s.is_finite() => {
            Err(format!("time_s '{}' is not a finite time", cell.trim()))
        }
        Some(time_s) if time_s.abs() > MAX_TIME_S => Err(format!(
            "time_s '{}' is beyond {MAX_TIME_S:e} s: not a plausible time",
            cell.trim()
        )),
        Some(time_s) => Ok(time_s),
    }
}

/// Parses a number cell with '.' decimals, or with ',' decimals when `decimal_comma` (files
/// separated by ';' from spreadsheets in many locales). `Ok(None)` for an empty cell.
pub fn parse_number(cell: &str, decimal_comma: bool) -> Result<Option<f64>, String> {
    if decimal_comma && cell.contains(',') {
        parse_optional_number(&cell.replace(',', "."))
    } else {
        parse_optional_number(cell)
    }
}

/// How a CSV file is written: its separator, and whether numbers use ',' as the decimal mark.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CsvDialect {
    /// The field separator.
    pub separator: u8,
    /// Numbers written with ',' decimals (only possible when the separator is not ',').
    pub decimal_comma: bool,
}

impl Default for CsvDialect {
    fn default() -> Self {
        Self {
            separator: b',',
            decimal_comma: false,
        }
    }
}

impl CsvDialect {
    /// Words for people: "';'-separated with ',' decimals".
    pub fn describe(&self) -> String {
        let decimals = if self.decimal_comma { "','" } else { "'.'" };
        format!(
            "'{}'-separated with {decimals} decimals",
            char::from(self.separator)
        )
    }

    /// A CSV reader of this dialect (header row, rows of varying length allowed).
    pub fn reader<R: Read>(&self, input: R) -> csv::Reader<R> {
        csv::ReaderBuilder::new()
            .has_headers(true)
            .flexible(true)
            .delimiter(self.separator)
            .from_reader(input)
    }
}

/// Reads the first line of `input` and chooses the dialect whose separator splits it into
/// fields that include `wanted_column`: ',' first, then ';' and tab. With ';' or tab, ','
/// decimals are accepted. Returns the dialect and a reader that still yields the whole input.
pub fn detect_dialect<R: BufRead>(
    mut input: R,
    wanted_column: &str,
) -> std::io::Result<(CsvDialect, impl Read)> {
    let mut first_line = Vec::new();
    // A header longer than this is not a header the tool wrote; the reader reports it.
    let limit = 64 * 1024;
    (&mut input)
        .take(limit)
        .read_until(b'\n', &mut first_line)?;
    if first_line.len() as u64 == limit && !first_line.ends_with(b"\n") {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            "the first line is longer than 64 KiB: this is not a CSV file with a header row",
        ));
    }
    let text = String::from_utf8_lossy(&first_line);
    let dialect = [b',', b';', b'\t']
        .into_iter()
        .find(|&separator| {
            text.split(char::from(separator)).any(|field| {
                field
                    .trim_start_matches('\u{feff}')
                    .trim()
                    .trim_matches('"')
                    == wanted_column
            })
        })
        .map(|separator| CsvDialect {
            separator,
            decimal_comma: separator != b',',
        })
        .unwrap_or_default();
    Ok((dialect, std::io::Cursor::new(first_line).chain(input)))
}

/// At most 40 characters of a cell, for messages.
fn shortened_cell(cell: &str) -> String {
    if cell.chars().count() <= 40 {
        cell.to_owned()
    } else {
        format!("{}…", cell.chars().take(40).collect::<String>())
    }
}

/// The temperature-source cell of a recording.
pub fn temperature_source_name(source: TemperatureSource) -> &'static str {
    match source {
        TemperatureSource::None => "none",
        TemperatureSource::Tmp117 => "tmp117",
        TemperatureSource::McuInternal => "mcu_internal",
        TemperatureSource::LastKnown => "last_known",
    }
}

/// The temperature source for people.
pub fn temperature_source_words(source: TemperatureSource) -> &'static str {
    match source {
        TemperatureSource::None => "no sensor",
        TemperatureSource::Tmp117 => "TMP117",
        TemperatureSource::McuInternal => "MCU internal sensor (fallback)",
        TemperatureSource::LastKnown => "last known value (held)",
    }
}

/// Index of each wanted column in a header row, or the list of the missing ones.
pub fn find_columns<const N: usize>(
    header: &csv::StringRecord,
    wanted: [&str; N],
) -> Result<[usize; N], Vec<String>> {
    let mut indices = [0usize; N];
    let mut missing = Vec::new();
    for (slot, name) in indices.iter_mut().zip(wanted) {
        match find_column(header, name) {
            Some(index) => *slot = index,
            None => missing.push(name.to_owned()),
        }
    }
    if missing.is_empty() {
        Ok(indices)
    } else {
        Err(missing)
    }
}

/// Index of a column in a header row (surrounding spaces and a leading byte-order mark, as
/// spreadsheets write, are ignored).
pub fn find_column(header: &csv::StringRecord, name: &str) -> Option<usize> {
    header
        .iter()
        .position(|column| column.trim_start_matches('\u{feff}').trim() == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flag_cells_round_trip_in_bit_order() {
        let flags = TaxelFlags::NOT_TARED | TaxelFlags::BELOW_BASELINE;
        assert_eq!(flag_names(flags), "below_baseline|not_tared");
        assert_eq!(parse_flag_names("below_baseline|not_tared"), Ok(flags));
        assert_eq!(flag_names(TaxelFlags::empty()), "");
        assert_eq!(parse_flag_names(""), Ok(TaxelFlags::empty()));
        assert_eq!(
            wire_flag_names(0x1001),
            "below_baseline|temperature_fallback"
        );
        assert_eq!(
            wire_flag_names(0x2001),
            "below_baseline|temperature_implausible"
        );
        // A bit no model defines (yet) is shown by position and read back.
        assert_eq!(wire_flag_names(0x8001), "below_baseline|bit15");
        assert_eq!(
            parse_flag_names("below_baseline|bit15").map(|flags| flags.bits()),
            Ok(0x8001)
        );
        assert_eq!(parse_flag_names("open|bogus"), Err("bogus".to_owned()));
        assert_eq!(flag_words(flags), "below baseline, not tared");
    }

    #[test]
    fn header_lookup_ignores_spaces_and_a_byte_order_mark() {
        let header = csv::StringRecord::from(vec!["\u{feff}time_s", " temp_c ", "c11_pf"]);
        assert_eq!(find_columns(&header, ["temp_c", "time_s"]), Ok([1, 0]));
        assert_eq!(
            find_columns(&header, ["time_s", "c12_pf"]),
            Err(vec!["c12_pf".to_owned()])
        );
    }

    #[test]
    fn numbers_use_a_point_and_round_trip() {
        assert_eq!(format_number(12.5), "12.5");
        assert_eq!(format_number(0.0829), "0.0829");
        assert_eq!(format_number(1e-7), "0.0000001");
        assert_eq!(format_number(f32::NAN), "");
        let value = 4.512_346_f32;
        assert_eq!(format_number(value).parse::<f32>(), Ok(value));
        assert_eq!(format_time_us(5_000_250), "5.000250");
        assert_eq!(format_time_us(42), "0.000042");
        assert_eq!(parse_optional_number(" 1.5 "), Ok(Some(1.5)));
        assert_eq!(parse_optional_number(""), Ok(None));
        assert!(parse_optional_number("1,5").is_err());
    }
}
