//! ROS 2 type descriptions and their RIHS01 hashes (REP-2011), as `rosidl` generates them for
//! ROS 2 Iron and later (Jazzy, Kilted, Rolling): the type hash in rmw_zenoh's key expressions
//! and liveliness tokens.
//!
//! The hash is SHA-256 over a JSON text of the type's description: the type and every type it
//! references (directly or not, sorted by name), each a list of fields with a numeric type id,
//! array capacity, string capacity and nested type name. Constants and default values are not
//! part of it. The JSON is Python's `json.dumps` with its default separators (`", "` and
//! `": "`), keys in the order below; `rosidl_generator_type_description` writes exactly that.

use std::fmt::Write as _;

use sha2::{Digest, Sha256};

/// Type ids of `type_description_interfaces/msg/FieldType` used by this crate's messages.
pub mod type_id {
    /// A nested message type (`nested_type_name` says which).
    pub const NESTED_TYPE: u8 = 1;
    /// `uint8`.
    pub const UINT8: u8 = 3;
    /// `int32`.
    pub const INT32: u8 = 6;
    /// `uint32`.
    pub const UINT32: u8 = 7;
    /// `float32`.
    pub const FLOAT: u8 = 10;
    /// `float64`.
    pub const DOUBLE: u8 = 11;
    /// `bool`.
    pub const BOOLEAN: u8 = 15;
    /// `byte`.
    pub const BYTE: u8 = 16;
    /// `string` (unbounded).
    pub const STRING: u8 = 17;
    /// Added to an element's id for an unbounded sequence (`T[]`).
    pub const UNBOUNDED_SEQUENCE: u8 = 144;
}

/// One field of a type description.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FieldDescription {
    /// The field's name.
    pub name: &'static str,
    /// Its `FieldType` id (see [`type_id`]).
    pub type_id: u8,
    /// The nested type's full name (`pkg/msg/Type`), empty for primitives.
    pub nested_type_name: &'static str,
}

impl FieldDescription {
    /// A primitive field.
    pub const fn primitive(name: &'static str, type_id: u8) -> Self {
        Self {
            name,
            type_id,
            nested_type_name: "",
        }
    }

    /// A field of a nested message type.
    pub const fn nested(name: &'static str, nested_type_name: &'static str) -> Self {
        Self {
            name,
            type_id: type_id::NESTED_TYPE,
            nested_type_name,
        }
    }

    /// An unbounded sequence of a nested message type.
    pub const fn nested_sequence(name: &'static str, nested_type_name: &'static str) -> Self {
        Self {
            name,
            type_id: type_id::NESTED_TYPE + type_id::UNBOUNDED_SEQUENCE,
            nested_type_name,
        }
    }
}

/// One message type's fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TypeDescription {
    /// Full name, `pkg/msg/Type`.
    pub type_name: &'static str,
    /// The fields in declaration order.
    pub fields: &'static [FieldDescription],
}

/// A message type as a middleware and a recorder need it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MessageType {
    /// The type itself.
    pub description: &'static TypeDescription,
    /// Every type it references, directly or not, in any order.
    pub references: &'static [&'static TypeDescription],
    /// The ROS 2 message definition (`.msg` text) followed by those of the referenced types,
    /// each after a line of `=` and a `MSG: pkg/Type` line: MCAP's `ros2msg` schema encoding.
    pub definition: &'static str,
}

impl MessageType {
    /// Full name, `pkg/msg/Type`.
    pub fn name(&self) -> &'static str {
        self.description.type_name
    }

    /// The name as DDS and rmw_zenoh spell it: `pkg::msg::dds_::Type_`.
    pub fn dds_type_name(&self) -> String {
        let name = self.name();
        match name.rsplit_once('/') {
            Some((package, type_name)) => {
                format!("{}::dds_::{type_name}_", package.replace('/', "::"))
            }
            None => format!("{name}_"),
        }
    }

    /// The REP-2011 hashable JSON text of this type (see the module documentation).
    pub fn hashable_json(&self) -> String {
        let mut references: Vec<&TypeDescription> = self.references.to_vec();
        references.sort_by_key(|description| description.type_name);
        references.dedup_by_key(|description| description.type_name);
        let mut json = String::from("{\"type_description\": ");
        write_description(&mut json, self.description);
        json.push_str(", \"referenced_type_descriptions\": [");
        for (index, reference) in references.iter().enumerate() {
            if index > 0 {
                json.push_str(", ");
            }
            write_description(&mut json, reference);
        }
        json.push_str("]}");
        json
    }

    /// The type hash, `RIHS01_` and 64 lowercase hexadecimal digits.
    pub fn type_hash(&self) -> String {
        let digest = Sha256::digest(self.hashable_json().as_bytes());
        let mut text = String::from("RIHS01_");
        for byte in digest {
            let _ = write!(text, "{byte:02x}");
        }
        text
    }
}

fn write_description(json: &mut String, description: &TypeDescription) {
    let _ = write!(
        json,
        "{{\"type_name\": \"{}\", \"fields\": [",
        description.type_name
    );
    for (index, field) in description.fields.iter().enumerate() {
        if index > 0 {
            json.push_str(", ");
        }
        let _ = write!(
            json,
            "{{\"name\": \"{}\", \"type\": {{\"type_id\": {}, \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \"{}\"}}}}",
            field.name, field.type_id, field.nested_type_name
        );
    }
    json.push_str("]}");
}
