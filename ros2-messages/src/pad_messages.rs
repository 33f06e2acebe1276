//! One sample frame of a pad as ROS 2 messages, as the bridge publishes them and an MCAP
//! recording stores them, and the topics and frame id of each pad (docs/BRIDGE.md says why
//! these types).
//!
//! - pressures: `sensor_msgs/msg/PointCloud2`, one point per taxel (C11, C12, C21, C22) at the
//!   electrode's centre in the pad's frame (m, z = 0), with `pressure` (Pa, NaN when the taxel
//!   is faulted) and `flags` (the taxel's flag bits);
//! - force: `geometry_msgs/msg/WrenchStamped`, the wrench the contact exerts on the pad about
//!   the pad frame's origin: the normal force `F` pushes along −z at the centre of pressure
//!   `(x, y)`, so force = (0, 0, −F) N and torque = (x, y, 0) × force = (−yF, xF, 0) N·m.

use crate::messages::{
    Header, PointCloud2, PointField, PointFieldType, Vector3, Wrench, WrenchStamped,
};
use model_core::PadGeometry;
use wire::SampleFrame;

/// The namespace of the pad topics unless the user gives another.
pub const DEFAULT_NAMESPACE: &str = "/taxel";

/// The start of each pad's frame id unless the user gives another.
pub const DEFAULT_FRAME_PREFIX: &str = "taxel_";

/// Bytes per point: x, y, z, pressure (float32) and flags (uint32).
pub const POINT_STEP_BYTES: u32 = 20;

/// The topics and frame id of one pad.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PadTopics {
    /// Pressures and flags (`PointCloud2`).
    pub pressure: String,
    /// Force at the centre of pressure (`WrenchStamped`).
    pub wrench: String,
    /// Contact started events (`std_msgs/msg/Header`).
    pub contact_started: String,
    /// Contact ended events (`std_msgs/msg/Header`).
    pub contact_ended: String,
    /// The pad's coordinate frame.
    pub frame_id: String,
}

impl PadTopics {
    /// The topics of `pad` of device `device` under `namespace` (`/taxel` by default), and its
    /// frame `<frame_prefix>device<d>_pad<p>`.
    pub fn new(namespace: &str, frame_prefix: &str, device: usize, pad: u8) -> Self {
        let base = format!(
            "{}/device{device}/pad{pad}",
            namespace.trim_end_matches('/')
        );
        Self {
            pressure: format!("{base}/pressure"),
            wrench: format!("{base}/wrench"),
            contact_started: format!("{base}/contact_started"),
            contact_ended: format!("{base}/contact_ended"),
            frame_id: format!("{frame_prefix}device{device}_pad{pad}"),
        }
    }
}

fn float32_field(name: &str, offset: u32) -> PointField {
    PointField {
        name: name.to_owned(),
        offset,
        datatype: PointFieldType::Float32,
        count: 1,
    }
}

/// The taxels of `sample` as a cloud of four points (see the module documentation).
pub fn pressure_cloud(sample: &SampleFrame, header: Header, geometry: &PadGeometry) -> PointCloud2 {
    let mut data = Vec::with_capacity(4 * POINT_STEP_BYTES as usize);
    let mut is_dense = true;
    for (taxel, place) in sample.taxels.iter().zip(geometry.taxels()) {
        let pressure_pa = match taxel.pressure_kpa {
            Some(kpa) => kpa * 1000.0,
            None => {
                is_dense = false;
                f32::NAN
            }
        };
        data.extend_from_slice(&(place.x_mm / 1000.0).to_le_bytes());
        data.extend_from_slice(&(place.y_mm / 1000.0).to_le_bytes());
        data.extend_from_slice(&0.0f32.to_le_bytes());
        data.extend_from_slice(&pressure_pa.to_le_bytes());
        data.extend_from_slice(&u32::from(taxel.flags).to_le_bytes());
    }
    let width = sample.taxels.len() as u32;
    PointCloud2 {
        header,
        height: 1,
        width,
        fields: vec![
            float32_field("x", 0),
            float32_field("y", 4),
            float32_field("z", 8),
            float32_field("pressure", 12),
            PointField {
                name: "flags".to_owned(),
                offset: 16,
                datatype: PointFieldType::Uint32,
                count: 1,
            },
        ],
        is_bigendian: false,
        point_step: POINT_STEP_BYTES,
        row_step: POINT_STEP_BYTES * width,
        data,
        is_dense,
    }
}

/// The pad's force at its centre of pressure as a wrench (see the module documentation). No
/// force (no taxel reads): every component NaN. A force too small to place (the device gives no
/// centre below 5 mN): applied at the origin, torque 0.
pub fn pad_wrench(sample: &SampleFrame, header: Header) -> WrenchStamped {
    let wrench = match sample.summary.force_n {
        None => Wrench {
            force: Vector3 {
                x: f64::NAN,
                y: f64::NAN,
                z: f64::NAN,
            },
            torque: Vector3 {
                x: f64::NAN,
                y: f64::NAN,
                z: f64::NAN,
            },
        },
        Some(force_n) => {
            let force_n = f64::from(force_n);
            let [x_m, y_m] = sample
                .summary
                .centre_of_pressure_mm
                .map_or([0.0, 0.0], |[x_mm, y_mm]| {
                    [f64::from(x_mm) / 1000.0, f64::from(y_mm) / 1000.0]
                });
            Wrench {
                force: Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: -force_n,
                },
                torque: Vector3 {
                    x: -y_m * force_n,
                    y: x_m * force_n,
                    z: 0.0,
                },
            }
        }
    };
    WrenchStamped { header, wrench }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wire::{PadIndex, PadSummary, TaxelSample, TemperatureSource};

    fn sample() -> SampleFrame {
        SampleFrame {
            pad: PadIndex::default(),
            sequence: 3,
            timestamp_us: 0,
            temperature_c: Some(25.0),
            temperature_source: TemperatureSource::Tmp117,
            taxels: [
                TaxelSample {
                    pressure_kpa: Some(10.0),
                    capacitance_pf: 4.5,
                    flags: 0,
                },
                TaxelSample {
                    pressure_kpa: None,
                    capacitance_pf: 4.5,
                    flags: 1 << 2,
                },
                TaxelSample {
                    pressure_kpa: Some(0.0),
                    capacitance_pf: 4.5,
                    flags: 0,
                },
                TaxelSample {
                    pressure_kpa: Some(0.0),
                    capacitance_pf: 4.5,
                    flags: 0,
                },
            ],
            summary: PadSummary {
                force_n: Some(0.25),
                centre_of_pressure_mm: Some([-2.75, 2.75]),
                partial: true,
                contact: true,
            },
        }
    }

    #[test]
    fn a_faulted_taxel_is_nan_with_its_flags_and_the_cloud_not_dense() {
        let cloud = pressure_cloud(&sample(), Header::default(), &PadGeometry::ARTICLE);
        assert!(!cloud.is_dense);
        assert_eq!(cloud.data.len(), 80);
        let value = |point: usize, offset: usize| {
            let start = point * 20 + offset;
            f32::from_le_bytes(cloud.data[start..start + 4].try_into().unwrap())
        };
        assert_eq!(value(0, 12), 10_000.0);
        assert!(value(1, 12).is_nan());
        assert_eq!(cloud.data[36], 4, "flags of taxel 1");
        assert_eq!(value(0, 0), PadGeometry::ARTICLE.taxels()[0].x_mm / 1000.0);
    }

    #[test]
    fn the_torque_puts_the_force_at_the_centre_of_pressure() {
        let wrench = pad_wrench(&sample(), Header::default()).wrench;
        assert_eq!(wrench.force.z, -0.25);
        // Centre = (τy / −Fz, −τx / −Fz) back.
        let force = -wrench.force.z;
        assert!((wrench.torque.y / force - (-0.00275)).abs() < 1e-9);
        assert!((-wrench.torque.x / force - 0.00275).abs() < 1e-9);
    }
}
