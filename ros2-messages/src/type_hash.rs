//! ROS 2 type descriptions and their RIHS01 hashes (REP-2011), as `rosidl` generates them for
//! ROS 2 Iron and later (Jazzy, Kilted, Rolling): the type hash in rmw_zenoh's key expressions
//! and liveliness tokens.
//!
//! The hash is SHA-256 over a JSON text of the type's description: the type and every type it
//! references (directly or not, sorted by name), each a list of fields with a numeric type id,
//! array capacity, string capacity and nested type name. Constants and default values are not
//! part of it. The JSON is Python's `json.dumps` with its default separators (`", "` and
//! `": "`), keys in the order below; `rosidl_generator_type_description` writes exactly that.
//!
//! A service (`pkg/srv/Name`, [`ServiceType`]) is hashed the same way, as a type of three
//! fields `request_message`, `response_message` and `event_message` (`Name_Request`,
//! `Name_Response`, and `Name_Event`: `service_msgs/ServiceEventInfo info`,
//! `Name_Request[<=1] request`, `Name_Response[<=1] response`). A message without fields (an
//! empty request) has the one field `uint8 structure_needs_at_least_one_member`.

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
    /// `int64`.
    pub const INT64: u8 = 8;
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
    /// Added to an element's id for an array (`T[N]`, the capacity being N).
    pub const ARRAY: u8 = 48;
    /// Added to an element's id for a bounded sequence (`T[<=N]`, the capacity being N).
    pub const BOUNDED_SEQUENCE: u8 = 96;
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
    /// An array's length or a bounded sequence's bound; 0 for anything else.
    pub capacity: u64,
    /// The nested type's full name (`pkg/msg/Type`), empty for primitives.
    pub nested_type_name: &'static str,
}

impl FieldDescription {
    /// A primitive field.
    pub const fn primitive(name: &'static str, type_id: u8) -> Self {
        Self {
            name,
            type_id,
            capacity: 0,
            nested_type_name: "",
        }
    }

    /// An array of `length` primitives (`T[N]`).
    pub const fn primitive_array(name: &'static str, element_type_id: u8, length: u64) -> Self {
        Self {
            name,
            type_id: element_type_id + type_id::ARRAY,
            capacity: length,
            nested_type_name: "",
        }
    }

    /// A field of a nested message type.
    pub const fn nested(name: &'static str, nested_type_name: &'static str) -> Self {
        Self {
            name,
            type_id: type_id::NESTED_TYPE,
            capacity: 0,
            nested_type_name,
        }
    }

    /// An unbounded sequence of a nested message type.
    pub const fn nested_sequence(name: &'static str, nested_type_name: &'static str) -> Self {
        Self {
            name,
            type_id: type_id::NESTED_TYPE + type_id::UNBOUNDED_SEQUENCE,
            capacity: 0,
            nested_type_name,
        }
    }

    /// A sequence of at most `bound` elements of a nested message type (`T[<=N]`).
    pub const fn nested_bounded_sequence(
        name: &'static str,
        nested_type_name: &'static str,
        bound: u64,
    ) -> Self {
        Self {
            name,
            type_id: type_id::NESTED_TYPE + type_id::BOUNDED_SEQUENCE,
            capacity: bound,
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
        dds_type_name(self.name())
    }

    /// The REP-2011 hashable JSON text of this type (see the module documentation).
    pub fn hashable_json(&self) -> String {
        hashable_json(self.description, self.references)
    }

    /// The type hash, `RIHS01_` and 64 lowercase hexadecimal digits.
    pub fn type_hash(&self) -> String {
        rihs01(&self.hashable_json())
    }
}

/// A service type: its description (the three fields of the module documentation), the types
/// it references, and its `.srv` text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ServiceType {
    /// The service itself, `pkg/srv/Name`, with the fields `request_message`,
    /// `response_message` and `event_message`.
    pub description: &'static TypeDescription,
    /// Every type it references, directly or not, in any order (request, response, event,
    /// `service_msgs/msg/ServiceEventInfo`, `builtin_interfaces/msg/Time`, ...).
    pub references: &'static [&'static TypeDescription],
    /// The `.srv` text: the request's fields, a `---` line, the response's.
    pub definition: &'static str,
}

impl ServiceType {
    /// Full name, `pkg/srv/Name`.
    pub fn name(&self) -> &'static str {
        self.description.type_name
    }

    /// The name as rmw_zenoh puts it in key expressions and tokens: the response type's DDS
    /// name without `Response_`, `pkg::srv::dds_::Name_`.
    pub fn dds_type_name(&self) -> String {
        dds_type_name(self.name())
    }

    /// The REP-2011 hashable JSON text of this service.
    pub fn hashable_json(&self) -> String {
        hashable_json(self.description, self.references)
    }

    /// The service's type hash, `RIHS01_` and 64 lowercase hexadecimal digits.
    pub fn type_hash(&self) -> String {
        rihs01(&self.hashable_json())
    }
}

/// A ROS 2 interface type as a middleware names it: a message or a service.
pub trait InterfaceType {
    /// The DDS name (`pkg::msg::dds_::Type_`, `pkg::srv::dds_::Name_`).
    fn dds_type_name(&self) -> String;
    /// The RIHS01 type hash.
    fn type_hash(&self) -> String;
}

impl InterfaceType for MessageType {
    fn dds_type_name(&self) -> String {
        MessageType::dds_type_name(self)
    }

    fn type_hash(&self) -> String {
        MessageType::type_hash(self)
    }
}

impl InterfaceType for ServiceType {
    fn dds_type_name(&self) -> String {
        ServiceType::dds_type_name(self)
    }

    fn type_hash(&self) -> String {
        ServiceType::type_hash(self)
    }
}

/// `pkg/kind/Type` as DDS spells it: `pkg::kind::dds_::Type_`.
fn dds_type_name(name: &str) -> String {
    match name.rsplit_once('/') {
        Some((package, type_name)) => {
            format!("{}::dds_::{type_name}_", package.replace('/', "::"))
        }
        None => format!("{name}_"),
    }
}

/// The hashable JSON of `description` with `references` sorted by name, each once.
fn hashable_json(description: &TypeDescription, references: &[&TypeDescription]) -> String {
    let mut references: Vec<&TypeDescription> = references.to_vec();
    references.sort_by_key(|description| description.type_name);
    references.dedup_by_key(|description| description.type_name);
    let mut json = String::from("{\"type_description\": ");
    write_description(&mut json, description);
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

/// `RIHS01_` and the SHA-256 of `json` in lowercase hexadecimal.
fn rihs01(json: &str) -> String {
    let digest = Sha256::digest(json.as_bytes());
    let mut text = String::from("RIHS01_");
    for byte in digest {
        let _ = write!(text, "{byte:02x}");
    }
    text
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
            "{{\"name\": \"{}\", \"type\": {{\"type_id\": {}, \"capacity\": {}, \"string_capacity\": 0, \"nested_type_name\": \"{}\"}}}}",
            field.name, field.type_id, field.capacity, field.nested_type_name
        );
    }
    json.push_str("]}");
}
