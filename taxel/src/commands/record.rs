//! `taxel record`: one device or several, each read by the host library's worker, recorded by
//! its recorder into the one recording schema (CSV) and/or MCAP, with every device's raw byte
//! log and state.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use anyhow::Context;
use taxel_args::{LinkArgs, MultiBoardArgs};
use taxel_host::device_link::{open_serial, DeviceLink};
use taxel_host::device_words::{event_words, info_words};
use taxel_host::host_clock::UnixClock;
use taxel_host::noteln;
use taxel_host::recorder::{DeviceSummary, Recorder, RecordingPaths};
use taxel_host::schema;
use taxel_host::session::{DeviceSession, SessionConfig, SessionEvent};
use taxel_host::worker::{EndReason, EventQueue, Overflow, Worker, WorkerEvent};

/// Events the recorder may fall behind by before the devices' threads wait (their links then
/// hold the rest, and a device's drops are counted by its accounting).
const QUEUE_EVENTS: usize = 100_000;

/// How often the files are flushed.
const FLUSH_INTERVAL: Duration = Duration::from_millis(500);

/// The long help of the subcommand, with the schema's columns.
pub fn long_about() -> &'static str {
    static TEXT: OnceLock<String> = OnceLock::new();
    TEXT.get_or_init(|| {
        format!(
            "Record one device or several: a CSV file of the recording schema (-o) and/or an MCAP \
file of the ROS 2 messages `taxel bridge` publishes (--mcap), with each device's raw byte log \
and state beside it.\n\n\
Every recording has the same columns, whatever the number of devices and pads: one row per pad \
per sample set (RFC 4180, '.' decimals):\n{}\n\n\
Device n's raw log is FILE.dev<n>.raw (every byte received, for `taxel convert --raw`) and its \
state FILE.dev<n>.device.json (identity, and per pad the calibration, tier and baselines with the \
set each applies from), so that `taxel convert FILE` reproduces what the devices computed. \
Frames waiting in a port from before the connection are discarded. Each device's clock is mapped \
onto the host's (offset and drift, from the lower envelope of its frames' device times against \
their arrivals); a set waits up to 3 s for its device's first clock estimate and is then stamped \
with its device time mapped onto the host clock (never later than its arrival), else with its \
arrival and an empty sync_error_ms. Nothing is dropped on the way to the file.\n\n\
--samples N records N sample sets of each device (a set closes when every pad's frame arrived or \
a later set began). Ctrl-C or a device unplugged ends the recording of all. The files are written \
under temporary names and renamed when the recording ends; if writing fails half-way, the partial \
files are kept and named. At the end each device's line says: sets recorded, frames missing, \
received, lost on the link, dropped by the device, and its clock's offset, drift and error.\n\n\
Examples:\n  taxel record /dev/ttyACM0 -o rec.csv --samples 1000\n  \
taxel record /dev/ttyACM0 /dev/ttyACM1 -o both.csv --mcap both.mcap",
            schema::describe()
        )
    })
}

/// Arguments of `taxel record`.
#[derive(Debug, Clone, clap::Args)]
pub struct RecordArgs {
    /// The device, or several.
    #[command(flatten)]
    pub board: MultiBoardArgs,
    /// CSV file of the recording schema to write.
    #[arg(short, long, value_name = "FILE", required_unless_present = "mcap")]
    pub output: Option<PathBuf>,
    /// MCAP file of the ROS 2 messages `taxel bridge` publishes to write (with or without -o).
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// Stop after this many sample sets of each device.
    #[arg(long, value_name = "N")]
    pub samples: Option<u64>,
    /// How long to wait for the devices.
    #[command(flatten)]
    pub link: LinkArgs,
}

/// Runs `taxel record`.
pub fn run(args: &RecordArgs) -> anyhow::Result<ExitCode> {
    // The host clock starts before any device is opened: a device's first sets may have been
    // taken before its stream started, and the mapping must not place them before the origin.
    let clock = UnixClock::new();
    let ports = args.board.select_ports()?;
    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = Arc::clone(&stop);
    ctrlc::set_handler(move || handler_stop.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;
    let paths = RecordingPaths {
        csv: args.output.clone(),
        mcap: args.mcap.clone(),
    };
    let config = SessionConfig {
        request_timeout: args.link.timeout(),
        follow_state: true,
    };
    let mut sessions = Vec::new();
    for (device, port) in ports.iter().enumerate() {
        let opened = open_serial(port, Duration::from_millis(20))?;
        if let Some(error) = &opened.dtr_error {
            noteln!("note: {port}: DTR not set ({error}); a simulated device does not need it");
        }
        let session = DeviceSession::open(DeviceLink::new(opened.port), config)
            .with_context(|| format!("the device on {port}"))?;
        noteln!("device {device} on {port}: {}", info_words(session.info()));
        sessions.push(session);
    }
    let mut recorder = Recorder::create(paths.clone(), sessions.len(), clock, args.samples)?;
    for (device, session) in sessions.iter_mut().enumerate() {
        recorder.set_clock_us_per_s(device, session.info().clock_us_per_s);
        if let Some(state) = session.state() {
            recorder.set_pad_geometries(device, state);
        }
        session.link_mut().set_raw_log(recorder.raw_log(device)?);
        session
            .start()
            .with_context(|| format!("device {device}: nothing was recorded"))?;
    }
    let queue = Arc::new(EventQueue::new(QUEUE_EVENTS, Overflow::Wait));
    let worker = Worker::start(sessions, Arc::clone(&queue), Arc::new(clock))
        .context("starting the devices' reader threads")?;
    noteln!(
        "recording {} device(s) to {} (Ctrl-C to stop)",
        ports.len(),
        [&paths.csv, &paths.mcap]
            .into_iter()
            .flatten()
            .map(|path| path.display().to_string())
            .collect::<Vec<_>>()
            .join(" and ")
    );
    let result = record_until_done(&queue, &mut recorder, &stop);
    let sessions = worker.finish();
    let mut result = result;
    for mut session in sessions.into_iter().flatten() {
        if let Some(mut raw) = session.link_mut().take_raw_log() {
            if let (Err(error), Ok(())) = (raw.flush(), &result) {
                result = Err(anyhow::Error::from(error).context("writing a raw log"));
            }
        }
    }
    let result = result.and_then(|()| {
        for event in queue.drain() {
            recorder.take(event)?;
        }
        Ok(())
    });
    if let Err(error) = result {
        let kept = recorder.abandon();
        let names: Vec<String> = kept.iter().map(|path| path.display().to_string()).collect();
        return Err(error.context(format!(
            "the recording stopped; what was received is kept in {}",
            names.join(", ")
        )));
    }
    let summary = recorder.finish()?;
    for (device, summary) in summary.devices.iter().enumerate() {
        noteln!(
            "device {device} ({}): {}",
            ports[device],
            device_words(summary)
        );
    }
    noteln!(
        "wrote {}",
        summary
            .files
            .iter()
            .map(|path| path.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(ExitCode::SUCCESS)
}

/// Feeds the recorder until Ctrl-C, every device's limit, or a device's end.
fn record_until_done(
    queue: &EventQueue,
    recorder: &mut Recorder,
    stop: &AtomicBool,
) -> anyhow::Result<()> {
    let mut last_flush = Instant::now();
    let mut ended = 0;
    // A device that went away ends the recording of all (as the live view does): the files
    // then hold the same span of every device.
    while !stop.load(Ordering::Relaxed) && !recorder.is_complete() && ended == 0 {
        if let Some(arrived) = queue.pop_until(Instant::now() + Duration::from_millis(100)) {
            match &arrived.event {
                WorkerEvent::Session(SessionEvent::Device(event)) => {
                    noteln!("device {}: {}", arrived.device, event_words(event));
                }
                WorkerEvent::Session(SessionEvent::BaselinesUnread { pad, reason }) => noteln!(
                    "warning: device {} pad {}: the new baselines could not be read ({reason}); `convert` will not reproduce its pressures after this point",
                    arrived.device,
                    pad.get()
                ),
                WorkerEvent::Ended(_) => ended += 1,
                _ => {}
            }
            recorder.take(arrived)?;
        }
        if last_flush.elapsed() >= FLUSH_INTERVAL {
            recorder.flush()?;
            last_flush = Instant::now();
        }
    }
    Ok(())
}

/// One device's closing line.
fn device_words(summary: &DeviceSummary) -> String {
    let mut words = format!("{} sample sets recorded", summary.sets);
    if summary.missing_frames > 0 {
        words.push_str(&format!(
            " ({} pad frames missing: their rows hold only the set's identity)",
            summary.missing_frames
        ));
    }
    if let Some(end) = &summary.end {
        words.push_str(&format!("; {}", end.accounting.summary()));
        match &end.reason {
            EndReason::Stopped => {}
            EndReason::Disconnected(message) => {
                words.push_str(&format!("; disconnected: {message}"));
            }
            EndReason::Failed(message) => words.push_str(&format!("; failed: {message}")),
        }
    }
    match &summary.clock {
        Some(clock) => words.push_str(&format!(
            "; clock offset {:+.6} s, drift {:+.1} ppm, sync error {:.3} ms",
            clock.offset_us as f64 / 1e6,
            clock.drift_ppm,
            clock.uncertainty_us as f64 / 1e3
        )),
        None => match summary.refused_clock_rate {
            Some(rate) => words.push_str(&format!(
                "; no clock estimate: the device clock runs {rate:.4} times as fast as the host's, beyond any crystal's error (a simulated device at another speed that does not say so?)"
            )),
            None => words.push_str("; no clock estimate (fewer than 2 s of sample sets)"),
        },
    }
    if summary.stamped_at_arrival > 0 {
        words.push_str(&format!(
            "; {} sets or events stamped at their arrival (no clock estimate yet, error unknown)",
            summary.stamped_at_arrival
        ));
    }
    words
}
