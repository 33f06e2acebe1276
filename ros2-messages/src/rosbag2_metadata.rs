//! What rosbag2's MCAP storage plugin writes besides the messages, so that `ros2 bag info` and
//! `ros2 bag play` read a file [`crate::McapRecorder`] wrote as one of their own. From
//! rosbag2_storage_mcap's `mcap_storage.cpp` (branches `jazzy` and `humble` of ros2/rosbag2)
//! and rosbag2_storage's `yaml.hpp` and `qos.cpp`:
//!
//! - each channel's metadata: `offered_qos_profiles`, the YAML list of the publishers' QoS
//!   profiles (`serialize_rclcpp_qos_vector`), and, from Jazzy on, `topic_type_hash`;
//! - one Metadata record named `rosbag2`: from Jazzy on its key `serialized_metadata` holds the
//!   bag's `BagMetadata` as YAML (version 9, what `MCAPStorage::update_metadata` writes and
//!   `MCAPStorage::read_metadata` decodes); in Humble its only key is `ROS_DISTRO`.
//!
//! Version 9 writes QoS policies as words (`keep_last`, `reliable`, `volatile`, `automatic`:
//! rmw's `rmw_qos_*_policy_to_str`), Humble as the rmw enumerations' numbers; Jazzy reads both.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use crate::distro::RosDistro;

/// rmw's `RMW_DURATION_INFINITE`: what a publisher without deadline, lifespan or lease offers.
const INFINITE_SEC: u64 = 9_223_372_036;
/// The nanoseconds of [`INFINITE_SEC`].
const INFINITE_NSEC: u64 = 854_775_807;

/// The depth of the keep-last history every publisher of the bridge offers.
pub const HISTORY_DEPTH: u32 = 10;

/// `offered_qos_profiles` of a topic published reliable, volatile, keep last
/// [`HISTORY_DEPTH`] (every topic of the bridge and of `taxel record`), in `distro`'s form.
pub fn offered_qos_profiles(distro: RosDistro) -> String {
    // The rmw enumerations (rmw/types.h): KEEP_LAST 1, RELIABLE 1, VOLATILE 2, AUTOMATIC 1.
    let (history, reliability, durability, liveliness) = match distro {
        RosDistro::Humble => ("1", "1", "2", "1"),
        RosDistro::Jazzy => ("keep_last", "reliable", "volatile", "automatic"),
    };
    let infinite = format!("\n    sec: {INFINITE_SEC}\n    nsec: {INFINITE_NSEC}");
    format!(
        "- history: {history}\n  depth: {HISTORY_DEPTH}\n  reliability: {reliability}\n  durability: {durability}\n  deadline:{infinite}\n  lifespan:{infinite}\n  liveliness: {liveliness}\n  liveliness_lease_duration:{infinite}\n  avoid_ros_namespace_conventions: false"
    )
}

/// The channel metadata of a topic of type hash `type_hash`.
pub fn channel_metadata(distro: RosDistro, type_hash: &str) -> BTreeMap<String, String> {
    let mut metadata = BTreeMap::from([(
        "offered_qos_profiles".to_owned(),
        offered_qos_profiles(distro),
    )]);
    if distro.has_type_hashes() {
        metadata.insert("topic_type_hash".to_owned(), type_hash.to_owned());
    }
    metadata
}

/// One topic of a bag, as the metadata lists it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicSummary {
    /// The topic.
    pub name: String,
    /// Its type, `pkg/msg/Type`.
    pub type_name: String,
    /// Its RIHS01 type hash.
    pub type_hash: String,
    /// Messages written on it.
    pub message_count: u64,
}

/// What the `rosbag2` record says of a bag.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct BagSummary {
    /// The file's name (no directory), if known.
    pub file_name: Option<String>,
    /// Every topic, in the order added.
    pub topics: Vec<TopicSummary>,
    /// The earliest and latest log time, ns since the Unix epoch (`None`: no message).
    pub time_range_ns: Option<(u64, u64)>,
}

/// The `rosbag2` Metadata record's map for `distro`.
pub fn metadata_record(distro: RosDistro, summary: &BagSummary) -> BTreeMap<String, String> {
    match distro {
        RosDistro::Humble => BTreeMap::from([("ROS_DISTRO".to_owned(), distro.name().to_owned())]),
        RosDistro::Jazzy => BTreeMap::from([(
            "serialized_metadata".to_owned(),
            serialized_metadata(summary, distro),
        )]),
    }
}

/// The bag's `BagMetadata` as rosbag2's `YAML::convert<BagMetadata>::encode` writes it
/// (version 9).
pub fn serialized_metadata(summary: &BagSummary, distro: RosDistro) -> String {
    // An empty bag starts at the latest time point, as rosbag2's writer leaves it.
    let (start_ns, end_ns) = summary
        .time_range_ns
        .unwrap_or((i64::MAX as u64, i64::MAX as u64));
    let duration_ns = end_ns.saturating_sub(start_ns);
    let message_count: u64 = summary.topics.iter().map(|topic| topic.message_count).sum();
    let mut yaml = String::new();
    let _ = write!(
        yaml,
        "version: 9\nstorage_identifier: mcap\nduration:\n  nanoseconds: {duration_ns}\nstarting_time:\n  nanoseconds_since_epoch: {start_ns}\nmessage_count: {message_count}\n"
    );
    if summary.topics.is_empty() {
        yaml.push_str("topics_with_message_count: []\n");
    } else {
        yaml.push_str("topics_with_message_count:\n");
    }
    let qos = indented(&offered_qos_profiles(distro), "        ");
    for topic in &summary.topics {
        let _ = write!(
            yaml,
            "  - topic_metadata:\n      name: {}\n      type: {}\n      serialization_format: cdr\n      offered_qos_profiles:\n{qos}\n      type_description_hash: {}\n    message_count: {}\n",
            scalar(&topic.name),
            scalar(&topic.type_name),
            scalar(&topic.type_hash),
            topic.message_count
        );
    }
    yaml.push_str("compression_format: \"\"\ncompression_mode: \"\"\n");
    match &summary.file_name {
        Some(name) => {
            let name = scalar(name);
            let _ = write!(
                yaml,
                "relative_file_paths:\n  - {name}\nfiles:\n  - path: {name}\n    starting_time:\n      nanoseconds_since_epoch: {start_ns}\n    duration:\n      nanoseconds: {duration_ns}\n    message_count: {message_count}\n"
            );
        }
        None => yaml.push_str("relative_file_paths: []\nfiles: []\n"),
    }
    let _ = write!(yaml, "custom_data: ~\nros_distro: {}", distro.name());
    yaml
}

/// Every line of `text` after `indent`.
fn indented(text: &str, indent: &str) -> String {
    text.lines()
        .map(|line| format!("{indent}{line}"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// `text` as a YAML scalar: plain when it is a name (letters, digits, `_/.-`, starting with a
/// letter or `/`), else double-quoted.
fn scalar(text: &str) -> String {
    let plain = text
        .chars()
        .next()
        .is_some_and(|first| first.is_ascii_alphabetic() || first == '/')
        && text
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '/' | '.' | '-'))
        && !matches!(
            text.to_ascii_lowercase().as_str(),
            "true" | "false" | "yes" | "no" | "on" | "off" | "null" | "y" | "n"
        );
    if plain {
        return text.to_owned();
    }
    let mut quoted = String::from("\"");
    for c in text.chars() {
        match c {
            '"' => quoted.push_str("\\\""),
            '\\' => quoted.push_str("\\\\"),
            c if c.is_control() => {
                let _ = write!(quoted, "\\u{:04x}", u32::from(c));
            }
            c => quoted.push(c),
        }
    }
    quoted.push('"');
    quoted
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_plain_and_anything_else_is_quoted() {
        assert_eq!(
            scalar("/taxel/device0/pad0/pressure"),
            "/taxel/device0/pad0/pressure"
        );
        assert_eq!(scalar("rec 1.mcap"), "\"rec 1.mcap\"");
        assert_eq!(scalar("10"), "\"10\"");
        assert_eq!(scalar("yes"), "\"yes\"");
        assert_eq!(scalar("a\"b\n"), "\"a\\\"b\\u000a\"");
    }

    #[test]
    fn humble_has_numbers_no_hash_and_only_the_distribution() {
        let humble = offered_qos_profiles(RosDistro::Humble);
        assert!(
            humble.starts_with("- history: 1\n  depth: 10\n  reliability: 1\n  durability: 2\n")
        );
        assert!(!channel_metadata(RosDistro::Humble, "RIHS01_x").contains_key("topic_type_hash"));
        assert_eq!(
            metadata_record(RosDistro::Humble, &BagSummary::default()),
            BTreeMap::from([("ROS_DISTRO".to_owned(), "humble".to_owned())])
        );
    }

    #[test]
    fn the_jazzy_record_lists_every_topic_with_its_count() {
        let summary = BagSummary {
            file_name: Some("rec.mcap".to_owned()),
            topics: vec![TopicSummary {
                name: "/a".to_owned(),
                type_name: "std_msgs/msg/Header".to_owned(),
                type_hash: "RIHS01_f4".to_owned(),
                message_count: 3,
            }],
            time_range_ns: Some((10, 25)),
        };
        let yaml = serialized_metadata(&summary, RosDistro::Jazzy);
        for expected in [
            "version: 9\n",
            "duration:\n  nanoseconds: 15\n",
            "starting_time:\n  nanoseconds_since_epoch: 10\n",
            "message_count: 3\n",
            "      offered_qos_profiles:\n        - history: keep_last\n          depth: 10\n",
            "      type_description_hash: RIHS01_f4\n    message_count: 3\n",
            "relative_file_paths:\n  - rec.mcap\n",
            "custom_data: ~\nros_distro: jazzy",
        ] {
            assert!(yaml.contains(expected), "{expected:?} in\n{yaml}");
        }
    }
}
