//! `taxel record`: its arguments, and the command that records one device, several onto one
//! host timeline, or one device as MCAP (the loops are the host library's).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use anyhow::Context;
use taxel_host::device_link::{self, DeviceLink};
use taxel_host::device_words::{board_serial_hex, counters_words, info_words};
use taxel_host::mcap_record::McapSink;
use taxel_host::multi_record::{record_devices, DeviceInput, MonotonicClock, MultiRecordOptions};
use taxel_host::noteln;
use taxel_host::record::{
    identify_device, record_accounted, start_stream, stop_stream, stop_words, StopReason,
};
use taxel_host::recording::{default_raw_path, Recording};
use taxel_host::timeline_files::device_raw_path;

use taxel_args::MultiBoardArgs;

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

/// Runs `taxel record`: one device as a single recording, several onto one host timeline.
pub fn run(args: &RecordArgs) -> anyhow::Result<ExitCode> {
    let ports = args.board.select_ports()?;
    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = Arc::clone(&stop);
    ctrlc::set_handler(move || handler_stop.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;
    match (ports.as_slice(), args.format) {
        ([port_path], RecordFormat::Csv) => run_single(args, port_path, &stop),
        ([port_path], RecordFormat::Mcap) => run_mcap(args, port_path, &stop),
        (_, RecordFormat::Csv) => run_several(args, &ports, &stop),
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

/// Runs `taxel record` with several devices on `ports` (already selected, in device order).
fn run_several(args: &RecordArgs, ports: &[String], stop: &AtomicBool) -> anyhow::Result<ExitCode> {
    if args.raw.is_some() {
        anyhow::bail!(
            "--raw names one file: with several devices the raw logs are {} and so on",
            device_raw_path(&args.output, 0).display()
        );
    }
    let mut devices = Vec::new();
    for port_path in ports {
        let opened = device_link::open_serial(port_path, Duration::from_millis(100))?;
        if let Some(error) = &opened.dtr_error {
            noteln!(
                "note: {port_path}: DTR not set ({error}); a simulated device does not need it"
            );
        }
        devices.push(DeviceInput {
            name: port_path.clone(),
            port: opened.port,
        });
    }
    let clock = MonotonicClock::new();
    let origin = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .unwrap_or_default();
    noteln!(
        "recording {} devices ({}) to {} (Ctrl-C to stop); host_time_s 0 is Unix time {}.{:06} s",
        ports.len(),
        ports
            .iter()
            .enumerate()
            .map(|(device, port)| format!("device {device}: {port}"))
            .collect::<Vec<_>>()
            .join(", "),
        args.output.display(),
        origin.as_secs(),
        origin.subsec_micros()
    );
    let options = MultiRecordOptions {
        timeout: Duration::from_millis(args.timeout_ms),
        samples_per_device: args.samples,
        ..MultiRecordOptions::default()
    };
    let summary = record_devices(devices, &args.output, &clock, stop, &options, &|message| {
        noteln!("{message}")
    })?;
    for (device, summary) in summary.devices.iter().enumerate() {
        noteln!(
            "device {device} ({}, serial {}): {}",
            summary.name,
            board_serial_hex(&summary.info),
            summary.words()
        );
        if summary.samples_beyond_pad_count > 0 {
            noteln!(
                "warning: device {device}: {} sample frames named a pad the device does not have (protocol violation); set aside",
                summary.samples_beyond_pad_count
            );
        }
    }
    let reason = match &summary.stop_reason {
        StopReason::Interrupted => "stopped by Ctrl-C".to_owned(),
        StopReason::SampleLimit => "sample limit reached on every device".to_owned(),
        StopReason::Disconnected(message) => format!("{message}; the recording ended"),
    };
    let names: Vec<String> = summary
        .files
        .iter()
        .map(|path| path.display().to_string())
        .collect();
    noteln!(
        "{reason}; wrote {} rows in host-time order; files: {}",
        summary.rows,
        names.join(", ")
    );
    Ok(ExitCode::SUCCESS)
}

/// Runs `taxel record --format mcap` on the device at `port_path` until `stop` is set, the
/// sample limit is reached or the device goes away.
fn run_mcap(args: &RecordArgs, port_path: &str, stop: &AtomicBool) -> anyhow::Result<ExitCode> {
    let opened = device_link::open_serial(port_path, Duration::from_millis(100))?;
    let mut link = DeviceLink::new(opened.port);
    let timeout = Duration::from_millis(args.timeout_ms);
    let (_, _, stale) = identify_device(&mut link, timeout, &mut |info| {
        noteln!("device on {port_path}: {}", info_words(info));
    })
    .with_context(|| format!("the device on {port_path}"))?;
    let mut sink = McapSink::create(&args.output)?;
    let mut accounting = start_stream(&mut link, stale, timeout).context("nothing was recorded")?;
    noteln!(
        "recording from {port_path} to {} (Ctrl-C to stop)",
        args.output.display()
    );
    let result = record_accounted(
        &mut link,
        &mut sink,
        &mut accounting,
        stop,
        args.samples,
        Duration::from_millis(500),
        &mut |message| noteln!("{message}"),
    );
    let stop_reason = match result {
        Ok(stop_reason) => stop_reason,
        Err(error) => {
            let kept = sink
                .abandon()
                .map_or_else(|| "nothing".to_owned(), |path| path.display().to_string());
            return Err(error.context(format!(
                "the recording stopped; what was received is kept in {kept}"
            )));
        }
    };
    if let Some(counters) = stop_stream(&mut link, &mut accounting, &stop_reason) {
        noteln!("device counters {}", counters_words(&counters));
    }
    let (path, messages) = sink.finish()?;
    noteln!(
        "{}; wrote {} ({messages} messages): {}",
        stop_words(&stop_reason),
        path.display(),
        accounting.summary()
    );
    Ok(ExitCode::SUCCESS)
}
