//! What the live view shows, kept apart from drawing and from the port so it is testable: every
//! pad's last sample and recent history per taxel, which pad the detailed view shows, the
//! layout, whether each pad is live or stale, the device's identity and counters, the honest
//! accounting of sample sets, and the recording in progress.
//!
//! It is fed with the device session's events ([`ViewState::apply_event`]), each with its
//! arrival in µs on the view's host clock (the worker's), and with the session's accounting
//! as the view last read it ([`ViewState::set_accounting`]): the view never counts sample sets
//! itself, so sets it skipped because it fell behind are not taken for losses on the link.
//!
//! Staleness: a pad is stale when its last frame is more than [`STALE_AFTER`] old, measured on
//! the host clock (nothing arrived from it: the device stalled or was unplugged) or on the
//! device clock against the newest frame of any pad (the device sends other pads' sets but not
//! this one's), and every pad with data is stale while the device is disconnected. A stale pad's
//! last values are never drawn as if live.

use std::collections::VecDeque;
use std::time::Duration;

use model_core::{PadGeometry, TAXEL_COUNT};
use taxel_host::device_state::RecordedDeviceState;
use taxel_host::device_words::event_words;
use taxel_host::session::SessionEvent;
use taxel_host::stream_accounting::StreamAccounting;
use wire::{CountersFrame, InfoFrame, SampleFrame};

use crate::layout::{Arrangement, Layout, MAX_PADS};

/// Sample timestamps kept for the sample-set rate.
const RATE_WINDOW: usize = 128;

/// A pad whose last frame is older than this is shown as stale (see the module's notes): five
/// times the slowest set period the device runs at (8 pads on a 100 kHz bus, 25 sets/s, 40 ms)
/// plus a busy host's scheduling, yet short enough that an unplugged pad shows at once.
pub const STALE_AFTER: Duration = Duration::from_millis(500);

/// Whether a pad's values can be shown as live.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PadFreshness {
    /// The device does not have this pad (its index is at or above the device's pad count).
    NotOnDevice,
    /// No frame of the pad yet.
    NoData,
    /// Its last frame is recent.
    Live,
    /// Its last frame is older than [`STALE_AFTER`], or the device is disconnected.
    Stale {
        /// How long ago the last frame came, s (host or device clock, whichever is longer).
        age_s: f64,
    },
}

/// One pad as the view holds it.
#[derive(Debug, Clone, Default, PartialEq)]
struct PadView {
    /// The last sample shown (frozen while paused).
    sample: Option<SampleFrame>,
    /// When the last frame arrived, µs on the host clock (also while paused).
    arrival_us: Option<u64>,
    /// The device timestamp of the last frame, µs.
    device_time_us: Option<u64>,
    /// (device timestamp µs, pressures kPa) over the last `history_s`.
    history: VecDeque<(u64, [Option<f32>; TAXEL_COUNT])>,
    /// The pad's geometry as the device reports it (the built-in one until known).
    geometry: PadGeometry,
}

/// The recording in progress, as the view shows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordingStatus {
    /// The CSV file being written (it gets this name when the recording stops).
    pub file: String,
    /// Sample sets recorded, every device's together.
    pub sets: u64,
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
    /// The sample of the pad the detailed view shows ([`ViewState::detail_pad`], pad 0 by
    /// default).
    pub sample: Option<SampleFrame>,
    /// The device's identity, when known.
    pub info: Option<InfoFrame>,
    /// The device's last counters (since its boot), when known.
    pub counters: Option<CountersFrame>,
    /// Where this connection's sample sets went, as the device's session counts them (the view
    /// reads it every half second, see [`ViewState::set_accounting`]).
    pub accounting: StreamAccounting,
    /// Frames that could not be decoded on this connection.
    pub frames_rejected: u64,
    /// Sample sets of this connection the view skipped because it fell behind (its queue
    /// dropped the oldest); they were received and are counted by the accounting.
    pub view_dropped_sets: u64,
    /// Pressure drawn in the hottest colour and at the top of the time series, kPa.
    pub full_scale_kpa: f32,
    /// Seconds of history the time series shows.
    pub history_s: f64,
    /// The recording in progress, if any.
    pub recording: Option<RecordingStatus>,
    /// The layout given with `--layout`; `None`: an automatic grid in pad order.
    pub layout: Option<Layout>,
    /// The pad shown in the detailed view; `None`: every pad when the device has several or a
    /// layout is given, pad 0 in detail otherwise.
    pub detail_pad: Option<u8>,
    /// Which device this is when the view shows several ("dev 1"): put before every pad's
    /// name.
    pub device_label: Option<String>,
    pads: [PadView; MAX_PADS as usize],
    newest_device_time_us: Option<u64>,
    now_us: Option<u64>,
    recent_timestamps_us: VecDeque<u64>,
    sets_received: u64,
    highest_pad_seen: Option<u8>,
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
            view_dropped_sets: 0,
            full_scale_kpa: 50.0,
            history_s: 10.0,
            recording: None,
            layout: None,
            detail_pad: None,
            device_label: None,
            pads: std::array::from_fn(|_| PadView::default()),
            newest_device_time_us: None,
            now_us: None,
            recent_timestamps_us: VecDeque::new(),
            sets_received: 0,
            highest_pad_seen: None,
        }
    }

    /// Takes one event of the device's session that arrived at `arrival_us` (host clock).
    pub fn apply_event(&mut self, event: &SessionEvent, arrival_us: u64) {
        match event {
            SessionEvent::Set { set, .. } => {
                self.sets_received += 1;
                for frame in set.pads.iter().flatten() {
                    self.apply_sample(frame, arrival_us);
                }
            }
            SessionEvent::Device(event) => self.status = event_words(event),
            SessionEvent::Info(info) => self.info = Some(*info),
            SessionEvent::Counters(counters) => self.counters = Some(*counters),
            SessionEvent::Baselines { .. } => {}
            SessionEvent::Refused { request_id, code } => {
                self.status = format!("the device refused request {request_id}: {code:?}");
            }
            SessionEvent::BaselinesUnread { pad, reason } => {
                self.status = format!(
                    "pad {}: its new baselines could not be read ({reason})",
                    pad.get()
                );
            }
        }
    }

    /// Takes the session's accounting and the link's count of undecodable frames.
    pub fn set_accounting(&mut self, accounting: StreamAccounting, frames_rejected: u64) {
        self.accounting = accounting;
        self.frames_rejected = frames_rejected;
    }

    /// Sample sets the view took on this connection (not the accounting's: see the module
    /// documentation).
    pub fn sets_received(&self) -> u64 {
        self.sets_received
    }

    /// Takes one pad's sample frame that arrived at `arrival_us` (host clock).
    pub fn apply_sample(&mut self, sample: &SampleFrame, arrival_us: u64) {
        self.refresh(arrival_us);
        let pad = sample.pad.get();
        self.highest_pad_seen = Some(self.highest_pad_seen.map_or(pad, |seen| seen.max(pad)));
        let Some(view) = self.pads.get_mut(usize::from(pad)) else {
            return;
        };
        if view
            .device_time_us
            .is_some_and(|last| sample.timestamp_us <= last)
        {
            // The device clock went backwards: it restarted.
            self.recent_timestamps_us.clear();
            self.newest_device_time_us = None;
            for view in &mut self.pads {
                view.device_time_us = None;
                view.history.clear();
            }
        }
        let Some(view) = self.pads.get_mut(usize::from(pad)) else {
            return;
        };
        view.device_time_us = Some(sample.timestamp_us);
        view.arrival_us = Some(arrival_us);
        self.newest_device_time_us = Some(
            self.newest_device_time_us
                .map_or(sample.timestamp_us, |newest| {
                    newest.max(sample.timestamp_us)
                }),
        );
        let shown_in_detail = pad == self.detail_pad.unwrap_or(0);
        if shown_in_detail {
            self.recent_timestamps_us.push_back(sample.timestamp_us);
            while self.recent_timestamps_us.len() > RATE_WINDOW {
                self.recent_timestamps_us.pop_front();
            }
        }
        if self.paused {
            return;
        }
        view.sample = Some(*sample);
        view.history.push_back((
            sample.timestamp_us,
            sample.taxels.map(|taxel| taxel.pressure_kpa),
        ));
        let window_us = (self.history_s.max(0.0) * 1e6) as u64;
        while view
            .history
            .front()
            .is_some_and(|(time_us, _)| sample.timestamp_us.saturating_sub(*time_us) > window_us)
        {
            view.history.pop_front();
        }
        if shown_in_detail {
            self.sample = Some(*sample);
        }
    }

    /// The host clock moved on to `now_us` (the live loop calls it before drawing): pads that
    /// sent nothing since [`STALE_AFTER`] become stale.
    pub fn refresh(&mut self, now_us: u64) {
        self.now_us = Some(self.now_us.map_or(now_us, |before| before.max(now_us)));
    }

    /// Shows one pad in the detailed view (`None`: back to every pad).
    pub fn show_pad(&mut self, pad: Option<u8>) {
        let pad = pad.filter(|pad| *pad < MAX_PADS);
        if pad == self.detail_pad {
            return;
        }
        self.detail_pad = pad;
        self.sample = self
            .pads
            .get(usize::from(pad.unwrap_or(0)))
            .and_then(|view| view.sample);
        self.recent_timestamps_us.clear();
    }

    /// How many pads the device reads: its Info's, or before that one more than the highest pad
    /// seen (at least 1).
    pub fn pad_count(&self) -> u8 {
        match &self.info {
            Some(info) => info.pad_count,
            None => self
                .highest_pad_seen
                .map_or(1, |pad| pad.saturating_add(1).min(MAX_PADS)),
        }
    }

    /// Whether the view shows every pad (tiles) rather than one pad in detail.
    pub fn shows_every_pad(&self) -> bool {
        self.detail_pad.is_none() && (self.layout.is_some() || self.pad_count() > 1)
    }

    /// Whether the view is about several pads (a layout, or a device with several), so pads
    /// are named.
    pub fn several_pads(&self) -> bool {
        self.layout.is_some() || self.pad_count() > 1
    }

    /// The tiles: the layout's (or the automatic grid's), fitted to the device's pad count,
    /// their names after the [`ViewState::device_label`].
    pub fn arrangement(&self) -> Arrangement {
        let device_pad_count = self.info.map(|info| info.pad_count);
        let mut arrangement = match &self.layout {
            Some(layout) => layout.arrange(device_pad_count),
            None => Layout::automatic(self.pad_count()).arrange(device_pad_count),
        };
        if let Some(label) = &self.device_label {
            for tile in &mut arrangement.tiles {
                tile.place.name = format!("{label} {}", tile.place.name);
            }
        }
        arrangement
    }

    /// The name a pad has in the layout ("pad N" when it names none), after the
    /// [`ViewState::device_label`].
    pub fn pad_name(&self, pad: u8) -> String {
        let name = self
            .layout
            .as_ref()
            .and_then(|layout| layout.pad(pad))
            .map_or_else(|| format!("pad {pad}"), |place| place.name.clone());
        match &self.device_label {
            Some(label) => format!("{label} {name}"),
            None => name,
        }
    }

    /// Every pad's geometry, as the device's state reports it.
    pub fn set_geometries(&mut self, state: &RecordedDeviceState) {
        for pad in &state.pads {
            if let Some(view) = self.pads.get_mut(usize::from(pad.pad)) {
                view.geometry = pad.geometry;
            }
        }
    }

    /// A pad's geometry (the built-in one for a pad the device did not describe).
    pub fn pad_geometry(&self, pad: u8) -> PadGeometry {
        self.pads
            .get(usize::from(pad))
            .map_or(PadGeometry::ARTICLE, |view| view.geometry)
    }

    /// The last sample of a pad (frozen while paused), whether live or stale: see
    /// [`ViewState::pad_freshness`] before showing it.
    pub fn pad_sample(&self, pad: u8) -> Option<&SampleFrame> {
        self.pads.get(usize::from(pad))?.sample.as_ref()
    }

    /// Whether any pad has sent a sample.
    pub fn any_sample(&self) -> bool {
        self.pads.iter().any(|view| view.sample.is_some())
    }

    /// Whether a pad's values can be shown as live (the rule is in the module's notes).
    pub fn pad_freshness(&self, pad: u8) -> PadFreshness {
        if self.info.is_some_and(|info| pad >= info.pad_count) {
            return PadFreshness::NotOnDevice;
        }
        let Some(view) = self.pads.get(usize::from(pad)) else {
            return PadFreshness::NotOnDevice;
        };
        let (Some(arrival_us), Some(_)) = (view.arrival_us, view.sample) else {
            return PadFreshness::NoData;
        };
        let host_age = Duration::from_micros(
            self.now_us
                .map_or(0, |now_us| now_us.saturating_sub(arrival_us)),
        );
        let device_lag = match (self.newest_device_time_us, view.device_time_us) {
            (Some(newest_us), Some(last_us)) => {
                Duration::from_micros(newest_us.saturating_sub(last_us))
            }
            _ => Duration::ZERO,
        };
        let age = host_age.max(device_lag);
        if !self.connected || age > STALE_AFTER {
            PadFreshness::Stale {
                age_s: age.as_secs_f64(),
            }
        } else {
            PadFreshness::Live
        }
    }

    /// Sample sets per second over the recent window, from the device's timestamps (of the pad
    /// shown in detail, pad 0 in the view of every pad).
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
        let Some(view) = self.pads.get(usize::from(self.detail_pad.unwrap_or(0))) else {
            return Vec::new();
        };
        let Some((newest_us, _)) = view.history.back() else {
            return Vec::new();
        };
        view.history
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
        self.view_dropped_sets = 0;
        self.sets_received = 0;
        self.recent_timestamps_us.clear();
        // The new connection's device clock may have restarted: the host clock judges the pads
        // until they send again, and the time series (on the device clock) starts over.
        self.newest_device_time_us = None;
        for view in &mut self.pads {
            view.device_time_us = None;
            view.history.clear();
        }
    }

    /// The device went away.
    pub fn connection_lost(&mut self, why: impl Into<String>) {
        self.connected = false;
        self.status = why.into();
    }
}
