//! Live ROS 2 topics over Zenoh (`[output.zenoh]`, slam-node's `zenoh` feature): the pose
//! (`nav_msgs/Odometry` with covariance), `/tf` and `/tf_static`, the map (`PointCloud2` and
//! `MarkerArray`) and each rotation's detections, CDR-encoded as in the MCAP recording
//! ([`super::ros`]); the same session takes the vehicle's odometry
//! (`[odometry] source = "zenoh"`, `crate::daemon::zenoh_odometry`).
//!
//! The topics are keyed by one of two conventions (`[output.zenoh] convention`,
//! zenoh-bridge-ros2dds's or rmw_zenoh's), spelled out in [`super::zenoh_keys`].
//!
//! Never blocking the pipeline: [`LivePublisher::offer`] clones the event into a bounded
//! crossbeam channel with `try_send`; when the channel is full the event is dropped and
//! counted. A thread of its own encodes and publishes; Zenoh's congestion control is `Drop`,
//! so a slow subscriber costs messages, never time on that thread.

use std::collections::BTreeMap;

use config::live::ZenohSettings;
use radar_model::motion::MotionModel;

pub use super::live_error::LiveError;
pub use super::zenoh_keys::{
    bridge_liveliness_key, bridge_qos, dds_type_name, fully_qualified, key_for, mangle,
    rmw_zenoh_attachment, rmw_zenoh_entity_token, rmw_zenoh_key, rmw_zenoh_node_token,
    rmw_zenoh_qos, topic_key, type_hash, type_hashes, EntityKind,
};

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
                    if poses.is_multiple_of(TF_STATIC_EVERY_POSES) {
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
            let changed = self
                .geometry
                .as_ref()
                .is_none_or(|g| !(Arc::ptr_eq(g, &az.geometry) || **g == *az.geometry));
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
