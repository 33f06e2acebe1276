//! `taxel record` with several devices: one reader thread per device, every sample frame
//! stamped with its arrival on one host clock, each device's clock mapped onto it, and one CSV
//! in long format (one row per sample frame of any device and pad) in host-time order.
//!
//! The files (the CSV, and each device's raw log and state) are described in
//! [`crate::timeline_files`]; when writing fails half-way, the partial files are kept under
//! their temporary names. When rows get their host time and what the error column means is in
//! [`crate::host_timeline`].

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};

use anyhow::Context;
use wire::{InfoFrame, PadIndex, SampleFrame};

use crate::clock_sync::ClockEstimate;
use crate::device_link::DeviceLink;
use crate::device_words::{counters_words, info_words};
pub use crate::host_clock::{HostClock, MonotonicClock};
use crate::host_timeline::{DeviceTimelineCounts, HostTimeline, TimelineConfig};
use crate::record::{identify_device, record_accounted, start_stream, stop_stream, StopReason};
use crate::recording::{BaselineChange, RecordedDeviceState, SampleSink, SetCounter};
use crate::stream_accounting::StreamAccounting;
use crate::timeline_files::{format_sync_error_ms, TimelineFiles};

/// One device to record: a name for messages (its port) and the open port.
#[derive(Debug)]
pub struct DeviceInput<P> {
    /// The port's path, or any name that tells the device apart in messages.
    pub name: String,
    /// The open port.
    pub port: P,
}

/// Settings of [`record_devices`].
#[derive(Debug, Clone)]
pub struct MultiRecordOptions {
    /// How long to wait for each reply from a device.
    pub timeout: Duration,
    /// Stop reading a device after this many sample sets of it (each device on its own).
    pub samples_per_device: Option<u64>,
    /// How often the CSV and raw logs are flushed at least.
    pub flush_interval: Duration,
    /// The host timeline's settings.
    pub timeline: TimelineConfig,
}

impl Default for MultiRecordOptions {
    fn default() -> Self {
        Self {
            timeout: Duration::from_millis(2000),
            samples_per_device: None,
            flush_interval: Duration::from_millis(500),
            timeline: TimelineConfig::default(),
        }
    }
}

/// What one device of a recording gave.
#[derive(Debug, Clone)]
pub struct DeviceSummary {
    /// Its name (port).
    pub name: String,
    /// Its identity.
    pub info: InfoFrame,
    /// Its sample frames: received, lost on the link, dropped by the device.
    pub accounting: StreamAccounting,
    /// Its clock mapped onto the host clock, at the end; `None` when there never were frames
    /// enough.
    pub estimate: Option<ClockEstimate>,
    /// How often its clock mapping started again (the device rebooted, a clock stepped).
    pub clock_restarts: u64,
    /// Its rows on the timeline.
    pub timeline: DeviceTimelineCounts,
    /// Bytes received (all in its raw log).
    pub bytes_received: u64,
    /// Frames that could not be decoded.
    pub frames_rejected: u64,
    /// Sample frames naming a pad beyond the device's pad count (set aside by the link).
    pub samples_beyond_pad_count: u64,
    /// Why its reading ended.
    pub stop_reason: StopReason,
}

impl DeviceSummary {
    /// One line for people: the accounting, then the clock's offset, drift and error.
    pub fn words(&self) -> String {
        let clock = match &self.estimate {
            Some(estimate) => format!(
                "clock offset {:+.6} s, drift {:+.1} ppm, synchronisation error {} ms",
                estimate.offset_us as f64 / 1e6,
                estimate.drift_ppm,
                format_sync_error_ms(Some(estimate.uncertainty_us))
            ),
            None => "no clock estimate (too few frames)".to_owned(),
        };
        let mut text = format!("{}; {clock}", self.accounting.summary());
        if self.timeline.rows_without_estimate > 0 {
            text.push_str(&format!(
                "; {} rows without a clock estimate (at their arrival, error unknown)",
                self.timeline.rows_without_estimate
            ));
        }
        if self.timeline.rows_shifted > 0 {
            text.push_str(&format!(
                "; {} rows moved later to keep host-time order (the move is in their error)",
                self.timeline.rows_shifted
            ));
        }
        if self.clock_restarts > 0 {
            text.push_str(&format!(
                "; the clock mapping started again {} times",
                self.clock_restarts
            ));
        }
        text
    }
}

/// What a recording of several devices captured.
#[derive(Debug, Clone)]
pub struct MultiRecordSummary {
    /// Per device, in device order.
    pub devices: Vec<DeviceSummary>,
    /// Rows written to the CSV.
    pub rows: u64,
    /// Why it ended: the first device that disconnected, else the sample limit when every
    /// device reached it, else an interruption.
    pub stop_reason: StopReason,
    /// The files written: the CSV, the raw logs, the device states.
    pub files: Vec<PathBuf>,
}

/// A sample frame and when it arrived, from a reader thread to the writer.
struct Stamped {
    device: usize,
    sample: SampleFrame,
    arrival_us: u64,
}

/// The reader thread's sink: stamps each frame with the host clock and passes it on; keeps the
/// device's baseline changes in its state.
struct StampingSink<'a> {
    device: usize,
    clock: &'a dyn HostClock,
    sender: Sender<Stamped>,
    state: RecordedDeviceState,
    /// The sample sets seen, so that `--samples` counts sample sets for several devices as for
    /// one.
    sets: SetCounter,
}

impl SampleSink for StampingSink<'_> {
    fn write_sample(&mut self, sample: &SampleFrame) -> anyhow::Result<()> {
        self.sets.observe(sample);
        let stamped = Stamped {
            device: self.device,
            sample: *sample,
            arrival_us: self.clock.now_us(),
        };
        self.sender
            .send(stamped)
            .map_err(|_| anyhow::anyhow!("the recording stopped taking samples"))
    }

    fn flush(&mut self) -> anyhow::Result<()> {
        Ok(())
    }

    /// Sample sets closed: every set started but the one in progress.
    fn rows(&self) -> Option<u64> {
        Some(self.sets.closed())
    }

    fn would_close_set(&self, sample: &SampleFrame) -> bool {
        self.sets.would_close(sample)
    }

    fn baselines_changed(&mut self, pad: PadIndex, change: BaselineChange) {
        if let Some(history) = self.state.baselines_mut(pad.get()) {
            history.push(change);
        }
    }
}

/// How a reader thread ended well.
struct DeviceEnd {
    info: InfoFrame,
    state: RecordedDeviceState,
    accounting: StreamAccounting,
    stop_reason: StopReason,
    bytes_received: u64,
    frames_rejected: u64,
    samples_beyond_pad_count: u64,
}

/// How a reader thread failed: before streaming (nothing recorded) or after.
struct ReaderFailure {
    recording_started: bool,
    error: anyhow::Error,
}

/// What every reader thread shares.
struct ReaderContext<'a> {
    clock: &'a dyn HostClock,
    stop: &'a AtomicBool,
    options: &'a MultiRecordOptions,
    status: &'a (dyn Fn(&str) + Sync),
}

/// One device from the first request to the end: identity, state, stream, stop.
fn read_device<P: Read + Write>(
    device: usize,
    input: DeviceInput<P>,
    raw_writer: BufWriter<File>,
    sender: Sender<Stamped>,
    context: &ReaderContext<'_>,
) -> Result<DeviceEnd, ReaderFailure> {
    let DeviceInput { name, port } = input;
    let failure = |recording_started: bool| {
        let name = name.clone();
        move |error: anyhow::Error| ReaderFailure {
            recording_started,
            error: error.context(format!("device {device} on {name}")),
        }
    };
    let timeout = context.options.timeout;
    let mut link = DeviceLink::new(port);
    let (info, state, stale) = identify_device(&mut link, timeout, &mut |info| {
        (context.status)(&format!("device {device} on {name}: {}", info_words(info)))
    })
    .map_err(failure(false))?;
    link.set_raw_log(Box::new(raw_writer));
    let mut accounting = start_stream(&mut link, stale, timeout).map_err(failure(false))?;
    let mut sink = StampingSink {
        device,
        clock: context.clock,
        sender,
        state,
        sets: SetCounter::default(),
    };
    let result = record_accounted(
        &mut link,
        &mut sink,
        &mut accounting,
        context.stop,
        context.options.samples_per_device,
        context.options.flush_interval,
        &mut |message| (context.status)(&format!("device {device}: {message}")),
    );
    // The sender goes now: the writer ends when every reader's sender is gone.
    let StampingSink { state, .. } = sink;
    let mut raw_log = link.take_raw_log();
    let stop_reason = match result {
        Ok(stop_reason) => stop_reason,
        Err(error) => {
            if let Some(log) = raw_log.as_mut() {
                let _ = log.flush();
            }
            return Err(failure(true)(error));
        }
    };
    if let Some(counters) = stop_stream(&mut link, &mut accounting, &stop_reason) {
        (context.status)(&format!(
            "device {device} counters {}",
            counters_words(&counters)
        ));
    }
    if let Some(mut log) = raw_log {
        log.flush()
            .context("writing the raw log")
            .map_err(failure(true))?;
    }
    Ok(DeviceEnd {
        info,
        state,
        accounting,
        stop_reason,
        bytes_received: link.statistics().bytes_received,
        frames_rejected: link.statistics().frames_rejected,
        samples_beyond_pad_count: link.statistics().samples_beyond_pad_count,
    })
}

/// Takes the readers' frames onto the timeline and writes the rows it releases, until every
/// reader is done.
fn merge_frames(
    receiver: &Receiver<Stamped>,
    timeline: &mut HostTimeline,
    files: &mut TimelineFiles,
    flush_interval: Duration,
) -> anyhow::Result<()> {
    let mut last_flush = Instant::now();
    loop {
        match receiver.recv_timeout(Duration::from_millis(100)) {
            Ok(stamped) => {
                timeline.push(stamped.device, stamped.sample, stamped.arrival_us);
                for stamped in receiver.try_iter().take(10_000) {
                    timeline.push(stamped.device, stamped.sample, stamped.arrival_us);
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => return Ok(()),
        }
        for row in timeline.release() {
            files.write_row(&row)?;
        }
        if last_flush.elapsed() >= flush_interval {
            files.flush()?;
            last_flush = Instant::now();
        }
    }
}

/// Records several devices onto one host timeline in `csv_path` and the files beside it (see
/// the module documentation), stamping arrivals with `clock`, until `stop` is set (Ctrl-C),
/// one device disconnects or fails (which sets `stop`), or every device gave
/// [`MultiRecordOptions::samples_per_device`] sample sets. `status` gets progress lines (from the
/// reader threads too).
///
/// A device that cannot be set up (no answer, a refused request) fails the whole recording,
/// with nothing kept; a failure while recording keeps the partial files under their temporary
/// names and names them in the error.
pub fn record_devices<P: Read + Write + Send>(
    devices: Vec<DeviceInput<P>>,
    csv_path: &Path,
    clock: &dyn HostClock,
    stop: &AtomicBool,
    options: &MultiRecordOptions,
    status: &(dyn Fn(&str) + Sync),
) -> anyhow::Result<MultiRecordSummary> {
    let names: Vec<String> = devices.iter().map(|input| input.name.clone()).collect();
    let mut timeline = HostTimeline::new(devices.len(), options.timeline);
    let (mut files, raw_writers) = TimelineFiles::create(csv_path, devices.len())?;
    let context = ReaderContext {
        clock,
        stop,
        options,
        status,
    };
    let (merged, ends) = std::thread::scope(|scope| {
        let (sender, receiver) = mpsc::channel();
        let handles: Vec<_> = devices
            .into_iter()
            .zip(raw_writers)
            .enumerate()
            .map(|(device, (input, raw_writer))| {
                let sender = sender.clone();
                let context = &context;
                scope.spawn(move || {
                    let result = read_device(device, input, raw_writer, sender, context);
                    // One device unplugged or failed ends the recording for all.
                    let ends_all = result.as_ref().map_or(true, |end| {
                        matches!(end.stop_reason, StopReason::Disconnected(_))
                    });
                    if ends_all {
                        context.stop.store(true, Ordering::Relaxed);
                    }
                    result
                })
            })
            .collect();
        drop(sender);
        let merged = merge_frames(&receiver, &mut timeline, &mut files, options.flush_interval);
        if merged.is_err() {
            stop.store(true, Ordering::Relaxed);
        }
        drop(receiver);
        let ends: Vec<Result<DeviceEnd, ReaderFailure>> = handles
            .into_iter()
            .map(|handle| {
                handle.join().unwrap_or_else(|_| {
                    Err(ReaderFailure {
                        recording_started: true,
                        error: anyhow::anyhow!("a reader thread failed"),
                    })
                })
            })
            .collect();
        (merged, ends)
    });
    let mut failures = Vec::new();
    let mut finished = Vec::new();
    for end in ends {
        match end {
            Ok(end) => finished.push(end),
            Err(failure) => failures.push(failure),
        }
    }
    if let Some(index) = failures
        .iter()
        .position(|failure| !failure.recording_started)
    {
        // Dropping the files removes them: nothing was recorded.
        drop(files);
        let failure = failures.swap_remove(index);
        return Err(failure
            .error
            .context("a device could not be set up (nothing was recorded)"));
    }
    let written = merged.and_then(|()| {
        for row in timeline.finish() {
            files.write_row(&row)?;
        }
        Ok(())
    });
    let error = match (written, failures.into_iter().next()) {
        (Err(error), _) => Some(error),
        (Ok(()), Some(failure)) => Some(failure.error),
        (Ok(()), None) => None,
    };
    if let Some(error) = error {
        let kept: Vec<String> = files
            .abandon()
            .iter()
            .map(|path| path.display().to_string())
            .collect();
        return Err(error.context(format!(
            "the recording stopped; what was received is kept in {}",
            kept.join(", ")
        )));
    }
    let rows = files.rows;
    let states: Vec<&RecordedDeviceState> = finished.iter().map(|end| &end.state).collect();
    let written_files = files.finish(&states)?;
    let devices: Vec<DeviceSummary> = finished
        .into_iter()
        .zip(names)
        .enumerate()
        .map(|(device, (end, name))| DeviceSummary {
            name,
            info: end.info,
            accounting: end.accounting,
            estimate: timeline.estimate(device),
            clock_restarts: timeline.restarts(device),
            timeline: timeline.counts(device),
            bytes_received: end.bytes_received,
            frames_rejected: end.frames_rejected,
            samples_beyond_pad_count: end.samples_beyond_pad_count,
            stop_reason: end.stop_reason,
        })
        .collect();
    Ok(MultiRecordSummary {
        stop_reason: overall_stop_reason(&devices),
        devices,
        rows,
        files: written_files,
    })
}

fn overall_stop_reason(devices: &[DeviceSummary]) -> StopReason {
    let disconnected =
        devices
            .iter()
            .enumerate()
            .find_map(|(device, summary)| match &summary.stop_reason {
                StopReason::Disconnected(message) => Some(StopReason::Disconnected(format!(
                    "device {device} ({}): {message}",
                    summary.name
                ))),
                _ => None,
            });
    let all_at_limit = devices
        .iter()
        .all(|summary| summary.stop_reason == StopReason::SampleLimit);
    match disconnected {
        Some(reason) => reason,
        None if all_at_limit => StopReason::SampleLimit,
        None => StopReason::Interrupted,
    }
}
