//! Each device's health as a `diagnostic_msgs/msg/DiagnosticStatus`: the device's counters, its
//! pads' temperature sources and calibrations, what the link lost, what the bridge dropped, and
//! the clock mapping. Level: ERROR when the device stopped, WARN when anything was lost or
//! dropped or a pad runs on a fallback temperature or a default calibration, else OK.

use taxel_host::device_words::{board_serial_hex, calibration_source_words};
use taxel_ros2::{DiagnosticLevel, DiagnosticStatus, KeyValue};
use wire::{CalibrationSource, TemperatureSensor, TemperatureSource};

use crate::device_reader::{DeviceHealth, ReaderState};

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
        KeyValue::new("frames published or queued", health.queued),
        KeyValue::new(
            "frames dropped by the bridge (queue full)",
            health.queue_dropped,
        ),
        KeyValue::new(
            "frames dropped by the bridge (waiting for the clock)",
            health.waiting_dropped,
        ),
    ];
    let mut warnings = Vec::new();
    if let Some(counters) = &health.counters {
        values.extend([
            KeyValue::new("device: sample sets not sent", counters.dropped_sample_sets),
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
    let lost = health.accounting.lost_on_link()
        + health.accounting.device_dropped()
        + health.queue_dropped
        + health.waiting_dropped;
    if lost > 0 {
        warnings.push(format!("{lost} frames lost or dropped"));
    }
    let (level, message) = match &health.state {
        ReaderState::Stopped(reason) => (DiagnosticLevel::Error, reason.clone()),
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
