//! The record key: every device the view shows, recorded by the host library's
//! [`Recorder`] into one CSV file of the recording schema (`taxel-YYYYMMDD-HHMMSS.csv` in
//! `--record-dir`), with each device's state beside it (`NAME.csv.dev<n>.device.json`).
//!
//! A recording started from the view has no raw byte logs: a raw log must be handed to a link
//! before its stream starts, and the view's streams are running. Each device's state is what
//! its session followed (identity, every pad's calibration, tier and baselines with the set
//! each applies from): the recorder writes it for a device whose stream ended while recording;
//! for the others the view asks each session for it when the recording stops, and writes it.
//! The recording stops when the key is pressed again, when a device goes away, or when the
//! view ends.

use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use taxel_host::console::error_message;
use taxel_host::device_state::RecordedDeviceState;
use taxel_host::host_clock::UnixClock;
use taxel_host::recorder::{Recorder, RecordingPaths};
use taxel_host::worker::ArrivedEvent;

use super::state::RecordingStatus;

/// How often a recording's file is flushed.
const FLUSH_INTERVAL: Duration = Duration::from_secs(1);

/// How long a stopping recording waits for the devices' states.
pub(super) const STATE_WAIT: Duration = Duration::from_secs(3);

/// The file name of a recording started now: taxel-YYYYMMDD-HHMMSS.csv (UTC).
pub fn recording_file_name(since_epoch: Duration) -> String {
    let seconds = since_epoch.as_secs();
    let (days, second_of_day) = (seconds / 86_400, seconds % 86_400);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let day_of_era = z.rem_euclid(146_097);
    let year_of_era =
        (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let month_index = (5 * day_of_year + 2) / 153;
    let day = day_of_year - (153 * month_index + 2) / 5 + 1;
    let month = if month_index < 10 {
        month_index + 3
    } else {
        month_index - 9
    };
    let year = year_of_era + era * 400 + i64::from(month <= 2);
    format!(
        "taxel-{year:04}{month:02}{day:02}-{:02}{:02}{:02}.csv",
        second_of_day / 3600,
        second_of_day / 60 % 60,
        second_of_day % 60
    )
}

/// A recording in progress.
pub(super) struct ViewRecording {
    recorder: Recorder,
    csv_path: PathBuf,
    markers: u64,
    /// Sets the view had skipped (every device's) when the recording started.
    skipped_at_start: u64,
    last_flush: Instant,
}

impl ViewRecording {
    /// Starts a recording of the devices whose clocks count `clock_rates` µs per second (their
    /// Infos') in `directory`, whose events arrive on `clock`; `skipped_now` is how many sets
    /// the view has skipped so far.
    pub(super) fn start(
        directory: &Path,
        clock_rates: &[u32],
        clock: UnixClock,
        skipped_now: u64,
    ) -> anyhow::Result<Self> {
        let since_epoch = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        let csv_path = directory.join(recording_file_name(since_epoch));
        if csv_path.exists() {
            anyhow::bail!(
                "{} exists already; try again in a second",
                csv_path.display()
            );
        }
        let paths = RecordingPaths {
            csv: Some(csv_path.clone()),
            mcap: None,
        };
        let mut recorder = Recorder::create(paths, clock_rates.len(), clock, None)?;
        for (device, clock_us_per_s) in clock_rates.iter().enumerate() {
            recorder.set_clock_us_per_s(device, *clock_us_per_s);
        }
        Ok(Self {
            recorder,
            csv_path,
            markers: 0,
            skipped_at_start: skipped_now,
            last_flush: Instant::now(),
        })
    }

    /// The file, as the view shows it.
    pub(super) fn file(&self) -> String {
        self.csv_path.display().to_string()
    }

    /// What the view shows of it.
    pub(super) fn status(&self) -> RecordingStatus {
        RecordingStatus {
            file: self.file(),
            sets: self.recorder.sets_taken().iter().sum(),
            markers: self.markers,
        }
    }

    /// Takes one event of a device (every event, while recording), flushing now and then.
    pub(super) fn take(&mut self, event: ArrivedEvent) -> anyhow::Result<()> {
        self.recorder.take(event)?;
        if self.last_flush.elapsed() >= FLUSH_INTERVAL {
            self.last_flush = Instant::now();
            self.recorder.flush()?;
        }
        Ok(())
    }

    /// Drops the next marker; returns its label.
    pub(super) fn mark(&mut self) -> String {
        self.markers += 1;
        let label = format!("marker {}", self.markers);
        self.recorder.mark(&label);
        label
    }

    /// Gives up after `error`, keeping what was written; returns what happened, in words.
    pub(super) fn abandon(self, error: &anyhow::Error) -> String {
        let kept = self.recorder.abandon();
        format!(
            "recording stopped: {}; kept {}",
            error_message(error),
            kept.iter()
                .map(|path| path.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )
    }

    /// Ends the recording: the files renamed into place, and each device's state written
    /// (the recorder's, from a stream that ended, else `states[device]`); `skipped_now` is how
    /// many sets the view has skipped so far. Returns what was saved, in words.
    fn finish(self, states: Vec<Option<RecordedDeviceState>>, skipped_now: u64) -> String {
        let file = self.file();
        let paths = self.recorder.paths().clone();
        let markers = self.markers;
        let summary = match self.recorder.finish() {
            Ok(summary) => summary,
            Err(error) => {
                return format!("recording {file} failed: {}", error_message(&error));
            }
        };
        let sets: u64 = summary.devices.iter().map(|device| device.sets).sum();
        let mut missing_states = Vec::new();
        let mut problems = Vec::new();
        for (device, state) in states.into_iter().enumerate() {
            let written = summary
                .devices
                .get(device)
                .and_then(|device| device.end.as_ref())
                .is_some_and(|end| end.state.is_some());
            if written {
                continue;
            }
            match (state, paths.device_state(device)) {
                (Some(state), Some(path)) => {
                    if let Err(error) = state.write(&path) {
                        problems.push(error_message(&error));
                    }
                }
                _ => missing_states.push(format!("dev {device}")),
            }
        }
        let mut words = format!("saved {file} ({sets} sets, {markers} markers");
        let skipped = skipped_now.saturating_sub(self.skipped_at_start);
        if skipped > 0 {
            words.push_str(&format!("; {skipped} sets the view skipped are missing"));
        }
        words.push(')');
        if !missing_states.is_empty() {
            words.push_str(&format!(
                "; no device state for {}",
                missing_states.join(", ")
            ));
        }
        if !problems.is_empty() {
            words.push_str(&format!("; {}", problems.join("; ")));
        }
        words
    }
}

/// One device's state, asked of its session when a recording stops.
enum StateRead {
    Waiting(Receiver<Option<RecordedDeviceState>>),
    Done(Option<Box<RecordedDeviceState>>),
}

/// A recording that stopped taking events and waits for the devices' states before it is
/// saved.
pub(super) struct Stopping {
    recording: ViewRecording,
    states: Vec<StateRead>,
    deadline: Instant,
}

impl Stopping {
    /// Stops taking events; `states[device]` is where device `device`'s state will arrive
    /// (`None`: it will not).
    pub(super) fn new(
        recording: ViewRecording,
        states: Vec<Option<Receiver<Option<RecordedDeviceState>>>>,
    ) -> Self {
        let states = states
            .into_iter()
            .map(|state| match state {
                Some(receiver) => StateRead::Waiting(receiver),
                None => StateRead::Done(None),
            })
            .collect();
        Self {
            recording,
            states,
            deadline: Instant::now() + STATE_WAIT,
        }
    }

    /// The file, as the view shows it.
    pub(super) fn file(&self) -> String {
        self.recording.file()
    }

    /// A device's stream ended with `state`: the state to write if its session's did not come.
    pub(super) fn ended(&mut self, device: usize, state: Option<&RecordedDeviceState>) {
        if let Some(read) = self.states.get_mut(device) {
            if !matches!(read, StateRead::Done(Some(_))) {
                *read = StateRead::Done(state.cloned().map(Box::new));
            }
        }
    }

    /// Whether every state came (or will not come), or the wait is over.
    pub(super) fn ready(&mut self) -> bool {
        for read in &mut self.states {
            if let StateRead::Waiting(receiver) = read {
                match receiver.try_recv() {
                    Ok(state) => *read = StateRead::Done(state.map(Box::new)),
                    Err(TryRecvError::Disconnected) => *read = StateRead::Done(None),
                    Err(TryRecvError::Empty) => {}
                }
            }
        }
        Instant::now() >= self.deadline
            || self
                .states
                .iter()
                .all(|read| matches!(read, StateRead::Done(_)))
    }

    /// Saves the recording with the states that came; returns what was saved, in words.
    pub(super) fn finish(self, skipped_now: u64) -> String {
        let states = self
            .states
            .into_iter()
            .map(|read| match read {
                StateRead::Done(state) => state.map(|state| *state),
                StateRead::Waiting(_) => None,
            })
            .collect();
        self.recording.finish(states, skipped_now)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recording_names_are_utc_date_and_time() {
        // 2026-11-23 23:11:25 UTC.
        assert_eq!(
            recording_file_name(Duration::from_secs(1_795_475_485)),
            "taxel-20261123-231125.csv"
        );
        assert_eq!(
            recording_file_name(Duration::ZERO),
            "taxel-19700101-000000.csv"
        );
        // A leap day.
        assert_eq!(
            recording_file_name(Duration::from_secs(951_782_400)),
            "taxel-20000229-000000.csv"
        );
    }
}
