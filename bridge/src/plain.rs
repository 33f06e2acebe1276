//! The plain mode (`--mode plain`): for Zenoh users without ROS, fixed little-endian records on
//! short key expressions, with no CDR, type hash or liveliness token. docs/BRIDGE.md lists the
//! layouts; Python reads a sample with `struct.unpack("<QIBBHfff4f4HfB3x", payload)`.
//!
//! | key expression | payload |
//! |---|---|
//! | `<prefix>/device<d>/pad<p>/sample` | [`SAMPLE_BYTES`] bytes, [`encode_sample`] |
//! | `<prefix>/device<d>/pad<p>/contact` | [`CONTACT_BYTES`] bytes, [`encode_contact`] |
//! | `<prefix>/device<d>/health` | JSON: the device's diagnostic status ([`health_json`]) |

use std::collections::HashMap;

use taxel_ros2::DiagnosticStatus;
use wire::SampleFrame;
use zenoh::bytes::Encoding;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::{Session, Wait};

use crate::health::{device_status, DeviceHealth};
use crate::publisher::FramePublisher;
use crate::publisher::Outgoing;

/// Bytes of one sample record.
pub const SAMPLE_BYTES: usize = 60;
/// Bytes of one contact record.
pub const CONTACT_BYTES: usize = 16;
/// The encoding a sample record is published with.
pub const SAMPLE_ENCODING: &str = "application/octet-stream;taxel-sample-v1";
/// The encoding a contact record is published with.
pub const CONTACT_ENCODING: &str = "application/octet-stream;taxel-contact-v1";

/// Summary bit: the pad is in contact.
pub const SUMMARY_CONTACT: u8 = 1 << 0;
/// Summary bit: some taxels were left out of force and centre (faulted).
pub const SUMMARY_PARTIAL: u8 = 1 << 1;

/// One sample frame as a record, little-endian, offsets in bytes:
/// 0 stamp (u64, ns since the Unix epoch, device time mapped onto the host clock),
/// 8 sequence (u32, the device's), 12 pad (u8), 13 summary bits (u8: [`SUMMARY_CONTACT`],
/// [`SUMMARY_PARTIAL`]), 14 zero (u16), 16 force (f32, N), 20 and 24 centre of pressure x and y
/// (f32, mm), 28 the four pressures (f32, kPa, C11 C12 C21 C22), 44 the four taxels' flags (u16),
/// 52 temperature (f32, °C), 56 temperature source (u8: 0 none, 1 TMP117, 2 MCU, 3 last known),
/// 57 zero (3 bytes). A value the device did not give (faulted taxel, no force, no centre, no
/// temperature) is NaN.
pub fn encode_sample(sample: &SampleFrame, stamp_ns: u64) -> [u8; SAMPLE_BYTES] {
    let mut bytes = [0u8; SAMPLE_BYTES];
    let mut put = |offset: usize, value: &[u8]| {
        bytes[offset..offset + value.len()].copy_from_slice(value);
    };
    put(0, &stamp_ns.to_le_bytes());
    put(8, &sample.sequence.to_le_bytes());
    put(12, &[sample.pad.get()]);
    let mut summary = 0;
    if sample.summary.contact {
        summary |= SUMMARY_CONTACT;
    }
    if sample.summary.partial {
        summary |= SUMMARY_PARTIAL;
    }
    put(13, &[summary]);
    put(
        16,
        &sample.summary.force_n.unwrap_or(f32::NAN).to_le_bytes(),
    );
    let [x_mm, y_mm] = sample
        .summary
        .centre_of_pressure_mm
        .unwrap_or([f32::NAN, f32::NAN]);
    put(20, &x_mm.to_le_bytes());
    put(24, &y_mm.to_le_bytes());
    for (index, taxel) in sample.taxels.iter().enumerate() {
        put(
            28 + 4 * index,
            &taxel.pressure_kpa.unwrap_or(f32::NAN).to_le_bytes(),
        );
        put(44 + 2 * index, &taxel.flags.to_le_bytes());
    }
    put(52, &sample.temperature_c.unwrap_or(f32::NAN).to_le_bytes());
    put(56, &[sample.temperature_source.code()]);
    bytes
}

/// A contact event as a record: 0 stamp (u64, ns since the Unix epoch), 8 pad (u8), 9 started
/// (u8: 1 started, 0 ended), 10 zero (6 bytes).
pub fn encode_contact(pad: u8, started: bool, stamp_ns: u64) -> [u8; CONTACT_BYTES] {
    let mut bytes = [0u8; CONTACT_BYTES];
    bytes[..8].copy_from_slice(&stamp_ns.to_le_bytes());
    bytes[8] = pad;
    bytes[9] = u8::from(started);
    bytes
}

/// A device's health as JSON: `{"device", "stamp_ns", "level" (0 OK, 1 WARN, 2 ERROR,
/// 3 STALE), "name", "message", "hardware_id", "values": {key: text}}`.
pub fn health_json(device: usize, status: &DiagnosticStatus, stamp_ns: u64) -> String {
    let values: serde_json::Map<String, serde_json::Value> = status
        .values
        .iter()
        .map(|pair| {
            (
                pair.key.clone(),
                serde_json::Value::from(pair.value.clone()),
            )
        })
        .collect();
    serde_json::json!({
        "device": device,
        "stamp_ns": stamp_ns,
        "level": status.level as u8,
        "name": status.name,
        "message": status.message,
        "hardware_id": status.hardware_id,
        "values": values,
    })
    .to_string()
}

/// The plain mode's publishers, declared as their keys first come.
pub struct PlainPublisher {
    session: Session,
    prefix: String,
    publishers: HashMap<String, Publisher<'static>>,
}

impl PlainPublisher {
    /// Publishes under `prefix` (`taxel`) on `session`.
    pub fn new(session: Session, prefix: &str) -> Self {
        Self {
            session,
            prefix: prefix.trim_matches('/').to_owned(),
            publishers: HashMap::new(),
        }
    }

    fn put(&mut self, key: String, encoding: &str, payload: Vec<u8>) -> anyhow::Result<()> {
        if !self.publishers.contains_key(&key) {
            let publisher = self
                .session
                .declare_publisher(key.clone())
                .congestion_control(CongestionControl::Block)
                .encoding(Encoding::from(encoding))
                .wait()
                .map_err(|error| anyhow::anyhow!("zenoh: {error}"))?;
            self.publishers.insert(key.clone(), publisher);
        }
        match self.publishers.get(&key) {
            Some(publisher) => publisher
                .put(payload)
                .wait()
                .map_err(|error| anyhow::anyhow!("zenoh: {error}")),
            None => Ok(()),
        }
    }
}

impl FramePublisher for PlainPublisher {
    fn publish(&mut self, outgoing: &Outgoing) -> anyhow::Result<()> {
        match outgoing {
            Outgoing::Sample {
                device,
                sample,
                stamp_ns,
                ..
            } => {
                let key = format!(
                    "{}/device{device}/pad{}/sample",
                    self.prefix,
                    sample.pad.get()
                );
                self.put(
                    key,
                    SAMPLE_ENCODING,
                    encode_sample(sample, *stamp_ns).to_vec(),
                )
            }
            Outgoing::Contact {
                device,
                pad,
                started,
                stamp_ns,
                ..
            } => {
                let key = format!("{}/device{device}/pad{pad}/contact", self.prefix);
                self.put(
                    key,
                    CONTACT_ENCODING,
                    encode_contact(*pad, *started, *stamp_ns).to_vec(),
                )
            }
        }
    }

    fn publish_health(&mut self, healths: &[DeviceHealth], stamp_ns: u64) -> anyhow::Result<()> {
        for (device, health) in healths.iter().enumerate() {
            let json = health_json(device, &device_status(device, health), stamp_ns);
            let key = format!("{}/device{device}/health", self.prefix);
            self.put(key, "application/json", json.into_bytes())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wire::{PadIndex, PadSummary, TaxelSample, TemperatureSource};

    #[test]
    fn a_sample_record_has_the_documented_layout() {
        let sample = SampleFrame {
            pad: PadIndex::new(3).unwrap(),
            sequence: 0x0102_0304,
            timestamp_us: 0,
            temperature_c: None,
            temperature_source: TemperatureSource::McuInternal,
            taxels: [TaxelSample {
                pressure_kpa: Some(12.5),
                capacitance_pf: 4.5,
                flags: 0x1001,
            }; 4],
            summary: PadSummary {
                force_n: Some(1.25),
                centre_of_pressure_mm: None,
                partial: false,
                contact: true,
            },
        };
        let bytes = encode_sample(&sample, 7);
        assert_eq!(bytes[..8], 7u64.to_le_bytes());
        assert_eq!(bytes[8..12], [4, 3, 2, 1]);
        assert_eq!(bytes[12], 3);
        assert_eq!(bytes[13], SUMMARY_CONTACT);
        assert_eq!(bytes[16..20], 1.25f32.to_le_bytes());
        assert!(f32::from_le_bytes(bytes[20..24].try_into().unwrap()).is_nan());
        assert_eq!(bytes[40..44], 12.5f32.to_le_bytes());
        assert_eq!(bytes[50..52], [0x01, 0x10]);
        assert!(f32::from_le_bytes(bytes[52..56].try_into().unwrap()).is_nan());
        assert_eq!(bytes[56], 2);
        assert_eq!(encode_contact(2, true, 9)[8..10], [2, 1]);
    }
}
