//! One connection to one device, and the host's only stream loop: identify the device (stale
//! frames from before the connection discarded), read its state, start the stream, then turn
//! frames into [`SessionEvent`]s — sample sets gathered from every pad's frame with the sets
//! missing before them, device events, Info changes, counters — and stop. Requests go through
//! the link's one reply matcher ([`DeviceLink::request`], [`DeviceLink::send_awaited`] and
//! [`DeviceLink::wait_reply`]); frames that arrive while a request waits are kept, in order.
//!
//! Every consumer builds on it: the recorder and the live view through [`crate::worker`], the
//! bridge, the Python package. A device of one pad is a device of `pad_count = 1`: its sets
//! hold one frame.

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::time::{Duration, Instant};

use anyhow::Context;
use model_core::{BaselineRecord, TAXEL_COUNT};
use wire::{
    Command, CountersFrame, DeviceEvent, DeviceFrame, ErrorCode, EventFrame, InfoFrame, PadIndex,
    ReplyPayload,
};

use crate::calibration_transfer::pull_baselines;
use crate::device_link::{DeviceLink, LinkError, LinkStatistics, RequestError};
use crate::device_state::{read_device_state, read_pad_state, BaselineChange, RecordedDeviceState};
use crate::pad_set::{PadSet, PadSetAssembler};
use crate::stream_accounting::{sequence_gap, StreamAccounting};

/// How a session talks to its device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SessionConfig {
    /// How long each request waits for its reply.
    pub request_timeout: Duration,
    /// Read every pad's calibration, tier and baselines at the start, and a pad's new
    /// baselines after each of its tares: what a recording needs to be re-processed exactly.
    pub follow_state: bool,
}

impl Default for SessionConfig {
    fn default() -> Self {
        Self {
            request_timeout: Duration::from_millis(2000),
            follow_state: false,
        }
    }
}

/// What a streaming device produced, in the order it arrived.
#[derive(Debug, Clone, PartialEq)]
pub enum SessionEvent {
    /// A sample set closed: every pad's frame, or those that arrived before a later set began
    /// (the others are `None`). `sets_missing_before` counts the sets missing from the
    /// sequence numbers just before it (dropped by the device or lost on the link).
    Set {
        /// The frames of the set, one slot per pad.
        set: PadSet,
        /// Sets missing just before this one.
        sets_missing_before: u64,
    },
    /// Something the device reports: contact started or ended, a tare started or finished,
    /// the temperature source changed.
    Device(EventFrame),
    /// The device's identity as it now says (it sends Info when its state changes).
    Info(InfoFrame),
    /// The device's counters (already taken into the accounting).
    Counters(CountersFrame),
    /// A pad's new baselines after its tare, applying from set `change.from_sequence` on
    /// (only with [`SessionConfig::follow_state`]; also in [`DeviceSession::state`]).
    Baselines {
        /// The pad that was tared.
        pad: PadIndex,
        /// Its baselines and the set they apply from.
        change: BaselineChange,
    },
    /// The device refused a request nobody waited for.
    Refused {
        /// The request's id.
        request_id: u16,
        /// The device's error code.
        code: ErrorCode,
    },
    /// A pad's new baselines could not be read after its tare: a re-processed recording will
    /// not reproduce that pad's pressures after this point.
    BaselinesUnread {
        /// The pad that was tared.
        pad: PadIndex,
        /// Why, in words.
        reason: String,
    },
}

/// A contact change the device reported: the pad, and whether the contact started (or ended).
pub fn contact_change(event: &EventFrame) -> Option<(PadIndex, bool)> {
    match event.event {
        DeviceEvent::ContactStarted { pad } => Some((pad, true)),
        DeviceEvent::ContactEnded { pad } => Some((pad, false)),
        _ => None,
    }
}

/// A device's stream, from identification to stop (see the module documentation).
pub struct DeviceSession<P> {
    link: DeviceLink<P>,
    config: SessionConfig,
    info: InfoFrame,
    state: Option<RecordedDeviceState>,
    assembler: PadSetAssembler,
    accounting: StreamAccounting,
    events: VecDeque<SessionEvent>,
    // The sequence number of the last set closed: a set's gap is from it (a set closed without
    // some pads is not a lost set).
    last_set_sequence: Option<u32>,
    // New baselines read after a tare, waiting for the pad's next frame to be dated.
    pending_baselines: Vec<(PadIndex, [Option<BaselineRecord>; TAXEL_COUNT])>,
    stale_frames: u64,
    streaming: bool,
}

impl<P: Read + Write> DeviceSession<P> {
    /// Identifies the device on `link` (discarding the frames that waited in the port from
    /// before), and with [`SessionConfig::follow_state`] reads its state. The stream is not
    /// started yet ([`DeviceSession::start`]), so that a raw log can be put in place first.
    pub fn open(mut link: DeviceLink<P>, config: SessionConfig) -> anyhow::Result<Self> {
        let (info, stale_frames) = link
            .synchronise(config.request_timeout)
            .context("asking the device who it is")?;
        let state = if config.follow_state {
            Some(read_device_state(&mut link, &info, config.request_timeout)?)
        } else {
            None
        };
        Ok(Self {
            link,
            config,
            info,
            state,
            assembler: PadSetAssembler::new(info.pad_count),
            accounting: StreamAccounting::new(),
            events: VecDeque::new(),
            last_set_sequence: None,
            pending_baselines: Vec::new(),
            stale_frames,
            streaming: false,
        })
    }

    /// Starts the stream: the accounting begins with the stale frames discarded and the
    /// device's counters now (when it gives them), then StartStreaming.
    pub fn start(&mut self) -> anyhow::Result<()> {
        self.accounting = StreamAccounting::new();
        self.accounting.stale_discarded(self.stale_frames);
        self.last_set_sequence = None;
        let timeout = self.config.request_timeout;
        if let Ok(ReplyPayload::Counters(counters)) =
            self.link.request(Command::ReadCounters, timeout)
        {
            self.accounting.counters(&counters);
        }
        self.link
            .request(Command::StartStreaming, timeout)
            .context("starting the stream")?;
        self.streaming = true;
        Ok(())
    }

    /// The next event, reading the link until `until` at most (one read may overrun it by the
    /// port's read timeout). `Ok(None)`: nothing by then. An error is the link's: the device
    /// went away or the raw log could not be written.
    pub fn next_event(&mut self, until: Instant) -> Result<Option<SessionEvent>, LinkError> {
        loop {
            if let Some(event) = self.events.pop_front() {
                return Ok(Some(event));
            }
            if Instant::now() >= until {
                return Ok(None);
            }
            if let Some(frame) = self.link.next_frame()? {
                self.take_frame(frame);
            }
        }
    }

    /// The end of the stream (the device went away, or the caller stops): the set still open,
    /// with its missing pads, as a last event if there is one.
    pub fn close_open_set(&mut self) -> Option<SessionEvent> {
        let set = self.assembler.finish()?;
        let sets_missing_before = self.set_gap(set.sequence);
        Some(SessionEvent::Set {
            set,
            sets_missing_before,
        })
    }

    /// Stops the stream, best effort (the device may be gone): StopStreaming and the device's
    /// counters, which go to the accounting and are returned.
    pub fn stop(&mut self) -> Option<CountersFrame> {
        if !self.streaming {
            return None;
        }
        self.streaming = false;
        let _ = self.link.send(Command::StopStreaming);
        match self
            .link
            .request(Command::ReadCounters, Duration::from_millis(500))
        {
            Ok(ReplyPayload::Counters(counters)) => {
                self.accounting.counters(&counters);
                Some(counters)
            }
            _ => None,
        }
    }

    /// Sends a request and waits for its reply (frames arriving meanwhile become events
    /// later, in order).
    pub fn request(
        &mut self,
        command: Command,
        timeout: Duration,
    ) -> Result<ReplyPayload, RequestError> {
        self.link.request(command, timeout)
    }

    /// Sends a request without waiting: its reply is taken with [`DeviceSession::wait_reply`].
    pub fn send(&mut self, command: Command) -> Result<u16, LinkError> {
        self.link.send_awaited(command)
    }

    /// The reply to request `request_id` if it arrives by `deadline` (see
    /// [`DeviceLink::wait_reply`]); frames arriving meanwhile become events later, in order.
    pub fn wait_reply(
        &mut self,
        request_id: u16,
        deadline: Instant,
    ) -> Result<Option<Result<ReplyPayload, ErrorCode>>, LinkError> {
        self.link.wait_reply(request_id, deadline)
    }

    /// Why request `request_id` got no reply within `timeout` (it is no longer awaited).
    pub fn no_reply_error(&mut self, request_id: u16, timeout: Duration) -> RequestError {
        self.link.forget(request_id);
        self.link.no_reply_error(request_id, timeout)
    }

    /// The device's identity as last said.
    pub fn info(&self) -> &InfoFrame {
        &self.info
    }

    /// Takes a new identity (from a request that changed it).
    pub fn set_info(&mut self, info: InfoFrame) {
        self.info = info;
    }

    /// The number of pads of each sample set.
    pub fn pad_count(&self) -> usize {
        self.assembler.pad_count()
    }

    /// The device's state, with every baseline change so far (with
    /// [`SessionConfig::follow_state`]).
    pub fn state(&self) -> Option<&RecordedDeviceState> {
        self.state.as_ref()
    }

    /// Starts following the device's state on a session opened without
    /// [`SessionConfig::follow_state`], once its stream runs: every pad's calibration, tier,
    /// role, geometry and baselines are read now (the baselines as in force from the start).
    /// Unlike following from [`DeviceSession::open`], no frame is discarded: the frames that
    /// arrive meanwhile become events later, in order, and a tare they report is followed.
    pub fn start_following_state(&mut self) -> anyhow::Result<()> {
        if self.state.is_some() {
            return Ok(());
        }
        let timeout = self.config.request_timeout;
        let mut state = RecordedDeviceState::new(&self.info);
        for pad in (0..state.pad_count).filter_map(PadIndex::new) {
            let mut pad_state = read_pad_state(&mut self.link, pad, timeout)?;
            let taxels = pull_baselines(&mut self.link, pad, timeout)
                .with_context(|| format!("reading the baselines of pad {}", pad.get()))?;
            pad_state.baselines = vec![BaselineChange {
                from_sequence: 0,
                taxels,
            }];
            state.add_pad(pad_state);
        }
        self.state = Some(state);
        self.config.follow_state = true;
        Ok(())
    }

    /// Reads every pad's calibration, tier, role and geometry again into the followed state,
    /// each pad's baselines kept (with [`SessionConfig::follow_state`]; nothing otherwise): after
    /// a request that may have changed them (a calibration written, a tier or use case set,
    /// the defaults restored). Frames arriving meanwhile become events later, in order.
    /// The device's identity is asked again too ([`DeviceSession::info`]).
    pub fn refresh_state(&mut self) -> anyhow::Result<()> {
        let timeout = self.config.request_timeout;
        if let ReplyPayload::Info(info) = self
            .link
            .request(Command::Info, timeout)
            .context("asking the device who it is")?
        {
            self.info = info;
            if let Some(state) = self.state.as_mut() {
                state.converter_rate_sps = info.rate.sps();
            }
        }
        let Some(pads) = self.state.as_ref().map(|state| state.pad_count) else {
            return Ok(());
        };
        let mut fresh_pads = Vec::new();
        for pad in (0..pads).filter_map(PadIndex::new) {
            fresh_pads.push(read_pad_state(&mut self.link, pad, timeout)?);
        }
        // Every frame received so far goes through first: a set up to the one still open may
        // have been computed before the change (or during it); the sets after it were not.
        for frame in self.link.take_queued() {
            self.take_frame(frame);
        }
        let from_sequence = self
            .last_set_sequence
            .map_or(0, |sequence| sequence.wrapping_add(2));
        if let Some(state) = self.state.as_mut() {
            for mut fresh in fresh_pads {
                let Some(old) = state.pad_state(fresh.pad) else {
                    state.add_pad(fresh);
                    continue;
                };
                let changed = (&old.calibration, &old.tier, old.role, old.geometry)
                    != (&fresh.calibration, &fresh.tier, fresh.role, fresh.geometry);
                fresh.state_from_sequence = if changed {
                    from_sequence
                } else {
                    old.state_from_sequence
                };
                fresh.baselines = old.baselines;
                state.add_pad(fresh);
            }
        }
        Ok(())
    }

    /// Where every sample set went: received, missing from the sequence numbers, dropped by the
    /// device, lost on the link.
    pub fn accounting(&self) -> &StreamAccounting {
        &self.accounting
    }

    /// The link's decoding counters.
    pub fn link_statistics(&self) -> &LinkStatistics {
        self.link.statistics()
    }

    /// The link (calibration transfer, the raw log).
    pub fn link_mut(&mut self) -> &mut DeviceLink<P> {
        &mut self.link
    }

    /// How the session talks to the device.
    pub fn config(&self) -> SessionConfig {
        self.config
    }

    fn take_frame(&mut self, frame: DeviceFrame) {
        match frame {
            DeviceFrame::Sample(sample) => {
                self.accounting.sample(&sample);
                if let Some(index) = self
                    .pending_baselines
                    .iter()
                    .position(|(pad, _)| *pad == sample.pad)
                {
                    let (pad, taxels) = self.pending_baselines.swap_remove(index);
                    let change = BaselineChange {
                        from_sequence: sample.sequence,
                        taxels,
                    };
                    if let Some(history) = self
                        .state
                        .as_mut()
                        .and_then(|state| state.baselines_mut(pad.get()))
                    {
                        history.push(change.clone());
                    }
                    self.events
                        .push_back(SessionEvent::Baselines { pad, change });
                }
                for set in self.assembler.push(sample) {
                    let sets_missing_before = self.set_gap(set.sequence);
                    self.events.push_back(SessionEvent::Set {
                        set,
                        sets_missing_before,
                    });
                }
            }
            DeviceFrame::Event(event) => {
                if let (DeviceEvent::TareFinished { pad, .. }, true) =
                    (event.event, self.config.follow_state)
                {
                    self.follow_tare(pad);
                }
                self.events.push_back(SessionEvent::Device(event));
            }
            DeviceFrame::Info(info) => {
                if info != self.info {
                    self.info = info;
                    self.events.push_back(SessionEvent::Info(info));
                }
            }
            DeviceFrame::Counters(counters) => {
                self.accounting.counters(&counters);
                self.events.push_back(SessionEvent::Counters(counters));
            }
            DeviceFrame::Reply(reply) => match reply.result {
                Ok(ReplyPayload::Counters(counters)) => {
                    self.accounting.counters(&counters);
                    self.events.push_back(SessionEvent::Counters(counters));
                }
                Ok(_) => {}
                Err(code) => self.events.push_back(SessionEvent::Refused {
                    request_id: reply.request_id,
                    code,
                }),
            },
        }
    }

    fn follow_tare(&mut self, pad: PadIndex) {
        match pull_baselines(&mut self.link, pad, self.config.request_timeout) {
            Ok(taxels) => {
                self.pending_baselines.retain(|(known, _)| *known != pad);
                self.pending_baselines.push((pad, taxels));
            }
            Err(error) => self.events.push_back(SessionEvent::BaselinesUnread {
                pad,
                reason: crate::console::error_message(&error),
            }),
        }
    }

    /// Sets missing between the last set closed and set `sequence` (wrapping), which closes now.
    fn set_gap(&mut self, sequence: u32) -> u64 {
        let gap = self
            .last_set_sequence
            .map_or(0, |previous| sequence_gap(previous, sequence));
        self.last_set_sequence = Some(sequence);
        gap
    }
}
