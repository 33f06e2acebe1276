//! Names in rmw_zenoh's form (its docs/design.md, "Topic and Service name mapping to Zenoh key
//! expressions" and "Graph Cache"): a topic's data key expression
//! `<domain_id>/<topic>/<dds type name>/<type hash>`, and the liveliness tokens under
//! `@ros2_lv` that make the bridge's node and publishers appear in the ROS 2 graph.

use taxel_ros2::MessageType;

/// The QoS every publisher of the bridge declares, in rmw_zenoh's compact form (only what
/// differs from rmw_zenoh's defaults is written): reliable, volatile, keep last 10.
pub const QOS_KEEP_LAST_10: &str = "::,10:,:,:,,";

/// A name with each `/` replaced by `%` (rmw_zenoh's "mangled" names); `%` alone for an empty
/// name.
pub fn mangle(name: &str) -> String {
    if name.is_empty() {
        "%".to_owned()
    } else {
        name.replace('/', "%")
    }
}

/// The data key expression of `topic` (a fully qualified name, `/a/b`) carrying `message_type`.
pub fn data_key_expression(domain_id: u32, topic: &str, message_type: &MessageType) -> String {
    format!(
        "{domain_id}/{}/{}/{}",
        topic.trim_start_matches('/'),
        message_type.dds_type_name(),
        message_type.type_hash()
    )
}

/// Who declares liveliness tokens: one Zenoh session holding one ROS 2 node.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GraphNode {
    /// `ROS_DOMAIN_ID`.
    pub domain_id: u32,
    /// The Zenoh session id, as its `Display` writes it.
    pub session_id: String,
    /// The node's namespace (`/` or empty for none, else `/ns`).
    pub namespace: String,
    /// The node's name.
    pub node_name: String,
}

/// The node's id within its session; entities of the node are numbered after it.
pub const NODE_ID: u32 = 0;

impl GraphNode {
    fn prefix(&self, entity_id: u32, kind: &str) -> String {
        let namespace = if self.namespace == "/" {
            ""
        } else {
            self.namespace.as_str()
        };
        format!(
            "@ros2_lv/{}/{}/{NODE_ID}/{entity_id}/{kind}/%/{}/{}",
            self.domain_id,
            self.session_id,
            mangle(namespace),
            self.node_name
        )
    }

    /// The node's token (`NN`).
    pub fn node_token(&self) -> String {
        self.prefix(NODE_ID, "NN")
    }

    /// A publisher's token (`MP`): entity `entity_id` (from 1) publishing `message_type` on
    /// `topic`.
    pub fn publisher_token(
        &self,
        entity_id: u32,
        topic: &str,
        message_type: &MessageType,
    ) -> String {
        format!(
            "{}/{}/{}/{}/{QOS_KEEP_LAST_10}",
            self.prefix(entity_id, "MP"),
            mangle(topic),
            message_type.dds_type_name(),
            message_type.type_hash()
        )
    }
}

/// What every publisher sends along with a message, in rmw_zenoh's attachment layout: the
/// sequence number and source timestamp (ns since the Unix epoch) as little-endian `i64`, the
/// length of the publisher's GID (16) in one byte, and the GID.
pub fn attachment(sequence_number: i64, source_timestamp_ns: i64, gid: &[u8; 16]) -> [u8; 33] {
    let mut bytes = [0u8; 33];
    bytes[..8].copy_from_slice(&sequence_number.to_le_bytes());
    bytes[8..16].copy_from_slice(&source_timestamp_ns.to_le_bytes());
    bytes[16] = 16;
    bytes[17..].copy_from_slice(gid);
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;
    use taxel_ros2::types::{HEADER_MESSAGE, POINT_CLOUD2_MESSAGE};

    // The examples of rmw_zenoh's docs/design.md, with this crate's types in place of theirs.
    #[test]
    fn key_expressions_and_tokens_have_rmw_zenohs_shape() {
        assert_eq!(
            data_key_expression(0, "/robot1/chatter", &HEADER_MESSAGE),
            "0/robot1/chatter/std_msgs::msg::dds_::Header_/RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01"
        );
        let node = GraphNode {
            domain_id: 2,
            session_id: "8b20917502ee955ac4476e0266340d5c".into(),
            namespace: "/".into(),
            node_name: "talker".into(),
        };
        assert_eq!(
            node.node_token(),
            "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/0/NN/%/%/talker"
        );
        assert_eq!(
            node.publisher_token(10, "/chatter", &POINT_CLOUD2_MESSAGE),
            "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/sensor_msgs::msg::dds_::PointCloud2_/RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5/::,10:,:,:,,"
        );
        let namespaced = GraphNode {
            namespace: "/robot".into(),
            ..node
        };
        assert!(namespaced.node_token().ends_with("/NN/%/%robot/talker"));
    }

    #[test]
    fn the_attachment_is_33_bytes_little_endian() {
        let bytes = attachment(258, -1, &[7; 16]);
        assert_eq!(bytes[..8], [2, 1, 0, 0, 0, 0, 0, 0]);
        assert_eq!(bytes[8..16], [0xff; 8]);
        assert_eq!(bytes[16], 16);
        assert_eq!(bytes[17..], [7; 16]);
    }
}
