//! rmw_zenoh's names on the wire: the key expression of a topic, the liveliness tokens that make
//! nodes, publishers and subscriptions appear in the ROS graph (`ros2 node list`, `ros2 topic
//! list`), and the attachment every message carries.
//!
//! - Topic: `<domain>/<topic without its leading />/<pkg::msg::dds_::Type_>/<RIHS01_hash>`.
//! - Token: `@ros2_lv/<domain>/<zid>/<nid>/<eid>/<NN|MP|MS>/<enclave>/<namespace>/<node>`, and
//!   for a publisher or subscription `/<topic>/<type>/<hash>/<qos>`, each component with its
//!   `/` written `%` (an empty namespace or enclave, `/` in ROS, is `%`).
//! - QoS: `reliability:durability:history,depth:deadline_s,ns:lifespan_s,ns:liveliness,s,ns`
//!   with rmw's enum numbers, each left empty where it equals rmw_zenoh's default (reliable,
//!   volatile, keep last 42, infinite durations, automatic liveliness).
//! - Attachment (Zenoh's serialization): sequence number `i64`, source timestamp `i64` (ns
//!   since the Unix epoch), source GID as a 16-byte sequence (LEB128 length `0x10`, bytes).
//!
//! Plain functions of strings and numbers, no I/O.

use super::msgs::MsgType;

/// What an entity is in the ROS graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Entity {
    Node,
    Publisher,
    Subscription,
}

impl Entity {
    fn code(self) -> &'static str {
        match self {
            Entity::Node => "NN",
            Entity::Publisher => "MP",
            Entity::Subscription => "MS",
        }
    }
}

/// The QoS of an endpoint, as far as Kestrel's differ.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    pub transient_local: bool,
    /// `KEEP_LAST` depth.
    pub depth: u32,
}

/// rmw_zenoh's default depth: a QoS with it leaves the field empty.
const DEFAULT_DEPTH: u32 = 42;
/// `RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL`.
const TRANSIENT_LOCAL: u8 = 1;

impl Qos {
    /// Reliable, volatile, keep last 10 (the depth rclcpp's publishers are usually given).
    pub const DEFAULT: Qos = Qos {
        transient_local: false,
        depth: 10,
    };
    /// Reliable, transient local, keep last 1: a latched map, as `map_server` publishes it.
    pub const LATCHED: Qos = Qos {
        transient_local: true,
        depth: 1,
    };

    /// The QoS component of a liveliness token (always reliable, keep last).
    pub fn key(&self) -> String {
        let durability = if self.transient_local {
            TRANSIENT_LOCAL.to_string()
        } else {
            String::new()
        };
        let depth = if self.depth == DEFAULT_DEPTH {
            String::new()
        } else {
            self.depth.to_string()
        };
        format!(":{durability}:,{depth}:,:,:,,")
    }
}

/// A name as one key component: `/` as `%`, empty as `%`.
pub fn mangle(name: &str) -> String {
    if name.is_empty() {
        "%".into()
    } else {
        name.replace('/', "%")
    }
}

/// The key expression a topic's messages are put on.
pub fn topic_key(domain: u32, topic: &str, ty: &MsgType) -> String {
    format!(
        "{domain}/{}/{}/{}",
        topic.trim_matches('/'),
        ty.dds_name,
        ty.hash
    )
}

/// Who declares a token: the Zenoh session, the node's number and the entity's.
#[derive(Debug, Clone)]
pub struct Owner<'a> {
    pub domain: u32,
    /// The session's Zenoh id (hex, as Zenoh prints it).
    pub zid: &'a str,
    pub node_id: u32,
    /// ROS namespace of the node (`""` = `/`).
    pub namespace: &'a str,
    pub node: &'a str,
}

/// A topic an endpoint is on.
#[derive(Debug, Clone, Copy)]
pub struct Endpoint<'a> {
    /// Fully qualified (`/ns/drone_0/pose`).
    pub topic: &'a str,
    pub ty: &'a MsgType,
    pub qos: Qos,
}

/// The liveliness token of the node itself (`endpoint: None`, `entity` = its node id) or of
/// one of its publishers or subscriptions.
pub fn liveliness_token(
    owner: &Owner,
    entity_id: u32,
    kind: Entity,
    endpoint: Option<Endpoint>,
) -> String {
    let namespace = if owner.namespace.is_empty() {
        "/"
    } else {
        owner.namespace
    };
    let mut key = format!(
        "@ros2_lv/{}/{}/{}/{entity_id}/{}/%/{}/{}",
        owner.domain,
        owner.zid,
        owner.node_id,
        kind.code(),
        mangle(namespace),
        mangle(owner.node)
    );
    if let Some(e) = endpoint {
        key.push_str(&format!(
            "/{}/{}/{}/{}",
            mangle(e.topic),
            e.ty.dds_name,
            e.ty.hash,
            e.qos.key()
        ));
    }
    key
}

/// A 16-byte id for an entity, the same for the same token (FNV-1a, twice, with different
/// offsets). rmw_zenoh derives its GIDs another way (XXH3 of the token); any unique 16 bytes
/// serve a subscriber, which only compares them.
pub fn gid(token: &str) -> [u8; 16] {
    let fnv = |offset: u64| {
        token.bytes().fold(offset, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
        })
    };
    let mut out = [0; 16];
    out[..8].copy_from_slice(&fnv(0xcbf2_9ce4_8422_2325).to_le_bytes());
    out[8..].copy_from_slice(&fnv(0x6c62_272e_07bb_0142).to_le_bytes());
    out
}

/// What rmw_zenoh attaches to every message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Attachment {
    pub sequence_number: i64,
    pub source_timestamp_ns: i64,
    pub source_gid: [u8; 16],
}

/// Bytes of an attachment: 8 + 8 + 1 + 16.
pub const ATTACHMENT_BYTES: usize = 33;

impl Attachment {
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(ATTACHMENT_BYTES);
        out.extend_from_slice(&self.sequence_number.to_le_bytes());
        out.extend_from_slice(&self.source_timestamp_ns.to_le_bytes());
        out.push(16);
        out.extend_from_slice(&self.source_gid);
        out
    }

    /// `None` unless exactly the layout above.
    pub fn decode(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != ATTACHMENT_BYTES || bytes.get(16) != Some(&16) {
            return None;
        }
        let sequence_number = i64::from_le_bytes(bytes.get(0..8)?.try_into().ok()?);
        let source_timestamp_ns = i64::from_le_bytes(bytes.get(8..16)?.try_into().ok()?);
        let source_gid = bytes.get(17..33)?.try_into().ok()?;
        Some(Self {
            sequence_number,
            source_timestamp_ns,
            source_gid,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros2::msgs::{OCCUPANCY_GRID, POSE_STAMPED};

    const ZID: &str = "a1b2c3d4e5f60718293a4b5c6d7e8f90";

    fn owner(namespace: &str) -> Owner<'_> {
        Owner {
            domain: 0,
            zid: ZID,
            node_id: 0,
            namespace,
            node: "kestrel",
        }
    }

    #[test]
    fn topic_keys_drop_the_leading_slash_and_name_type_and_hash() {
        assert_eq!(
            topic_key(7, "/fleet/drone_0/pose", &POSE_STAMPED),
            "7/fleet/drone_0/pose/geometry_msgs::msg::dds_::PoseStamped_/\
             RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8"
        );
    }

    #[test]
    fn tokens_mangle_slashes_and_empty_names() {
        assert_eq!(
            liveliness_token(&owner(""), 0, Entity::Node, None),
            format!("@ros2_lv/0/{ZID}/0/0/NN/%/%/kestrel")
        );
        let pose = Endpoint {
            topic: "/fleet/drone_0/pose",
            ty: &POSE_STAMPED,
            qos: Qos::DEFAULT,
        };
        assert_eq!(
            liveliness_token(&owner("/fleet"), 3, Entity::Publisher, Some(pose)),
            format!(
                "@ros2_lv/0/{ZID}/0/3/MP/%/%fleet/kestrel/%fleet%drone_0%pose/\
                 geometry_msgs::msg::dds_::PoseStamped_/{}/::,10:,:,:,,",
                POSE_STAMPED.hash
            )
        );
        let map = Endpoint {
            topic: "/map",
            ty: &OCCUPANCY_GRID,
            qos: Qos::LATCHED,
        };
        let token = liveliness_token(&owner(""), 9, Entity::Subscription, Some(map));
        assert!(
            token.ends_with("/MS/%/%/kestrel/%map/nav_msgs::msg::dds_::OccupancyGrid_/RIHS01_8d348150c12913a31ee0ec170fbf25089e4745d17035792a1ba94d6f0bc0cfc7/:1:,1:,:,:,,"),
            "{token}"
        );
    }

    #[test]
    fn qos_fields_equal_to_the_default_are_left_empty() {
        assert_eq!(
            Qos {
                transient_local: false,
                depth: 42
            }
            .key(),
            "::,:,:,:,,"
        );
        assert_eq!(Qos::DEFAULT.key(), "::,10:,:,:,,");
        assert_eq!(Qos::LATCHED.key(), ":1:,1:,:,:,,");
    }

    #[test]
    fn the_attachment_is_33_bytes_and_reads_back() {
        let a = Attachment {
            sequence_number: 1,
            source_timestamp_ns: 0x0102_0304_0506_0708,
            source_gid: [0xab; 16],
        };
        let bytes = a.encode();
        let mut expected = vec![1, 0, 0, 0, 0, 0, 0, 0, 8, 7, 6, 5, 4, 3, 2, 1, 16];
        expected.extend([0xab; 16]);
        assert_eq!(bytes, expected);
        assert_eq!(Attachment::decode(&bytes), Some(a));
        assert_eq!(Attachment::decode(&bytes[..32]), None);
    }

    #[test]
    fn gids_differ_per_token_and_repeat_per_token() {
        assert_eq!(gid("a"), gid("a"));
        assert_ne!(gid("a"), gid("b"));
    }
}
