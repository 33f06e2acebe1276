//! The recording schema: one long ("tidy") table for every recording, whatever the number of
//! devices and pads — one row per pad per sample set, `device` and `pad` as columns (`0, 0`
//! for one pad on one device). `taxel record`, the live view's recording, `taxel convert`
//! (input and output), `taxel plot` and the Python package read and write this one table; every
//! column is defined once, in [`COLUMNS`], and the help texts are generated from it.
//!
//! A pad whose frame of a set never arrived, while other pads' frames of that set did, still has
//! its row, with the set's identity (`host_time_s`, `device`, `pad`, `seq`) and every other cell
//! empty. A set lost whole (every pad's frame) has no rows: it shows as a gap in `seq`, which
//! the recorder's closing line and the device's accounting count. A wide table (one row per set) is an export of this one
//! (`taxel convert --wide`), never a second input shape.

use std::io::{BufRead, Write};

use model_core::{TaxelFlags, TAXEL_COUNT};
use wire::{PadIndex, SampleFrame, TemperatureSource};

use crate::csv_format::{parse_flag_names, temperature_source_name, FLAG_SEPARATOR};

/// One column of the schema: its name, unit and meaning.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Column {
    /// The header cell.
    pub name: &'static str,
    /// What a cell holds, for people.
    pub meaning: &'static str,
}

const fn column(name: &'static str, meaning: &'static str) -> Column {
    Column { name, meaning }
}

/// Every column, in order.
pub const COLUMNS: [Column; 25] = [
    column("host_time_s", "when the set was sampled, Unix seconds on the host clock: the device clock mapped onto the host's, or the arrival when the device had no clock estimate yet"),
    column("device", "the device, numbered from 0 in the order given"),
    column("pad", "the pad of the device, from 0"),
    column("seq", "the sample set's sequence number (the device's; all pads of a set share it)"),
    column("device_time_s", "the device clock at the conversion, seconds since it booted; empty when the pad's frame is missing"),
    column("sync_error_ms", "bound on the distance of host_time_s from the true sampling instant, ms; empty without a clock estimate (host_time_s is then the arrival)"),
    column("temp_c", "the pad temperature, degC; empty when there is none"),
    column("temp_source", "where the temperature came from: tmp117, mcu_internal, last_known or none"),
    column("c11_pf", "taxel C11's capacitance, pF; empty without a reading"),
    column("c12_pf", "taxel C12's capacitance, pF"),
    column("c21_pf", "taxel C21's capacitance, pF"),
    column("c22_pf", "taxel C22's capacitance, pF"),
    column("p11_kpa", "taxel C11's pressure, kPa; empty when faulted (its flags say why)"),
    column("p12_kpa", "taxel C12's pressure, kPa"),
    column("p21_kpa", "taxel C21's pressure, kPa"),
    column("p22_kpa", "taxel C22's pressure, kPa"),
    column("flags11", "taxel C11's flags: documented names joined by '|'"),
    column("flags12", "taxel C12's flags"),
    column("flags21", "taxel C21's flags"),
    column("flags22", "taxel C22's flags"),
    column("force_n", "the pad's total normal force, N; empty when no taxel reads"),
    column("cop_x_mm", "the centre of pressure in the pad's frame, x, mm; empty when there is none"),
    column("cop_y_mm", "the centre of pressure, y, mm"),
    column("partial", "1 when faulted taxels were left out of force and centre, else 0"),
    column("contact", "1 while the device says the pad is in contact, else 0"),
];

/// The marker column, last: a label dropped into the recording (empty almost everywhere).
pub const MARKER: Column = column(
    "marker",
    "a label the user dropped into the recording at this set (empty otherwise)",
);

/// The header row.
pub fn header() -> Vec<&'static str> {
    COLUMNS
        .iter()
        .chain(std::iter::once(&MARKER))
        .map(|column| column.name)
        .collect()
}

/// The schema in words: one line per column, for help texts and the README.
pub fn describe() -> String {
    COLUMNS
        .iter()
        .chain(std::iter::once(&MARKER))
        .map(|column| format!("  {}: {}", column.name, column.meaning))
        .collect::<Vec<_>>()
        .join("\n")
}

/// What one pad's frame of a set says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PadReading {
    /// The device clock at the conversion, µs since boot.
    pub device_time_us: u64,
    /// The pad temperature, °C.
    pub temperature_c: Option<f32>,
    /// Where the temperature came from.
    pub temperature_source: TemperatureSource,
    /// Each taxel's capacitance, pF (`None`: no reading).
    pub capacitance_pf: [Option<f32>; TAXEL_COUNT],
    /// Each taxel's pressure, kPa (`None`: faulted).
    pub pressure_kpa: [Option<f32>; TAXEL_COUNT],
    /// Each taxel's flags.
    pub flags: [TaxelFlags; TAXEL_COUNT],
    /// The pad's total normal force, N.
    pub force_n: Option<f32>,
    /// The centre of pressure in the pad's frame, mm.
    pub centre_of_pressure_mm: Option<[f32; 2]>,
    /// Faulted taxels were left out of force and centre.
    pub partial: bool,
    /// The pad is in contact.
    pub contact: bool,
}

impl PadReading {
    /// A reading not converted yet: its device time, temperature and capacitances, no
    /// pressures, flags, force or contact (what a recording of readings alone holds).
    pub fn unconverted(
        device_time_us: u64,
        temperature_c: Option<f32>,
        temperature_source: TemperatureSource,
        capacitance_pf: [Option<f32>; TAXEL_COUNT],
    ) -> Self {
        Self {
            device_time_us,
            temperature_c,
            temperature_source,
            capacitance_pf,
            pressure_kpa: [None; TAXEL_COUNT],
            flags: [TaxelFlags::empty(); TAXEL_COUNT],
            force_n: None,
            centre_of_pressure_mm: None,
            partial: false,
            contact: false,
        }
    }

    /// What a sample frame says.
    pub fn from_frame(frame: &SampleFrame) -> Self {
        let value = |number: f32| (!number.is_nan()).then_some(number);
        Self {
            device_time_us: frame.timestamp_us,
            temperature_c: frame.temperature_c,
            temperature_source: frame.temperature_source,
            capacitance_pf: frame.taxels.map(|taxel| value(taxel.capacitance_pf)),
            pressure_kpa: frame.taxels.map(|taxel| taxel.pressure_kpa),
            flags: frame
                .taxels
                .map(|taxel| TaxelFlags::from_bits_retain(taxel.flags)),
            force_n: frame.summary.force_n,
            centre_of_pressure_mm: frame.summary.centre_of_pressure_mm,
            partial: frame.summary.partial,
            contact: frame.summary.contact,
        }
    }
}

/// One row: one pad of one sample set of one device.
#[derive(Debug, Clone, PartialEq)]
pub struct PadRow {
    /// When the set was sampled, µs since the Unix epoch on the host clock.
    pub host_time_us: u64,
    /// The device.
    pub device: u32,
    /// The pad.
    pub pad: u8,
    /// The set's sequence number.
    pub sequence: u32,
    /// Bound on the host time's error, µs (`None`: no clock estimate, arrival time).
    pub sync_error_us: Option<u64>,
    /// The pad's frame (`None`: it never arrived).
    pub reading: Option<PadReading>,
    /// A label dropped at this set (empty almost always).
    pub marker: String,
}

impl PadRow {
    /// The pad as a wire index (`None` beyond the protocol's pads).
    pub fn pad_index(&self) -> Option<PadIndex> {
        PadIndex::new(self.pad)
    }
}

fn push_f32(line: &mut Vec<u8>, value: Option<f32>) {
    if let Some(value) = value.filter(|value| value.is_finite()) {
        // The shortest text that reads back as the same f32, never in exponent form: ryu's
        // digits, or Rust's own formatting for the rare values ryu writes with an exponent.
        let mut buffer = ryu::Buffer::new();
        let text = buffer.format_finite(value);
        if text.as_bytes().contains(&b'e') {
            let _ = write!(line, "{value}");
        } else {
            line.extend_from_slice(text.strip_suffix(".0").unwrap_or(text).as_bytes());
        }
    } else if let Some(value) = value.filter(|value| !value.is_nan()) {
        let _ = write!(line, "{value}");
    }
}

fn push_integer(line: &mut Vec<u8>, value: u64) {
    line.extend_from_slice(itoa::Buffer::new().format(value).as_bytes());
}

/// `value` in units of 10^-`decimals`, written with exactly `decimals` decimals.
fn push_fixed(line: &mut Vec<u8>, value: u64, decimals: u32) {
    let scale = 10u64.pow(decimals);
    push_integer(line, value / scale);
    line.push(b'.');
    let fraction = value % scale;
    let mut buffer = itoa::Buffer::new();
    let digits = buffer.format(fraction);
    line.extend(std::iter::repeat_n(b'0', decimals as usize - digits.len()));
    line.extend_from_slice(digits.as_bytes());
}

fn push_micros(line: &mut Vec<u8>, value_us: u64) {
    push_fixed(line, value_us, 6);
}

fn push_milliseconds(line: &mut Vec<u8>, value_us: u64) {
    push_fixed(line, value_us, 3);
}

fn push_flags(line: &mut Vec<u8>, flags: TaxelFlags) {
    let mut first = true;
    for (flag, name) in TaxelFlags::NAMES {
        if flags.contains(flag) {
            if !first {
                line.push(FLAG_SEPARATOR as u8);
            }
            line.extend_from_slice(name.as_bytes());
            first = false;
        }
    }
    let undocumented = flags.bits() & !TaxelFlags::all().bits();
    for bit in (0..u16::BITS).filter(|bit| undocumented & (1 << bit) != 0) {
        if !first {
            line.push(FLAG_SEPARATOR as u8);
        }
        let _ = write!(line, "bit{bit}");
        first = false;
    }
}

fn push_text(line: &mut Vec<u8>, text: &str) {
    if text.contains([',', '"', '\n', '\r']) {
        line.push(b'"');
        line.extend_from_slice(text.replace('"', "\"\"").as_bytes());
        line.push(b'"');
    } else {
        line.extend_from_slice(text.as_bytes());
    }
}

/// Appends `row` as one CSV line (with its newline) to `line`.
pub fn format_row(row: &PadRow, line: &mut Vec<u8>) {
    push_micros(line, row.host_time_us);
    line.push(b',');
    push_integer(line, u64::from(row.device));
    line.push(b',');
    push_integer(line, u64::from(row.pad));
    line.push(b',');
    push_integer(line, u64::from(row.sequence));
    line.push(b',');
    if let Some(reading) = &row.reading {
        push_micros(line, reading.device_time_us);
    }
    line.push(b',');
    if let Some(error_us) = row.sync_error_us {
        push_milliseconds(line, error_us);
    }
    line.push(b',');
    match &row.reading {
        Some(reading) => {
            push_f32(line, reading.temperature_c);
            line.push(b',');
            line.extend_from_slice(temperature_source_name(reading.temperature_source).as_bytes());
            for value in reading.capacitance_pf {
                line.push(b',');
                push_f32(line, value);
            }
            for value in reading.pressure_kpa {
                line.push(b',');
                push_f32(line, value);
            }
            for flags in reading.flags {
                line.push(b',');
                push_flags(line, flags);
            }
            line.push(b',');
            push_f32(line, reading.force_n);
            line.push(b',');
            push_f32(line, reading.centre_of_pressure_mm.map(|[x_mm, _]| x_mm));
            line.push(b',');
            push_f32(line, reading.centre_of_pressure_mm.map(|[_, y_mm]| y_mm));
            line.push(b',');
            line.push(if reading.partial { b'1' } else { b'0' });
            line.push(b',');
            line.push(if reading.contact { b'1' } else { b'0' });
        }
        // Every cell of a missing frame empty: 19 separators after temp_c's.
        None => line.extend_from_slice(&[b','; COLUMNS.len() - 7]),
    }
    line.push(b',');
    push_text(line, &row.marker);
    line.push(b'\n');
}

/// Writes rows of the schema (the header first).
#[derive(Debug)]
pub struct RowWriter<W: Write> {
    output: W,
    line: Vec<u8>,
    rows: u64,
}

impl<W: Write> RowWriter<W> {
    /// A writer that has written the header.
    pub fn new(mut output: W) -> std::io::Result<Self> {
        let mut line = header().join(",").into_bytes();
        line.push(b'\n');
        output.write_all(&line)?;
        line.clear();
        Ok(Self {
            output,
            line,
            rows: 0,
        })
    }

    /// Writes one row.
    pub fn write(&mut self, row: &PadRow) -> std::io::Result<()> {
        self.line.clear();
        format_row(row, &mut self.line);
        self.rows += 1;
        self.output.write_all(&self.line)
    }

    /// Rows written.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Flushes what was written.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.output.flush()
    }

    /// The output back.
    pub fn into_inner(self) -> W {
        self.output
    }
}

/// Why a recording cannot be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SchemaError {
    /// The header is not the schema's.
    #[error("the header is not a taxel recording's (expected {expected}); {found}")]
    Header {
        /// The expected header.
        expected: String,
        /// What was found instead, in words.
        found: String,
    },
    /// A row cannot be read.
    #[error("line {line}: {reason}")]
    Row {
        /// The line number (1 = the header).
        line: u64,
        /// Why, in words.
        reason: String,
    },
    /// The file cannot be read at all.
    #[error("{0}")]
    Io(String),
}

/// Reads rows of the schema, one at a time, in constant memory.
pub struct RowReader<R: BufRead> {
    reader: csv::Reader<R>,
    record: csv::ByteRecord,
    line: u64,
}

/// At most `limit` characters of `text` for a message, "..." and its length marking a cut (a
/// megabyte cell must not make a megabyte message).
fn shown(text: &str, limit: usize) -> String {
    match text.char_indices().nth(limit) {
        Some((end, _)) => format!("{}... ({} bytes)", &text[..end], text.len()),
        None => text.to_owned(),
    }
}

/// The longest cell a message quotes whole.
const SHOWN_CELL: usize = 40;

fn text(cell: &[u8]) -> Result<&str, String> {
    std::str::from_utf8(cell).map_err(|_| "a cell is not UTF-8 text".to_owned())
}

/// A non-negative decimal with at most `decimals` decimals, exactly, in units of
/// 10^-`decimals` (seconds with 6 decimals as µs, milliseconds with 3 as µs).
fn parse_fixed(cell: &[u8], name: &str, decimals: u32) -> Result<u64, String> {
    let cell = text(cell)?;
    let (whole, fraction) = cell.split_once('.').unwrap_or((cell, ""));
    let digits = |part: &str| !part.is_empty() && part.bytes().all(|byte| byte.is_ascii_digit());
    if !digits(whole)
        || !(fraction.is_empty() || digits(fraction))
        || fraction.len() > decimals as usize
    {
        return Err(format!(
            "{name} '{}' is not a non-negative number with at most {decimals} decimals",
            shown(cell, SHOWN_CELL)
        ));
    }
    let scale = 10u64.pow(decimals);
    let whole: u64 = whole
        .parse()
        .map_err(|_| format!("{name} '{}' is out of range", shown(cell, SHOWN_CELL)))?;
    let fraction_units: u64 = fraction
        .bytes()
        .chain(std::iter::repeat(b'0'))
        .take(decimals as usize)
        .fold(0, |value, digit| value * 10 + u64::from(digit - b'0'));
    whole
        .checked_mul(scale)
        .and_then(|value| value.checked_add(fraction_units))
        .ok_or_else(|| format!("{name} '{}' is out of range", shown(cell, SHOWN_CELL)))
}

fn parse_optional_f32(cell: &[u8], name: &str) -> Result<Option<f32>, String> {
    if cell.is_empty() {
        return Ok(None);
    }
    let cell = text(cell)?;
    // An infinite value is written as `inf` and read back (a converter can report one); NaN is
    // never written: absent values are empty cells.
    match cell.parse::<f32>() {
        Ok(value) if !value.is_nan() => Ok(Some(value)),
        _ => Err(format!(
            "{name} '{}' is not a number",
            shown(cell, SHOWN_CELL)
        )),
    }
}

fn parse_integer<T: std::str::FromStr>(cell: &[u8], name: &str) -> Result<T, String> {
    let cell = text(cell)?;
    cell.parse().map_err(|_| {
        format!(
            "{name} '{}' is not a whole number in range",
            shown(cell, SHOWN_CELL)
        )
    })
}

fn parse_bool(cell: &[u8], name: &str) -> Result<bool, String> {
    match cell {
        b"0" => Ok(false),
        b"1" => Ok(true),
        _ => Err(format!("{name} must be 0 or 1")),
    }
}

fn parse_source(cell: &[u8]) -> Result<TemperatureSource, String> {
    [
        TemperatureSource::None,
        TemperatureSource::Tmp117,
        TemperatureSource::McuInternal,
        TemperatureSource::LastKnown,
    ]
    .into_iter()
    .find(|source| temperature_source_name(*source).as_bytes() == cell)
    .ok_or_else(|| {
        format!(
            "temp_source '{}' is not tmp117, mcu_internal, last_known or none",
            shown(&String::from_utf8_lossy(cell), SHOWN_CELL)
        )
    })
}

/// Parses one record of the schema's columns.
pub fn parse_record(record: &csv::ByteRecord) -> Result<PadRow, String> {
    if record.len() != COLUMNS.len() + 1 {
        return Err(format!(
            "{} cells where the header has {}",
            record.len(),
            COLUMNS.len() + 1
        ));
    }
    let mut cells: [&[u8]; COLUMNS.len() + 1] = [&[]; COLUMNS.len() + 1];
    for (slot, cell) in cells.iter_mut().zip(record.iter()) {
        *slot = cell;
    }
    let host_time_us = parse_fixed(cells[0], "host_time_s", 6)?;
    let device = parse_integer(cells[1], "device")?;
    let pad: u8 = parse_integer(cells[2], "pad")?;
    if PadIndex::new(pad).is_none() {
        return Err(format!(
            "pad {pad} is beyond the protocol's {} pads",
            PadIndex::MAX + 1
        ));
    }
    let sequence = parse_integer(cells[3], "seq")?;
    let sync_error_us = if cells[5].is_empty() {
        None
    } else {
        Some(parse_fixed(cells[5], "sync_error_ms", 3)?)
    };
    let reading = if cells[4].is_empty() {
        if cells[6..COLUMNS.len()].iter().any(|cell| !cell.is_empty()) {
            return Err(
                "device_time_s is empty (a missing frame) but other cells are not".to_owned(),
            );
        }
        None
    } else {
        let mut capacitance_pf = [None; TAXEL_COUNT];
        let mut pressure_kpa = [None; TAXEL_COUNT];
        let mut flags = [TaxelFlags::empty(); TAXEL_COUNT];
        for taxel in 0..TAXEL_COUNT {
            capacitance_pf[taxel] = parse_optional_f32(cells[8 + taxel], COLUMNS[8 + taxel].name)?;
            pressure_kpa[taxel] = parse_optional_f32(cells[12 + taxel], COLUMNS[12 + taxel].name)?;
            let cell = cells[16 + taxel];
            if !cell.is_empty() {
                flags[taxel] = parse_flag_names(text(cell)?).map_err(|name| {
                    format!(
                        "{}: unknown flag '{}'",
                        COLUMNS[16 + taxel].name,
                        shown(&name, SHOWN_CELL)
                    )
                })?;
            }
        }
        let cop_x = parse_optional_f32(cells[21], "cop_x_mm")?;
        let cop_y = parse_optional_f32(cells[22], "cop_y_mm")?;
        Some(PadReading {
            device_time_us: parse_fixed(cells[4], "device_time_s", 6)?,
            temperature_c: parse_optional_f32(cells[6], "temp_c")?,
            temperature_source: parse_source(cells[7])?,
            capacitance_pf,
            pressure_kpa,
            flags,
            force_n: parse_optional_f32(cells[20], "force_n")?,
            centre_of_pressure_mm: match (cop_x, cop_y) {
                (Some(x_mm), Some(y_mm)) => Some([x_mm, y_mm]),
                (None, None) => None,
                _ => {
                    return Err("cop_x_mm and cop_y_mm must be both given or both empty".to_owned())
                }
            },
            partial: parse_bool(cells[23], "partial")?,
            contact: parse_bool(cells[24], "contact")?,
        })
    };
    Ok(PadRow {
        host_time_us,
        device,
        pad,
        sequence,
        sync_error_us,
        reading,
        marker: text(cells[COLUMNS.len()])?.to_owned(),
    })
}

impl<R: BufRead> RowReader<R> {
    /// A reader over `input`, whose header must be the schema's.
    pub fn new(input: R) -> Result<Self, SchemaError> {
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .from_reader(input);
        let mut record = csv::ByteRecord::new();
        let expected = header().join(",");
        let found = match reader.read_byte_record(&mut record) {
            Ok(true) => record
                .iter()
                .map(|cell| String::from_utf8_lossy(cell).into_owned())
                .collect::<Vec<_>>()
                .join(","),
            Ok(false) => {
                return Err(SchemaError::Header {
                    expected,
                    found: "the file is empty".to_owned(),
                })
            }
            Err(error) => return Err(SchemaError::Io(error.to_string())),
        };
        if found.trim_start_matches('\u{feff}') != expected {
            return Err(SchemaError::Header {
                expected,
                found: format!(
                    "found {} (recordings of earlier versions are not read; record again)",
                    shown(&found, 300)
                ),
            });
        }
        Ok(Self {
            reader,
            record,
            line: 1,
        })
    }

    /// The next row; `None` at the end. A row that cannot be read is an error with its line;
    /// reading may go on after it.
    pub fn next_row(&mut self) -> Option<Result<PadRow, SchemaError>> {
        match self.reader.read_byte_record(&mut self.record) {
            Ok(false) => None,
            Ok(true) => {
                self.line += 1;
                Some(
                    parse_record(&self.record).map_err(|reason| SchemaError::Row {
                        line: self.line,
                        reason,
                    }),
                )
            }
            Err(error) => {
                self.line += 1;
                Some(Err(SchemaError::Row {
                    line: self.line,
                    reason: error.to_string(),
                }))
            }
        }
    }
}
