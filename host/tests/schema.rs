//! The recording schema: what is written reads back exactly (any f32, any flags, a missing
//! frame, a marker with commas and quotes), the flag cells are the documented names, and a
//! file that is not a recording of this schema is refused with its header named.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use model_core::{TaxelFlags, TAXEL_COUNT};
use proptest::prelude::*;
use taxel_host::csv_format::flag_names;
use taxel_host::schema::{
    format_row, header, PadReading, PadRow, RowReader, RowWriter, SchemaError,
};
use wire::TemperatureSource;

fn finite() -> impl Strategy<Value = Option<f32>> {
    prop::option::of(any::<f32>().prop_filter("a number", |value| !value.is_nan()))
}

fn reading() -> impl Strategy<Value = PadReading> {
    (
        any::<u64>().prop_map(|value| value % 10_000_000_000_000),
        finite(),
        prop::sample::select(vec![
            TemperatureSource::None,
            TemperatureSource::Tmp117,
            TemperatureSource::McuInternal,
            TemperatureSource::LastKnown,
        ]),
        prop::array::uniform4(finite()),
        prop::array::uniform4(finite()),
        prop::array::uniform4(any::<u16>()),
        finite(),
        prop::option::of((finite(), finite())),
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(
            |(
                device_time_us,
                temperature_c,
                temperature_source,
                capacitance_pf,
                pressure_kpa,
                flags,
                force_n,
                centre,
                partial,
                contact,
            )| {
                PadReading {
                    device_time_us,
                    temperature_c,
                    temperature_source,
                    capacitance_pf,
                    pressure_kpa,
                    flags: flags.map(TaxelFlags::from_bits_retain),
                    force_n,
                    centre_of_pressure_mm: centre.and_then(|(x_mm, y_mm)| Some([x_mm?, y_mm?])),
                    partial,
                    contact,
                }
            },
        )
}

fn row() -> impl Strategy<Value = PadRow> {
    (
        any::<u64>().prop_map(|value| value % 10_000_000_000_000_000),
        any::<u32>(),
        0u8..8,
        any::<u32>(),
        prop::option::of(any::<u64>().prop_map(|value| value % 1_000_000_000_000)),
        prop::option::of(reading()),
        "[ -~]{0,12}",
    )
        .prop_map(
            |(host_time_us, device, pad, sequence, sync_error_us, reading, marker)| PadRow {
                host_time_us,
                device,
                pad,
                sequence,
                sync_error_us,
                reading,
                marker,
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn every_row_reads_back_exactly(rows in prop::collection::vec(row(), 1..20)) {
        let mut writer = RowWriter::new(Vec::new()).unwrap();
        for row in &rows {
            writer.write(row).unwrap();
        }
        let bytes = writer.into_inner();
        let mut reader = RowReader::new(bytes.as_slice()).unwrap();
        for row in &rows {
            let read = reader.next_row().unwrap().unwrap();
            prop_assert_eq!(&read, row);
        }
        prop_assert!(reader.next_row().is_none());
    }
}

#[test]
fn flag_cells_are_the_documented_names_for_every_bit_pattern() {
    for bits in 0..=u16::MAX {
        let flags = TaxelFlags::from_bits_retain(bits);
        let row = PadRow {
            host_time_us: 0,
            device: 0,
            pad: 0,
            sequence: 0,
            sync_error_us: None,
            reading: Some(PadReading {
                device_time_us: 0,
                temperature_c: None,
                temperature_source: TemperatureSource::None,
                capacitance_pf: [None; TAXEL_COUNT],
                pressure_kpa: [None; TAXEL_COUNT],
                flags: [flags; TAXEL_COUNT],
                force_n: None,
                centre_of_pressure_mm: None,
                partial: false,
                contact: false,
            }),
            marker: String::new(),
        };
        let mut line = Vec::new();
        format_row(&row, &mut line);
        let text = String::from_utf8(line).unwrap();
        let cells: Vec<&str> = text.trim_end().split(',').collect();
        assert_eq!(cells[16], flag_names(flags), "bits {bits:#x}");
    }
}

#[test]
fn a_missing_frame_has_only_its_identity() {
    let row = PadRow {
        host_time_us: 1_700_000_000_123_456,
        device: 1,
        pad: 3,
        sequence: 42,
        sync_error_us: Some(1_500),
        reading: None,
        marker: String::new(),
    };
    let mut line = Vec::new();
    format_row(&row, &mut line);
    let text = String::from_utf8(line).unwrap();
    assert_eq!(
        text,
        format!("1700000000.123456,1,3,42,,1.500{}\n", ",".repeat(20))
    );
    assert_eq!(text.matches(',').count(), header().len() - 1);
}

#[test]
fn another_header_is_refused_naming_what_was_found() {
    let old = "seq,time_s,temp_c,temp_source,c11_pf,c12_pf,c21_pf,c22_pf\n1,0.1,25,tmp117,4.5,4.5,4.5,4.5\n";
    match RowReader::new(old.as_bytes()) {
        Err(SchemaError::Header { found, .. }) => assert!(found.contains("seq,time_s"), "{found}"),
        other => panic!("{:?}", other.err()),
    }
    assert!(matches!(
        RowReader::new("".as_bytes()),
        Err(SchemaError::Header { .. })
    ));
}

#[test]
fn a_bad_row_names_its_line_and_the_next_rows_still_read() {
    let mut writer = RowWriter::new(Vec::new()).unwrap();
    let good = PadRow {
        host_time_us: 5,
        device: 0,
        pad: 0,
        sequence: 1,
        sync_error_us: None,
        reading: None,
        marker: String::new(),
    };
    writer.write(&good).unwrap();
    let mut bytes = writer.into_inner();
    bytes.extend_from_slice(b"0.000001,0,9,2,,,,,,,,,,,,,,,,,,,,,,\n");
    bytes.extend_from_slice(b"0.000005,0,0,3,,,,,,,,,,,,,,,,,,,,,,\n");
    let mut reader = RowReader::new(bytes.as_slice()).unwrap();
    assert_eq!(reader.next_row().unwrap().unwrap(), good);
    match reader.next_row().unwrap() {
        Err(SchemaError::Row { line, reason }) => {
            assert_eq!(line, 3);
            assert!(reason.contains("pad 9"), "{reason}");
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(reader.next_row().unwrap().unwrap().sequence, 3);
}
