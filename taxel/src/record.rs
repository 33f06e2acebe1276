//! `taxel record`: streams sample frames from the device into a recording (see
//! [`crate::recording`]: a CSV file, a raw byte log and the device's state). Ctrl-C, an
//! unplugged device or the sample limit end it; the files are then renamed into place with
//! everything received. Several devices at once are recorded onto one host timeline by
//! [`crate::multi_record`].

use std::io::{Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use wire::{Command, CountersFrame, DeviceFrame, InfoFrame, ReplyPayload};

pub use crate::device_link::parse_hex_u16;
use crate::device_link::{self, DeviceLink, LinkError};
use crate::device_words::{counters_words, event_words, info_words};
use crate::multi_record::MultiBoardArgs;
use crate::noteln;
use crate::recording::{
    default_raw_path, read_device_state, BaselineFollower, RecordedDeviceState, Recording,
    SampleSink,
};
use crate::stream_accounting::StreamAccounting;

pub use crate::recording::{record_header, sample_cells};
pub use crate::stream_accounting::sequence_gap;

/// The long help of the subcommand.
pub const LONG_ABOUT: &str = "Record the device's samples to a CSV file, a raw byte log and \
the device's state (or, with --format mcap, to an MCAP file of the ROS 2 messages `taxel bridge` \
publishes: see docs/BRIDGE.md).\n\n\
The CSV has the columns seq,time_s,temp_c,temp_source,c11_pf..c22_pf,p11_kpa..p22_kpa,\
flags11..flags22,marker (RFC 4180, '.' decimal separator; empty pressure = faulted taxel; flags = \
documented names joined by '|'). The raw log (FILE.raw) holds every byte received, for `taxel \
convert --raw`. FILE.device.json holds what the device computed the pressures with: its \
identity, tier, calibration and baselines, so that `taxel convert` reproduces them.\n\n\
A device that reads several pads (its Info says how many) sends one frame per pad per sample \
set; the CSV then has one row per sample set: seq, then for each pad n in order the columns \
padN_time_s,padN_temp_c,padN_temp_source,padN_c11_pf..padN_c22_pf,padN_p11_kpa..padN_p22_kpa,\
padN_flags11..padN_flags22 (as above, of pad N), padN_force_n (total normal force, N), \
padN_cop_x_mm,padN_cop_y_mm (centre of pressure in the pad's frame, mm; empty when there is \
none), padN_partial (1 when faulted taxels were left out of force and centre) and padN_contact \
(1 while the device says the pad is in contact), then marker. A row is written when every pad's \
frame of its set arrived, or when a later set began or the recording ended without them: a pad \
whose frame is missing has every cell empty, padN_time_s included (a pad that arrived always \
has its time and 0/1 in partial and contact), and the end says how many rows lack which pad. \
--samples then counts sample sets (rows). FILE.device.json then holds every pad's calibration, \
tier and baselines (pad 0's where a single pad's are, the others' in other_pads) and how many \
pads there are; a tare's new baselines are read for the pad its TareFinished event names.\n\n\
Frames that were waiting in the port from before the connection are discarded. At the end the \
tool says how many sample sets were received, lost on the link (sequence gaps the device's \
counters do not explain) and dropped by the device (its counters, since the start).\n\n\
Stop with Ctrl-C; unplugging the device also ends the recording. The files are written under \
temporary names and renamed when the recording ends; if writing fails half-way, the partial \
files are kept and named.\n\n\
Several devices (several PORTs, or --serial SN repeated; numbered from 0: the PORTs in order, \
then the --serial boards) are recorded onto one host timeline. Each device is read by its own \
thread; every sample frame is stamped with its arrival on the host's monotonic clock, and each \
device's clock is mapped onto the host clock (offset and drift, from the lower envelope of the \
frames' device timestamps against their arrivals). The CSV then has one row per sample frame of \
any device and pad, in host-time order, with the columns host_time_s,device,pad,seq,\
device_time_s,sync_error_ms,temp_c,temp_source,c11_pf..c22_pf,p11_kpa..p22_kpa,\
flags11..flags22,force_n,cop_x_mm,cop_y_mm,partial,contact. host_time_s is seconds of the \
host's monotonic clock since the recording started (whose Unix time is printed at the start); \
sync_error_ms is the estimated bound on its distance from the true sampling instant, empty when \
the device had no clock estimate (the host time is then the arrival time). Rows are held 4 s \
and then written with the clock estimate of that moment, so the CSV follows the stream 4 s \
behind; a frame arriving later than that is written after the rows already written, and the \
shift is added to its error. Device n gets its own raw log FILE.dev<n>.raw and state \
FILE.dev<n>.device.json (`taxel convert --raw FILE.dev<n>.raw` finds it; --raw is for one \
device). --samples N counts the sample sets of each device (as for one device); Ctrl-C or one device unplugged \
ends the recording of all. At the end each device's line says: received, lost on the link, \
dropped by the device, and its clock's offset, drift (ppm) and synchronisation error.\n\n\
Examples:\n  taxel record /dev/ttyACM0 -o rec.csv --samples 1000\n  \
taxel record /dev/ttyACM0 /dev/ttyACM1 -o both.csv";

/// Arguments of `taxel record`.
#[derive(Debug, Clone, clap::Args)]
pub struct RecordArgs {
    /// The device, or several.
    #[command(flatten)]
    pub board: MultiBoardArgs,
    /// CSV file to write.
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Raw byte log to write (default: the CSV file name with `.raw` appended; one device only,
    /// several devices get FILE.dev<n>.raw).
    #[arg(long, value_name = "FILE")]
    pub raw: Option<PathBuf>,
    /// Stop after this many rows: sample frames of a single-pad device, sample sets of a
    /// device with several pads; with several devices, sample frames of each device.
    #[arg(long, value_name = "N")]
    pub samples: Option<u64>,
    /// How long to wait for each reply from the device, ms.
    #[arg(long, value_name = "MS", default_value_t = 2000)]
    pub timeout_ms: u64,
    /// What to write: CSV with a raw log and the device's state, or MCAP of the ROS 2 messages
    /// `taxel bridge` publishes (one device; no raw log).
    #[arg(long, value_enum, default_value_t = RecordFormat::Csv)]
    pub format: RecordFormat,
}

/// The file format of `taxel record`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum RecordFormat {
    /// RFC 4180 CSV, a raw byte log and the device state (re-processed by `taxel convert`).
    Csv,
    /// MCAP of ROS 2 messages (Foxglove, `ros2 bag`; see docs/BRIDGE.md for the topics).
    Mcap,
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
    /// Sample frames received (every pad's).
    pub samples: u64,
    /// Sample frames missing from the sequence numbers while streaming, summed over the pads.
    pub sequence_gap_samples: u64,
    /// Where every sample set went (received, lost on the link, dropped by the device).
    pub accounting: StreamAccounting,
    /// Bytes received (all in the raw log).
    pub bytes_received: u64,
    /// Frames that could not be decoded.
    pub frames_rejected: u64,
    /// Why it ended.
    pub stop_reason: StopReason,
}

/// Records from an open link until `stop` is set, `max_samples` are written, or the link
/// fails, with a fresh accounting; see [`record_accounted`].
pub fn record_link<P: Read + Write, S: SampleSink + ?Sized>(
    link: &mut DeviceLink<P>,
    sink: &mut S,
    stop: &AtomicBool,
    max_samples: Option<u64>,
    flush_interval: Duration,
    status: &mut dyn FnMut(&str),
) -> anyhow::Result<RecordSummary> {
    let mut accounting = StreamAccounting::new();
    let stop_reason = record_accounted(
        link,
        sink,
        &mut accounting,
        stop,
        max_samples,
        flush_interval,
        status,
    )?;
    Ok(RecordSummary {
        samples: accounting.received(),
        sequence_gap_samples: accounting.sequence_gap_sets(),
        accounting,
        bytes_received: link.statistics().bytes_received,
        frames_rejected: link.statistics().frames_rejected,
        stop_reason,
    })
}

/// Records from an open link until `stop` is set, `max_samples` rows are written in this call
/// (frames, for a sink that does not count rows), or the link fails. A frame that would close
/// the sample set in progress once the limit is reached is left unread by the sink, so that the
/// last row is that set's. Other frames are reported through `status` in words; counters go to
/// the accounting. The sink and the link's raw log are flushed at least every `flush_interval` and
/// at the end, also when writing fails (one file failing must not cost the other its data).
pub fn record_accounted<P: Read + Write, S: SampleSink + ?Sized>(
    link: &mut DeviceLink<P>,
    sink: &mut S,
    accounting: &mut StreamAccounting,
    stop: &AtomicBool,
    max_samples: Option<u64>,
    flush_interval: Duration,
    status: &mut dyn FnMut(&str),
) -> anyhow::Result<StopReason> {
    let result = record_until_stopped(
        link,
        sink,
        accounting,
        stop,
        max_samples,
        flush_interval,
        status,
    );
    if result.is_err() {
        let _ = sink.flush();
        let _ = link.flush_raw_log();
    }
    result
}

fn record_until_stopped<P: Read + Write, S: SampleSink + ?Sized>(
    link: &mut DeviceLink<P>,
    sink: &mut S,
    accounting: &mut StreamAccounting,
    stop: &AtomicBool,
    max_samples: Option<u64>,
    flush_interval: Duration,
    status: &mut dyn FnMut(&str),
) -> anyhow::Result<StopReason> {
    let mut last_flush = Instant::now();
    let received_before = accounting.received();
    let rows_before = sink.rows();
    let written = |sink: &S, accounting: &StreamAccounting| match (sink.rows(), rows_before) {
        (Some(rows), Some(before)) => rows.saturating_sub(before),
        _ => accounting.received().saturating_sub(received_before),
    };
    let mut baselines = BaselineFollower::default();
    // The device repeats these unsolicited; only changes are worth a line.
    let mut last_info = None;
    let baseline_timeout = Duration::from_millis(1000);
    let stop_reason = loop {
        if stop.load(Ordering::Relaxed) {
            break StopReason::Interrupted;
        }
        if max_samples.is_some_and(|limit| written(sink, accounting) >= limit) {
            break StopReason::SampleLimit;
        }
        match link.next_frame() {
            Ok(Some(DeviceFrame::Sample(sample))) => {
                if max_samples.is_some_and(|limit| {
                    sink.would_close_set(&sample) && written(sink, accounting) + 1 >= limit
                }) {
                    break StopReason::SampleLimit;
                }
                baselines.before_sample(sink, &sample);
                sink.write_sample(&sample).with_context(|| {
                    format!("writing the CSV after {} samples", accounting.received())
                })?;
                accounting.sample(&sample);
            }
            Ok(Some(DeviceFrame::Event(event))) => {
                status(&event_words(&event));
                sink.device_event(&event)?;
                if let Err(error) = baselines.on_event(link, &event, baseline_timeout) {
                    status(&format!(
                        "warning: the device's new baselines could not be read ({}); `convert` will not reproduce the pressures after this point",
                        crate::console::error_message(&error)
                    ));
                }
            }
            Ok(Some(DeviceFrame::Info(info))) => {
                if last_info != Some(info) {
                    status(&format!("device: {}", info_words(&info)));
                    last_info = Some(info);
                }
            }
            Ok(Some(DeviceFrame::Counters(counters))) => accounting.counters(&counters),
            Ok(Some(DeviceFrame::Reply(reply))) => match reply.result {
                Ok(ReplyPayload::Counters(counters)) => accounting.counters(&counters),
                Ok(_) => {}
                Err(code) => status(&format!(
                    "the device refused request {}: {code:?}",
                    reply.request_id
                )),
            },
            Ok(None) => {}
            Err(LinkError::RawLog(error)) => return Err(error).context("writing the raw log"),
            Err(error) => break StopReason::Disconnected(error.to_string()),
        }
        if last_flush.elapsed() >= flush_interval {
            sink.flush()?;
            link.flush_raw_log().context("writing the raw log")?;
            last_flush = Instant::now();
        }
    };
    sink.flush()?;
    link.flush_raw_log().context("writing the raw log")?;
    Ok(stop_reason)
}

/// The start of a recording on an open link: asks who the device is (`announce` gets its Info
/// to say so), then reads its state, every pad's. The stream starts later ([`start_stream`]),
/// once the raw log is in place. Returns the Info, the state and how many stale frames were
/// discarded.
pub fn identify_device<P: Read + Write>(
    link: &mut DeviceLink<P>,
    timeout: Duration,
    announce: &mut dyn FnMut(&InfoFrame),
) -> anyhow::Result<(InfoFrame, RecordedDeviceState, u64)> {
    let (info, stale) = link
        .synchronise(timeout)
        .context("asking the device who it is")?;
    announce(&info);
    let state = read_device_state(link, &info, timeout)?;
    Ok((info, state, stale))
}

/// Starts the stream: an accounting that begins with the `stale` frames discarded and the
/// device's counters now (when it gives them), then StartStreaming.
pub fn start_stream<P: Read + Write>(
    link: &mut DeviceLink<P>,
    stale: u64,
    timeout: Duration,
) -> anyhow::Result<StreamAccounting> {
    let mut accounting = StreamAccounting::new();
    accounting.stale_discarded(stale);
    if let Ok(ReplyPayload::Counters(counters)) = link.request(Command::ReadCounters, timeout) {
        accounting.counters(&counters);
    }
    link.request(Command::StartStreaming, timeout)
        .context("starting the stream")?;
    Ok(accounting)
}

/// The end of a recording: unless the device went away, StopStreaming and the device's
/// counters, which go to the accounting and are returned for the user.
pub fn stop_stream<P: Read + Write>(
    link: &mut DeviceLink<P>,
    accounting: &mut StreamAccounting,
    stop_reason: &StopReason,
) -> Option<CountersFrame> {
    if matches!(stop_reason, StopReason::Disconnected(_)) {
        return None;
    }
    // Best effort: the recording is complete whether or not the device hears this.
    let _ = link.send(Command::StopStreaming);
    match link.request(Command::ReadCounters, Duration::from_millis(500)) {
        Ok(ReplyPayload::Counters(counters)) => {
            accounting.counters(&counters);
            Some(counters)
        }
        _ => None,
    }
}

/// Why a recording ended, for the closing line.
pub fn stop_words(stop_reason: &StopReason) -> String {
    match stop_reason {
        StopReason::Interrupted => "stopped by Ctrl-C".to_owned(),
        StopReason::SampleLimit => "sample limit reached".to_owned(),
        StopReason::Disconnected(message) => format!("device disconnected: {message}"),
    }
}

/// Runs `taxel record`: one device as a single recording, several onto one host timeline.
pub fn run(args: &RecordArgs) -> anyhow::Result<ExitCode> {
    let ports = args.board.select_ports()?;
    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = Arc::clone(&stop);
    ctrlc::set_handler(move || handler_stop.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;
    match (ports.as_slice(), args.format) {
        ([port_path], RecordFormat::Csv) => run_single(args, port_path, &stop),
        ([port_path], RecordFormat::Mcap) => crate::mcap_record::run(args, port_path, &stop),
        (_, RecordFormat::Csv) => crate::multi_record::run(args, &ports, &stop),
        (_, RecordFormat::Mcap) => anyhow::bail!(
            "--format mcap records one device; `taxel bridge PORT PORT... --mcap FILE` writes several"
        ),
    }
}

/// `taxel record` of one device.
fn run_single(args: &RecordArgs, port_path: &str, stop: &AtomicBool) -> anyhow::Result<ExitCode> {
    let raw_path = args
        .raw
        .clone()
        .unwrap_or_else(|| default_raw_path(&args.output));
    let opened = device_link::open_serial(port_path, Duration::from_millis(100))?;
    if let Some(error) = &opened.dtr_error {
        noteln!("note: {port_path}: DTR not set ({error}); a simulated device does not need it");
    }
    let mut link = DeviceLink::new(opened.port);
    let timeout = Duration::from_millis(args.timeout_ms);
    let (info, device_state, stale) = identify_device(&mut link, timeout, &mut |info| {
        noteln!("device on {port_path}: {}", info_words(info));
        if info.pad_count > 1 {
            noteln!(
                "the device reads {} pads: one row per sample set; every pad's calibration and baselines are recorded",
                info.pad_count
            );
        }
    })
    .with_context(|| format!("the device on {port_path}"))?;
    let (mut recording, raw_writer) =
        Recording::create_with_pads(&args.output, Some(&raw_path), info.pad_count.max(1))?;
    recording.set_device_state(device_state);
    if let Some(writer) = raw_writer {
        link.set_raw_log(Box::new(writer));
    }
    let mut accounting = match start_stream(&mut link, stale, timeout) {
        Ok(accounting) => accounting,
        Err(error) => {
            drop(recording);
            return Err(error.context("nothing was recorded"));
        }
    };
    noteln!(
        "recording from {port_path} to {} and {} (Ctrl-C to stop)",
        args.output.display(),
        raw_path.display()
    );
    let result = record_accounted(
        &mut link,
        &mut recording,
        &mut accounting,
        stop,
        args.samples,
        Duration::from_millis(500),
        &mut |message| noteln!("{message}"),
    );
    let raw_writer = link.take_raw_log();
    let stop_reason = match result {
        Ok(stop_reason) => stop_reason,
        Err(error) => {
            drop(raw_writer);
            let kept = recording.abandon(None);
            let names: Vec<String> = kept.iter().map(|path| path.display().to_string()).collect();
            return Err(error.context(format!(
                "the recording stopped; what was received is kept in {}",
                names.join(" and ")
            )));
        }
    };
    if let Some(counters) = stop_stream(&mut link, &mut accounting, &stop_reason) {
        noteln!("device counters {}", counters_words(&counters));
    }
    // The raw log's writer went to the link boxed; flushing and dropping it closes the file,
    // which the recording then renames into place.
    if let Some(mut writer) = raw_writer {
        writer.flush().context("writing the raw log")?;
    }
    let files = recording.finish(None)?;
    if let Some(words) = &files.incomplete {
        noteln!("{words}");
    }
    let beyond = link.statistics().samples_beyond_pad_count;
    if beyond > 0 {
        noteln!(
            "warning: {beyond} sample frames named a pad the device does not have (protocol violation); set aside"
        );
    }
    let reason = stop_words(&stop_reason);
    noteln!(
        "{reason}; wrote {} ({} rows), {} and {}: {}; {} bytes, {} undecodable frames",
        files.csv.display(),
        files.samples,
        raw_path.display(),
        files.device_state.as_ref().map_or_else(
            || "no device state".to_owned(),
            |path| path.display().to_string()
        ),
        accounting.summary(),
        link.statistics().bytes_received,
        link.statistics().frames_rejected
    );
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_ids_parse_with_or_without_prefix() {
        assert_eq!(parse_hex_u16("0x1209"), Ok(0x1209));
        assert_eq!(parse_hex_u16("1209"), Ok(0x1209));
        assert!(parse_hex_u16("0xZZ").is_err());
    }
}
