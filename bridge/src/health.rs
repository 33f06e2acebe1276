//! Each device's health as a `diagnostic_msgs/msg/DiagnosticStatus`: the device's counters, its
//! pads' temperature sources and calibrations, what the link lost, what the bridge dropped, and
//! the clock mapping. Level: ERROR when the device stopped, WARN when anything was lost or
//! dropped, an item was stamped with its arrival for want of a clock estimate, or a pad runs on
//! a fallback temperature or a default calibration, else OK.

use taxel_host::clock_sync::ClockEstimate;
use taxel_host::device_words::{board_serial_hex, calibration_source_words};
use taxel_host::stream_accounting::StreamAccounting;
use taxel_host::worker::EndReason;
use taxel_ros2::{DiagnosticLevel, DiagnosticStatus, KeyValue};
use wire::{
    CalibrationSource, CountersFrame, InfoFrame, PadInfoFrame, TemperatureSensor, TemperatureSource,
};

/// Where a device's reading stands.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum ReaderState {
    /// Not open yet.
    #[default]
    Connecting,
    /// Streaming.
    Streaming,
    /// The device went away (the reason): its port is tried again until it is back.
    Reconnecting(String),
    /// Stopped: asked to, or the device went away or never answered (the reason).
    Stopped(String),
}

/// The reason of [`ReaderState::Stopped`] when the bridge stopped the device.
pub const STOPPED_WORDS: &str = "stopped";

impl ReaderState {
    /// The state after the device's stream ended for `reason`, when a device that went away
    /// is looked for again (`reconnect`) or not.
    pub fn after_end(reason: &EndReason, reconnect: bool) -> Self {
        match reason {
            EndReason::Disconnected(message) if reconnect => Self::Reconnecting(format!(
                "the device went away ({message}); looking for it again"
            )),
            _ => Self::ended(reason),
        }
    }

    /// The state after the device's stream ended for `reason`.
    pub fn ended(reason: &EndReason) -> Self {
        Self::Stopped(match reason {
            EndReason::Stopped => STOPPED_WORDS.to_owned(),
            EndReason::Disconnected(message) => format!("the device went away: {message}"),
            EndReason::Failed(message) => message.clone(),
        })
    }
}

/// One device's health as the bridge reports it.
#[derive(Debug, Clone, Default)]
pub struct DeviceHealth {
    /// The device's name (its port).
    pub name: String,
    /// Where reading stands.
    pub state: ReaderState,
    /// Its identity.
    pub info: Option<InfoFrame>,
    /// Each pad's place, temperature sensor and calibration.
    pub pads: Vec<PadInfoFrame>,
    /// The device's counters, as last sent.
    pub counters: Option<CountersFrame>,
    /// Sample frames received, lost on the link, dropped by the device: the session's
    /// accounting, as last read from the device's thread.
    pub accounting: StreamAccounting,
    /// Each pad's temperature source in its last sample, by pad index.
    pub temperature_sources: Vec<Option<TemperatureSource>>,
    /// The device's clock mapping now.
    pub clock: Option<ClockEstimate>,
    /// Sample frames published (each as a pressure cloud and a wrench, or a plain record).
    pub frames_published: u64,
    /// Sample frames and contact events stamped with their arrival because the device's clock
    /// had no estimate after the longest wait (`taxel_host::stamping::MAX_WAIT_US`).
    pub stamped_at_arrival: u64,
    /// Sample sets the bridge dropped because its queue was full: one queue for every device,
    /// so this is the count of all devices.
    pub sets_dropped_by_bridge: u64,
    /// Times the device went away and was read again (the accounting is the current
    /// connection's).
    pub reconnections: u64,
}

fn temperature_source_words(source: Option<TemperatureSource>) -> &'static str {
    match source {
        None => "no sample yet",
        Some(TemperatureSource::Tmp117) => "TMP117",
        Some(TemperatureSource::McuInternal) => "MCU die sensor (fallback)",
        Some(TemperatureSource::LastKnown) => "last known reading (no sensor answers)",
        Some(TemperatureSource::None) => "none",
    }
}

fn temperature_sensor_words(sensor: TemperatureSensor) -> String {
    match sensor {
        TemperatureSensor::OwnTmp117 { address } => format!("own TMP117 at 0x{address:02X}"),
        TemperatureSensor::SharedTmp117 { address } => {
            format!("shared TMP117 at 0x{address:02X}")
        }
        TemperatureSensor::DieOnly => "MCU die sensor only".to_owned(),
    }
}

/// The key of the sample sets the bridge dropped (queue full, every device's together).
pub const SETS_DROPPED_BY_BRIDGE_KEY: &str =
    "sample sets dropped by the bridge (queue full, all devices)";

/// The status of device `device` (named `taxel_bridge: device<d>` in the array).
pub fn device_status(device: usize, health: &DeviceHealth) -> DiagnosticStatus {
    let mut values = vec![
        KeyValue::new("port", &health.name),
        KeyValue::new("frames received", health.accounting.received()),
        KeyValue::new("frames lost on the link", health.accounting.lost_on_link()),
        KeyValue::new(
            "sample sets dropped by the device",
            health.accounting.device_dropped(),
        ),
        KeyValue::new("frames published", health.frames_published),
        KeyValue::new(SETS_DROPPED_BY_BRIDGE_KEY, health.sets_dropped_by_bridge),
        KeyValue::new(
            "frames and events stamped with their arrival (no clock estimate)",
            health.stamped_at_arrival,
        ),
        KeyValue::new("reconnections", health.reconnections),
    ];
    let mut warnings = Vec::new();
    if let Some(counters) = &health.counters {
        values.extend([
            KeyValue::new(
                "device: sample frames not sent (one per pad per set)",
                counters.dropped_sample_frames,
            ),
            KeyValue::new("device: frames not sent", counters.frames_dropped_no_host),
            KeyValue::new(
                "device: converter re-initialisations",
                counters.converter_reinits,
            ),
            KeyValue::new("device: I2C errors", counters.i2c_errors),
            KeyValue::new(
                "device: temperature-sensor errors",
                counters.temperature_sensor_errors,
            ),
            KeyValue::new(
                "device: bad frames from the host",
                counters.host_frames_rejected,
            ),
        ]);
    }
    if let Some(info) = &health.info {
        values.extend([
            KeyValue::new("calibration id", format!("{:#010x}", info.calibration_id)),
            KeyValue::new(
                "calibration source",
                calibration_source_words(info.calibration_source),
            ),
            KeyValue::new("pads", info.pad_count),
        ]);
    }
    for pad in &health.pads {
        let index = pad.pad.get();
        values.extend([
            KeyValue::new(
                &format!("pad{index} calibration id"),
                format!("{:#010x}", pad.calibration_id),
            ),
            KeyValue::new(
                &format!("pad{index} calibration source"),
                calibration_source_words(pad.calibration_source),
            ),
            KeyValue::new(
                &format!("pad{index} temperature sensor"),
                temperature_sensor_words(pad.temperature_sensor),
            ),
        ]);
        if matches!(
            pad.calibration_source,
            CalibrationSource::DefaultsAfterCorruptFlash
        ) {
            warnings.push(format!("pad{index}: calibration flash corrupt"));
        }
    }
    for (index, source) in health.temperature_sources.iter().enumerate() {
        values.push(KeyValue::new(
            &format!("pad{index} temperature source"),
            temperature_source_words(*source),
        ));
        if matches!(
            source,
            Some(TemperatureSource::McuInternal | TemperatureSource::LastKnown)
        ) {
            warnings.push(format!("pad{index}: temperature fallback"));
        }
    }
    match &health.clock {
        Some(clock) => values.extend([
            KeyValue::new(
                "clock offset (s)",
                format!("{:.6}", clock.offset_us as f64 / 1e6),
            ),
            KeyValue::new("clock drift (ppm)", format!("{:.1}", clock.drift_ppm)),
            KeyValue::new("clock uncertainty (us)", clock.uncertainty_us),
        ]),
        None => values.push(KeyValue::new("clock", "estimating")),
    }
    let lost_frames = health.accounting.lost_on_link() + health.accounting.device_dropped();
    if lost_frames > 0 {
        warnings.push(format!("{lost_frames} frames lost or dropped"));
    }
    if health.sets_dropped_by_bridge > 0 {
        warnings.push(format!(
            "{} sample sets dropped by the bridge",
            health.sets_dropped_by_bridge
        ));
    }
    if health.stamped_at_arrival > 0 {
        warnings.push(format!(
            "{} stamped with their arrival (no clock estimate)",
            health.stamped_at_arrival
        ));
    }
    let (level, message) = match &health.state {
        ReaderState::Stopped(reason) | ReaderState::Reconnecting(reason) => {
            (DiagnosticLevel::Error, reason.clone())
        }
        ReaderState::Connecting => (DiagnosticLevel::Stale, "connecting".to_owned()),
        ReaderState::Streaming if warnings.is_empty() => {
            (DiagnosticLevel::Ok, "streaming".to_owned())
        }
        ReaderState::Streaming => (DiagnosticLevel::Warn, warnings.join("; ")),
    };
    DiagnosticStatus {
        level,
        name: format!("taxel_bridge: device{device}"),
        message,
        hardware_id: health
            .info
            .as_ref()
            .map(board_serial_hex)
            .unwrap_or_default(),
        values,
    }
}
