//! Conversion throughput: `taxel convert`'s engine over a 1,000,000-row recording, side by side
//! with a reference CSV pipeline on the same file in the same run (the `csv` crate reading every
//! record, parsing every number and writing every record back: what any CSV-to-CSV pass costs
//! at least), both single-threaded, with their peak memory. Prints a markdown table:
//!
//!     cargo run --release -p taxel-host --example convert_throughput > host/PERFORMANCE.md
//!
//! (`cargo xtask report` copies the table into docs/PERFORMANCE.md.)
#![allow(clippy::print_stdout, clippy::print_stderr)]

use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::Path;
use std::time::Instant;

use model_core::{TaxelFlags, TAXEL_COUNT};
use taxel_host::convert::{convert_recording, ConversionEngine, ConvertSettings, RecordedStates};
use taxel_host::schema::{PadReading, PadRow, RowWriter};
use wire::TemperatureSource;

const ROWS: u64 = 1_000_000;
const PADS: u64 = 4;
const REPEATS: usize = 3;

/// Peak resident memory of this process so far, KiB.
fn peak_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            status
                .lines()
                .find_map(|line| line.strip_prefix("VmHWM:"))
                .and_then(|rest| rest.split_whitespace().next()?.parse().ok())
        })
        .unwrap_or(0)
}

/// A recording of one device of four pads, as `taxel record` writes it: presses that come and
/// go on every taxel, with the pressures, force and centre the device sent.
fn write_recording(path: &Path) -> std::io::Result<()> {
    let mut rows = RowWriter::new(BufWriter::new(File::create(path)?))?;
    for index in 0..ROWS {
        let set = index / PADS;
        let pad = (index % PADS) as u8;
        let phase = set as f32 * 0.01 + f32::from(pad);
        let load: [f32; TAXEL_COUNT] =
            std::array::from_fn(|taxel| (phase + taxel as f32).sin().max(0.0));
        let capacitance_pf = load.map(|load| Some(4.5 + 1.5 * load));
        // What the device sent with them: a pressure per taxel, the force and its centre.
        let pressure_kpa = load.map(|load| Some(45.0 * load));
        let force_n = load.iter().sum::<f32>() * 0.25;
        let row = PadRow {
            host_time_us: 1_700_000_000_000_000 + set * 10_000,
            device: 0,
            pad,
            sequence: set as u32,
            sync_error_us: Some(612),
            reading: Some(PadReading {
                device_time_us: set * 10_000 + u64::from(pad) * 2_000,
                temperature_c: Some(25.0 + (phase * 0.1).sin()),
                temperature_source: TemperatureSource::Tmp117,
                capacitance_pf,
                pressure_kpa,
                flags: [TaxelFlags::empty(); TAXEL_COUNT],
                force_n: Some(force_n),
                centre_of_pressure_mm: (force_n > 0.0).then_some([0.4 * force_n, -0.3 * force_n]),
                partial: false,
                contact: force_n > 0.05,
            }),
            marker: String::new(),
        };
        rows.write(&row)?;
    }
    rows.into_inner().flush()
}

/// Reads every record, parses every number, writes every record back.
fn reference(input: &Path, output: &Path) -> anyhow::Result<u64> {
    let mut reader =
        csv::Reader::from_reader(BufReader::with_capacity(1 << 20, File::open(input)?));
    let mut writer = csv::Writer::from_writer(BufWriter::new(File::create(output)?));
    writer.write_byte_record(reader.byte_headers()?)?;
    let mut record = csv::ByteRecord::new();
    let mut checksum = 0.0f64;
    while reader.read_byte_record(&mut record)? {
        for cell in record.iter() {
            if let Some(value) = std::str::from_utf8(cell)
                .ok()
                .and_then(|text| text.parse::<f64>().ok())
            {
                checksum += value;
            }
        }
        writer.write_byte_record(&record)?;
    }
    writer.flush()?;
    Ok(checksum as u64)
}

fn engine(input: &Path, output: &Path) -> anyhow::Result<u64> {
    let mut rows = RowWriter::new(BufWriter::new(File::create(output)?))?;
    let engine = ConversionEngine::new(ConvertSettings::default(), RecordedStates::default());
    let summary = convert_recording(
        BufReader::with_capacity(1 << 20, File::open(input)?),
        &mut rows,
        engine,
    )?;
    Ok(summary.rows_written)
}

/// The best of [`REPEATS`] runs: CPU seconds, and the peak memory added.
fn measure(run: impl Fn() -> anyhow::Result<u64>) -> anyhow::Result<(f64, u64)> {
    let mut best = f64::INFINITY;
    let before = peak_kib();
    for _ in 0..REPEATS {
        let start = cpu_time::ProcessTime::now();
        let started = Instant::now();
        run()?;
        let cpu_s = start.elapsed().as_secs_f64();
        eprintln!(
            "  {cpu_s:.3} s CPU, {:.3} s wall",
            started.elapsed().as_secs_f64()
        );
        best = best.min(cpu_s);
    }
    Ok((best, peak_kib().saturating_sub(before)))
}

fn main() -> anyhow::Result<()> {
    let directory = tempfile::tempdir()?;
    let input = directory.path().join("recording.csv");
    let output = directory.path().join("out.csv");
    write_recording(&input)?;
    let megabytes = std::fs::metadata(&input)?.len() as f64 / 1e6;
    eprintln!("reference pipeline:");
    let (reference_s, reference_kib) = measure(|| reference(&input, &output))?;
    eprintln!("taxel convert's engine:");
    let (engine_s, engine_kib) = measure(|| engine(&input, &output))?;
    println!("# Conversion throughput\n");
    println!(
        "Generated by `cargo run --release -p taxel-host --example convert_throughput > host/PERFORMANCE.md`; do not edit by hand.\n"
    );
    println!(
        "One core, the best CPU time of {REPEATS} runs, a {ROWS}-row recording of the schema \
({megabytes:.1} MB, one device of {PADS} pads) read from and written to files. The reference \
is the `csv` crate reading every record, parsing every number and writing the record back, \
the least a CSV-to-CSV pass costs; the engine reads the schema, runs every row through its pad's \
model, force, centre of pressure and contact, and writes the schema.\n"
    );
    println!("| pipeline | CPU time | throughput (input) | peak memory added | goal |");
    println!("|---|---|---|---|---|");
    println!(
        "| reference (read, parse, write) | {reference_s:.3} s | {:.0} MB/s | {} KiB | |",
        megabytes / reference_s,
        reference_kib
    );
    let goal = if megabytes / engine_s >= 100.0 {
        "at least 100 MB/s: met"
    } else {
        "at least 100 MB/s: **not met**"
    };
    println!(
        "| `taxel convert` engine | {engine_s:.3} s | {:.0} MB/s | {} KiB | {goal} |",
        megabytes / engine_s,
        engine_kib
    );
    Ok(())
}
