//! ROS 2 topics as Zenoh keys: the key expressions, liveliness tokens, type hashes and
//! message attachment of the live output and the Zenoh odometry, as text. No IO, no Zenoh
//! session: the session (`zenoh_node`) declares what these name.
//!
//! Two key conventions (`[output.zenoh] convention`), the payload the CDR serialisation with
//! its 4-byte encapsulation header either way (what a DDS writer puts on the wire):
//!
//! - `ros2dds` (default), zenoh-bridge-ros2dds's: the ROS 2 topic `/slam/odometry` is the
//!   key `slam/odometry` (`namespace = "robot1"` gives `robot1/slam/odometry`, as the bridge's
//!   `namespace` option does), the Zenoh encoding `application/cdr;<ros type>`. For each topic
//!   the daemon also declares the liveliness token a bridge declares for a route from a ROS
//!   publisher (`@/<zid>/@ros2_lv/MP/<key>/<type>/<qos>`, `/` written `§`), so a
//!   zenoh-bridge-ros2dds 1.x on the ROS side can create the matching DDS writers. The
//!   default because a ROS 2 system on its usual DDS reaches us through the bridge, and plain
//!   Zenoh tools read the keys as topic names.
//! - `rmw_zenoh`, for ROS 2 nodes running `rmw_zenoh_cpp` (rmw_zenoh's `docs/design.md`):
//!   `<domain_id>/<fully qualified topic>/<package>::msg::dds_::<Type>_/RIHS01_<sha256>`, each
//!   message with rmw_zenoh's 33-byte attachment (sequence number and time as little-endian
//!   i64, then 16 and the publisher's 16-byte GID), and the graph's liveliness tokens: the node
//!   `@ros2_lv/<domain>/<zid>/<node id>/<node id>/NN/%/<namespace>/slam_node` and one per
//!   publisher (`MP`) or subscription (`MS`) with the mangled topic, type, hash and QoS. The
//!   type hashes are tabulated ([`type_hash`]): computed with `rosbags` 0.11.9's
//!   `Typestore.hash_rihs01` (the ROS 2 Humble and Jazzy stores agree; Navtech's types from
//!   our `ros-msgs` definitions), which gives `std_msgs/msg/String`'s hash as rmw_zenoh's design
//!   document prints it and `std_msgs/msg/Header`'s and `builtin_interfaces/msg/Time`'s as
//!   rosidl's generated `header__description.c` holds them; `tests/python/check_zenoh.py`
//!   recomputes the table with rosbags.

use config::live::{ZenohConvention, ZenohSettings};

use super::live_error::LiveError;

/// The Zenoh key of a ROS 2 topic under `namespace`, as zenoh-bridge-ros2dds maps it: the
/// topic without its leading slash, after the namespace.
pub fn topic_key(namespace: &str, topic: &str) -> String {
    let topic = topic.trim_start_matches('/');
    if namespace.is_empty() {
        topic.to_owned()
    } else {
        format!("{namespace}/{topic}")
    }
}

/// The zenoh-bridge-ros2dds QoS text of a keyless topic: reliable; durability volatile
/// (default) or transient-local; keep-last `depth`.
pub fn bridge_qos(transient_local: bool, depth: u32) -> String {
    // cyclors' enums: RELIABLE = 1, TRANSIENT_LOCAL = 1, KEEP_LAST = 0.
    format!(":1:{}:0,{depth}", if transient_local { "1" } else { "" })
}

/// The liveliness key a zenoh-bridge-ros2dds 1.x declares for a route from a ROS publisher.
pub fn bridge_liveliness_key(zid: &str, key: &str, ros_type: &str, qos: &str) -> String {
    format!(
        "@/{zid}/@ros2_lv/MP/{}/{}/{qos}",
        key.replace('/', "§"),
        ros_type.replace('/', "§")
    )
}

/// RIHS01 type hashes (REP-2011) of the types the daemon and `radar-zenoh` publish or
/// subscribe to, by ROS 2 type name; computed with `rosbags` 0.11.9 (`hash_rihs01`, ROS 2
/// Humble and Jazzy stores alike; the Navtech types registered from `ros-msgs`' definitions).
/// (`std_msgs/msg/String` is here for the known answer in rmw_zenoh's design document.)
const TYPE_HASHES: &[(&str, &str)] = &[
    (
        "std_msgs/msg/String",
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    ),
    (
        "nav_msgs/msg/Odometry",
        "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
    ),
    (
        "geometry_msgs/msg/TwistStamped",
        "RIHS01_5f0fcd4f81d5d06ad9b4c4c63e3ea51b82d6ae4d0558f1d475229b1121db6f64",
    ),
    (
        "geometry_msgs/msg/PoseWithCovarianceStamped",
        "RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e",
    ),
    (
        "tf2_msgs/msg/TFMessage",
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    ),
    (
        "sensor_msgs/msg/PointCloud2",
        "RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5",
    ),
    (
        "visualization_msgs/msg/MarkerArray",
        "RIHS01_86cb8800b6fb05b5eff1abd7a56f62a5641d3ae9a1c29e78e67e704f1d067dcf",
    ),
    (
        "navtech_msgs/msg/RadarFftDataMsg",
        "RIHS01_b071acffe742f6e8f2a8168f8ea514e992079120f9dee57f2f32d5affc30e122",
    ),
    (
        "navtech_msgs/msg/RadarBScanMsg",
        "RIHS01_fb305313d56760acfdbf956d3a281ee6fe5f4c757a22accfbe6d05f6a87c3d33",
    ),
    (
        "navtech_msgs/msg/RadarConfigurationMsg",
        "RIHS01_f7488b9dec30986184334939b41b250984e6fbae5648f9b932535392eceee5dd",
    ),
];

/// The RIHS01 hash of `ros_type` (`package/msg/Type`), when it is tabulated.
pub fn type_hash(ros_type: &str) -> Option<&'static str> {
    TYPE_HASHES
        .iter()
        .find(|(name, _)| *name == ros_type)
        .map(|(_, hash)| *hash)
}

/// Every tabulated type and its hash.
pub fn type_hashes() -> &'static [(&'static str, &'static str)] {
    TYPE_HASHES
}

/// The DDS name of a ROS 2 type, as rmw_zenoh keys it: `nav_msgs/msg/Odometry` is
/// `nav_msgs::msg::dds_::Odometry_`.
pub fn dds_type_name(ros_type: &str) -> String {
    match ros_type.rsplit_once('/') {
        Some((package, name)) => format!("{}::dds_::{name}_", package.replace('/', "::")),
        None => format!("{ros_type}_"),
    }
}

/// The fully qualified name of `topic` under `namespace`: `/robot1/slam/odometry`.
pub fn fully_qualified(namespace: &str, topic: &str) -> String {
    format!("/{}", topic_key(namespace, topic))
}

/// `/` written `%`, as rmw_zenoh mangles names in liveliness tokens; empty is `%`.
pub fn mangle(name: &str) -> String {
    if name.is_empty() {
        "%".into()
    } else {
        name.replace('/', "%")
    }
}

/// rmw_zenoh's key for `topic` of `ros_type` in `domain_id` under `namespace`.
pub fn rmw_zenoh_key(
    domain_id: u32,
    namespace: &str,
    topic: &str,
    ros_type: &str,
) -> Result<String, LiveError> {
    let hash = type_hash(ros_type).ok_or_else(|| LiveError::UnknownTypeHash(ros_type.into()))?;
    Ok(format!(
        "{domain_id}{}/{}/{hash}",
        fully_qualified(namespace, topic),
        dds_type_name(ros_type)
    ))
}

/// rmw_zenoh's compact QoS text (`qos_to_keyexpr`): each policy left empty when it is the
/// default (reliable, volatile, keep-last), so reliable keep-last 10 is `::,10:,:,:,,` and
/// with transient-local durability (`1`) `:1:,1:,:,:,,` for depth 1.
pub fn rmw_zenoh_qos(transient_local: bool, depth: u32) -> String {
    format!(
        ":{}:,{depth}:,:,:,,",
        if transient_local { "1" } else { "" }
    )
}

/// What a liveliness token of rmw_zenoh's graph stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EntityKind {
    /// A message publisher (`MP`).
    Publisher,
    /// A message subscription (`MS`).
    Subscription,
}

/// rmw_zenoh's liveliness token of the node `node` (id `node_id`) of session `zid`.
pub fn rmw_zenoh_node_token(
    domain_id: u32,
    zid: &str,
    node_id: u32,
    namespace: &str,
    node: &str,
) -> String {
    let ns = if namespace.is_empty() {
        "%".to_owned()
    } else {
        mangle(&format!("/{namespace}"))
    };
    format!("@ros2_lv/{domain_id}/{zid}/{node_id}/{node_id}/NN/%/{ns}/{node}")
}

/// rmw_zenoh's liveliness token of a publisher or subscription (`entity_id`) of the node.
#[allow(clippy::too_many_arguments)]
pub fn rmw_zenoh_entity_token(
    domain_id: u32,
    zid: &str,
    node_id: u32,
    entity_id: u32,
    kind: EntityKind,
    namespace: &str,
    node: &str,
    topic: &str,
    ros_type: &str,
    qos: &str,
) -> Result<String, LiveError> {
    let hash = type_hash(ros_type).ok_or_else(|| LiveError::UnknownTypeHash(ros_type.into()))?;
    let ns = if namespace.is_empty() {
        "%".to_owned()
    } else {
        mangle(&format!("/{namespace}"))
    };
    let kind = match kind {
        EntityKind::Publisher => "MP",
        EntityKind::Subscription => "MS",
    };
    Ok(format!(
        "@ros2_lv/{domain_id}/{zid}/{node_id}/{entity_id}/{kind}/%/{ns}/{node}/{}/{}/{hash}/{qos}",
        mangle(&fully_qualified(namespace, topic)),
        dds_type_name(ros_type)
    ))
}

/// rmw_zenoh's attachment to each message: the sequence number and the source time (ns
/// since the epoch) as little-endian i64, the GID's length (16), the GID.
pub fn rmw_zenoh_attachment(sequence: i64, time_ns: i64, gid: &[u8; 16]) -> [u8; 33] {
    let mut out = [0u8; 33];
    out[..8].copy_from_slice(&sequence.to_le_bytes());
    out[8..16].copy_from_slice(&time_ns.to_le_bytes());
    out[16] = 16;
    out[17..].copy_from_slice(gid);
    out
}

/// The key of `topic` (`ros_type`) under the settings' convention and namespace.
pub fn key_for(settings: &ZenohSettings, topic: &str, ros_type: &str) -> Result<String, LiveError> {
    match settings.convention {
        ZenohConvention::Ros2dds => Ok(topic_key(&settings.namespace, topic)),
        ZenohConvention::RmwZenoh => {
            rmw_zenoh_key(settings.domain_id, &settings.namespace, topic, ros_type)
        }
    }
}
