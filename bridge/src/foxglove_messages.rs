//! What the Foxglove view ([`crate::foxglove`]) shows, as messages: each pad's state as JSON
//! (with its JSON schema, for the Plot and Raw Messages panels), every pad as cubes in a
//! `foxglove.SceneUpdate` with the `foxglove.FrameTransforms` that lay the pads out side by
//! side (the 3D panel), and the devices' health as JSON. docs/BRIDGE.md describes each field.

use foxglove::messages::{
    Color, CubePrimitive, FrameTransform, Pose, Quaternion, SceneEntity, TextPrimitive, Timestamp,
    Vector3,
};
use model_core::PadGeometry;
use serde_json::{json, Value};
use taxel_ros2::DiagnosticLevel;
use wire::SampleFrame;

use crate::health::{device_status, DeviceHealth};

/// The schema name of a pad's state.
pub const PAD_STATE_SCHEMA_NAME: &str = "taxel.PadState";
/// The schema name of the devices' health.
pub const HEALTH_SCHEMA_NAME: &str = "taxel.Health";

/// The pressure drawn fully red; 0 kPa is blue (the pad's range, README).
pub const FULL_SCALE_KPA: f32 = 50.0;
/// A cube's height at 0 kPa (and for a faulted taxel), mm.
pub const BASE_HEIGHT_MM: f64 = 1.0;
/// A cube's height added per kPa, mm (11 mm at [`FULL_SCALE_KPA`]).
pub const HEIGHT_MM_PER_KPA: f64 = 0.2;
/// The gap between two pads laid side by side, mm.
pub const PAD_GAP_MM: f64 = 10.0;

/// Nanoseconds since the Unix epoch as a Foxglove timestamp (saturating beyond 2106).
pub fn timestamp(unix_ns: u64) -> Timestamp {
    let sec = u32::try_from(unix_ns / 1_000_000_000).unwrap_or(u32::MAX);
    Timestamp::new(sec, (unix_ns % 1_000_000_000) as u32)
}

/// A timestamp as JSON, in the form Foxglove reads a time from (`sec`, `nsec`).
fn time_json(unix_ns: u64) -> Value {
    json!({ "sec": unix_ns / 1_000_000_000, "nsec": unix_ns % 1_000_000_000 })
}

fn time_schema() -> Value {
    json!({
        "type": "object",
        "properties": {
            "sec": { "type": "integer", "minimum": 0 },
            "nsec": { "type": "integer", "minimum": 0 },
        },
        "required": ["sec", "nsec"],
    })
}

/// The JSON schema of [`pad_state_json`].
pub fn pad_state_schema() -> Value {
    let number_or_null = json!({ "type": ["number", "null"] });
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": PAD_STATE_SCHEMA_NAME,
        "description": "One pad's sample set: pressures and flags per taxel (C11, C12, C21, C22), force, centre of pressure, contact. null: the device gave no value (a faulted taxel, no force, no centre, no temperature).",
        "type": "object",
        "properties": {
            "timestamp": time_schema(),
            "stamp_ns": { "type": "integer", "description": "the device time on the host clock, ns since the Unix epoch" },
            "device": { "type": "integer" },
            "pad": { "type": "integer" },
            "sequence": { "type": "integer", "description": "the device's sample-set number" },
            "pressure_kpa": { "type": "array", "items": number_or_null, "minItems": 4, "maxItems": 4 },
            "flags": { "type": "array", "items": { "type": "integer" }, "minItems": 4, "maxItems": 4 },
            "force_n": number_or_null,
            "centre_of_pressure_mm": {
                "type": ["object", "null"],
                "properties": { "x": { "type": "number" }, "y": { "type": "number" } },
            },
            "contact": { "type": "boolean" },
            "partial": { "type": "boolean", "description": "faulted taxels left out of force and centre" },
            "temperature_c": number_or_null,
        },
        "required": ["timestamp", "stamp_ns", "device", "pad", "sequence", "pressure_kpa", "flags",
                     "force_n", "centre_of_pressure_mm", "contact", "partial", "temperature_c"],
    })
}

/// One pad's sample frame as JSON, stamped `stamp_ns` (ns since the Unix epoch).
pub fn pad_state_json(device: usize, sample: &SampleFrame, stamp_ns: u64) -> Value {
    let summary = &sample.summary;
    json!({
        "timestamp": time_json(stamp_ns),
        "stamp_ns": stamp_ns,
        "device": device,
        "pad": sample.pad.get(),
        "sequence": sample.sequence,
        "pressure_kpa": sample.taxels.iter().map(|taxel| taxel.pressure_kpa).collect::<Vec<_>>(),
        "flags": sample.taxels.iter().map(|taxel| taxel.flags).collect::<Vec<_>>(),
        "force_n": summary.force_n,
        "centre_of_pressure_mm": summary.centre_of_pressure_mm.map(|[x, y]| json!({ "x": x, "y": y })),
        "contact": summary.contact,
        "partial": summary.partial,
        "temperature_c": sample.temperature_c,
    })
}

fn level_name(level: DiagnosticLevel) -> &'static str {
    match level {
        DiagnosticLevel::Ok => "OK",
        DiagnosticLevel::Warn => "WARN",
        DiagnosticLevel::Error => "ERROR",
        DiagnosticLevel::Stale => "STALE",
    }
}

/// The JSON schema of [`health_json`].
pub fn health_schema() -> Value {
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": HEALTH_SCHEMA_NAME,
        "description": "Every device's health, as the bridge's diagnostics have it.",
        "type": "object",
        "properties": {
            "timestamp": time_schema(),
            "stamp_ns": { "type": "integer" },
            "devices": {
                "type": "array",
                "items": {
                    "type": "object",
                    "properties": {
                        "device": { "type": "integer" },
                        "name": { "type": "string" },
                        "level": { "type": "integer", "description": "0 OK, 1 WARN, 2 ERROR, 3 STALE" },
                        "level_name": { "type": "string" },
                        "message": { "type": "string" },
                        "hardware_id": { "type": "string" },
                        "values": { "type": "object", "additionalProperties": { "type": "string" } },
                    },
                    "required": ["device", "name", "level", "level_name", "message", "hardware_id", "values"],
                },
            },
        },
        "required": ["timestamp", "stamp_ns", "devices"],
    })
}

/// Every device's health as JSON, stamped `stamp_ns`: per device its diagnostic status (the
/// same as on `/diagnostics`).
pub fn health_json(healths: &[DeviceHealth], stamp_ns: u64) -> Value {
    let devices: Vec<Value> = healths
        .iter()
        .enumerate()
        .map(|(device, health)| {
            let status = device_status(device, health);
            let values: serde_json::Map<String, Value> = status
                .values
                .iter()
                .map(|pair| (pair.key.clone(), Value::from(pair.value.clone())))
                .collect();
            json!({
                "device": device,
                "name": status.name,
                "level": status.level as u8,
                "level_name": level_name(status.level),
                "message": status.message,
                "hardware_id": status.hardware_id,
                "values": values,
            })
        })
        .collect();
    json!({ "timestamp": time_json(stamp_ns), "stamp_ns": stamp_ns, "devices": devices })
}

/// A pressure's colour: blue at 0 kPa to red at [`FULL_SCALE_KPA`] (clamped), grey when the
/// taxel is faulted.
pub fn pressure_colour(pressure_kpa: Option<f32>) -> Color {
    match pressure_kpa {
        Some(kpa) if kpa.is_finite() => {
            let red = f64::from((kpa / FULL_SCALE_KPA).clamp(0.0, 1.0));
            Color {
                r: red,
                g: 0.0,
                b: 1.0 - red,
                a: 1.0,
            }
        }
        _ => Color {
            r: 0.5,
            g: 0.5,
            b: 0.5,
            a: 1.0,
        },
    }
}

/// A cube's height for a pressure, mm.
fn height_mm(pressure_kpa: Option<f32>) -> f64 {
    let kpa = pressure_kpa
        .filter(|kpa| kpa.is_finite())
        .map_or(0.0, |kpa| f64::from(kpa.clamp(0.0, FULL_SCALE_KPA)));
    BASE_HEIGHT_MM + HEIGHT_MM_PER_KPA * kpa
}

/// The side of a taxel's square electrode of `area_mm2`, mm.
fn side_mm(area_mm2: f32) -> f64 {
    f64::from(area_mm2.max(0.0)).sqrt()
}

/// How far the pad's electrodes reach from its centre along x or y, mm.
pub fn pad_half_extent_mm(geometry: &PadGeometry) -> f64 {
    geometry
        .taxels()
        .iter()
        .map(|taxel| {
            let half_side = side_mm(taxel.area_mm2) / 2.0;
            (f64::from(taxel.x_mm.abs()) + half_side).max(f64::from(taxel.y_mm.abs()) + half_side)
        })
        .fold(0.0, f64::max)
}

/// The distance between the centres of two neighbouring pads when the largest of them reaches
/// `largest_half_extent_mm` from its centre, mm.
pub fn pad_pitch_mm(largest_half_extent_mm: f64) -> f64 {
    2.0 * largest_half_extent_mm + PAD_GAP_MM
}

/// Where pad `pad` of device `device` lies in the view's root frame, mm: a device's pads in a
/// row along x, the devices' rows one below the other along −y.
pub fn pad_offset_mm(device: usize, pad: u8, pitch_mm: f64) -> [f64; 2] {
    [f64::from(pad) * pitch_mm, -(device as f64) * pitch_mm]
}

fn vector_m(x_mm: f64, y_mm: f64, z_mm: f64) -> Vector3 {
    Vector3 {
        x: x_mm / 1000.0,
        y: y_mm / 1000.0,
        z: z_mm / 1000.0,
    }
}

const IDENTITY: Quaternion = Quaternion {
    x: 0.0,
    y: 0.0,
    z: 0.0,
    w: 1.0,
};

/// The transform placing a pad's frame `frame_id` in the view's root frame `root_frame` at
/// `offset_mm`, stamped `stamp_ns`.
pub fn pad_transform(
    root_frame: &str,
    frame_id: &str,
    offset_mm: [f64; 2],
    stamp_ns: u64,
) -> FrameTransform {
    FrameTransform {
        timestamp: Some(timestamp(stamp_ns)),
        parent_frame_id: root_frame.to_owned(),
        child_frame_id: frame_id.to_owned(),
        translation: Some(vector_m(offset_mm[0], offset_mm[1], 0.0)),
        rotation: Some(IDENTITY),
    }
}

/// A pad as a scene entity `id` in its own frame `frame_id`: one cube per taxel at its
/// electrode's centre, its electrode's size (a square of its area), standing on the pad (z up)
/// as tall as [`BASE_HEIGHT_MM`] plus [`HEIGHT_MM_PER_KPA`] per kPa, coloured by
/// [`pressure_colour`]; and a label `label` below the pad. Stamped `stamp_ns`; it replaces the
/// entity of the same id and stays until replaced.
pub fn pad_entity(
    id: &str,
    frame_id: &str,
    label: &str,
    geometry: &PadGeometry,
    sample: &SampleFrame,
    stamp_ns: u64,
) -> SceneEntity {
    let cubes = sample
        .taxels
        .iter()
        .zip(geometry.taxels())
        .map(|(taxel, place)| {
            let side_mm = side_mm(place.area_mm2);
            let height_mm = height_mm(taxel.pressure_kpa);
            CubePrimitive {
                pose: Some(Pose {
                    position: Some(vector_m(
                        f64::from(place.x_mm),
                        f64::from(place.y_mm),
                        height_mm / 2.0,
                    )),
                    orientation: Some(IDENTITY),
                }),
                size: Some(vector_m(side_mm, side_mm, height_mm)),
                color: Some(pressure_colour(taxel.pressure_kpa)),
            }
        })
        .collect();
    let below_mm = -pad_half_extent_mm(geometry) - PAD_GAP_MM / 2.0;
    SceneEntity {
        timestamp: Some(timestamp(stamp_ns)),
        frame_id: frame_id.to_owned(),
        id: id.to_owned(),
        // Drawn where the pad's frame is now, whatever the stamp of the latest transform.
        frame_locked: true,
        cubes,
        texts: vec![TextPrimitive {
            pose: Some(Pose {
                position: Some(vector_m(0.0, below_mm, 0.0)),
                orientation: Some(IDENTITY),
            }),
            billboard: true,
            font_size: 14.0,
            scale_invariant: true,
            color: Some(Color {
                r: 1.0,
                g: 1.0,
                b: 1.0,
                a: 1.0,
            }),
            text: label.to_owned(),
        }],
        ..SceneEntity::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wire::PadIndex;

    fn sample(pressures_kpa: [Option<f32>; 4]) -> SampleFrame {
        let mut sample = wire::testing::sample_frame(1);
        for (taxel, pressure_kpa) in sample.taxels.iter_mut().zip(pressures_kpa) {
            taxel.pressure_kpa = pressure_kpa;
        }
        sample.pad = PadIndex::new(1).unwrap();
        sample
    }

    #[test]
    fn a_state_has_every_documented_field_and_null_for_what_the_device_did_not_give() {
        let frame = sample([Some(10.0), None, Some(30.0), Some(40.0)]);
        let state = pad_state_json(2, &frame, 1_700_000_000_123_456_789);
        assert_eq!(state["timestamp"]["sec"], 1_700_000_000_u64);
        assert_eq!(state["timestamp"]["nsec"], 123_456_789_u64);
        assert_eq!(
            (state["device"].clone(), state["pad"].clone()),
            (json!(2), json!(1))
        );
        assert_eq!(state["pressure_kpa"], json!([10.0, null, 30.0, 40.0]));
        let schema = pad_state_schema();
        let required = schema["required"].as_array().unwrap();
        for field in required {
            assert!(state.get(field.as_str().unwrap()).is_some(), "{field}");
        }
        assert_eq!(
            required.len(),
            state.as_object().unwrap().len(),
            "every field is in the schema"
        );
    }

    #[test]
    fn colours_go_from_blue_to_red_over_the_range_and_grey_when_faulted() {
        assert_eq!(pressure_colour(Some(0.0)).b, 1.0);
        assert_eq!(pressure_colour(Some(FULL_SCALE_KPA)).r, 1.0);
        assert_eq!(pressure_colour(Some(25.0)).r, 0.5);
        assert_eq!(pressure_colour(Some(80.0)).r, 1.0);
        assert_eq!(pressure_colour(Some(-3.0)).b, 1.0);
        let faulted = pressure_colour(None);
        assert_eq!((faulted.r, faulted.g, faulted.b), (0.5, 0.5, 0.5));
    }

    #[test]
    fn a_pad_is_four_cubes_at_its_electrodes_and_pads_do_not_overlap() {
        let geometry = PadGeometry::ARTICLE;
        let entity = pad_entity(
            "device0/pad1",
            "taxel_device0_pad1",
            "device0 pad1",
            &geometry,
            &sample([Some(0.0), Some(50.0), None, Some(25.0)]),
            7,
        );
        assert_eq!(entity.cubes.len(), 4);
        for (cube, place) in entity.cubes.iter().zip(geometry.taxels()) {
            let position = cube.pose.unwrap().position.unwrap();
            assert!((position.x - f64::from(place.x_mm) / 1000.0).abs() < 1e-9);
            assert!((position.y - f64::from(place.y_mm) / 1000.0).abs() < 1e-9);
            let size = cube.size.unwrap();
            assert!((size.x - 0.005).abs() < 1e-9 && (size.y - 0.005).abs() < 1e-9);
            assert!(
                (position.z - size.z / 2.0).abs() < 1e-12,
                "standing on the pad"
            );
        }
        assert!((entity.cubes[1].size.unwrap().z - 0.011).abs() < 1e-9);
        assert_eq!(entity.frame_id, "taxel_device0_pad1");
        let half_mm = pad_half_extent_mm(&geometry);
        assert!((half_mm - 5.25).abs() < 1e-6);
        let pitch_mm = pad_pitch_mm(half_mm);
        assert!(pitch_mm > 2.0 * half_mm);
        let [x0, _] = pad_offset_mm(0, 0, pitch_mm);
        let [x1, _] = pad_offset_mm(0, 1, pitch_mm);
        let [_, y1] = pad_offset_mm(1, 0, pitch_mm);
        assert!(x1 - x0 >= 2.0 * half_mm && -y1 >= 2.0 * half_mm);
    }

    #[test]
    fn health_carries_every_devices_status() {
        let healths = vec![DeviceHealth::default(), DeviceHealth::default()];
        let health = health_json(&healths, 3_000_000_001);
        let devices = health["devices"].as_array().unwrap();
        assert_eq!(devices.len(), 2);
        assert_eq!(devices[1]["name"], "taxel_bridge: device1");
        assert_eq!(devices[0]["level_name"], "STALE");
        assert_eq!(health["timestamp"]["nsec"], 1);
    }
}
