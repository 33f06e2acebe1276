//! ROS 2 messages for the taxel pad without a ROS installation: the few standard message types
//! the bridge publishes, serialised as ROS 2 does (CDR, [`cdr`]), with their REP-2011 type
//! hashes ([`type_hash`]), their message definitions, and an MCAP writer that stores them so
//! Foxglove and the ROS 2 bag tools open the file ([`mcap_file`]).
//!
//! [`services`] holds the services the bridge serves (their types, hashes, requests and
//! responses); [`distro`] what differs between ROS 2 distributions.
//!
//! [`pad_messages`] turns a pad's sample frame into those messages. Light on purpose: no
//! middleware here, so `taxel record --mcap` can use the same
//! messages without the Zenoh dependency of the bridge. Which message carries what, and why
//! these types, is in docs/BRIDGE.md.
#![deny(missing_docs)]

pub mod cdr;
pub mod distro;
pub mod mcap_file;
pub mod messages;
pub mod pad_file;
pub mod pad_messages;
pub mod rosbag2_metadata;
pub mod services;
pub mod type_hash;
pub mod types;

pub use cdr::{CdrError, CdrReader, CdrWriter};
pub use distro::RosDistro;
pub use mcap_file::{McapError, McapRecorder};
pub use messages::{
    DiagnosticArray, DiagnosticLevel, DiagnosticStatus, Header, KeyValue, PointCloud2, PointField,
    PointFieldType, RosMessage, Time, Vector3, Wrench, WrenchStamped,
};
pub use pad_file::PadMessagesFile;
pub use services::{ServiceResponse, SetUseCaseRequest};
pub use type_hash::{FieldDescription, InterfaceType, MessageType, ServiceType, TypeDescription};
