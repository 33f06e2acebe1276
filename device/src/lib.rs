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

pub use boot::{boot, boot_calibration, BoardConfig, BoardParts, BootReport, BootedDevice, BOARD};
pub use control::DeviceControl;
pub use convert::{
    baseline_record, baseline_wire, calibration_record, converter_rate, counters_frame,
    pad_summary, sample_frame, taxel_calibration_spec, wire_sample_rate, wire_temperature_source,
    CalibrationConversionError,
};
pub use host_input::{HostInput, HostInputEvent};
pub use persistence::{CalibrationPersistence, PersistenceFailed};
pub use retained::{boot_plan, BootPlan, ResetKind, RetainedState, RETAINED_LEN};
pub use supervisor::{Supervisor, SupervisorAction};

use acquisition::{ProcessedSample, TemperatureOrigin};
use model_core::{
    pad_force, BaselineError, BaselineRecord, Calibration, ContactConfig, ContactDetector,
    ContactEvent, PadGeometry, TareStatus, TAXEL_COUNT,
};
use wire::{
    CalibrationSource, Command, DeviceEvent, DeviceFrame, ErrorCode, EventFrame, FirmwareVersion,
    InfoFrame, PadIndex, ReplyFrame, ReplyPayload, Request, SampleFrame, TaxelBaselineWire,
    PROTOCOL_VERSION,
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
}

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
    /// Sample sets produced while streaming that were not sent (no host had the port open, or
    /// its queue was full): among `frames_dropped_no_host`, the ones that were sample sets.
    pub sample_sets_dropped: u32,
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
    /// Where the taxels are and how large, for force and centre of pressure.
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

/// The device application: the acquisition loop plus the protocol.
pub struct Device<A, P> {
    control: A,
    persistence: P,
    identity: DeviceIdentity,
    config: DeviceConfig,
    calibration_source: CalibrationSource,
    streaming: bool,
    text_mode: bool,
    host_connected: bool,
    pending_tare: Option<u16>,
    host_counters: HostCounters,
    sets_since_counters: u32,
    last_converter_reinits: u32,
    last_temperature_origin: Option<TemperatureOrigin>,
    announce_flash_corrupt: bool,
    retained_written: Option<RetainedState>,
    announced_baselines: [Option<BaselineRecord>; TAXEL_COUNT],
    announced_generation: Option<u32>,
    contact: ContactDetector,
}

impl<A: DeviceControl, P: CalibrationPersistence> Device<A, P> {
    /// The application around an acquisition loop whose model already holds the calibration
    /// that `calibration_source` describes.
    pub fn new(
        control: A,
        persistence: P,
        identity: DeviceIdentity,
        calibration_source: CalibrationSource,
        config: DeviceConfig,
    ) -> Self {
        Self {
            control,
            persistence,
            identity,
            config,
            calibration_source,
            streaming: config.streaming_at_start,
            text_mode: false,
            host_connected: false,
            pending_tare: None,
            host_counters: HostCounters::default(),
            sets_since_counters: 0,
            last_converter_reinits: 0,
            last_temperature_origin: None,
            announce_flash_corrupt: calibration_source
                == CalibrationSource::DefaultsAfterCorruptFlash,
            retained_written: None,
            announced_baselines: [None; TAXEL_COUNT],
            announced_generation: None,
            contact: ContactDetector::new(config.contact),
        }
    }

    /// The acquisition loop (and model) under control.
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

    /// What must survive an MCU-only reset.
    pub fn retained_state(&self) -> RetainedState {
        RetainedState {
            baselines: self.control.pad().baseline_records(),
            tier: self.control.pad().tier(),
        }
    }

    /// The state to keep in no-init RAM when it changed since the last call (after a tare or a
    /// tier change), `None` otherwise: the sampling loop encodes and writes the record only then.
    pub fn retained_state_change(&mut self) -> Option<RetainedState> {
        let state = self.retained_state();
        if self.retained_written == Some(state) {
            return None;
        }
        self.retained_written = Some(state);
        Some(state)
    }

    /// The info frame as of now.
    pub fn info(&self) -> InfoFrame {
        InfoFrame {
            protocol_version: PROTOCOL_VERSION,
            firmware_version: self.identity.firmware_version,
            board_serial: self.identity.board_serial,
            calibration_id: self.control.pad().calibration().id(),
            calibration_source: self.calibration_source,
            rate: self.control.sample_rate(),
            model_tier: self.control.pad().tier(),
            streaming: self.streaming,
            text_mode: self.text_mode,
            pad_count: 1,
        }
    }

    /// One converter cycle with everything around it: requests received since the last step
    /// are applied first, then the cycle runs and its frames are queued.
    pub async fn step<H: HostPort>(&mut self, host: &mut H) -> ProcessedSample {
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
        let sample = self.control.cycle().await;
        self.after_cycle(host, &sample);
        sample
    }

    fn after_cycle<H: HostPort>(&mut self, host: &mut H, sample: &ProcessedSample) {
        let reinits = sample.counters.converter_reinits();
        if reinits != self.last_converter_reinits {
            self.last_converter_reinits = reinits;
            self.send_event(
                host,
                sample.timestamp_us,
                DeviceEvent::ConverterReinitialised {
                    reinit_count: reinits,
                },
            );
        }
        if self.last_temperature_origin != Some(sample.temperature_origin) {
            if self.last_temperature_origin.is_some() {
                let source = wire_temperature_source(sample, self.control.pad());
                self.send_event(
                    host,
                    sample.timestamp_us,
                    DeviceEvent::TemperatureSourceChanged { source },
                );
            }
            self.last_temperature_origin = Some(sample.temperature_origin);
        }
        if let (Some(request_id), TareStatus::Finished { tared_mask }) =
            (self.pending_tare, self.control.pad().tare_status())
        {
            self.pending_tare = None;
            let not_still = self
                .control
                .pad()
                .last_tare_errors()
                .iter()
                .any(|error| matches!(error, Some(BaselineError::NotStill { .. })));
            let result = if tared_mask == 0b1111 {
                Ok(ReplyPayload::Ack)
            } else if not_still {
                Err(ErrorCode::TareNotStill)
            } else {
                Err(ErrorCode::TareFailed)
            };
            self.send(
                host,
                Outgoing::Frame(DeviceFrame::Reply(ReplyFrame { request_id, result })),
            );
        }
        let force = pad_force(&sample.output.taxels, &self.config.geometry);
        let contact_event = self.contact.update(&force, sample.timestamp_us);
        if self.streaming {
            let summary = pad_summary(&force, self.contact.in_contact());
            let frame = sample_frame(sample, self.control.pad(), PadIndex::default(), summary);
            let outgoing = if self.text_mode {
                Outgoing::CsvLine(frame)
            } else {
                Outgoing::Frame(DeviceFrame::Sample(frame))
            };
            if !self.send(host, outgoing) {
                self.host_counters.sample_sets_dropped =
                    self.host_counters.sample_sets_dropped.saturating_add(1);
            }
        }
        if let Some(event) = contact_event {
            let (timestamp_us, event) = match event {
                ContactEvent::Started { timestamp_us } => (
                    timestamp_us,
                    DeviceEvent::ContactStarted {
                        pad: PadIndex::default(),
                    },
                ),
                ContactEvent::Ended { timestamp_us } => (
                    timestamp_us,
                    DeviceEvent::ContactEnded {
                        pad: PadIndex::default(),
                    },
                ),
            };
            self.send_event(host, timestamp_us, event);
        }
        // Only a tare, a restore or a new calibration changes the generation, so the records
        // are built and compared only then, not every cycle.
        let generation = self.control.pad().baseline_generation();
        if self.announced_generation != Some(generation) {
            self.announced_generation = Some(generation);
            let baselines = self.control.pad().baseline_records();
            if baselines != self.announced_baselines {
                // Whatever changed them (a tare at boot or on command, a restore after a
                // reset), a recording host learns it after this cycle's sample (computed
                // before the change) and before the first sample computed with them.
                self.announced_baselines = baselines;
                let tared_mask = (0u8..)
                    .zip(&baselines)
                    .filter(|(_, baseline)| baseline.is_some())
                    .fold(0u8, |mask, (taxel, _)| mask | (1 << taxel));
                self.send_event(
                    host,
                    sample.timestamp_us,
                    DeviceEvent::TareFinished { tared_mask },
                );
            }
        }
        self.sets_since_counters = self.sets_since_counters.wrapping_add(1);
        if self.config.counters_every_sets != 0
            && self.sets_since_counters >= self.config.counters_every_sets
        {
            self.sets_since_counters = 0;
            let counters = counters_frame(&sample.counters, &self.host_counters);
            self.send_status(host, DeviceFrame::Counters(counters));
        }
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
            Command::Tare { sample_sets } => {
                if self.pending_tare.is_some() {
                    Err(ErrorCode::Busy)
                } else {
                    self.control.pad_mut().start_tare(sample_sets);
                    self.pending_tare = Some(request_id);
                    return None;
                }
            }
            Command::SetModelTier { tier } => match self.control.pad_mut().set_tier(tier) {
                Ok(()) => Ok(ReplyPayload::Ack),
                Err(_) => Err(ErrorCode::NotSupported),
            },
            Command::SetUseCase(use_case) => {
                match self.control.pad_mut().apply_use_case(&use_case) {
                    Ok(choice) => Ok(ReplyPayload::ModelTier(choice.tier)),
                    Err(_) => Err(ErrorCode::NotSupported),
                }
            }
            Command::ReadCalibration { taxel_index } => {
                let calibration = self.control.pad().calibration();
                match calibration_record(calibration, taxel_index) {
                    Ok(record) => Ok(ReplyPayload::Calibration(record)),
                    Err(_) => Err(ErrorCode::InvalidArgument),
                }
            }
            Command::WriteCalibration(record) => {
                let updated = taxel_calibration_spec(&record.calibration)
                    .ok()
                    .and_then(|spec| {
                        let calibration = self.control.pad().calibration().clone();
                        let taxel = usize::from(record.taxel_index);
                        calibration
                            .with_taxel(taxel, &spec, record.calibration_id)
                            .ok()
                    });
                match updated {
                    Some(calibration) => {
                        self.control.pad_mut().set_calibration(calibration);
                        self.calibration_source = CalibrationSource::Host;
                        Ok(ReplyPayload::Ack)
                    }
                    None => Err(ErrorCode::InvalidArgument),
                }
            }
            Command::SaveCalibration => {
                let spec = self.control.pad().calibration().to_spec();
                match self.persistence.save(&spec).await {
                    Ok(()) => {
                        self.calibration_source = CalibrationSource::Flash;
                        Ok(ReplyPayload::Ack)
                    }
                    Err(PersistenceFailed) => Err(ErrorCode::FlashError),
                }
            }
            Command::RestoreDefaults => {
                self.control
                    .pad_mut()
                    .set_calibration(Calibration::default());
                self.calibration_source = CalibrationSource::Defaults;
                Ok(ReplyPayload::Ack)
            }
            Command::SetTextMode { enabled } => {
                self.text_mode = enabled;
                Ok(ReplyPayload::Ack)
            }
            Command::ReadBaseline { taxel_index } => {
                match self
                    .control
                    .pad()
                    .baseline_records()
                    .get(usize::from(taxel_index))
                {
                    Some(record) => Ok(ReplyPayload::Baseline(TaxelBaselineWire {
                        taxel_index,
                        baseline: record.as_ref().map(baseline_wire),
                    })),
                    None => Err(ErrorCode::InvalidArgument),
                }
            }
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
