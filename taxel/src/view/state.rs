//! What the live view shows, kept apart from drawing and from the port so it is testable: the
//! sample on display (pad 0's, on a device with several pads), the recent history per taxel, the device's identity and counters, the
//! honest accounting of sample sets, and the recording in progress.

use std::collections::VecDeque;

use model_core::TAXEL_COUNT;
use wire::{CountersFrame, DeviceFrame, InfoFrame, ReplyPayload, SampleFrame};

use crate::device_words::event_words;
use crate::stream_accounting::StreamAccounting;

/// Sample timestamps kept for the sample-set rate.
const RATE_WINDOW: usize = 128;

/// The recording in progress, as the view shows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordingStatus {
    /// The CSV file being written (it gets this name when the recording stops).
    pub file: String,
    /// Sample rows written.
    pub samples: u64,
    /// Markers dropped.
    pub markers: u64,
}

/// Everything the view shows.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewState {
    /// Which port or board is shown.
    pub source: String,
    /// Whether the device is connected.
    pub connected: bool,
    /// The status line (connection, tare progress, recording, errors).
    pub status: String,
    /// Display frozen (samples are still counted and recorded).
    pub paused: bool,
    /// The sample on display.
    pub sample: Option<SampleFrame>,
    /// The device's identity, when known.
    pub info: Option<InfoFrame>,
    /// The device's last counters (since its boot), when known.
    pub counters: Option<CountersFrame>,
    /// Where this connection's sample sets went.
    pub accounting: StreamAccounting,
    /// Frames that could not be decoded on this connection.
    pub frames_rejected: u64,
    /// Pressure drawn in the hottest colour and at the top of the time series, kPa.
    pub full_scale_kpa: f32,
    /// Seconds of history the time series shows.
    pub history_s: f64,
    /// The recording in progress, if any.
    pub recording: Option<RecordingStatus>,
    history: VecDeque<(u64, [Option<f32>; TAXEL_COUNT])>,
    recent_timestamps_us: VecDeque<u64>,
}

impl ViewState {
    /// An empty view of `source`.
    pub fn new(source: impl Into<String>) -> Self {
        Self {
            source: source.into(),
            connected: false,
            status: "connecting".to_owned(),
            paused: false,
            sample: None,
            info: None,
            counters: None,
            accounting: StreamAccounting::new(),
            frames_rejected: 0,
            full_scale_kpa: 50.0,
            history_s: 10.0,
            recording: None,
            history: VecDeque::new(),
            recent_timestamps_us: VecDeque::new(),
        }
    }

    /// Takes one frame from the device.
    pub fn apply_frame(&mut self, frame: &DeviceFrame) {
        match frame {
            DeviceFrame::Sample(sample) => self.apply_sample(sample),
            DeviceFrame::Info(info) => self.info = Some(*info),
            DeviceFrame::Counters(counters) => self.apply_counters(counters),
            DeviceFrame::Reply(reply) => match &reply.result {
                Ok(ReplyPayload::Info(info)) => self.info = Some(*info),
                Ok(ReplyPayload::Counters(counters)) => self.apply_counters(counters),
                _ => {}
            },
            DeviceFrame::Event(event) => self.status = event_words(event),
        }
    }

    fn apply_counters(&mut self, counters: &CountersFrame) {
        self.accounting.counters(counters);
        self.counters = Some(*counters);
    }

    fn apply_sample(&mut self, sample: &SampleFrame) {
        self.accounting.sample(sample);
        // The view draws pad 0; the other pads' frames are accounted (and recorded) only.
        if sample.pad.get() != 0 {
            return;
        }
        if self
            .recent_timestamps_us
            .back()
            .is_some_and(|last| sample.timestamp_us <= *last)
        {
            // The device clock went backwards: it restarted.
            self.recent_timestamps_us.clear();
            self.history.clear();
        }
        self.recent_timestamps_us.push_back(sample.timestamp_us);
        while self.recent_timestamps_us.len() > RATE_WINDOW {
            self.recent_timestamps_us.pop_front();
        }
        if self.paused {
            return;
        }
        self.sample = Some(*sample);
        self.history.push_back((
            sample.timestamp_us,
            sample.taxels.map(|taxel| taxel.pressure_kpa),
        ));
        let window_us = (self.history_s.max(0.0) * 1e6) as u64;
        while self
            .history
            .front()
            .is_some_and(|(time_us, _)| sample.timestamp_us.saturating_sub(*time_us) > window_us)
        {
            self.history.pop_front();
        }
    }

    /// Sample sets per second over the recent window, from the device's timestamps.
    pub fn sample_set_rate_hz(&self) -> Option<f64> {
        let (first, last) = (
            self.recent_timestamps_us.front()?,
            self.recent_timestamps_us.back()?,
        );
        let span_us = last.checked_sub(*first).filter(|span| *span > 0)?;
        Some((self.recent_timestamps_us.len() - 1) as f64 * 1e6 / span_us as f64)
    }

    /// The time series of one taxel: (seconds relative to the newest sample, kPa), faulted
    /// samples left out (a gap, never a zero).
    pub fn history_of(&self, taxel: usize) -> Vec<(f64, f64)> {
        let Some((newest_us, _)) = self.history.back() else {
            return Vec::new();
        };
        self.history
            .iter()
            .filter_map(|(time_us, pressures)| {
                let pressure_kpa = pressures.get(taxel).copied().flatten()?;
                let age_s = newest_us.saturating_sub(*time_us) as f64 / 1e6;
                Some((-age_s, f64::from(pressure_kpa)))
            })
            .collect()
    }

    /// The device is connected (again) on `source`: the accounting starts over for this
    /// connection.
    pub fn connected_to(&mut self, source: impl Into<String>) {
        self.source = source.into();
        self.connected = true;
        self.status.clear();
        self.accounting = StreamAccounting::new();
        self.frames_rejected = 0;
        self.recent_timestamps_us.clear();
    }

    /// The device went away.
    pub fn connection_lost(&mut self, why: impl Into<String>) {
        self.connected = false;
        self.status = why.into();
    }
}
