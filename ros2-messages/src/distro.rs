//! The ROS 2 distribution a consumer runs, where it changes what is written: rmw_zenoh's key
//! expressions and liveliness tokens carry the RIHS01 type hash from Iron on and the constant
//! `TypeHashNotSupported` in its Humble releases (rmw_zenoh 0.1.x, `rmw_publisher_data.cpp`,
//! `rmw_service_data.cpp`); rosbag2's MCAP files carry the type hash and a YAML metadata record
//! from Jazzy on, integer QoS enumerations and only `ROS_DISTRO` in Humble
//! (rosbag2_storage_mcap's `mcap_storage.cpp` on each branch).

use std::fmt;
use std::str::FromStr;

/// A ROS 2 distribution with its own forms (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RosDistro {
    /// Humble Hawksbill (2022): no type hashes.
    Humble,
    /// Jazzy Jalisco (2024) and later (Kilted, Rolling): RIHS01 type hashes.
    #[default]
    Jazzy,
}

/// What rmw_zenoh's Humble releases put where a type hash goes.
pub const TYPE_HASH_NOT_SUPPORTED: &str = "TypeHashNotSupported";

impl RosDistro {
    /// The distribution's name, as `ROS_DISTRO` says it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Humble => "humble",
            Self::Jazzy => "jazzy",
        }
    }

    /// Whether the distribution's interfaces have REP-2011 type hashes.
    pub fn has_type_hashes(self) -> bool {
        self != Self::Humble
    }

    /// What rmw_zenoh of this distribution writes in key expressions and tokens for a type whose
    /// hash is `type_hash`.
    pub fn key_expression_hash(self, type_hash: String) -> String {
        if self.has_type_hashes() {
            type_hash
        } else {
            TYPE_HASH_NOT_SUPPORTED.to_owned()
        }
    }
}

impl fmt::Display for RosDistro {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        formatter.write_str(self.name())
    }
}

/// A distribution name this crate does not know.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown ROS 2 distribution {0:?} (humble or jazzy; kilted and rolling write as jazzy)")]
pub struct UnknownDistro(pub String);

impl FromStr for RosDistro {
    type Err = UnknownDistro;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        match name {
            "humble" => Ok(Self::Humble),
            "jazzy" | "kilted" | "rolling" => Ok(Self::Jazzy),
            other => Err(UnknownDistro(other.to_owned())),
        }
    }
}
