//! Text mode: the CSV line format and the `binary` line that leaves text mode.

mod common;

use common::*;
use heapless::String;
use proptest::prelude::*;
use wire::{
    format_csv_line, CsvLineTooLong, TemperatureSource, TextCommand, TextCommandParser, CSV_HEADER,
    CSV_LINE_MAX_LEN,
};

#[test]
fn csv_line_has_the_header_columns() {
    let mut line = String::<CSV_LINE_MAX_LEN>::new();
    format_csv_line(&example_sample(), &mut line).unwrap();
    assert_eq!(
        line.as_str(),
        "1234,1,5.000250,23.500,12.500,nan,nan,0.000,0,5,128,1,0.312\r\n"
    );
    assert_eq!(
        line.trim_end().split(',').count(),
        CSV_HEADER.split(',').count()
    );
}

#[test]
fn missing_temperature_and_faulted_pressure_never_print_a_number() {
    let mut sample = example_sample();
    sample.temperature_c = None;
    sample.temperature_source = TemperatureSource::None;
    for taxel in &mut sample.taxels {
        taxel.pressure_kpa = None;
    }
    sample.summary.force_n = None;
    let mut line = String::<CSV_LINE_MAX_LEN>::new();
    format_csv_line(&sample, &mut line).unwrap();
    assert_eq!(
        line.as_str(),
        "1234,1,5.000250,nan,nan,nan,nan,nan,0,5,128,1,nan\r\n"
    );
}

#[test]
fn worst_case_line_has_the_documented_length() {
    let mut sample = worst_case_sample();
    sample.temperature_c = Some(f32::MIN);
    for taxel in &mut sample.taxels {
        taxel.pressure_kpa = Some(f32::MIN);
    }
    sample.summary.force_n = Some(f32::MIN);
    let mut line = String::<CSV_LINE_MAX_LEN>::new();
    format_csv_line(&sample, &mut line).unwrap();
    assert_eq!(line.len(), CSV_LINE_MAX_LEN);
    assert!(line.starts_with(
        "4294967295,7,18446744073709.551615,-340282346638528859811704183484516925440.000,"
    ));
}

#[test]
fn a_too_small_string_is_an_error_and_left_empty() {
    let mut line = String::<20>::new();
    assert_eq!(
        format_csv_line(&example_sample(), &mut line),
        Err(CsvLineTooLong)
    );
    assert!(line.is_empty());
}

proptest! {
    #![proptest_config(config(2000))]

    #[test]
    fn any_sample_formats_within_the_maximum(sample in sample_frame()) {
        let mut line = String::<CSV_LINE_MAX_LEN>::new();
        prop_assert!(format_csv_line(&sample, &mut line).is_ok());
        prop_assert!(line.ends_with("\r\n"));
        prop_assert_eq!(line.matches(',').count(), 12);
        for (index, taxel) in sample.taxels.iter().enumerate() {
            let field = line.trim_end().split(',').nth(4 + index).unwrap();
            if taxel.pressure_kpa.is_none() {
                prop_assert_eq!(field, "nan");
            }
        }
    }

    #[test]
    fn the_parser_ignores_arbitrary_bytes_without_a_binary_line(
        bytes in prop::collection::vec(any::<u8>(), 0..300)
    ) {
        let mut parser = TextCommandParser::new();
        for byte in bytes {
            let _ = parser.push(byte);
        }
        // Whatever came before, a fresh line `binary` is recognised.
        let commands: Vec<_> = b"\nbinary\n".iter().filter_map(|&byte| parser.push(byte)).collect();
        prop_assert_eq!(commands, vec![TextCommand::Binary]);
    }
}

fn commands_in(bytes: &[u8]) -> Vec<TextCommand> {
    let mut parser = TextCommandParser::new();
    bytes.iter().filter_map(|&byte| parser.push(byte)).collect()
}

#[test]
fn the_binary_line_is_recognised() {
    assert_eq!(commands_in(b"binary\n"), [TextCommand::Binary]);
    assert_eq!(commands_in(b"binary\r\n"), [TextCommand::Binary]);
    assert_eq!(commands_in(b"  BINARY \r"), [TextCommand::Binary]);
    assert_eq!(commands_in(b"hello\nbinary\n"), [TextCommand::Binary]);
    assert_eq!(commands_in(b"binary"), []);
    assert_eq!(commands_in(b"binaryx\n"), []);
    assert_eq!(commands_in(b"xbinary\n"), []);
    assert_eq!(commands_in(b"a very long line that ends in binary\n"), []);
    assert_eq!(
        commands_in(b"a very long line that ends\0binary\n"),
        [TextCommand::Binary]
    );
}
