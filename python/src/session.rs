//! One connection to a device (a board's serial port or the simulated device's in-memory link):
//! the host library's [`DeviceLink`] for frames and requests, its [`PadSetAssembler`] for
//! gathering every pad's frame of a set, and its [`StreamAccounting`] for gaps and drops.
//!
//! Every call is bounded by an instant, so that the Python side can wait in short slices with
//! the GIL released and look for Ctrl-C between them.

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::time::{Duration, Instant};

use anyhow::Context;
use taxel_host::device_link::{DeviceLink, RequestError};
use taxel_host::pad_set::PadSetAssembler;
use taxel_host::stream_accounting::StreamAccounting;
use wire::{Command, DeviceFrame, ErrorCode, InfoFrame, ReplyFrame, ReplyPayload};

use crate::sample_set::{host_time_s, SetRecord};

/// A byte stream to a device.
pub trait Transport: Read + Write + Send {}

impl<T: Read + Write + Send> Transport for T {}

/// Sample sets kept for a caller that sends commands without reading; older ones are dropped
/// (and counted in [`SessionCounters::sets_dropped_unread`]) beyond this.
pub const READY_CAPACITY: usize = 65_536;

/// Replies kept for requests nobody waits for any more (answers that came after a timeout).
const STRAY_REPLY_CAPACITY: usize = 16;

/// Sequence gaps remembered for sets still being gathered.
const GAP_MEMORY: usize = 64;

/// Counts this session keeps besides the host library's accounting.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SessionCounters {
    /// Sample sets delivered to the caller.
    pub sets_delivered: u64,
    /// Sets closed with at least one pad's frame missing.
    pub incomplete_sets: u64,
    /// Sets dropped because the caller read none while more than [`READY_CAPACITY`] piled up.
    pub sets_dropped_unread: u64,
}

/// One connection.
pub struct Session {
    link: DeviceLink<Box<dyn Transport>>,
    info: InfoFrame,
    assembler: PadSetAssembler,
    accounting: StreamAccounting,
    ready: VecDeque<SetRecord>,
    replies: VecDeque<ReplyFrame>,
    gaps: Vec<(u32, u64)>,
    counters: SessionCounters,
}

impl Session {
    /// Starts a session on a freshly opened port, as `taxel record` does: asks who the device
    /// is (discarding the stale frames before the answer), takes its counters as the origin of
    /// the accounting and starts the stream.
    pub fn start(port: Box<dyn Transport>, timeout: Duration) -> anyhow::Result<Self> {
        let mut link = DeviceLink::new(port);
        let (info, stale) = link
            .synchronise(timeout)
            .context("asking the device who it is")?;
        let accounting = taxel_host::record::start_stream(&mut link, stale, timeout)?;
        Ok(Self {
            link,
            info,
            assembler: PadSetAssembler::new(info.pad_count),
            accounting,
            ready: VecDeque::new(),
            replies: VecDeque::new(),
            gaps: Vec::new(),
            counters: SessionCounters::default(),
        })
    }

    /// The device's identity as last asked.
    pub fn info(&self) -> &InfoFrame {
        &self.info
    }

    /// The number of pads of each sample set.
    pub fn pad_count(&self) -> usize {
        self.assembler.pad_count()
    }

    /// The host library's accounting of this connection's samples.
    pub fn accounting(&self) -> &StreamAccounting {
        &self.accounting
    }

    /// This session's own counts.
    pub fn counters(&self) -> &SessionCounters {
        &self.counters
    }

    /// The link (for the host library's calibration transfer).
    pub fn link_mut(&mut self) -> &mut DeviceLink<Box<dyn Transport>> {
        &mut self.link
    }

    /// The next sample set, waiting until `until` at most.
    pub fn next_set(&mut self, until: Instant) -> anyhow::Result<Option<SetRecord>> {
        loop {
            if let Some(set) = self.ready.pop_front() {
                self.counters.sets_delivered += 1;
                return Ok(Some(set));
            }
            if Instant::now() >= until {
                return Ok(None);
            }
            self.pump_once()?;
        }
    }

    /// Sends a request without waiting; returns its id for [`Session::reply`].
    pub fn send(&mut self, command: Command) -> anyhow::Result<u16> {
        Ok(self.link.send(command)?)
    }

    /// The reply to request `request_id` if it arrives before `until`; sample sets arriving
    /// meanwhile are kept for [`Session::next_set`].
    pub fn reply(
        &mut self,
        request_id: u16,
        until: Instant,
    ) -> anyhow::Result<Option<Result<ReplyPayload, ErrorCode>>> {
        loop {
            if let Some(position) = self
                .replies
                .iter()
                .position(|reply| reply.request_id == request_id)
            {
                return Ok(self.replies.remove(position).map(|reply| reply.result));
            }
            if Instant::now() >= until {
                return Ok(None);
            }
            self.pump_once()?;
        }
    }

    /// Why a request got no reply by its deadline, in the host library's words.
    pub fn no_reply_error(&self, request_id: u16, timeout: Duration) -> RequestError {
        match self.link.statistics().other_protocol_version {
            Some(found) => RequestError::OtherProtocolVersion {
                found,
                supported: wire::PROTOCOL_VERSION,
            },
            None => RequestError::Timeout {
                request_id,
                timeout_ms: timeout.as_millis(),
            },
        }
    }

    /// Takes a new Info (after a command that changes it).
    pub fn set_info(&mut self, info: InfoFrame) {
        self.info = info;
    }

    /// Ends the stream, best effort (the device may be gone).
    pub fn stop_stream(&mut self) {
        let _ = self.link.send(Command::StopStreaming);
    }

    /// Reads once from the port and takes every frame that completes.
    fn pump_once(&mut self) -> anyhow::Result<()> {
        while let Some(frame) = self.link.next_frame()? {
            match frame {
                DeviceFrame::Sample(sample) => {
                    let gap = self.accounting.sample(&sample);
                    if gap > 0 {
                        self.remember_gap(sample.sequence, gap);
                    }
                    for set in self.assembler.push(sample) {
                        self.gathered(&set);
                    }
                }
                DeviceFrame::Counters(counters) => self.accounting.counters(&counters),
                DeviceFrame::Reply(reply) => {
                    if let Ok(ReplyPayload::Counters(counters)) = &reply.result {
                        self.accounting.counters(counters);
                    }
                    if self.replies.len() >= STRAY_REPLY_CAPACITY {
                        self.replies.pop_front();
                    }
                    self.replies.push_back(reply);
                }
                DeviceFrame::Info(info) => self.info = info,
                _ => {}
            }
            // Stop at a complete set or reply: the caller decides whether to wait for more.
            if !self.ready.is_empty() || !self.replies.is_empty() {
                break;
            }
        }
        Ok(())
    }

    fn remember_gap(&mut self, sequence: u32, gap: u64) {
        match self.gaps.iter_mut().find(|(known, _)| *known == sequence) {
            Some((_, largest)) => *largest = (*largest).max(gap),
            None => {
                if self.gaps.len() >= GAP_MEMORY {
                    self.gaps.remove(0);
                }
                self.gaps.push((sequence, gap));
            }
        }
    }

    fn gathered(&mut self, set: &taxel_host::pad_set::PadSet) {
        let gap = self
            .gaps
            .iter()
            .position(|(sequence, _)| *sequence == set.sequence)
            .map_or(0, |position| self.gaps.remove(position).1);
        if !set.is_complete() {
            self.counters.incomplete_sets += 1;
        }
        if self.ready.len() >= READY_CAPACITY {
            self.ready.pop_front();
            self.counters.sets_dropped_unread += 1;
        }
        self.ready
            .push_back(SetRecord::from_pad_set(set, host_time_s(), gap));
    }
}
