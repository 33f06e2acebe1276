//! What a device reports besides its sample sets (contact started or ended, a tare finished or
//! refused for some taxels, the temperature source changed, the converter re-initialised, the calibration in flash
//! corrupt), as the Python `DeviceEvent`: its kind, pad, device time, arrival and fields.

use pyo3::prelude::*;
use pyo3::types::PyDict;
use taxel_host::csv_format::temperature_source_name;
use taxel_host::device_words::event_words;
use wire::{DeviceEvent as WireEvent, EventFrame};

/// A device event with the device it came from and its arrival.
#[derive(Debug, Clone, PartialEq)]
pub struct EventRecord {
    /// The device, numbered in the order the devices were given (0 for a single device).
    pub device: usize,
    /// The event as the device sent it.
    pub frame: EventFrame,
    /// When it arrived, Unix seconds on the host clock.
    pub arrival_unix_s: f64,
}

/// The names of the taxels whose bits are set in `mask`.
fn taxel_names(mask: u8) -> Vec<&'static str> {
    model_core::TAXEL_NAMES
        .iter()
        .enumerate()
        .filter(|(taxel, _)| mask & (1 << taxel) != 0)
        .map(|(_, name)| *name)
        .collect()
}

/// The kind's name, its pad and its fields.
fn described(event: &WireEvent) -> (&'static str, Option<u8>, Vec<(&'static str, FieldValue)>) {
    match *event {
        WireEvent::ConverterReinitialised { pad, reinit_count } => (
            "converter_reinitialised",
            Some(pad.get()),
            vec![("reinit_count", FieldValue::Integer(u64::from(reinit_count)))],
        ),
        WireEvent::TemperatureSourceChanged { pad, source } => (
            "temperature_source_changed",
            Some(pad.get()),
            vec![("source", FieldValue::Text(temperature_source_name(source)))],
        ),
        WireEvent::CalibrationFlashCorrupt => ("calibration_flash_corrupt", None, Vec::new()),
        WireEvent::TareFinished { pad, tared_mask } => (
            "tare_finished",
            Some(pad.get()),
            vec![
                ("tared_mask", FieldValue::Integer(u64::from(tared_mask))),
                ("tared", FieldValue::Taxels(taxel_names(tared_mask))),
            ],
        ),
        WireEvent::TareRefused { pad, refused_mask } => (
            "tare_refused",
            Some(pad.get()),
            vec![
                ("refused_mask", FieldValue::Integer(u64::from(refused_mask))),
                ("refused", FieldValue::Taxels(taxel_names(refused_mask))),
            ],
        ),
        WireEvent::ContactStarted { pad } => ("contact_started", Some(pad.get()), Vec::new()),
        WireEvent::ContactEnded { pad } => ("contact_ended", Some(pad.get()), Vec::new()),
    }
}

/// A field's value.
enum FieldValue {
    Integer(u64),
    Text(&'static str),
    Taxels(Vec<&'static str>),
}

/// Something a device reported: contact started or ended on a pad, a tare finished (or was
/// refused for some taxels), the
/// temperature source changed, the converter was re-initialised after an error (samples were
/// lost), the calibration in flash was found corrupt at boot.
#[pyclass(frozen, module = "taxel")]
pub struct DeviceEvent {
    record: EventRecord,
}

impl DeviceEvent {
    /// The Python object of an event.
    pub fn new(record: EventRecord) -> Self {
        Self { record }
    }
}

#[pymethods]
impl DeviceEvent {
    /// What happened: ``"contact_started"``, ``"contact_ended"``, ``"tare_finished"``,
    /// ``"tare_refused"``, ``"temperature_source_changed"``, ``"converter_reinitialised"`` or
    /// ``"calibration_flash_corrupt"``.
    #[getter]
    fn kind(&self) -> &'static str {
        described(&self.record.frame.event).0
    }

    /// The pad it concerns (``None`` for an event of the whole device).
    #[getter]
    fn pad(&self) -> Option<u8> {
        described(&self.record.frame.event).1
    }

    /// The device (0 for :class:`taxel.Device`; its index for :class:`taxel.Devices`).
    #[getter]
    fn device(&self) -> usize {
        self.record.device
    }

    /// The device clock when it happened, µs since boot (a contact event has the time of the
    /// sample set that confirmed it).
    #[getter]
    fn device_time_us(&self) -> u64 {
        self.record.frame.timestamp_us
    }

    /// The device clock when it happened, seconds since boot.
    #[getter]
    fn device_time_s(&self) -> f64 {
        self.record.frame.timestamp_us as f64 / 1e6
    }

    /// The host clock when it arrived, seconds since the Unix epoch.
    #[getter]
    fn host_time_s(&self) -> f64 {
        self.record.arrival_unix_s
    }

    /// The kind's own fields: ``tared_mask`` and ``tared`` (taxel names) of
    /// ``tare_finished``, ``refused_mask`` and ``refused`` of ``tare_refused`` (the taxels that
    /// got no new baseline: loaded, moving, open or shorted), ``source`` of ``temperature_source_changed``, ``reinit_count`` of
    /// ``converter_reinitialised``; empty for the others.
    #[getter]
    fn fields<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for (name, value) in described(&self.record.frame.event).2 {
            match value {
                FieldValue::Integer(value) => dict.set_item(name, value)?,
                FieldValue::Text(value) => dict.set_item(name, value)?,
                FieldValue::Taxels(value) => dict.set_item(name, value)?,
            }
        }
        Ok(dict)
    }

    /// The event in words, as ``taxel record`` prints it.
    #[getter]
    fn text(&self) -> String {
        event_words(&self.record.frame)
    }

    /// Whether both are the same event of the same device, arrived at the same time.
    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other
            .downcast::<DeviceEvent>()
            .is_ok_and(|other| other.get().record == self.record)
    }

    /// A short description.
    fn __repr__(&self) -> String {
        let (kind, pad, _) = described(&self.record.frame.event);
        format!(
            "DeviceEvent(kind={kind:?}, device={}, pad={}, device_time_s={:.6})",
            self.record.device,
            pad.map_or("None".to_owned(), |pad| pad.to_string()),
            self.record.frame.timestamp_us as f64 / 1e6
        )
    }
}
