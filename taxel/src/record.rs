//! `taxel record`: streams sample frames from the device into a CSV file (RFC 4180, '.' decimal
//! separator, units in the header) and every received byte into a raw log that `taxel convert
//! --raw` can re-process. Ctrl-C or an unplugged device closes both files cleanly with
//! everything received so far.

use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use wire::{Command, DeviceFrame, ReplyPayload, SampleFrame};

use crate::csv_format::{
    format_number, format_optional, format_time_us, temperature_source_name, wire_flag_names,
    CAPACITANCE_COLUMNS, FLAGS_COLUMNS, PRESSURE_COLUMNS,
};
use crate::device_link::{self, DeviceLink, LinkError};

/// The long help of the subcommand.
pub const LONG_ABOUT: &str = "Record the device's samples to a CSV file and a raw byte log.\n\n\
The CSV has the columns seq,time_s,temp_c,temp_source,c11_pf..c22_pf,p11_kpa..p22_kpa,\
flags11..flags22 (RFC 4180, '.' decimal separator; empty pressure = faulted taxel; flags = \
documented names joined by '|'). The raw log holds every byte received, for `taxel convert --raw`.\n\n\
Stop with Ctrl-C; unplugging the device also ends the recording. Both files are closed cleanly \
with everything received so far.";

/// Arguments of `taxel record`.
#[derive(Debug, Clone, clap::Args)]
pub struct RecordArgs {
    /// Serial port of the device (default: the only attached board, or --serial).
    #[arg(value_name = "PORT")]
    pub port: Option<String>,
    /// Choose the attached board with this USB serial number.
    #[arg(long, value_name = "SN", conflicts_with = "port")]
    pub serial: Option<String>,
    /// CSV file to write.
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Raw byte log to write (default: the CSV file name with `.raw` appended).
    #[arg(long, value_name = "FILE")]
    pub raw: Option<PathBuf>,
    /// Stop after this many sample frames.
    #[arg(long, value_name = "N")]
    pub samples: Option<u64>,
    /// USB vendor id of the board, for finding it.
    #[arg(long, value_name = "VID", default_value = "0x1209", value_parser = parse_hex_u16)]
    pub vid: u16,
    /// USB product id of the board, for finding it.
    #[arg(long, value_name = "PID", default_value = "0x0001", value_parser = parse_hex_u16)]
    pub pid: u16,
    /// How long to wait for each reply from the device, ms.
    #[arg(long, value_name = "MS", default_value_t = 2000)]
    pub timeout_ms: u64,
}

/// Parses a USB id written in hexadecimal, with or without `0x`.
pub fn parse_hex_u16(text: &str) -> Result<u16, String> {
    let digits = text
        .trim()
        .trim_start_matches("0x")
        .trim_start_matches("0X");
    u16::from_str_radix(digits, 16).map_err(|_| format!("'{text}' is not a 16-bit hex number"))
}

/// The CSV header of a recording.
pub fn record_header() -> Vec<&'static str> {
    let mut header = vec!["seq", "time_s", "temp_c", "temp_source"];
    header.extend(CAPACITANCE_COLUMNS);
    header.extend(PRESSURE_COLUMNS);
    header.extend(FLAGS_COLUMNS);
    header
}

/// The CSV cells of one sample frame, in [`record_header`] order.
pub fn sample_cells(sample: &SampleFrame) -> Vec<String> {
    let mut cells = vec![
        sample.sequence.to_string(),
        format_time_us(sample.timestamp_us),
        format_optional(sample.temperature_c),
        temperature_source_name(sample.temperature_source).to_owned(),
    ];
    cells.extend(
        sample
            .taxels
            .iter()
            .map(|taxel| format_number(taxel.capacitance_pf)),
    );
    cells.extend(
        sample
            .taxels
            .iter()
            .map(|taxel| format_optional(taxel.pressure_kpa)),
    );
    cells.extend(
        sample
            .taxels
            .iter()
            .map(|taxel| wire_flag_names(taxel.flags)),
    );
    cells
}

/// Why a recording ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StopReason {
    /// Ctrl-C (or the stop flag was set).
    Interrupted,
    /// The requested number of samples was reached.
    SampleLimit,
    /// The device went away; the message says how.
    Disconnected(String),
}

/// What a recording captured.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordSummary {
    /// Sample frames written to the CSV.
    pub samples: u64,
    /// Sample sets lost according to sequence gaps.
    pub sequence_gap_samples: u64,
    /// Bytes received (all in the raw log).
    pub bytes_received: u64,
    /// Frames that could not be decoded.
    pub frames_rejected: u64,
    /// Why it ended.
    pub stop_reason: StopReason,
}

/// Lost sample sets between two sequence numbers (wrapping), 0 for consecutive ones. A repeated
/// or backward number (the device restarted) counts as no loss.
pub fn sequence_gap(previous: u32, current: u32) -> u64 {
    let step = current.wrapping_sub(previous);
    if step == 0 || step > u32::MAX / 2 {
        0
    } else {
        u64::from(step - 1)
    }
}

/// Records from an open link until `stop` is set, `max_samples` are written, or the link
/// fails. Non-sample frames are reported through `status`. The CSV and the link's raw log are
/// flushed at least every `flush_interval` and at the end.
pub fn record_link<P: Read + Write, W: Write>(
    link: &mut DeviceLink<P>,
    csv_writer: &mut csv::Writer<W>,
    stop: &AtomicBool,
    max_samples: Option<u64>,
    flush_interval: Duration,
    status: &mut dyn FnMut(&str),
) -> anyhow::Result<RecordSummary> {
    let result = record_until_stopped(link, csv_writer, stop, max_samples, flush_interval, status);
    if result.is_err() {
        // One file failing (a full disk, a removed drive) must not cost the other what it has
        // buffered: flush both as far as they go, then report the first error.
        let _ = csv_writer.flush();
        let _ = link.flush_raw_log();
    }
    result
}

fn record_until_stopped<P: Read + Write, W: Write>(
    link: &mut DeviceLink<P>,
    csv_writer: &mut csv::Writer<W>,
    stop: &AtomicBool,
    max_samples: Option<u64>,
    flush_interval: Duration,
    status: &mut dyn FnMut(&str),
) -> anyhow::Result<RecordSummary> {
    let mut samples = 0u64;
    let mut sequence_gap_samples = 0u64;
    let mut previous_sequence: Option<u32> = None;
    let mut last_flush = Instant::now();
    // The device repeats these unsolicited; only changes are worth a line.
    let mut last_info = None;
    let mut last_counters = None;
    let stop_reason = loop {
        if stop.load(Ordering::Relaxed) {
            break StopReason::Interrupted;
        }
        if max_samples.is_some_and(|limit| samples >= limit) {
            break StopReason::SampleLimit;
        }
        match link.next_frame() {
            Ok(Some(DeviceFrame::Sample(sample))) => {
                if let Some(previous) = previous_sequence {
                    sequence_gap_samples += sequence_gap(previous, sample.sequence);
                }
                previous_sequence = Some(sample.sequence);
                csv_writer
                    .write_record(sample_cells(&sample))
                    .with_context(|| format!("writing the CSV after {samples} samples"))?;
                samples += 1;
            }
            Ok(Some(DeviceFrame::Event(event))) => status(&format!(
                "device event at {} s: {:?}",
                format_time_us(event.timestamp_us),
                event.event
            )),
            Ok(Some(DeviceFrame::Info(info))) => {
                if last_info != Some(info) {
                    status(&format!("device info: {info:?}"));
                    last_info = Some(info);
                }
            }
            Ok(Some(DeviceFrame::Counters(counters))) => {
                if last_counters != Some(counters) {
                    status(&format!("device counters: {counters:?}"));
                    last_counters = Some(counters);
                }
            }
            Ok(Some(DeviceFrame::Reply(reply))) => {
                if let Err(code) = reply.result {
                    status(&format!(
                        "device refused request {}: {code:?}",
                        reply.request_id
                    ));
                }
            }
            Ok(None) => {}
            Err(LinkError::RawLog(error)) => return Err(error).context("writing the raw log"),
            Err(error) => break StopReason::Disconnected(error.to_string()),
        }
        if last_flush.elapsed() >= flush_interval {
            csv_writer
                .flush()
                .with_context(|| format!("writing the CSV after {samples} samples"))?;
            link.flush_raw_log().context("writing the raw log")?;
            last_flush = Instant::now();
        }
    };
    csv_writer.flush()?;
    link.flush_raw_log()?;
    Ok(RecordSummary {
        samples,
        sequence_gap_samples,
        bytes_received: link.statistics().bytes_received,
        frames_rejected: link.statistics().frames_rejected,
        stop_reason,
    })
}

/// The default raw log path: the CSV path with `.raw` appended.
pub fn default_raw_path(csv_path: &std::path::Path) -> PathBuf {
    let mut name = csv_path.as_os_str().to_owned();
    name.push(".raw");
    PathBuf::from(name)
}

/// Runs `taxel record`.
pub fn run(args: &RecordArgs) -> anyhow::Result<ExitCode> {
    let port_path = device_link::select_port(
        args.port.as_deref(),
        args.serial.as_deref(),
        args.vid,
        args.pid,
    )?;
    let raw_path = args
        .raw
        .clone()
        .unwrap_or_else(|| default_raw_path(&args.output));
    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = Arc::clone(&stop);
    ctrlc::set_handler(move || handler_stop.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;

    let opened = device_link::open_serial(&port_path, Duration::from_millis(100))?;
    if let Some(error) = &opened.dtr_error {
        eprintln!("warning: {port_path}: DTR not asserted ({error}); continuing");
    }
    let mut link = DeviceLink::new(opened.port);
    let csv_file = File::create(&args.output)
        .with_context(|| format!("creating {}", args.output.display()))?;
    let raw_file =
        File::create(&raw_path).with_context(|| format!("creating {}", raw_path.display()))?;
    link.set_raw_log(Box::new(BufWriter::new(raw_file)));
    let mut csv_writer = csv::WriterBuilder::new()
        .terminator(csv::Terminator::CRLF)
        .from_writer(BufWriter::new(csv_file));
    csv_writer.write_record(record_header())?;

    let timeout = Duration::from_millis(args.timeout_ms);
    match link.request(Command::Info, timeout) {
        Ok(ReplyPayload::Info(info)) => eprintln!(
            "device on {port_path}: firmware {}.{}.{}, protocol {}, calibration id {} ({:?}), {} samples/s",
            info.firmware_version.major,
            info.firmware_version.minor,
            info.firmware_version.patch,
            info.protocol_version,
            info.calibration_id,
            info.calibration_source,
            info.rate_sps
        ),
        Ok(other) => eprintln!("unexpected reply to Info: {other:?}"),
        Err(error) => eprintln!("warning: no device info: {error}"),
    }
    if let Err(error) = link.request(Command::StartStreaming, timeout) {
        csv_writer.flush()?;
        link.flush_raw_log()?;
        return Err(error).context("starting the stream");
    }
    eprintln!(
        "recording from {port_path} to {} and {} (Ctrl-C to stop)",
        args.output.display(),
        raw_path.display()
    );
    let summary = record_link(
        &mut link,
        &mut csv_writer,
        &stop,
        args.samples,
        Duration::from_millis(500),
        &mut |message| eprintln!("{message}"),
    )?;
    if !matches!(summary.stop_reason, StopReason::Disconnected(_)) {
        // Best effort: the recording is complete whether or not the device hears this.
        let _ = link.send(Command::StopStreaming);
    }
    if let Some(mut raw_log) = link.take_raw_log() {
        raw_log.flush().context("flushing the raw log")?;
    }
    drop(csv_writer);
    let reason = match &summary.stop_reason {
        StopReason::Interrupted => "stopped by Ctrl-C".to_owned(),
        StopReason::SampleLimit => "sample limit reached".to_owned(),
        StopReason::Disconnected(message) => format!("device disconnected: {message}"),
    };
    eprintln!(
        "{reason}; files closed with everything received: {} samples ({} lost in sequence gaps), {} bytes, {} undecodable frames",
        summary.samples, summary.sequence_gap_samples, summary.bytes_received, summary.frames_rejected
    );
    let _ = io::stderr().flush();
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sequence_gaps_wrap() {
        assert_eq!(sequence_gap(1, 2), 0);
        assert_eq!(sequence_gap(1, 5), 3);
        assert_eq!(sequence_gap(u32::MAX, 0), 0);
        assert_eq!(sequence_gap(u32::MAX - 1, 1), 2);
        assert_eq!(sequence_gap(7, 7), 0);
        assert_eq!(sequence_gap(1000, 3), 0);
    }

    #[test]
    fn hex_ids_parse_with_or_without_prefix() {
        assert_eq!(parse_hex_u16("0x1209"), Ok(0x1209));
        assert_eq!(parse_hex_u16("1209"), Ok(0x1209));
        assert!(parse_hex_u16("0xZZ").is_err());
    }
}
