//! The messages as Rust values, each serialised to CDR exactly as a ROS 2 node would send it.

use crate::cdr::CdrWriter;
use crate::type_hash::MessageType;
use crate::types;

/// A message this crate can serialise.
pub trait RosMessage {
    /// Its type: name, hash, definition.
    fn message_type() -> &'static MessageType;
    /// Writes its fields (no encapsulation header) to `writer`.
    fn write_fields(&self, writer: &mut CdrWriter);
    /// The whole serialised message, encapsulation header first.
    fn to_cdr(&self) -> Vec<u8> {
        let mut writer = CdrWriter::new();
        self.write_fields(&mut writer);
        writer.finish()
    }
}

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds since the Unix epoch (ROS time).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds within the second, 0..1e9.
    pub nanosec: u32,
}

impl Time {
    /// The instant `unix_ns` nanoseconds after the Unix epoch (seconds saturate at `i32::MAX`,
    /// the year 2038, as ROS 2's own `Time` does).
    pub fn from_unix_ns(unix_ns: u64) -> Self {
        Self {
            sec: i32::try_from(unix_ns / 1_000_000_000).unwrap_or(i32::MAX),
            nanosec: (unix_ns % 1_000_000_000) as u32,
        }
    }

    /// Nanoseconds since the Unix epoch (0 for a time before it).
    pub fn unix_ns(&self) -> u64 {
        u64::try_from(self.sec).unwrap_or(0) * 1_000_000_000 + u64::from(self.nanosec)
    }

    fn write(&self, writer: &mut CdrWriter) {
        writer.write_i32(self.sec);
        writer.write_u32(self.nanosec);
    }
}

/// `std_msgs/msg/Header`: when and in which coordinate frame.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Header {
    /// When the data was taken.
    pub stamp: Time,
    /// The coordinate frame (tf2 name) the data is expressed in.
    pub frame_id: String,
}

impl RosMessage for Header {
    fn message_type() -> &'static MessageType {
        &types::HEADER_MESSAGE
    }

    fn write_fields(&self, writer: &mut CdrWriter) {
        self.stamp.write(writer);
        writer.write_string(&self.frame_id);
    }
}

/// `sensor_msgs/msg/PointField` data types (the constants of the message).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum PointFieldType {
    /// `UINT16 = 4`.
    Uint16 = 4,
    /// `UINT32 = 6`.
    Uint32 = 6,
    /// `FLOAT32 = 7`.
    Float32 = 7,
}

/// `sensor_msgs/msg/PointField`: one named value of every point.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PointField {
    /// The value's name.
    pub name: String,
    /// Its byte offset in a point.
    pub offset: u32,
    /// Its data type.
    pub datatype: PointFieldType,
    /// How many values (1 for a scalar).
    pub count: u32,
}

/// `sensor_msgs/msg/PointCloud2`: points with named fields, packed in `data`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PointCloud2 {
    /// Time and frame of the points.
    pub header: Header,
    /// Rows (1 for an unordered cloud).
    pub height: u32,
    /// Points per row.
    pub width: u32,
    /// The fields of each point.
    pub fields: Vec<PointField>,
    /// Byte order of `data` (false: little-endian).
    pub is_bigendian: bool,
    /// Bytes per point.
    pub point_step: u32,
    /// Bytes per row.
    pub row_step: u32,
    /// The points.
    pub data: Vec<u8>,
    /// No invalid (NaN) values in any point.
    pub is_dense: bool,
}

impl RosMessage for PointCloud2 {
    fn message_type() -> &'static MessageType {
        &types::POINT_CLOUD2_MESSAGE
    }

    fn write_fields(&self, writer: &mut CdrWriter) {
        self.header.write_fields(writer);
        writer.write_u32(self.height);
        writer.write_u32(self.width);
        writer.write_sequence_length(self.fields.len());
        for field in &self.fields {
            writer.write_string(&field.name);
            writer.write_u32(field.offset);
            writer.write_u8(field.datatype as u8);
            writer.write_u32(field.count);
        }
        writer.write_bool(self.is_bigendian);
        writer.write_u32(self.point_step);
        writer.write_u32(self.row_step);
        writer.write_bytes(&self.data);
        writer.write_bool(self.is_dense);
    }
}

/// `geometry_msgs/msg/Vector3`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

impl Vector3 {
    fn write(&self, writer: &mut CdrWriter) {
        writer.write_f64(self.x);
        writer.write_f64(self.y);
        writer.write_f64(self.z);
    }
}

/// `geometry_msgs/msg/Wrench`: force (N) and torque (N·m) about the frame's origin.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Wrench {
    /// Force, N.
    pub force: Vector3,
    /// Torque about the origin of the header's frame, N·m.
    pub torque: Vector3,
}

/// `geometry_msgs/msg/WrenchStamped`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct WrenchStamped {
    /// Time and frame.
    pub header: Header,
    /// The wrench in that frame.
    pub wrench: Wrench,
}

impl RosMessage for WrenchStamped {
    fn message_type() -> &'static MessageType {
        &types::WRENCH_STAMPED_MESSAGE
    }

    fn write_fields(&self, writer: &mut CdrWriter) {
        self.header.write_fields(writer);
        self.wrench.force.write(writer);
        self.wrench.torque.write(writer);
    }
}

/// `diagnostic_msgs/msg/KeyValue`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct KeyValue {
    /// What the value is.
    pub key: String,
    /// The value, as text.
    pub value: String,
}

impl KeyValue {
    /// A pair from anything printable.
    pub fn new(key: &str, value: impl ToString) -> Self {
        Self {
            key: key.to_owned(),
            value: value.to_string(),
        }
    }
}

/// `diagnostic_msgs/msg/DiagnosticStatus` levels (the constants of the message).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
#[repr(u8)]
pub enum DiagnosticLevel {
    /// `OK = 0`.
    #[default]
    Ok = 0,
    /// `WARN = 1`.
    Warn = 1,
    /// `ERROR = 2`.
    Error = 2,
    /// `STALE = 3`.
    Stale = 3,
}

/// `diagnostic_msgs/msg/DiagnosticStatus`: one component's health.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct DiagnosticStatus {
    /// Overall level.
    pub level: DiagnosticLevel,
    /// The component.
    pub name: String,
    /// One line for people.
    pub message: String,
    /// The hardware's identity (serial number).
    pub hardware_id: String,
    /// The figures.
    pub values: Vec<KeyValue>,
}

/// `diagnostic_msgs/msg/DiagnosticArray`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct DiagnosticArray {
    /// Time of the report.
    pub header: Header,
    /// One status per component.
    pub status: Vec<DiagnosticStatus>,
}

impl RosMessage for DiagnosticArray {
    fn message_type() -> &'static MessageType {
        &types::DIAGNOSTIC_ARRAY_MESSAGE
    }

    fn write_fields(&self, writer: &mut CdrWriter) {
        self.header.write_fields(writer);
        writer.write_sequence_length(self.status.len());
        for status in &self.status {
            writer.write_u8(status.level as u8);
            writer.write_string(&status.name);
            writer.write_string(&status.message);
            writer.write_string(&status.hardware_id);
            writer.write_sequence_length(status.values.len());
            for pair in &status.values {
                writer.write_string(&pair.key);
                writer.write_string(&pair.value);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_header_serialises_as_ros_2_does() {
        let header = Header {
            stamp: Time { sec: 1, nanosec: 2 },
            frame_id: "pad".into(),
        };
        assert_eq!(
            header.to_cdr(),
            [0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 4, 0, 0, 0, b'p', b'a', b'd', 0]
        );
    }

    #[test]
    fn the_wrench_is_aligned_to_eight_after_the_frame_id() {
        let message = WrenchStamped {
            header: Header {
                stamp: Time::default(),
                frame_id: "a".into(),
            },
            wrench: Wrench {
                force: Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: 2.5,
                },
                torque: Vector3::default(),
            },
        };
        let bytes = message.to_cdr();
        // Header: 8 (stamp) + 4 (length) + 2 ("a\0") = 14 bytes, padded to 16.
        assert_eq!(bytes.len(), 4 + 16 + 6 * 8);
        assert_eq!(bytes[4 + 16 + 16..4 + 16 + 24], 2.5f64.to_le_bytes());
    }

    #[test]
    fn time_splits_nanoseconds() {
        let time = Time::from_unix_ns(1_700_000_000_123_456_789);
        assert_eq!(time.sec, 1_700_000_000);
        assert_eq!(time.nanosec, 123_456_789);
        assert_eq!(time.unix_ns(), 1_700_000_000_123_456_789);
    }
}
