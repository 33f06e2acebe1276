//! Names in rmw_zenoh's form (its docs/design.md, "Topic and Service name mapping to Zenoh key
//! expressions" and "Graph Cache"; rmw_zenoh_cpp's `liveliness_utils.cpp`): a topic's or
//! service's key expression `<domain_id>/<name>/<dds type name>/<type hash>`, the liveliness
//! tokens under `@ros2_lv` that make the bridge's node, publishers and services appear in the
//! ROS 2 graph, each entity's GID (XXH3-128 of its token), and the attachment of every message,
//! request and reply.
//!
//! For Humble ([`RosDistro::Humble`]) the type hash chunk is `TypeHashNotSupported`, as
//! rmw_zenoh's Humble releases write it; nothing else differs.

use taxel_ros2::{InterfaceType, RosDistro};

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

/// The key expression of `name` (a fully qualified topic or service name, `/a/b`) of
/// `interface` (a message type for a topic, a service type for a service), as rmw_zenoh of
/// `distro` declares it.
pub fn key_expression(
    domain_id: u32,
    name: &str,
    interface: &dyn InterfaceType,
    distro: RosDistro,
) -> String {
    format!(
        "{domain_id}/{}/{}/{}",
        name.trim_start_matches('/').trim_end_matches('/'),
        interface.dds_type_name(),
        distro.key_expression_hash(interface.type_hash())
    )
}

/// An entity's GID as rmw_zenoh computes it (`liveliness::Entity`'s constructor): XXH3-128 of
/// its liveliness token's key expression, the low 64 bits then the high 64 bits, each
/// little-endian. `ros2 topic info -v` and a subscriber's `publisher_gid` show it.
pub fn gid(liveliness_key_expression: &str) -> [u8; 16] {
    // Low 64 bits then high 64 bits, each little-endian: the 128-bit value little-endian.
    xxhash_rust::xxh3::xxh3_128(liveliness_key_expression.as_bytes()).to_le_bytes()
}

/// Who declares liveliness tokens: one Zenoh session holding one ROS 2 node.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GraphNode {
    /// The ROS 2 distribution whose rmw_zenoh the tokens are for.
    pub ros_distro: RosDistro,
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
        message_type: &dyn InterfaceType,
    ) -> String {
        self.entity_token(entity_id, "MP", topic, message_type)
    }

    /// A service server's token (`SS`): entity `entity_id` serving `service_type` on
    /// `service` (rmw_zenoh's default service QoS is also reliable, volatile, keep last 10).
    pub fn service_token(
        &self,
        entity_id: u32,
        service: &str,
        service_type: &dyn InterfaceType,
    ) -> String {
        self.entity_token(entity_id, "SS", service, service_type)
    }

    fn entity_token(
        &self,
        entity_id: u32,
        kind: &str,
        name: &str,
        interface: &dyn InterfaceType,
    ) -> String {
        format!(
            "{}/{}/{}/{}/{QOS_KEEP_LAST_10}",
            self.prefix(entity_id, kind),
            mangle(name),
            interface.dds_type_name(),
            self.ros_distro.key_expression_hash(interface.type_hash())
        )
    }
}

/// What every publisher sends along with a message, in rmw_zenoh's attachment layout
/// (`attachment_helpers.cpp`, zenoh-ext's serialisation of two `int64` and a 16-byte array):
/// the sequence number and source timestamp (ns since the Unix epoch) as little-endian `i64`,
/// the length of the GID (16) in one byte, and the GID. A client's request carries the same,
/// with its own GID; the reply carries the request's sequence number and GID.
pub fn attachment(sequence_number: i64, source_timestamp_ns: i64, gid: &[u8; 16]) -> [u8; 33] {
    let mut bytes = [0u8; 33];
    bytes[..8].copy_from_slice(&sequence_number.to_le_bytes());
    bytes[8..16].copy_from_slice(&source_timestamp_ns.to_le_bytes());
    bytes[16] = 16;
    bytes[17..].copy_from_slice(gid);
    bytes
}

/// An attachment read back ([`attachment`]'s layout).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Attachment {
    /// The sender's sequence number.
    pub sequence_number: i64,
    /// When it was sent, ns since the Unix epoch.
    pub source_timestamp_ns: i64,
    /// The sender's GID.
    pub gid: [u8; 16],
}

impl Attachment {
    /// Reads an attachment; `None` unless it is [`attachment`]'s 33 bytes.
    pub fn parse(bytes: &[u8]) -> Option<Self> {
        let bytes: &[u8; 33] = bytes.try_into().ok()?;
        let (sequence, rest) = bytes.split_first_chunk::<8>()?;
        let (timestamp, rest) = rest.split_first_chunk::<8>()?;
        let (length, gid) = rest.split_first()?;
        Some(Self {
            sequence_number: i64::from_le_bytes(*sequence),
            source_timestamp_ns: i64::from_le_bytes(*timestamp),
            gid: (*length == 16).then(|| gid.try_into().ok()).flatten()?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use taxel_ros2::services::TRIGGER_SERVICE;
    use taxel_ros2::types::{HEADER_MESSAGE, POINT_CLOUD2_MESSAGE};

    // The examples of rmw_zenoh's docs/design.md, with this crate's types in place of theirs.
    #[test]
    fn key_expressions_and_tokens_have_rmw_zenohs_shape() {
        assert_eq!(
            key_expression(0, "/robot1/chatter", &HEADER_MESSAGE, RosDistro::Jazzy),
            "0/robot1/chatter/std_msgs::msg::dds_::Header_/RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01"
        );
        let node = GraphNode {
            ros_distro: RosDistro::Jazzy,
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
        assert_eq!(
            node.service_token(11, "/taxel/device0/tare", &TRIGGER_SERVICE),
            "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/11/SS/%/%/talker/%taxel%device0%tare/std_srvs::srv::dds_::Trigger_/RIHS01_eeff2cd6fa5ad9d27cdf4dec64818317839b62f212a91e6b5304b634b2062c5f/::,10:,:,:,,"
        );
        let namespaced = GraphNode {
            namespace: "/robot".into(),
            ..node
        };
        assert!(namespaced.node_token().ends_with("/NN/%/%robot/talker"));
    }

    // rmw_zenoh's Humble releases (0.1.x: rmw_publisher_data.cpp, rmw_service_data.cpp) put
    // this constant where a type hash goes, in key expressions and tokens alike.
    #[test]
    fn humble_has_no_type_hash() {
        assert_eq!(
            key_expression(
                0,
                "/taxel/device0/tare",
                &TRIGGER_SERVICE,
                RosDistro::Humble
            ),
            "0/taxel/device0/tare/std_srvs::srv::dds_::Trigger_/TypeHashNotSupported"
        );
        let node = GraphNode {
            ros_distro: RosDistro::Humble,
            domain_id: 0,
            session_id: "1".into(),
            namespace: "/".into(),
            node_name: "n".into(),
        };
        assert_eq!(
            node.publisher_token(1, "/t", &HEADER_MESSAGE),
            "@ros2_lv/0/1/0/1/MP/%/%/n/%t/std_msgs::msg::dds_::Header_/TypeHashNotSupported/::,10:,:,:,,"
        );
    }

    // XXH3-128's published test vector of the empty input (xxHash's sanity check:
    // 0x99AA06D3014798D86001C324468D497F) and a token hashed by Python's `xxhash` 4.1.0 (a
    // binding of the reference C library), `xxh3_128_intdigest(token).to_bytes(16, "little")`.
    #[test]
    fn the_gid_is_xxh3_128_of_the_token_low_half_first() {
        let mut empty = [0u8; 16];
        empty[..8].copy_from_slice(&0x6001_C324_468D_497F_u64.to_le_bytes());
        empty[8..].copy_from_slice(&0x99AA_06D3_0147_98D8_u64.to_le_bytes());
        assert_eq!(gid(""), empty);
        let token = "@ros2_lv/0/8b20917502ee955ac4476e0266340d5c/0/1/MP/%/%/taxel_bridge/%taxel%device0%pad0%pressure/sensor_msgs::msg::dds_::PointCloud2_/RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5/::,10:,:,:,,";
        assert_eq!(hex(&gid(token)), PYTHON_XXH3_OF_TOKEN);
    }

    /// `xxhash.xxh3_128_intdigest(token).to_bytes(16, "little").hex()` of the token above.
    const PYTHON_XXH3_OF_TOKEN: &str = "d65ad764ed38b6144669a31eec5d62a2";

    fn hex(bytes: &[u8]) -> String {
        bytes.iter().map(|byte| format!("{byte:02x}")).collect()
    }

    #[test]
    fn an_attachment_reads_back() {
        let bytes = attachment(7, 9, &[3; 16]);
        assert_eq!(
            Attachment::parse(&bytes),
            Some(Attachment {
                sequence_number: 7,
                source_timestamp_ns: 9,
                gid: [3; 16]
            })
        );
        assert_eq!(Attachment::parse(&bytes[..32]), None);
        let mut bad_length = bytes;
        bad_length[16] = 15;
        assert_eq!(Attachment::parse(&bad_length), None);
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
