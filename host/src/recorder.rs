//! A recording of any number of devices: the worker's events in, stamped by the one policy
//! ([`crate::stamping`]), out to a CSV file of the recording schema ([`crate::schema`]) and/or
//! an MCAP file of the ROS 2 messages the bridge publishes, beside each device's raw byte log
//! and state. One device is a recording of one device.
//!
//! Files, for a CSV `NAME.csv` (an MCAP-only recording names them after the MCAP file):
//! - `NAME.csv`: the rows (see [`crate::schema`]), in the order their sets were stamped;
//! - `NAME.csv.dev<n>.raw`: every byte device `n` sent, for `taxel convert --raw`;
//! - `NAME.csv.dev<n>.device.json`: what device `n` computed its pressures with: its identity,
//!   and per pad the calibration, tier and baselines with the set each applies from
//!   ([`crate::device_state`]), so that `taxel convert` reproduces the device.
//!
//! Every file is written under a temporary name and renamed when the recording ends; if
//! writing fails half-way, the partial files are kept under their temporary names and named.
//! `--samples N` counts each device's sample sets as the session closes them (every pad's
//! frame, or a later set began): rows of sets beyond `N` are not written.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::Context;
use taxel_ros2::pad_messages::{DEFAULT_FRAME_PREFIX, DEFAULT_NAMESPACE};
use taxel_ros2::PadMessagesFile;
use wire::SampleFrame;

use crate::clock_sync::ClockEstimate;
use crate::device_state::RecordedDeviceState;
use crate::host_clock::UnixClock;
use crate::output_file::{OutputFile, PendingRename};
use crate::pad_set::PadSet;
use crate::schema::{PadReading, PadRow, RowWriter};
use crate::session::{contact_change, SessionEvent};
use crate::stamping::{Stamped, Stamper};
use crate::worker::{ArrivedEvent, DeviceEnd, WorkerEvent};

/// Where a recording goes.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RecordingPaths {
    /// The CSV file of the recording schema.
    pub csv: Option<PathBuf>,
    /// The MCAP file of ROS 2 messages.
    pub mcap: Option<PathBuf>,
}

impl RecordingPaths {
    /// The file the device files are named after: the CSV, else the MCAP file.
    fn base(&self) -> Option<&Path> {
        self.csv.as_deref().or(self.mcap.as_deref())
    }

    /// Device `device`'s raw byte log.
    pub fn raw_log(&self, device: usize) -> Option<PathBuf> {
        self.base().map(|base| device_file(base, device, "raw"))
    }

    /// Device `device`'s state.
    pub fn device_state(&self, device: usize) -> Option<PathBuf> {
        self.base()
            .map(|base| device_file(base, device, "device.json"))
    }
}

/// `NAME.dev<n>.<extension>` beside `base`.
pub fn device_file(base: &Path, device: usize, extension: &str) -> PathBuf {
    let mut name = base.as_os_str().to_owned();
    name.push(format!(".dev{device}.{extension}"));
    PathBuf::from(name)
}

/// What is stamped: a sample set, or a contact event.
#[derive(Debug, Clone)]
enum Item {
    Set { set: PadSet, marker: String },
    Contact { pad: u8, started: bool },
}

/// One device's part of the recording.
struct DeviceRecord {
    stamper: Stamper<Item>,
    sets_taken: u64,
    rows: u64,
    missing_frames: u64,
    end: Option<DeviceEnd>,
    raw: Option<PendingRename>,
    marker: Option<String>,
}

/// What a device's recording holds, for the closing words.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceSummary {
    /// Sample sets recorded.
    pub sets: u64,
    /// Rows written (a row per pad per set).
    pub rows: u64,
    /// Pad frames missing from recorded sets (their rows hold only the set's identity).
    pub missing_frames: u64,
    /// Sets and events stamped with their arrival for want of a clock estimate.
    pub stamped_at_arrival: u64,
    /// The device's clock mapping at the end.
    pub clock: Option<ClockEstimate>,
    /// Without a mapping: the device-to-host clock rate the mapper measured and refused as an
    /// implausible drift (see `ClockMapper::refused_rate`).
    pub refused_clock_rate: Option<f64>,
    /// How the device's stream ended, with its accounting.
    pub end: Option<DeviceEnd>,
}

/// What a finished recording wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingSummary {
    /// Each device's part.
    pub devices: Vec<DeviceSummary>,
    /// The files, renamed into place.
    pub files: Vec<PathBuf>,
}

/// A recording in progress (see the module documentation).
pub struct Recorder {
    paths: RecordingPaths,
    clock: UnixClock,
    csv: Option<(RowWriter<BufWriter<File>>, PendingRename)>,
    mcap: Option<(PadMessagesFile<BufWriter<File>>, PendingRename)>,
    devices: Vec<DeviceRecord>,
    sets_per_device: Option<u64>,
}

fn writer_of(path: &Path) -> anyhow::Result<(BufWriter<File>, PendingRename)> {
    Ok(OutputFile::create(path)?.into_parts())
}

impl Recorder {
    /// Starts a recording of `device_count` devices into `paths` (at least one of them), whose
    /// arrivals are on `clock` — the clock the worker stamps with (a copy of it: the recorder
    /// uses its origin's Unix time); with `sets_per_device`, each device's sets beyond it (and
    /// its events after them) are not recorded.
    pub fn create(
        paths: RecordingPaths,
        device_count: usize,
        clock: UnixClock,
        sets_per_device: Option<u64>,
    ) -> anyhow::Result<Self> {
        anyhow::ensure!(
            paths.base().is_some(),
            "a recording needs a CSV or an MCAP file"
        );
        let csv = match &paths.csv {
            Some(path) => {
                let (writer, pending) = writer_of(path)?;
                let rows = RowWriter::new(writer)
                    .with_context(|| format!("writing {}", path.display()))?;
                Some((rows, pending))
            }
            None => None,
        };
        let mcap = match &paths.mcap {
            Some(path) => {
                let (writer, pending) = writer_of(path)?;
                let mut file =
                    PadMessagesFile::new(writer, DEFAULT_NAMESPACE, DEFAULT_FRAME_PREFIX)
                        .with_context(|| format!("starting {}", path.display()))?;
                if let Some(name) = path.file_name() {
                    file.set_file_name(&name.to_string_lossy());
                }
                Some((file, pending))
            }
            None => None,
        };
        let devices = (0..device_count)
            .map(|_| DeviceRecord {
                stamper: Stamper::default(),
                sets_taken: 0,
                rows: 0,
                missing_frames: 0,
                end: None,
                raw: None,
                marker: None,
            })
            .collect();
        Ok(Self {
            paths,
            clock,
            csv,
            mcap,
            devices,
            sets_per_device,
        })
    }

    /// Where the files go.
    pub fn paths(&self) -> &RecordingPaths {
        &self.paths
    }

    /// A raw byte log for device `device`, to hand to its link before the stream starts; it
    /// is renamed into place when the recording finishes (after the link let go of it).
    pub fn raw_log(&mut self, device: usize) -> anyhow::Result<Box<dyn Write + Send>> {
        let path = self
            .paths
            .raw_log(device)
            .context("a recording without files has no raw log")?;
        let (writer, pending) = writer_of(&path)?;
        if let Some(record) = self.devices.get_mut(device) {
            record.raw = Some(pending);
        }
        Ok(Box::new(writer))
    }

    /// Says how many µs device `device`'s clock counts per second of real time (its Info's
    /// `clock_us_per_s`), for the clock mapping (see [`crate::stamping`]).
    pub fn set_clock_us_per_s(&mut self, device: usize, clock_us_per_s: u32) {
        if let Some(record) = self.devices.get_mut(device) {
            record.stamper.set_clock_us_per_s(clock_us_per_s);
        }
    }

    /// Device `device`'s pads have the geometries of `state` (what their PadInfo reports): the
    /// MCAP file's pressure clouds place the taxels there.
    pub fn set_pad_geometries(&mut self, device: usize, state: &RecordedDeviceState) {
        if let Some((file, _)) = &mut self.mcap {
            for pad in &state.pads {
                file.set_geometry(device, pad.pad, pad.geometry);
            }
        }
    }

    /// Drops a marker: it goes into the rows of each device's next set.
    pub fn mark(&mut self, label: &str) {
        for device in &mut self.devices {
            device.marker = Some(label.to_owned());
        }
    }

    /// Whether every device has recorded its sets (with a limit), or ended.
    pub fn is_complete(&self) -> bool {
        self.devices.iter().all(|device| {
            device.end.is_some()
                || self
                    .sets_per_device
                    .is_some_and(|limit| device.sets_taken >= limit)
        })
    }

    /// Sets taken so far per device.
    pub fn sets_taken(&self) -> Vec<u64> {
        self.devices
            .iter()
            .map(|device| device.sets_taken)
            .collect()
    }

    /// Takes one event of the worker; writes what can be stamped now.
    pub fn take(&mut self, arrived: ArrivedEvent) -> anyhow::Result<()> {
        let ArrivedEvent {
            device,
            arrival_us,
            event,
        } = arrived;
        let limit = self.sets_per_device;
        let Some(record) = self.devices.get_mut(device) else {
            return Ok(());
        };
        match event {
            WorkerEvent::Session(SessionEvent::Set { set, .. }) => {
                let Some(device_us) = set_time_us(&set) else {
                    return Ok(());
                };
                for frame in set.pads.iter().flatten() {
                    record.stamper.observe(frame.timestamp_us, arrival_us);
                }
                if limit.is_some_and(|limit| record.sets_taken >= limit) {
                    return Ok(());
                }
                record.sets_taken += 1;
                let marker = record.marker.take().unwrap_or_default();
                record
                    .stamper
                    .push(Item::Set { set, marker }, device_us, arrival_us);
            }
            WorkerEvent::Session(SessionEvent::Device(event)) => {
                // Events after the device's last recorded set are beyond the recording.
                let within = limit.is_none_or(|limit| record.sets_taken < limit);
                if let (Some((pad, started)), true) = (contact_change(&event), within) {
                    let item = Item::Contact {
                        pad: pad.get(),
                        started,
                    };
                    record.stamper.push(item, event.timestamp_us, arrival_us);
                }
            }
            WorkerEvent::Session(_) => {}
            WorkerEvent::Ended(end) => {
                record.end = Some(*end);
                let released = record.stamper.finish();
                return self.write(device, released);
            }
        }
        let released = record.stamper.release(arrival_us);
        self.write(device, released)
    }

    fn write(&mut self, device: usize, released: Vec<Stamped<Item>>) -> anyhow::Result<()> {
        for stamped in released {
            let host_unix_us = self.clock.unix_us(stamped.host_us);
            let arrival_ns = self.clock.unix_us(stamped.arrival_us).saturating_mul(1_000);
            let stamp_ns = host_unix_us.saturating_mul(1_000);
            match &stamped.item {
                Item::Set { set, marker } => {
                    if let Some((rows, _)) = &mut self.csv {
                        for (pad, frame) in set.pads.iter().enumerate() {
                            let row = PadRow {
                                host_time_us: host_unix_us,
                                device: u32::try_from(device).unwrap_or(u32::MAX),
                                pad: u8::try_from(pad).unwrap_or(u8::MAX),
                                sequence: set.sequence,
                                sync_error_us: stamped.error_us,
                                reading: frame.as_ref().map(PadReading::from_frame),
                                marker: marker.clone(),
                            };
                            rows.write(&row).context("writing the CSV file")?;
                        }
                    }
                    if let Some((file, _)) = &mut self.mcap {
                        for frame in set.pads.iter().flatten() {
                            file.write_sample(device, frame, stamp_ns, arrival_ns)
                                .context("writing the MCAP file")?;
                        }
                    }
                    if let Some(record) = self.devices.get_mut(device) {
                        record.rows += set.pads.len() as u64;
                        record.missing_frames +=
                            set.pads.iter().filter(|frame| frame.is_none()).count() as u64;
                    }
                }
                Item::Contact { pad, started } => {
                    if let Some((file, _)) = &mut self.mcap {
                        file.write_contact(device, *pad, *started, stamp_ns, arrival_ns)
                            .context("writing the MCAP file")?;
                    }
                }
            }
        }
        Ok(())
    }

    /// Pushes what was written to the files (the raw logs are the links').
    pub fn flush(&mut self) -> anyhow::Result<()> {
        if let Some((rows, _)) = &mut self.csv {
            rows.flush().context("writing the CSV file")?;
        }
        Ok(())
    }

    /// Ends the recording: stamps and writes what still waits, writes each device's state,
    /// closes every file and renames it into place. The raw logs' writers must be closed
    /// (taken back from the links) before. When any step fails, every file not yet in place is
    /// kept under its temporary name and the error names them: a recording is never lost to a
    /// failure at its end.
    pub fn finish(mut self) -> anyhow::Result<RecordingSummary> {
        let mut files = Vec::new();
        match self.finish_files(&mut files) {
            Ok(devices) => Ok(RecordingSummary { devices, files }),
            Err(error) => {
                let kept = self.abandon();
                let names: Vec<String> =
                    kept.iter().map(|path| path.display().to_string()).collect();
                Err(error.context(format!(
                    "the recording could not be finished; what was received is kept in {}",
                    if names.is_empty() {
                        "the files already renamed".to_owned()
                    } else {
                        names.join(", ")
                    }
                )))
            }
        }
    }

    /// The steps of [`Recorder::finish`]; a file leaves `self` only once it is in place.
    fn finish_files(&mut self, files: &mut Vec<PathBuf>) -> anyhow::Result<Vec<DeviceSummary>> {
        for device in 0..self.devices.len() {
            let released = self.devices[device].stamper.finish();
            self.write(device, released)?;
        }
        if let Some((rows, _)) = &mut self.csv {
            rows.flush().context("writing the CSV file")?;
        }
        if let Some((rows, pending)) = self.csv.take() {
            let target = pending.target().to_path_buf();
            match rows.into_inner().into_inner() {
                Ok(file) => pending.commit_file(file)?,
                Err(error) => {
                    let kept = pending.keep()?;
                    return Err(error.into_error()).with_context(|| {
                        format!("writing {} (kept as {})", target.display(), kept.display())
                    });
                }
            }
            files.push(target);
        }
        if let Some((mcap, pending)) = self.mcap.take() {
            let target = pending.target().to_path_buf();
            let finished = mcap
                .finish()
                .map_err(anyhow::Error::from)
                .and_then(|writer| {
                    writer
                        .into_inner()
                        .map_err(|error| error.into_error().into())
                });
            match finished {
                Ok(file) => pending.commit_file(file)?,
                Err(error) => {
                    let kept = pending.keep()?;
                    return Err(error).with_context(|| {
                        format!(
                            "finishing {} (kept as {})",
                            target.display(),
                            kept.display()
                        )
                    });
                }
            }
            files.push(target);
        }
        let mut devices = Vec::new();
        for index in 0..self.devices.len() {
            if let Some(raw) = self.devices[index].raw.take() {
                let target = raw.target().to_path_buf();
                raw.commit()?;
                files.push(target);
            }
            let record = &self.devices[index];
            let state = record.end.as_ref().and_then(|end| end.state.as_ref());
            if let (Some(state), Some(path)) = (state, self.paths.device_state(index)) {
                state.write(&path)?;
                files.push(path);
            }
            devices.push(DeviceSummary {
                sets: record.sets_taken,
                rows: record.rows,
                missing_frames: record.missing_frames,
                stamped_at_arrival: record.stamper.stamped_at_arrival(),
                clock: record.stamper.estimate(),
                refused_clock_rate: record.stamper.mapper().refused_rate(),
                end: record.end.clone(),
            });
        }
        Ok(devices)
    }

    /// Gives up: keeps every file written so far under its temporary name and returns the
    /// names (a recording that failed keeps what it has).
    pub fn abandon(mut self) -> Vec<PathBuf> {
        let mut kept = Vec::new();
        if let Some((rows, pending)) = self.csv.take() {
            let _ = rows.into_inner().flush();
            kept.extend(pending.keep().ok());
        }
        if let Some((mcap, pending)) = self.mcap.take() {
            drop(mcap);
            kept.extend(pending.keep().ok());
        }
        for record in self.devices {
            kept.extend(record.raw.and_then(|raw| raw.keep().ok()));
        }
        kept
    }
}

/// The device time of a set: its first present pad's conversion.
fn set_time_us(set: &PadSet) -> Option<u64> {
    set.pads
        .iter()
        .flatten()
        .map(|frame: &SampleFrame| frame.timestamp_us)
        .next()
}
