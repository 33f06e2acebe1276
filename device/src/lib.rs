//! The device application, portable: what the firmware does between the converter and the USB
//! port, written once so the desktop simulator runs exactly the same code.
//!
//! - [`HostInput`] turns received bytes into requests (binary frames, or the text line `binary`
//!   that leaves text mode), answering what it cannot parse.
//! - [`Device`] owns the acquisition loop; each [`Device::step`] runs one converter cycle, applies
//!   the requests that arrived, and emits [`Outgoing`] frames: samples (or CSV lines in text mode)
//!   while streaming to a connected host, replies, events and periodic counters.
//! - [`encode_outgoing`] turns them into bytes for the port.
#![no_std]
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

mod boot;
mod control;
mod convert;
mod host_input;
mod persistence;
mod retained;
mod supervisor;

pub use boot::{
    boot, boot_pad, calibration_key, BoardAcquisition, BoardConfig, BoardParts, BootPad,
    BootReport, BootedDevice, PadI2c, BOARD,
};
pub use control::DeviceControl;
pub use convert::{
    baseline_record, baseline_wire, calibration_record, converter_rate, counters_frame,
    pad_summary, sample_frame, taxel_calibration_spec, wire_sample_rate, wire_temperature_source,
    CalibrationConversionError,
};
pub use host_input::{HostInput, HostInputEvent};
pub use persistence::{CalibrationPersistence, PersistenceFailed};
pub use retained::{boot_plan, BootPlan, ResetKind, RetainedPad, RetainedState, RETAINED_LEN};
pub use supervisor::{Supervisor, SupervisorAction};

use acquisition::discovery::{PadSlot, PadTemperature, MAX_PADS};
use acquisition::{ProcessedSample, TemperatureOrigin};
use calibration_store::{PadRecord, RecordScope};
use model_core::{
    BaselineError, Calibration, ContactConfig, ContactEvent, ForceAndContact, PadGeometry,
    PadModel, PadRole, TareStatus, Tier,
};
use wire::{
    CalibrationSource, Command, DeviceEvent, DeviceFrame, ErrorCode, EventFrame, FirmwareVersion,
    InfoFrame, PadIndex, PadInfoFrame, ReplyFrame, ReplyPayload, Request, SampleFrame,
    TaxelBaselineWire, TemperatureSensor, PROTOCOL_VERSION,
};

/// Largest encoded output: a CSV line or the largest frame, whichever is longer.
pub const MAX_OUTGOING_LEN: usize = if wire::CSV_LINE_MAX_LEN > wire::MAX_FRAME_ENCODED_LEN {
    wire::CSV_LINE_MAX_LEN
} else {
    wire::MAX_FRAME_ENCODED_LEN
};

const _: () = assert!(wire::MAX_FRAME_ENCODED_LEN <= MAX_OUTGOING_LEN);

/// The version of the device application, which the firmware and the simulated device both
/// report: this package's version (every component must be below 255).
pub const FIRMWARE_VERSION: FirmwareVersion = FirmwareVersion {
    major: version_component(env!("CARGO_PKG_VERSION_MAJOR")),
    minor: version_component(env!("CARGO_PKG_VERSION_MINOR")),
    patch: version_component(env!("CARGO_PKG_VERSION_PATCH")),
};

const _: () = assert!(
    FIRMWARE_VERSION.major != u8::MAX
        && FIRMWARE_VERSION.minor != u8::MAX
        && FIRMWARE_VERSION.patch != u8::MAX,
    "every component of the package version must be below 255"
);

/// A version component, or `u8::MAX` (refused at compile time above) when it is not a `u8`.
const fn version_component(text: &str) -> u8 {
    match u8::from_str_radix(text, 10) {
        Ok(component) => component,
        Err(_) => u8::MAX,
    }
}

/// Who the device is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceIdentity {
    /// Firmware version.
    pub firmware_version: FirmwareVersion,
    /// The MCU's 96-bit unique ID.
    pub board_serial: [u8; 12],
    /// How many µs the device clock counts per second of real time
    /// ([`REAL_TIME_CLOCK_US_PER_S`] for a board; see `InfoFrame::clock_us_per_s`).
    pub clock_us_per_s: u32,
}

/// A board's clock: a µs per µs of real time.
pub const REAL_TIME_CLOCK_US_PER_S: u32 = 1_000_000;

/// Something to send to the host.
#[derive(Debug, Clone, PartialEq)]
pub enum Outgoing {
    /// A binary frame.
    Frame(DeviceFrame),
    /// A sample as a CSV line (text mode).
    CsvLine(SampleFrame),
    /// The CSV header line, sent when text mode starts.
    CsvHeader,
}

/// The host's queue could not take a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct QueueFull;

/// The host side of the device: requests in, frames out, never waiting.
pub trait HostPort {
    /// Whether a host has the port open (DTR set); may refresh the port's state.
    fn host_connected(&mut self) -> bool;
    /// The next request or input event that arrived, if any.
    fn try_receive(&mut self) -> Option<HostInputEvent>;
    /// Queues something to send; `Err` when the queue is full (it is then dropped and counted).
    fn try_send(&mut self, outgoing: Outgoing) -> Result<(), QueueFull>;
}

/// Counters of what happened on the host side.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HostCounters {
    /// Frames not sent because no host had the port open, or its queue was full.
    pub frames_dropped_no_host: u32,
    /// Sample frames produced while streaming that were not sent (no host had the port open, or
    /// its queue was full), one per pad per set: among `frames_dropped_no_host`, the ones that
    /// were sample frames.
    pub sample_frames_dropped: u32,
    /// Host frames that could not be decoded or were refused without a reply.
    pub host_frames_rejected: u32,
}

/// Settings of the device application.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceConfig {
    /// A counters frame goes out every this many sample sets (0 = never).
    pub counters_every_sets: u32,
    /// Whether streaming is on at start.
    pub streaming_at_start: bool,
    /// Where the taxels are and how large, for force and centre of pressure: every pad's until
    /// one is set for it (saved with its calibration, or `SetPadGeometry`).
    pub geometry: PadGeometry,
    /// When the pad counts as in contact.
    pub contact: ContactConfig,
}

impl DeviceConfig {
    /// Counters every 100 sets, streaming at start, the article's pad, the default contact
    /// thresholds.
    pub const DEFAULT: DeviceConfig = DeviceConfig {
        counters_every_sets: 100,
        streaming_at_start: true,
        geometry: PadGeometry::ARTICLE,
        contact: ContactConfig::DEFAULT,
    };
}

impl Default for DeviceConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// What the application remembers about one pad between sample sets.
struct PadReporting {
    channel: Option<u8>,
    temperature_sensor: TemperatureSensor,
    calibration_source: CalibrationSource,
    force_and_contact: ForceAndContact,
    last_converter_reinits: u32,
    last_temperature_origin: Option<TemperatureOrigin>,
    announced_generation: Option<u32>,
    // A tare was running at the pad's last sample set.
    tare_running: bool,
}

impl PadReporting {
    fn new(slot: &PadSlot, calibration_source: CalibrationSource, config: &DeviceConfig) -> Self {
        Self {
            channel: slot.channel.map(|channel| channel.index()),
            temperature_sensor: match slot.temperature {
                PadTemperature::Own(address) => TemperatureSensor::OwnTmp117 {
                    address: address.seven_bit(),
                },
                PadTemperature::Shared(address) => TemperatureSensor::SharedTmp117 {
                    address: address.seven_bit(),
                },
                PadTemperature::DieOnly => TemperatureSensor::DieOnly,
            },
            calibration_source,
            force_and_contact: ForceAndContact::new(
                PadRole::Unspecified,
                config.geometry,
                config.contact,
            ),
            last_converter_reinits: 0,
            last_temperature_origin: None,
            announced_generation: None,
            tare_running: false,
        }
    }
}

/// The device application: the acquisition loop plus the protocol.
pub struct Device<A, P> {
    control: A,
    persistence: P,
    identity: DeviceIdentity,
    config: DeviceConfig,
    streaming: bool,
    text_mode: bool,
    host_connected: bool,
    pending_tare: Option<PendingTare>,
    host_counters: HostCounters,
    sets_since_counters: u32,
    announce_flash_corrupt: bool,
    pads: heapless::Vec<PadReporting, MAX_PADS>,
}

/// A tare command waiting for its pads to finish.
#[derive(Clone, Copy)]
struct PendingTare {
    request_id: u16,
    // The one pad tared, or every pad.
    pad: Option<usize>,
}

/// Every taxel of a pad, as a mask (bit n: taxel n).
const ALL_TAXELS_MASK: u8 = (1 << model_core::TAXEL_COUNT) - 1;

/// The pad whose calibration the Info frame shows.
const FIRST_PAD: usize = 0;

impl<A: DeviceControl, P: CalibrationPersistence> Device<A, P> {
    /// The application around an acquisition loop whose models already hold the calibrations
    /// that `calibration_sources` describe, pad by pad; `slots` says where each of the loop's
    /// pads is.
    pub fn new(
        control: A,
        persistence: P,
        identity: DeviceIdentity,
        calibration_sources: &[CalibrationSource],
        slots: &[PadSlot],
        config: DeviceConfig,
    ) -> Self {
        let mut pads = heapless::Vec::new();
        for (index, slot) in slots.iter().take(control.pad_count()).enumerate() {
            let source = calibration_sources
                .get(index)
                .copied()
                .unwrap_or(CalibrationSource::Defaults);
            // Cannot fail: at most MAX_PADS slots are taken.
            let _ = pads.push(PadReporting::new(slot, source, &config));
        }
        let announce_flash_corrupt = pads.iter().any(|pad: &PadReporting| {
            pad.calibration_source == CalibrationSource::DefaultsAfterCorruptFlash
        });
        Self {
            control,
            persistence,
            identity,
            config,
            streaming: config.streaming_at_start,
            text_mode: false,
            host_connected: false,
            pending_tare: None,
            host_counters: HostCounters::default(),
            sets_since_counters: 0,
            announce_flash_corrupt,
            pads,
        }
    }

    /// The acquisition loop (and models) under control.
    pub fn control(&self) -> &A {
        &self.control
    }

    /// The acquisition loop, mutably (tests, fault injection).
    pub fn control_mut(&mut self) -> &mut A {
        &mut self.control
    }

    /// The persistence backend.
    pub fn persistence_mut(&mut self) -> &mut P {
        &mut self.persistence
    }

    /// Host-side counters.
    pub fn host_counters(&self) -> HostCounters {
        self.host_counters
    }

    /// Whether samples are being streamed.
    pub fn streaming(&self) -> bool {
        self.streaming
    }

    /// What must survive an MCU-only reset: every pad's baselines and tier, with its channel.
    pub fn retained_state(&self) -> RetainedState {
        let mut pads = [None; MAX_PADS];
        for (index, (slot, reporting)) in pads.iter_mut().zip(&self.pads).enumerate() {
            *slot = self.control.pad(index).map(|pad| RetainedPad {
                channel: reporting.channel,
                baselines: pad.baseline_records(),
                tier: pad.tier(),
            });
        }
        RetainedState { pads }
    }

    /// The record to keep in no-init RAM: [`Self::retained_state`] encoded. The caller writes
    /// it only where it differs from what the RAM holds (comparing the bytes costs less RAM than
    /// keeping a copy of the state here).
    pub fn retained_record(&self) -> [u8; RETAINED_LEN] {
        self.retained_state().encode()
    }

    /// The info frame as of now (calibration and tier: the first pad's).
    pub fn info(&self) -> InfoFrame {
        let first = self.control.pad(FIRST_PAD);
        InfoFrame {
            protocol_version: PROTOCOL_VERSION,
            firmware_version: self.identity.firmware_version,
            board_serial: self.identity.board_serial,
            calibration_id: first.map_or(0, |pad| pad.calibration().id()),
            calibration_source: self.calibration_source(FIRST_PAD),
            rate: self.control.sample_rate(),
            model_tier: first.map_or(Tier::default(), PadModel::tier),
            streaming: self.streaming,
            text_mode: self.text_mode,
            pad_count: u8::try_from(self.control.pad_count()).unwrap_or(u8::MAX),
            clock_us_per_s: self.identity.clock_us_per_s,
        }
    }

    /// Where a pad's calibration came from (`Defaults` for a pad that does not exist).
    fn calibration_source(&self, pad: usize) -> CalibrationSource {
        self.pads
            .get(pad)
            .map_or(CalibrationSource::Defaults, |reporting| {
                reporting.calibration_source
            })
    }

    /// Pad `pad`'s role and geometry from now on (boot: what was saved with its calibration);
    /// false for a pad that does not exist.
    pub fn set_pad_geometry(&mut self, pad: usize, role: PadRole, geometry: PadGeometry) -> bool {
        match self.pads.get_mut(pad) {
            Some(reporting) => {
                reporting.force_and_contact.set_geometry(role, geometry);
                true
            }
            None => false,
        }
    }

    /// Pad `pad`'s role and geometry, `None` for a pad that does not exist.
    pub fn pad_geometry(&self, pad: usize) -> Option<(PadRole, PadGeometry)> {
        self.pads.get(pad).map(|reporting| {
            let pad = &reporting.force_and_contact;
            (pad.role(), *pad.geometry())
        })
    }

    /// A pad's description, `None` for a pad that does not exist.
    pub fn pad_info(&self, pad: PadIndex) -> Option<PadInfoFrame> {
        let index = usize::from(pad.get());
        let model = self.control.pad(index)?;
        let reporting = self.pads.get(index)?;
        Some(PadInfoFrame {
            pad,
            channel: reporting.channel,
            temperature_sensor: reporting.temperature_sensor,
            calibration_id: model.calibration().id(),
            calibration_source: reporting.calibration_source,
            model_tier: model.tier(),
            role: reporting.force_and_contact.role(),
            taxels: *reporting.force_and_contact.geometry().taxels(),
        })
    }

    /// One sample set with everything around it: requests received since the last step are
    /// applied first, then every pad is read in turn and its frames are queued as soon as it is
    /// read.
    pub async fn step<H: HostPort>(&mut self, host: &mut H) {
        self.step_observed(host, |_| {}).await;
    }

    /// [`Device::step`], handing every pad's sample to `observe` as it is read (the simulated
    /// device and tests look at them; the firmware keeps none, so that no sample set stays in
    /// the task's state across the other pads' reads).
    pub async fn step_observed<H: HostPort>(
        &mut self,
        host: &mut H,
        mut observe: impl FnMut(&ProcessedSample),
    ) {
        // Read once per step: asking the port again for every frame costs a system call on
        // the desktop's pseudo-terminal and tells nothing new within one cycle.
        let connected = host.host_connected();
        let newly_connected = connected && !self.host_connected;
        self.host_connected = connected;
        if newly_connected {
            self.send(host, Outgoing::Frame(DeviceFrame::Info(self.info())));
            if self.announce_flash_corrupt {
                self.announce_flash_corrupt = false;
                self.send_event(host, 0, DeviceEvent::CalibrationFlashCorrupt);
            }
        }
        while let Some(event) = host.try_receive() {
            match event {
                HostInputEvent::Request(request) => {
                    let was_text_mode = self.text_mode;
                    if let Some(reply) = self.handle(request).await {
                        self.send(host, Outgoing::Frame(DeviceFrame::Reply(reply)));
                    }
                    if self.text_mode && !was_text_mode {
                        self.send(host, Outgoing::CsvHeader);
                    }
                }
                HostInputEvent::ErrorReply(reply) => {
                    self.send(host, Outgoing::Frame(DeviceFrame::Reply(reply)));
                }
                HostInputEvent::Rejected => {
                    self.host_counters.host_frames_rejected =
                        self.host_counters.host_frames_rejected.saturating_add(1);
                }
                HostInputEvent::UnsupportedVersion => {
                    self.host_counters.host_frames_rejected =
                        self.host_counters.host_frames_rejected.saturating_add(1);
                    self.send(host, Outgoing::Frame(DeviceFrame::Info(self.info())));
                }
                HostInputEvent::LeaveTextMode => self.text_mode = false,
            }
        }
        for pad in 0..self.control.pad_count() {
            if let Some(sample) = self.control.read_pad(pad).await {
                self.after_pad(host, &sample);
                observe(&sample);
            }
        }
        self.control.finish_set().await;
        self.after_set(host);
    }

    /// Events, the sample frame and contact of one pad's sample.
    fn after_pad<H: HostPort>(&mut self, host: &mut H, sample: &ProcessedSample) {
        let index = usize::from(sample.pad);
        let (Some(wire_pad), Some(model)) = (PadIndex::new(sample.pad), self.control.pad(index))
        else {
            return;
        };
        let Some(reporting) = self.pads.get_mut(index) else {
            return;
        };
        let mut events: heapless::Vec<DeviceEvent, 3> = heapless::Vec::new();
        let reinits = sample.counters.converter_reinits;
        if reinits != reporting.last_converter_reinits {
            reporting.last_converter_reinits = reinits;
            let _ = events.push(DeviceEvent::ConverterReinitialised {
                pad: wire_pad,
                reinit_count: reinits,
            });
        }
        if reporting.last_temperature_origin != Some(sample.temperature_origin) {
            if reporting.last_temperature_origin.is_some() {
                let _ = events.push(DeviceEvent::TemperatureSourceChanged {
                    pad: wire_pad,
                    source: wire_temperature_source(sample, model),
                });
            }
            reporting.last_temperature_origin = Some(sample.temperature_origin);
        }
        let contact = reporting
            .force_and_contact
            .update(&sample.output.taxels, sample.timestamp_us);
        let frame = self.streaming.then(|| {
            let summary = pad_summary(&contact);
            sample_frame(sample, model, wire_pad, summary)
        });
        // A tare, a restore or a new calibration installs baselines and changes the generation
        // (tracking does not): whatever installed them, a recording host learns it after this
        // pad's sample (computed before the change) and before the first sample computed with
        // them. At the first sample only baselines restored at boot are news.
        let generation = model.baseline_generation();
        let mut tare_finished = None;
        if reporting.announced_generation != Some(generation) {
            let first_look = reporting.announced_generation.is_none();
            reporting.announced_generation = Some(generation);
            let tared_mask = (0u8..)
                .zip(&model.baseline_records())
                .filter(|(_, baseline)| baseline.is_some())
                .fold(0u8, |mask, (taxel, _)| mask | (1 << taxel));
            if !first_look || tared_mask != 0 {
                tare_finished = Some(DeviceEvent::TareFinished {
                    pad: wire_pad,
                    tared_mask,
                });
            }
        }
        // A tare that just finished without every taxel says which taxels it could not tare.
        let tare_running = matches!(model.tare_status(), TareStatus::Running { .. });
        let tare_refused = match model.tare_status() {
            TareStatus::Finished { tared_mask } if reporting.tare_running && !tare_running => {
                let refused_mask = !tared_mask & ALL_TAXELS_MASK;
                (refused_mask != 0).then_some(DeviceEvent::TareRefused {
                    pad: wire_pad,
                    refused_mask,
                })
            }
            _ => None,
        };
        reporting.tare_running = tare_running;
        for event in events {
            self.send_event(host, sample.timestamp_us, event);
        }
        if let Some(frame) = frame {
            let outgoing = if self.text_mode {
                Outgoing::CsvLine(frame)
            } else {
                Outgoing::Frame(DeviceFrame::Sample(frame))
            };
            if !self.send(host, outgoing) {
                self.host_counters.sample_frames_dropped =
                    self.host_counters.sample_frames_dropped.saturating_add(1);
            }
        }
        if let Some(event) = contact.event {
            let (timestamp_us, event) = match event {
                ContactEvent::Started { timestamp_us } => {
                    (timestamp_us, DeviceEvent::ContactStarted { pad: wire_pad })
                }
                ContactEvent::Ended { timestamp_us } => {
                    (timestamp_us, DeviceEvent::ContactEnded { pad: wire_pad })
                }
            };
            self.send_event(host, timestamp_us, event);
        }
        for event in [tare_refused, tare_finished].into_iter().flatten() {
            self.send_event(host, sample.timestamp_us, event);
        }
    }

    /// The reply to a tare every pad it tares finished, and the periodic counters.
    fn after_set<H: HostPort>(&mut self, host: &mut H) {
        if let Some(PendingTare { request_id, pad }) = self.pending_tare {
            if let Some(result) = self.tare_result(pad) {
                self.pending_tare = None;
                self.send(
                    host,
                    Outgoing::Frame(DeviceFrame::Reply(ReplyFrame { request_id, result })),
                );
            }
        }
        self.sets_since_counters = self.sets_since_counters.wrapping_add(1);
        if self.config.counters_every_sets != 0
            && self.sets_since_counters >= self.config.counters_every_sets
        {
            self.sets_since_counters = 0;
            let counters = counters_frame(&self.control.counters(), &self.host_counters);
            self.send_status(host, DeviceFrame::Counters(counters));
        }
    }

    /// The reply to a tare once every pad it tares (`only`, or every pad) finished it (`None`
    /// while one is still averaging): Ack when every taxel of those pads was tared, else why not.
    fn tare_result(&self, only: Option<usize>) -> Option<Result<ReplyPayload, ErrorCode>> {
        let mut all_tared = true;
        let mut not_still = false;
        let pads = match only {
            Some(pad) => pad..pad.saturating_add(1),
            None => 0..self.control.pad_count(),
        };
        for pad in pads {
            let model = self.control.pad(pad)?;
            let TareStatus::Finished { tared_mask } = model.tare_status() else {
                return None;
            };
            all_tared &= tared_mask == 0b1111;
            not_still |= model
                .last_tare_errors()
                .iter()
                .any(|error| matches!(error, Some(BaselineError::NotStill { .. })));
        }
        Some(if all_tared {
            Ok(ReplyPayload::Ack)
        } else if not_still {
            Err(ErrorCode::TareNotStill)
        } else {
            Err(ErrorCode::TareFailed)
        })
    }

    fn send_event<H: HostPort>(&mut self, host: &mut H, timestamp_us: u64, event: DeviceEvent) {
        self.send_status(
            host,
            DeviceFrame::Event(EventFrame {
                timestamp_us,
                event,
            }),
        );
    }

    /// Status frames (counters, events) are not sent in text mode, where they would garble the
    /// CSV a terminal or plotter shows.
    fn send_status<H: HostPort>(&mut self, host: &mut H, frame: DeviceFrame) {
        if !self.text_mode {
            self.send(host, Outgoing::Frame(frame));
        }
    }

    /// Queues something for the host; `false` (and counted) when it was dropped.
    fn send<H: HostPort>(&mut self, host: &mut H, outgoing: Outgoing) -> bool {
        let sent = self.host_connected && host.try_send(outgoing).is_ok();
        if !sent {
            self.host_counters.frames_dropped_no_host =
                self.host_counters.frames_dropped_no_host.saturating_add(1);
        }
        sent
    }

    /// Applies one request; `None` when the reply comes later (a tare).
    pub async fn handle(&mut self, request: Request) -> Option<ReplyFrame> {
        let request_id = request.request_id;
        let result = match request.command.check_arguments() {
            Err(code) => Err(code),
            Ok(()) => self.apply(request_id, request.command).await?,
        };
        Some(ReplyFrame { request_id, result })
    }

    /// Sets every pad's tier to the one `choose` picks for it, or none: when `choose` has no
    /// tier for one pad, or one pad's calibration cannot provide its tier, every pad keeps the
    /// tier it had (NotSupported, as on a board without pads). Returns the first pad's tier.
    fn set_tiers(
        &mut self,
        mut choose: impl FnMut(&PadModel) -> Option<Tier>,
    ) -> Result<Tier, ErrorCode> {
        // (pad, tier before, tier chosen) for every pad the loop holds.
        let mut changes: heapless::Vec<(usize, Tier, Tier), MAX_PADS> = heapless::Vec::new();
        for pad in 0..self.control.pad_count() {
            if let Some(model) = self.control.pad(pad) {
                let tier = choose(model).ok_or(ErrorCode::NotSupported)?;
                // Cannot fail: the loop holds at most MAX_PADS pads.
                let _ = changes.push((pad, model.tier(), tier));
            }
        }
        for (done, &(pad, _, tier)) in changes.iter().enumerate() {
            let Some(model) = self.control.pad_mut(pad) else {
                continue;
            };
            if model.set_tier(tier).is_err() {
                for &(changed, previous, _) in changes.iter().take(done) {
                    if let Some(model) = self.control.pad_mut(changed) {
                        // The tier was in use on this pad a moment ago.
                        let _ = model.set_tier(previous);
                    }
                }
                return Err(ErrorCode::NotSupported);
            }
        }
        changes
            .first()
            .map(|&(_, _, tier)| tier)
            .ok_or(ErrorCode::NotSupported)
    }

    /// Saves the pads' calibrations. A pad on the bus itself (no multiplexer) gets a record for
    /// every pad, the format earlier firmware reads; pads behind a multiplexer get one record
    /// each, under their channel (a record for every pad would also replace the calibration of
    /// a pad unplugged at the time). Each record is saved whole or not at all; if one fails, the
    /// pads before it are saved, the others keep what flash held, and the reply is FlashError.
    async fn save_calibrations(&mut self) -> Result<ReplyPayload, ErrorCode> {
        if self.control.pad_count() == 0 {
            return Err(ErrorCode::NotSupported);
        }
        for pad in 0..self.control.pad_count() {
            let (Some(model), Some(reporting)) = (self.control.pad(pad), self.pads.get(pad)) else {
                continue;
            };
            let scope = match reporting.channel {
                None => RecordScope::EveryPad,
                Some(channel) => RecordScope::Pad(channel),
            };
            let (role, geometry) = (
                reporting.force_and_contact.role(),
                *reporting.force_and_contact.geometry(),
            );
            let record = PadRecord {
                calibration: model.calibration().to_spec(),
                role,
                geometry,
            };
            self.persistence
                .save(scope, &record)
                .await
                .map_err(|PersistenceFailed| ErrorCode::FlashError)?;
            if let Some(reporting) = self.pads.get_mut(pad) {
                reporting.calibration_source = CalibrationSource::Flash;
            }
        }
        Ok(ReplyPayload::Ack)
    }

    async fn apply(
        &mut self,
        request_id: u16,
        command: Command,
    ) -> Option<Result<ReplyPayload, ErrorCode>> {
        let result = match command {
            Command::Info => Ok(ReplyPayload::Info(self.info())),
            Command::ReadCounters => Ok(ReplyPayload::Counters(counters_frame(
                &self.control.counters(),
                &self.host_counters,
            ))),
            Command::StartStreaming => {
                self.streaming = true;
                Ok(ReplyPayload::Ack)
            }
            Command::StopStreaming => {
                self.streaming = false;
                Ok(ReplyPayload::Ack)
            }
            Command::SetRate { rate } => {
                self.control.set_sample_rate(rate);
                Ok(ReplyPayload::Ack)
            }
            Command::Tare { sample_sets, pad } => {
                let pad = pad.map(|pad| usize::from(pad.get()));
                if self.pending_tare.is_some() {
                    Err(ErrorCode::Busy)
                } else if self.control.pad_count() == 0 {
                    Err(ErrorCode::NotSupported)
                } else if pad.is_some_and(|pad| pad >= self.control.pad_count()) {
                    Err(ErrorCode::InvalidArgument)
                } else {
                    for index in 0..self.control.pad_count() {
                        if pad.is_none_or(|pad| pad == index) {
                            if let Some(model) = self.control.pad_mut(index) {
                                model.start_tare(sample_sets);
                            }
                        }
                    }
                    self.pending_tare = Some(PendingTare { request_id, pad });
                    return None;
                }
            }
            Command::SetModelTier { tier } => {
                self.set_tiers(|_| Some(tier)).map(|_| ReplyPayload::Ack)
            }
            // Each pad chooses on its own calibration's evidence; none changes unless all fit.
            Command::SetUseCase(use_case) => self
                .set_tiers(|model| {
                    model
                        .select_tier_for(&use_case)
                        .ok()
                        .map(|choice| choice.tier)
                })
                .map(ReplyPayload::ModelTier),
            Command::ReadCalibration { pad, taxel_index } => {
                match self.control.pad(usize::from(pad.get())) {
                    Some(model) => calibration_record(model.calibration(), pad, taxel_index)
                        .map(ReplyPayload::Calibration)
                        .map_err(|_| ErrorCode::InvalidArgument),
                    None => Err(ErrorCode::InvalidArgument),
                }
            }
            Command::WriteCalibration(record) => {
                let index = usize::from(record.pad.get());
                let updated = taxel_calibration_spec(&record.calibration)
                    .ok()
                    .zip(self.control.pad(index))
                    .and_then(|(spec, model)| {
                        let calibration = model.calibration().clone();
                        let taxel = usize::from(record.taxel_index);
                        calibration
                            .with_taxel(taxel, &spec, record.calibration_id)
                            .ok()
                    });
                match (
                    updated,
                    self.control.pad_mut(index),
                    self.pads.get_mut(index),
                ) {
                    (Some(calibration), Some(model), Some(reporting)) => {
                        model.set_calibration(calibration);
                        reporting.calibration_source = CalibrationSource::Host;
                        Ok(ReplyPayload::Ack)
                    }
                    _ => Err(ErrorCode::InvalidArgument),
                }
            }
            Command::SaveCalibration => self.save_calibrations().await,
            Command::RestoreDefaults => {
                for pad in 0..self.control.pad_count() {
                    if let Some(model) = self.control.pad_mut(pad) {
                        model.set_calibration(Calibration::default());
                    }
                }
                for reporting in self.pads.iter_mut() {
                    reporting.calibration_source = CalibrationSource::Defaults;
                }
                Ok(ReplyPayload::Ack)
            }
            Command::SetTextMode { enabled } => {
                self.text_mode = enabled;
                Ok(ReplyPayload::Ack)
            }
            Command::ReadBaseline { pad, taxel_index } => {
                let records = self
                    .control
                    .pad(usize::from(pad.get()))
                    .map(PadModel::baseline_records);
                match records
                    .as_ref()
                    .and_then(|records| records.get(usize::from(taxel_index)))
                {
                    Some(record) => Ok(ReplyPayload::Baseline(TaxelBaselineWire {
                        pad,
                        taxel_index,
                        baseline: record.as_ref().map(baseline_wire),
                    })),
                    None => Err(ErrorCode::InvalidArgument),
                }
            }
            Command::PadInfo { pad } => self
                .pad_info(pad)
                .map(ReplyPayload::PadInfo)
                .ok_or(ErrorCode::InvalidArgument),
            Command::SetPadGeometry(record) => match record.geometry() {
                Ok(geometry)
                    if self.set_pad_geometry(
                        usize::from(record.pad.get()),
                        record.role,
                        geometry,
                    ) =>
                {
                    Ok(ReplyPayload::Ack)
                }
                _ => Err(ErrorCode::InvalidArgument),
            },
        };
        Some(result)
    }
}

/// Encodes something to send into `buffer` (at least [`MAX_OUTGOING_LEN`] bytes); returns the
/// length, or `None` if it does not fit (never for the device's own frames).
pub fn encode_outgoing(outgoing: &Outgoing, buffer: &mut [u8]) -> Option<usize> {
    match outgoing {
        Outgoing::Frame(frame) => wire::encode_frame(frame, buffer).ok(),
        Outgoing::CsvHeader => {
            let header = wire::CSV_HEADER.as_bytes();
            let length = header.len() + 2;
            let (line, line_end) = buffer.get_mut(..length)?.split_last_chunk_mut::<2>()?;
            line.copy_from_slice(header);
            *line_end = *b"\r\n";
            Some(length)
        }
        Outgoing::CsvLine(sample) => {
            let mut line: heapless::String<{ wire::CSV_LINE_MAX_LEN }> = heapless::String::new();
            wire::format_csv_line(sample, &mut line).ok()?;
            let bytes = line.as_bytes();
            let destination = buffer.get_mut(..bytes.len())?;
            destination.copy_from_slice(bytes);
            Some(bytes.len())
        }
    }
}
