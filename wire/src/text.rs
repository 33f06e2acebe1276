//! Text mode: the device prints one CSV line per sample set so that a plain serial terminal or
//! plotter works, and listens for the line `binary` to go back to binary frames.

use core::fmt::Write;

use heapless::String;

use crate::sample::SampleFrame;

/// The CSV column names, printed by the device when text mode starts (followed by `\r\n`).
pub const CSV_HEADER: &str =
    "seq,pad,time_s,temp_c,p11_kpa,p12_kpa,p21_kpa,p22_kpa,flags11,flags12,flags21,flags22,force_n";

/// The longest line [`format_csv_line`] can produce, `\r\n` included: sequence 10 + pad 1
/// + time 21 + six numbers of 44 (`-f32::MAX` with three decimals) + four flags of 5
/// + 12 commas + 2.
pub const CSV_LINE_MAX_LEN: usize = 10 + 1 + 21 + 6 * 44 + 4 * 5 + 12 + 2;

/// The line did not fit the string given to [`format_csv_line`]; the string was left empty.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CsvLineTooLong;

impl core::fmt::Display for CsvLineTooLong {
    fn fmt(&self, formatter: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        formatter.write_str("CSV line longer than the string capacity")
    }
}

#[cfg(feature = "std")]
impl std::error::Error for CsvLineTooLong {}

/// Writes `value` with three decimals, rounded half to even, exactly as `{:.3}` would, using
/// integer arithmetic only: core's float formatting costs about 10 KB of firmware flash.
fn write_three_decimals<W: Write>(line: &mut W, value: f32) -> core::fmt::Result {
    if value.is_nan() {
        return line.write_str("NaN");
    }
    let sign = if value.is_sign_negative() { "-" } else { "" };
    let magnitude = value.abs();
    if magnitude.is_infinite() {
        return write!(line, "{sign}inf");
    }
    // Above 2^23 an f32 has no fraction.
    if magnitude >= 8_388_608.0 {
        line.write_str(sign)?;
        write_large_integer(line, magnitude)?;
        return line.write_str(".000");
    }
    // f32 (24-bit mantissa) times 1000 (10 bits) is exact in f64's 53 bits.
    let thousandths = f64::from(magnitude) * 1000.0;
    let whole = thousandths as u64;
    let remainder = thousandths - whole as f64;
    let rounded = if remainder > 0.5 || (remainder == 0.5 && whole % 2 == 1) {
        whole + 1
    } else {
        whole
    };
    write!(line, "{sign}{}.{:03}", rounded / 1000, rounded % 1000)
}

/// Writes an f32 that is an integer of at least 2^23, exactly, by doubling its mantissa in base
/// 10^9 limbs: core's u128 `Display` would do it too, for 1.4 KB of firmware flash.
fn write_large_integer<W: Write>(line: &mut W, magnitude: f32) -> core::fmt::Result {
    const LIMB: u64 = 1_000_000_000;
    let bits = magnitude.to_bits();
    // value = mantissa x 2^doublings, with the implicit leading bit; >= 2^23 means doublings >= 0.
    let doublings = ((bits >> 23) & 0xFF).saturating_sub(127 + 23);
    let mantissa = (bits & 0x7F_FFFF) | 0x80_0000;
    // Least significant first; f32::MAX < 10^39 needs five limbs.
    let mut limbs = [mantissa, 0, 0, 0, 0];
    for _ in 0..doublings {
        let mut carry = 0u64;
        for limb in limbs.iter_mut() {
            let doubled = u64::from(*limb) * 2 + carry;
            *limb = (doubled % LIMB) as u32;
            carry = doubled / LIMB;
        }
    }
    let mut started = false;
    for limb in limbs.iter().rev() {
        if started {
            write!(line, "{limb:09}")?;
        } else if *limb != 0 {
            write!(line, "{limb}")?;
            started = true;
        }
    }
    if started {
        Ok(())
    } else {
        line.write_char('0')
    }
}

fn write_optional<W: Write>(line: &mut W, value: Option<f32>) -> core::fmt::Result {
    match value {
        Some(value) => {
            line.write_char(',')?;
            write_three_decimals(line, value)
        }
        // `nan` is read as not-a-number by spreadsheets, numpy and pandas, so a missing value
        // can never be mistaken for a measurement.
        None => line.write_str(",nan"),
    }
}

fn write_line<W: Write>(sample: &SampleFrame, line: &mut W) -> core::fmt::Result {
    write!(
        line,
        "{},{},{}.{:06}",
        sample.sequence,
        sample.pad.get(),
        sample.timestamp_us / 1_000_000,
        sample.timestamp_us % 1_000_000
    )?;
    write_optional(line, sample.temperature_c)?;
    for taxel in &sample.taxels {
        write_optional(line, taxel.pressure_kpa)?;
    }
    for taxel in &sample.taxels {
        write!(line, ",{}", taxel.flags)?;
    }
    write_optional(line, sample.summary.force_n)?;
    line.write_str("\r\n")
}

/// Replaces the content of `line` by the CSV line of `sample`, `\r\n` included, columns as in
/// [`CSV_HEADER`]: time in seconds with 6 decimals, temperature and pressures with 3 decimals
/// or `nan` when absent, flags in decimal. A capacity of [`CSV_LINE_MAX_LEN`] always suffices.
pub fn format_csv_line<const N: usize>(
    sample: &SampleFrame,
    line: &mut String<N>,
) -> Result<(), CsvLineTooLong> {
    line.clear();
    let result = write_line(sample, line);
    if result.is_err() {
        line.clear();
        return Err(CsvLineTooLong);
    }
    Ok(())
}

/// The longest text line [`TextCommandParser`] considers; longer lines are ignored.
pub const TEXT_COMMAND_LINE_MAX_LEN: usize = 16;

/// A command typed as a text line while the device is in text mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TextCommand {
    /// The line `binary`: leave text mode.
    Binary,
}

/// Recognises text commands in the received byte stream.
///
/// Feed it every received byte while in text mode (in addition to the frame decoder). A line
/// ends at `\n`, `\r` or 0x00; surrounding spaces and letter case are ignored.
#[derive(Debug, Clone, Default)]
pub struct TextCommandParser {
    line: [u8; TEXT_COMMAND_LINE_MAX_LEN],
    length: usize,
    overflowed: bool,
}

impl TextCommandParser {
    /// An empty parser.
    pub const fn new() -> Self {
        TextCommandParser {
            line: [0; TEXT_COMMAND_LINE_MAX_LEN],
            length: 0,
            overflowed: false,
        }
    }

    /// Takes one received byte; returns the command when it completed one.
    pub fn push(&mut self, byte: u8) -> Option<TextCommand> {
        if matches!(byte, b'\n' | b'\r' | 0) {
            let line = self.line.get(..self.length).unwrap_or_default();
            let command = if !self.overflowed && line.trim_ascii().eq_ignore_ascii_case(b"binary") {
                Some(TextCommand::Binary)
            } else {
                None
            };
            self.length = 0;
            self.overflowed = false;
            return command;
        }
        if !self.overflowed {
            match self.line.get_mut(self.length) {
                Some(slot) => {
                    *slot = byte;
                    self.length += 1;
                }
                None => self.overflowed = true,
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;

    fn three_decimals(value: f32) -> heapless::String<64> {
        let mut text = heapless::String::new();
        let _ = write_three_decimals(&mut text, value);
        text
    }

    #[test]
    fn integer_formatting_matches_core_formatting() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut values = edge_cases();
        for _ in 0..200_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            values.push(f32::from_bits(state as u32));
            values.push((state % 200_000) as f32 / 1000.0 - 100.0);
            values.push((state % 2_000_000) as f32 / 16.0 - 60_000.0);
        }
        for value in values {
            let mut expected = heapless::String::<64>::new();
            let _ = write!(expected, "{value:.3}");
            assert_eq!(
                three_decimals(value),
                expected,
                "{value:e} ({:#x})",
                value.to_bits()
            );
        }
    }

    fn edge_cases() -> std::vec::Vec<f32> {
        std::vec![
            0.0,
            -0.0,
            0.0005,
            -0.0005,
            0.0015,
            0.0025,
            1.0625,
            -1.0625,
            0.9995,
            999.9995,
            8_388_607.5,
            8_388_608.0,
            -8_388_609.0,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            f32::EPSILON,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            1e-40,
            123.4565,
        ]
    }
}
