//! The soak of the host library: several simulated devices of several pads at once (the
//! firmware's own code on pseudo-terminals, paced faster than real time), read by the one
//! session and worker, recorded by the one recorder into the recording schema and MCAP at
//! once, for a long stretch of device time; then the recording is read back and checked
//! against the devices' own accounting: every sample set is in the file or counted as lost,
//! every row says its clock sync error, and the process's resident memory stays flat.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, Write};
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use sim_device::{scene_config, SimulatorThread};
use taxel_host::device_link::{open_serial, DeviceLink};
use taxel_host::host_clock::UnixClock;
use taxel_host::recorder::{Recorder, RecordingPaths};
use taxel_host::schema::RowReader;
use taxel_host::session::{DeviceSession, SessionConfig};
use taxel_host::stream_accounting::sequence_gap;
use taxel_host::worker::{EventQueue, Overflow, Worker};

/// What to soak.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SoakConfig {
    /// Simulated devices.
    pub devices: usize,
    /// Pads per device.
    pub pads: u8,
    /// Device seconds to record.
    pub device_seconds: f64,
    /// Simulated seconds per wall-clock second.
    pub speed: f64,
}

/// What the soak saw.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SoakOutcome {
    /// Wall-clock seconds of the recording.
    pub wall_s: f64,
    /// Sample sets recorded per device.
    pub sets_per_device: Vec<u64>,
    /// Rows in the CSV file.
    pub rows: u64,
    /// Rows of pad frames that never arrived (flagged by their empty cells).
    pub missing_rows: u64,
    /// Pad frames missing from the sequence numbers in the file, every device and pad.
    pub sequence_gaps: u64,
    /// Pad frames the devices' accounting counts as lost (dropped by the device or on the
    /// link; the device counts one per pad per set).
    pub counted_losses: u64,
    /// Rows without a clock sync error.
    pub rows_without_sync_error: u64,
    /// Largest sync error in the file, ms.
    pub max_sync_error_ms: f64,
    /// Resident memory after the start, at the largest and at the end, KiB.
    pub rss_kib: (u64, u64, u64),
    /// CSV and MCAP sizes, bytes.
    pub file_bytes: (u64, u64),
}

impl SoakOutcome {
    /// Pad frames missing from the file that no accounting explains.
    pub fn unflagged_losses(&self) -> u64 {
        self.sequence_gaps.saturating_sub(self.counted_losses)
    }
}

/// This process's resident memory, KiB (0 where /proc is not there).
pub fn resident_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            status
                .lines()
                .find_map(|line| line.strip_prefix("VmRSS:"))
                .and_then(|rest| rest.split_whitespace().next()?.parse().ok())
        })
        .unwrap_or(0)
}

/// Runs the soak in `directory` (the recording stays there).
pub fn run_soak(config: SoakConfig, directory: &Path) -> anyhow::Result<SoakOutcome> {
    // The host clock starts first: no set is taken before its origin.
    let clock = UnixClock::new();
    let mut simulators = Vec::new();
    for device in 0..config.devices {
        let scene = scene_config(
            None,
            Some(config.pads),
            Some(config.speed),
            device as u64 + 1,
        )?;
        simulators.push(SimulatorThread::start(scene, None)?);
    }
    let paths = RecordingPaths {
        csv: Some(directory.join("soak.csv")),
        mcap: Some(directory.join("soak.mcap")),
    };
    let sets = (config.device_seconds * 100.0).round() as u64;
    let mut recorder = Recorder::create(paths.clone(), config.devices, clock, Some(sets))?;
    let session_config = SessionConfig {
        request_timeout: Duration::from_secs(5),
        follow_state: true,
    };
    let mut sessions = Vec::new();
    for (device, simulator) in simulators.iter().enumerate() {
        let port = open_serial(
            &simulator.path().display().to_string(),
            Duration::from_millis(20),
        )?;
        let mut session = DeviceSession::open(DeviceLink::new(port.port), session_config)?;
        recorder.set_clock_us_per_s(device, session.info().clock_us_per_s);
        session.link_mut().set_raw_log(recorder.raw_log(device)?);
        session.start()?;
        sessions.push(session);
    }
    let queue = Arc::new(EventQueue::new(100_000, Overflow::Wait));
    let worker = Worker::start(sessions, Arc::clone(&queue), Arc::new(clock))?;
    let started = Instant::now();
    let mut rss = (resident_kib(), 0, 0);
    let mut last_sample = Instant::now();
    let wall_limit = Duration::from_secs_f64(config.device_seconds / config.speed * 3.0 + 60.0);
    while !recorder.is_complete() {
        anyhow::ensure!(
            started.elapsed() < wall_limit,
            "the soak did not finish within {wall_limit:?}: sets so far {:?}",
            recorder.sets_taken()
        );
        if let Some(event) = queue.pop_until(Instant::now() + Duration::from_millis(100)) {
            recorder.take(event)?;
        }
        if last_sample.elapsed() >= Duration::from_secs(1) {
            rss.1 = rss.1.max(resident_kib());
            recorder.flush()?;
            last_sample = Instant::now();
        }
    }
    let wall_s = started.elapsed().as_secs_f64();
    for mut session in worker.finish().into_iter().flatten() {
        if let Some(mut raw) = session.link_mut().take_raw_log() {
            raw.flush().context("writing a raw log")?;
        }
    }
    for event in queue.drain() {
        recorder.take(event)?;
    }
    for simulator in simulators {
        simulator.stop();
    }
    let summary = recorder.finish()?;
    rss.2 = resident_kib();
    rss.1 = rss.1.max(rss.2);
    let counted_losses = summary
        .devices
        .iter()
        .filter_map(|device| device.end.as_ref())
        .map(|end| end.accounting.lost_on_link() + end.accounting.device_dropped())
        .sum();
    let csv_path = paths.csv.context("the CSV path")?;
    let mut outcome = check_file(&csv_path)?;
    outcome.wall_s = wall_s;
    outcome.sets_per_device = summary.devices.iter().map(|device| device.sets).collect();
    outcome.counted_losses = counted_losses;
    outcome.rss_kib = rss;
    let size = |path: &Path| std::fs::metadata(path).map_or(0, |metadata| metadata.len());
    outcome.file_bytes = (size(&csv_path), paths.mcap.as_deref().map_or(0, size));
    Ok(outcome)
}

/// Reads the recording back: rows, missing frames, sequence gaps per device and pad, sync
/// errors.
fn check_file(path: &Path) -> anyhow::Result<SoakOutcome> {
    let mut reader = RowReader::new(BufReader::new(File::open(path)?))?;
    let mut outcome = SoakOutcome::default();
    let mut last: BTreeMap<(u32, u8), u32> = BTreeMap::new();
    while let Some(row) = reader.next_row() {
        let row = row?;
        outcome.rows += 1;
        if row.reading.is_none() {
            outcome.missing_rows += 1;
        }
        match row.sync_error_us {
            Some(error_us) => {
                outcome.max_sync_error_ms = outcome.max_sync_error_ms.max(error_us as f64 / 1e3);
            }
            None => outcome.rows_without_sync_error += 1,
        }
        if let Some(previous) = last.insert((row.device, row.pad), row.sequence) {
            outcome.sequence_gaps += sequence_gap(previous, row.sequence);
        }
    }
    Ok(outcome)
}

/// The soak's figures as a markdown section for docs/RELIABILITY.md.
pub fn render_markdown(config: &SoakConfig, outcome: &SoakOutcome, command: &str) -> String {
    format!(
        "## Soak: {devices} simulated devices × {pads} pads, one recording\n\n\
Generated by `{command}`. The devices run the firmware's code on pseudo-terminals at {speed}× \
real time; the host library's sessions and worker read them and its recorder writes the \
recording schema (CSV) and MCAP at once; the file is then read back.\n\n\
| measure | value |\n|---|---|\n\
| device time recorded | {device_s:.0} s per device ({wall_s:.0} s of wall-clock time) |\n\
| sample sets per device | {sets:?} |\n\
| rows (a row per pad per set) | {rows} |\n\
| rows of pad frames that never arrived (flagged: empty cells) | {missing} |\n\
| pad frames missing from the sequence numbers in the file | {gaps} |\n\
| pad frames the devices' accounting counts as lost (dropped by the device or on the link) | {counted} |\n\
| pad frames lost unflagged | **{unflagged}** |\n\
| rows without a clock sync error | {without_sync} |\n\
| largest clock sync error | {max_sync:.3} ms |\n\
| resident memory: after start, largest, end | {rss_start} KiB, {rss_max} KiB, {rss_end} KiB |\n\
| CSV, MCAP | {csv_mb:.1} MB, {mcap_mb:.1} MB |\n",
        devices = config.devices,
        pads = config.pads,
        speed = config.speed,
        device_s = config.device_seconds,
        wall_s = outcome.wall_s,
        sets = outcome.sets_per_device,
        rows = outcome.rows,
        missing = outcome.missing_rows,
        gaps = outcome.sequence_gaps,
        counted = outcome.counted_losses,
        unflagged = outcome.unflagged_losses(),
        without_sync = outcome.rows_without_sync_error,
        max_sync = outcome.max_sync_error_ms,
        rss_start = outcome.rss_kib.0,
        rss_max = outcome.rss_kib.1,
        rss_end = outcome.rss_kib.2,
        csv_mb = outcome.file_bytes.0 as f64 / 1e6,
        mcap_mb = outcome.file_bytes.1 as f64 / 1e6,
    )
}
