//! Live ROS 2 topics over Zenoh (`[output.zenoh]`, slam-node's `zenoh` feature): the pose
//! (`nav_msgs/Odometry` with covariance), `/tf` and `/tf_static`, the map (`PointCloud2` and
//! `MarkerArray`) and each rotation's detections, CDR-encoded as in the MCAP recording
//! ([`super::ros`]); the same session takes the vehicle's odometry
//! (`[odometry] source = "zenoh"`, `crate::daemon::zenoh_odometry`).
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
//!
//! Never blocking the pipeline: [`LivePublisher::offer`] clones the event into a bounded
//! crossbeam channel with `try_send`; when the channel is full the event is dropped and
//! counted. A thread of its own encodes and publishes; Zenoh's congestion control is `Drop`,
//! so a slow subscriber costs messages, never time on that thread.

use std::collections::BTreeMap;

use config::live::{ZenohConvention, ZenohSettings};
use radar_model::motion::MotionModel;

/// The open Zenoh session a run shares between its publisher and its odometry subscription
/// (only with the `zenoh` feature; without it no value of this type exists).
#[cfg(feature = "zenoh")]
pub type SharedNode = std::sync::Arc<super::zenoh_node::ZenohNode>;
/// The open Zenoh session a run shares: without the `zenoh` feature no value exists.
#[cfg(not(feature = "zenoh"))]
#[derive(Debug, Clone)]
pub enum SharedNode {}

/// What the live output should do, from `[output.zenoh]`.
#[derive(Debug, Clone)]
pub struct LiveOutput {
    /// The validated `[output.zenoh]` table.
    pub zenoh: ZenohSettings,
    /// The motion model, to turn the odometry's steering into the pose message's yaw rate.
    pub motion: MotionModel,
    /// The session to publish on; `None`: the publisher opens its own.
    pub node: Option<SharedNode>,
}

/// Why the live output (or the Zenoh odometry) could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// `[output.zenoh] enabled = true` or `[odometry] source = "zenoh"` in a build without the
    /// `zenoh` feature.
    #[error("[output.zenoh] is enabled or [odometry] source is \"zenoh\" but this slam-node was built without its `zenoh` feature (cargo build --release -p slam-node --features zenoh)")]
    NotBuilt,
    /// The Zenoh session could not be opened (bad endpoint, port in use, no router).
    #[error("opening the Zenoh session: {0}")]
    Open(String),
    /// A key, a publisher or a subscriber could not be declared.
    #[error("declaring the Zenoh publisher or subscriber for {key}: {message}")]
    Declare {
        /// The key.
        key: String,
        /// Zenoh's message.
        message: String,
    },
    /// rmw_zenoh's keys need the type's hash, and this type's is not tabulated.
    #[error("no RIHS01 type hash is known for {0}: the rmw_zenoh convention cannot key it")]
    UnknownTypeHash(String),
    /// The publisher thread could not be started or stopped answering.
    #[error("the Zenoh publisher thread: {0}")]
    Thread(String),
}

/// What the live output published.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LiveSummary {
    /// Messages published per key.
    pub published: BTreeMap<String, u64>,
    /// Events dropped because the publisher's queue was full.
    pub dropped: u64,
    /// Messages that could not be encoded or put.
    pub failed: u64,
}

impl LiveSummary {
    /// Messages published over all keys.
    pub fn total(&self) -> u64 {
        self.published.values().sum()
    }
}

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

#[cfg(feature = "zenoh")]
pub use super::zenoh_node::zenoh_config;
#[cfg(feature = "zenoh")]
pub use publisher::{LivePublisher, RadarPublisher};

/// Topic of the radar's azimuths as Navtech's ROS 2 driver publishes them, one
/// `navtech_msgs/msg/RadarFftDataMsg` each.
pub const TOPIC_FFT_DATA: &str = "/radar_data/fft_data";

/// The node name the daemon's session stands for (rmw_zenoh's liveliness graph).
pub const NODE_NAME: &str = "slam_node";

#[cfg(feature = "zenoh")]
mod publisher {
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::sync::Arc;
    use std::thread::JoinHandle;
    use std::time::Duration;

    use crossbeam_channel::{bounded, Receiver, Sender, TrySendError};
    use radar_model::motion::MotionModel;
    use ros_msgs::builtin::Time;
    use ros_msgs::nav::{Odometry, TFMessage};
    use ros_msgs::sensor::PointCloud2;
    use ros_msgs::visualization::MarkerArray;
    use ros_msgs::{to_cdr, RosMessage};
    use slam_filter::OdometrySample;
    use tracing::{info, warn};

    use super::super::event::OutputEvent;
    use super::super::ros::{
        self, TOPIC_DETECTIONS, TOPIC_MAP, TOPIC_MAP_COVARIANCE, TOPIC_POSE, TOPIC_TF,
        TOPIC_TF_STATIC,
    };
    use super::super::zenoh_node::{Topic, ZenohNode};
    use super::{LiveError, LiveOutput, LiveSummary, SharedNode, NODE_NAME};

    /// `/tf_static` is published again every this many poses, for late subscribers.
    const TF_STATIC_EVERY_POSES: u64 = 10;
    /// How long [`LivePublisher::spawn`] waits for the topics to be declared.
    const READY_TIMEOUT: Duration = Duration::from_secs(20);

    struct Topics {
        pose: Topic,
        tf: Topic,
        tf_static: Topic,
        map: Topic,
        map_covariance: Topic,
        detections: Topic,
    }

    fn declare<M: RosMessage>(
        node: &ZenohNode,
        topic: &str,
        transient_local: bool,
        express: bool,
    ) -> Result<Topic, LiveError> {
        node.publisher(topic, &M::type_name(), transient_local, express)
    }

    fn declare_topics(node: &ZenohNode) -> Result<Topics, LiveError> {
        Ok(Topics {
            pose: declare::<Odometry>(node, TOPIC_POSE, false, true)?,
            tf: declare::<TFMessage>(node, TOPIC_TF, false, true)?,
            tf_static: declare::<TFMessage>(node, TOPIC_TF_STATIC, true, false)?,
            map: declare::<PointCloud2>(node, TOPIC_MAP, false, false)?,
            map_covariance: declare::<MarkerArray>(node, TOPIC_MAP_COVARIANCE, false, false)?,
            detections: declare::<PointCloud2>(node, TOPIC_DETECTIONS, false, false)?,
        })
    }

    /// The pipeline's end of the live output: a bounded queue to the publisher thread.
    #[derive(Debug)]
    pub struct LivePublisher {
        sender: Option<Sender<OutputEvent>>,
        dropped: Arc<AtomicU64>,
        join: Option<JoinHandle<LiveSummary>>,
    }

    impl LivePublisher {
        /// Declares the topics on the given session (or opens one of its own, closed at the
        /// end) on a thread of its own, waiting at most 20 s for it, then returns the
        /// handle the pipeline offers events to.
        pub fn spawn(live: LiveOutput) -> Result<Self, LiveError> {
            let (tx, rx) = bounded(live.zenoh.queue.get());
            let (ready_tx, ready_rx) = bounded::<Result<(), LiveError>>(1);
            let join = std::thread::Builder::new()
                .name("slam-zenoh".into())
                .spawn(move || {
                    let (node, owned): (SharedNode, bool) = match live.node {
                        Some(node) => (node, false),
                        None => match ZenohNode::open(&live.zenoh, NODE_NAME) {
                            Ok(node) => (Arc::new(node), true),
                            Err(e) => {
                                let _ = ready_tx.send(Err(e));
                                return LiveSummary::default();
                            }
                        },
                    };
                    let topics = match declare_topics(&node) {
                        Ok(t) => t,
                        Err(e) => {
                            let _ = ready_tx.send(Err(e));
                            return LiveSummary::default();
                        }
                    };
                    let keys: Vec<&str> = [
                        &topics.pose,
                        &topics.tf,
                        &topics.tf_static,
                        &topics.map,
                        &topics.map_covariance,
                        &topics.detections,
                    ]
                    .iter()
                    .map(|t| t.key.as_str())
                    .collect();
                    info!(?keys, "publishing live over Zenoh");
                    let _ = ready_tx.send(Ok(()));
                    let summary = run(&topics, &rx, live.motion);
                    drop(topics);
                    if owned {
                        node.close();
                    }
                    summary
                })
                .map_err(|e| LiveError::Thread(e.to_string()))?;
            match ready_rx.recv_timeout(READY_TIMEOUT) {
                Ok(Ok(())) => Ok(Self {
                    sender: Some(tx),
                    dropped: Arc::new(AtomicU64::new(0)),
                    join: Some(join),
                }),
                Ok(Err(e)) => {
                    let _ = join.join();
                    Err(e)
                }
                Err(_) => Err(LiveError::Thread(format!(
                    "the topics were not declared within {} s",
                    READY_TIMEOUT.as_secs()
                ))),
            }
        }

        /// Hands the publisher what it publishes from `event` (pose, map, detections, and
        /// the odometry for the pose's twist), never blocking: a full queue drops the event
        /// and counts it. Other events are ignored.
        pub fn offer(&self, event: &OutputEvent) {
            let wanted = matches!(
                event,
                OutputEvent::Pose(_)
                    | OutputEvent::Map(_)
                    | OutputEvent::Detections(_)
                    | OutputEvent::Odometry(_)
            );
            let Some(sender) = self.sender.as_ref().filter(|_| wanted) else {
                return;
            };
            match sender.try_send(event.clone()) {
                Ok(()) => {}
                Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                    let n = self.dropped.fetch_add(1, Ordering::Relaxed) + 1;
                    if n.is_power_of_two() {
                        warn!(dropped = n, "live Zenoh output behind: events dropped");
                    }
                }
            }
        }

        /// Events dropped so far because the queue was full.
        pub fn dropped(&self) -> u64 {
            self.dropped.load(Ordering::Relaxed)
        }

        /// Closes the queue, lets the thread publish what is in it (and close the session
        /// if it opened it).
        pub fn finish(mut self) -> LiveSummary {
            self.sender.take();
            let mut summary = self
                .join
                .take()
                .and_then(|j| j.join().ok())
                .unwrap_or_default();
            summary.dropped = self.dropped();
            summary
        }
    }

    impl Drop for LivePublisher {
        fn drop(&mut self) {
            self.sender.take();
            if let Some(j) = self.join.take() {
                let _ = j.join();
            }
        }
    }

    fn put<M: RosMessage>(topic: &Topic, msg: &M, summary: &mut LiveSummary) {
        let result = to_cdr(msg)
            .map_err(|e| e.to_string())
            .and_then(|bytes| topic.put(bytes).map_err(|e| e.to_string()));
        match result {
            Ok(()) => *summary.published.entry(topic.key.clone()).or_insert(0) += 1,
            Err(e) => {
                summary.failed += 1;
                if summary.failed.is_power_of_two() {
                    warn!(key = %topic.key, error = %e, count = summary.failed, "live Zenoh message not published");
                }
            }
        }
    }

    fn run(topics: &Topics, rx: &Receiver<OutputEvent>, motion: MotionModel) -> LiveSummary {
        let mut summary = LiveSummary::default();
        let mut last_input: Option<OdometrySample> = None;
        let mut poses = 0u64;
        for event in rx {
            match event {
                OutputEvent::Odometry(s) => last_input = Some(s),
                OutputEvent::Pose(p) => {
                    let (odometry, tf) = ros::pose_messages(&p, last_input.as_ref(), &motion);
                    put(&topics.pose, &odometry, &mut summary);
                    put(&topics.tf, &tf, &mut summary);
                    if poses % TF_STATIC_EVERY_POSES == 0 {
                        let stamp = Time::from_secs_f64(p.timestamp_s);
                        put(&topics.tf_static, &ros::tf_static(stamp), &mut summary);
                    }
                    poses += 1;
                }
                OutputEvent::Map(m) => {
                    let (cloud, markers) = ros::map_messages(&m);
                    put(&topics.map, &cloud, &mut summary);
                    put(&topics.map_covariance, &markers, &mut summary);
                }
                OutputEvent::Detections(d) => {
                    put(
                        &topics.detections,
                        &ros::detections_message(&d),
                        &mut summary,
                    );
                }
                _ => {}
            }
        }
        summary
    }

    /// Publishes what a radar driver receives as Navtech's ROS 2 driver does, so that a rig
    /// can record raw radar (`ros2 bag record`, through the bridge or on rmw_zenoh) without
    /// the SLAM: `RadarConfigurationMsg` when the geometry is first seen or changes, a
    /// `RadarBScanMsg` per rotation, and on request a `RadarFftDataMsg` per azimuth. Runs on
    /// the caller's thread (the driver's channel is bounded and drops on its own side).
    #[derive(Debug)]
    pub struct RadarPublisher {
        node: ZenohNode,
        configuration: Topic,
        bscan: Topic,
        fft: Option<Topic>,
        geometry: Option<Arc<protocol::Geometry>>,
        building: Option<ros::BScan>,
        summary: LiveSummary,
    }

    impl RadarPublisher {
        /// Opens the session and declares the radar topics (`fft`: the per-azimuth topic
        /// too). Blocks while Zenoh opens: call it from a plain thread, not an async task.
        pub fn open(settings: &config::live::ZenohSettings, fft: bool) -> Result<Self, LiveError> {
            use ros_msgs::navtech::{RadarBScanMsg, RadarConfigurationMsg, RadarFftDataMsg};
            let node = ZenohNode::open(settings, "radar_zenoh")?;
            let configuration = declare::<RadarConfigurationMsg>(
                &node,
                ros::TOPIC_RADAR_CONFIGURATION,
                false,
                false,
            )?;
            let bscan = declare::<RadarBScanMsg>(&node, ros::TOPIC_BSCAN, false, false)?;
            let fft = if fft {
                Some(declare::<RadarFftDataMsg>(
                    &node,
                    super::TOPIC_FFT_DATA,
                    false,
                    false,
                )?)
            } else {
                None
            };
            info!("publishing the radar live over Zenoh");
            Ok(Self {
                node,
                configuration,
                bscan,
                fft,
                geometry: None,
                building: None,
                summary: LiveSummary::default(),
            })
        }

        /// Publishes what `az` completes: the configuration if it is new, the previous
        /// rotation's B-scan when `az` starts another, `az` itself as FFT data on request.
        pub fn on_azimuth(&mut self, az: &radar_driver::Azimuth) {
            let changed = self.geometry.as_ref().map_or(true, |g| {
                !(Arc::ptr_eq(g, &az.geometry) || **g == *az.geometry)
            });
            if changed {
                self.geometry = Some(Arc::clone(&az.geometry));
                put(
                    &self.configuration,
                    &ros::radar_configuration(az),
                    &mut self.summary,
                );
            }
            if self.building.as_ref().is_some_and(|b| !b.fits(az)) {
                self.close_rotation();
            }
            if self.building.is_none() {
                self.building = ros::BScan::new(az);
                if self.building.is_none() {
                    // A geometry too large for a B-scan: counted, never allocated.
                    self.summary.failed += 1;
                }
            }
            if let Some(b) = self.building.as_mut() {
                b.push(az);
            }
            if let Some(topic) = &self.fft {
                put(topic, &ros::fft_data(az), &mut self.summary);
            }
        }

        fn close_rotation(&mut self) {
            if let Some(b) = self.building.take().filter(|b| b.rows() > 0) {
                put(&self.bscan, &b.into_message(), &mut self.summary);
            }
        }

        /// Publishes the rotation in progress, closes the session, returns the counts.
        pub fn finish(mut self) -> LiveSummary {
            self.close_rotation();
            let summary = std::mem::take(&mut self.summary);
            let Self {
                node,
                configuration,
                bscan,
                fft,
                ..
            } = self;
            drop((configuration, bscan, fft));
            node.close();
            summary
        }
    }
}
