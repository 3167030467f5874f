//! Live ROS 2 topics over Zenoh (`[output.zenoh]`, slam-node's `zenoh` feature): the pose
//! (`nav_msgs/Odometry` with covariance), `/tf` and `/tf_static`, the map (`PointCloud2` and
//! `MarkerArray`) and each rotation's detections, CDR-encoded as in the MCAP recording
//! ([`super::ros`]).
//!
//! Key convention: zenoh-bridge-ros2dds's. The ROS 2 topic `/slam/odometry` is the key
//! `slam/odometry` (`[output.zenoh] namespace = "robot1"` gives `robot1/slam/odometry`, as the
//! bridge's `namespace` option does); the payload is the CDR serialisation with its 4-byte
//! encapsulation header, exactly what a DDS writer puts on the wire and what the bridge
//! forwards, with the Zenoh encoding `application/cdr;<ros type>`. For each topic the daemon
//! also declares the liveliness token a bridge declares for a route from a ROS publisher
//! (`@/<zid>/@ros2_lv/MP/<key>/<type>/<qos>`, `/` written `§`), so a zenoh-bridge-ros2dds
//! 1.x on the ROS side can create the matching DDS writers. (rmw_zenoh's own convention,
//! `<domain>/<topic>/<type>/<type hash>` with per-message attachments and its liveliness
//! graph, is not implemented: a ROS 2 system on rmw_zenoh reaches us through the bridge.)
//!
//! Never blocking the pipeline: [`LivePublisher::offer`] clones the event into a bounded
//! crossbeam channel with `try_send`; when the channel is full the event is dropped and
//! counted. A thread of its own encodes and publishes; Zenoh's congestion control is `Drop`,
//! so a slow subscriber costs messages, never time on that thread.

use std::collections::BTreeMap;

use radar_model::motion::MotionModel;

/// What the live output should do, from `[output.zenoh]`.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveOutput {
    /// The validated `[output.zenoh]` table.
    pub zenoh: config::live::ZenohSettings,
    /// The motion model, to turn the odometry's steering into the pose message's yaw rate.
    pub motion: MotionModel,
}

/// Why the live output could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// `[output.zenoh] enabled = true` in a build without the `zenoh` feature.
    #[error("[output.zenoh] is enabled but this slam-node was built without its `zenoh` feature (cargo build --release -p slam-node --features zenoh)")]
    NotBuilt,
    /// The Zenoh session could not be opened (bad endpoint, port in use, no router).
    #[error("opening the Zenoh session: {0}")]
    Open(String),
    /// A key or a publisher could not be declared.
    #[error("declaring the Zenoh publisher for {key}: {message}")]
    Declare {
        /// The key.
        key: String,
        /// Zenoh's message.
        message: String,
    },
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

#[cfg(feature = "zenoh")]
pub use publisher::{zenoh_config, LivePublisher, RadarPublisher};

/// Topic of the radar's azimuths as Navtech's ROS 2 driver publishes them, one
/// `navtech_msgs/msg/RadarFftDataMsg` each.
pub const TOPIC_FFT_DATA: &str = "/radar_data/fft_data";

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
    use zenoh::bytes::Encoding;
    use zenoh::qos::CongestionControl;
    use zenoh::Wait;

    use super::super::ros::{
        self, TOPIC_DETECTIONS, TOPIC_MAP, TOPIC_MAP_COVARIANCE, TOPIC_POSE, TOPIC_TF,
        TOPIC_TF_STATIC,
    };
    use super::super::writer::OutputEvent;
    use super::{bridge_liveliness_key, bridge_qos, topic_key, LiveError, LiveOutput, LiveSummary};

    /// `/tf_static` is published again every this many poses, for late subscribers.
    const TF_STATIC_EVERY_POSES: u64 = 10;
    /// How long [`LivePublisher::spawn`] waits for the session to open.
    const OPEN_TIMEOUT: Duration = Duration::from_secs(10);

    /// A value as JSON5 text for `zenoh::Config::insert_json5` (JSON is JSON5).
    fn json<T: serde::Serialize + ?Sized>(value: &T) -> Result<String, LiveError> {
        serde_json::to_string(value).map_err(|e| LiveError::Open(e.to_string()))
    }

    /// The Zenoh session's configuration from `[output.zenoh]`: the mode, exactly the
    /// endpoints given (no default listener on every interface), multicast scouting as set.
    pub fn zenoh_config(s: &config::live::ZenohSettings) -> Result<zenoh::Config, LiveError> {
        let open = |e: zenoh::Error| LiveError::Open(e.to_string());
        let mut c = zenoh::Config::default();
        let mode = match s.mode {
            config::live::ZenohMode::Peer => "peer",
            config::live::ZenohMode::Client => "client",
        };
        c.insert_json5("mode", &json(mode)?).map_err(open)?;
        c.insert_json5("connect/endpoints", &json(&s.connect)?)
            .map_err(open)?;
        c.insert_json5("listen/endpoints", &json(&s.listen)?)
            .map_err(open)?;
        c.insert_json5("scouting/multicast/enabled", &json(&s.multicast_scouting)?)
            .map_err(open)?;
        Ok(c)
    }

    struct Topic {
        key: String,
        publisher: zenoh::pubsub::Publisher<'static>,
        _token: Option<zenoh::liveliness::LivelinessToken>,
    }

    struct Topics {
        pose: Topic,
        tf: Topic,
        tf_static: Topic,
        map: Topic,
        map_covariance: Topic,
        detections: Topic,
    }

    fn declare<M: RosMessage>(
        session: &zenoh::Session,
        namespace: &str,
        topic: &str,
        transient_local: bool,
        express: bool,
    ) -> Result<Topic, LiveError> {
        let key = topic_key(namespace, topic);
        let declare_err = |e: zenoh::Error| LiveError::Declare {
            key: key.clone(),
            message: e.to_string(),
        };
        let publisher = session
            .declare_publisher(key.clone())
            .encoding(Encoding::APPLICATION_CDR.with_schema(M::type_name()))
            .congestion_control(CongestionControl::Drop)
            .express(express)
            .wait()
            .map_err(declare_err)?;
        let zid = session.zid().to_string();
        let token_key = bridge_liveliness_key(
            &zid,
            &key,
            &M::type_name(),
            &bridge_qos(transient_local, if transient_local { 1 } else { 10 }),
        );
        // The token only helps a bridge find us; failing to declare it costs nothing else.
        let token = match session.liveliness().declare_token(token_key.clone()).wait() {
            Ok(t) => Some(t),
            Err(e) => {
                warn!(key = %token_key, error = %e, "Zenoh liveliness token not declared");
                None
            }
        };
        Ok(Topic {
            key,
            publisher,
            _token: token,
        })
    }

    fn open(settings: &config::live::ZenohSettings) -> Result<(zenoh::Session, Topics), LiveError> {
        let session = zenoh::open(zenoh_config(settings)?)
            .wait()
            .map_err(|e| LiveError::Open(e.to_string()))?;
        let ns = settings.namespace.as_str();
        let topics = Topics {
            pose: declare::<Odometry>(&session, ns, TOPIC_POSE, false, true)?,
            tf: declare::<TFMessage>(&session, ns, TOPIC_TF, false, true)?,
            tf_static: declare::<TFMessage>(&session, ns, TOPIC_TF_STATIC, true, false)?,
            map: declare::<PointCloud2>(&session, ns, TOPIC_MAP, false, false)?,
            map_covariance: declare::<MarkerArray>(
                &session,
                ns,
                TOPIC_MAP_COVARIANCE,
                false,
                false,
            )?,
            detections: declare::<PointCloud2>(&session, ns, TOPIC_DETECTIONS, false, false)?,
        };
        Ok((session, topics))
    }

    /// The pipeline's end of the live output: a bounded queue to the publisher thread.
    #[derive(Debug)]
    pub struct LivePublisher {
        sender: Option<Sender<OutputEvent>>,
        dropped: Arc<AtomicU64>,
        join: Option<JoinHandle<LiveSummary>>,
    }

    impl LivePublisher {
        /// Opens the Zenoh session and declares the topics on a thread of its own (waiting
        /// at most 10 s for it), then returns the handle the pipeline offers events to.
        pub fn spawn(live: LiveOutput) -> Result<Self, LiveError> {
            let (tx, rx) = bounded(live.zenoh.queue.get());
            let (ready_tx, ready_rx) = bounded::<Result<(), LiveError>>(1);
            let join = std::thread::Builder::new()
                .name("slam-zenoh".into())
                .spawn(move || match open(&live.zenoh) {
                    Ok((session, topics)) => {
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
                        info!(zid = %session.zid(), ?keys, "publishing live over Zenoh");
                        let _ = ready_tx.send(Ok(()));
                        let summary = run(&topics, &rx, live.motion);
                        drop(topics);
                        if let Err(e) = session.close().wait() {
                            warn!(error = %e, "closing the Zenoh session");
                        }
                        summary
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                        LiveSummary::default()
                    }
                })
                .map_err(|e| LiveError::Thread(e.to_string()))?;
            match ready_rx.recv_timeout(OPEN_TIMEOUT) {
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
                    "the session did not open within {} s",
                    OPEN_TIMEOUT.as_secs()
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

        /// Closes the queue, lets the thread publish what is in it and close the session.
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
            .and_then(|bytes| topic.publisher.put(bytes).wait().map_err(|e| e.to_string()));
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
    /// can record raw radar (`ros2 bag record`, through the bridge) without the SLAM:
    /// `RadarConfigurationMsg` when the geometry is first seen or changes, a
    /// `RadarBScanMsg` per rotation, and on request a `RadarFftDataMsg` per azimuth. Runs on
    /// the caller's thread (the driver's channel is bounded and drops on its own side).
    #[derive(Debug)]
    pub struct RadarPublisher {
        session: zenoh::Session,
        configuration: Topic,
        bscan: Topic,
        fft: Option<Topic>,
        geometry: Option<Arc<protocol::Geometry>>,
        building: Option<ros::BScan>,
        summary: LiveSummary,
    }

    impl std::fmt::Debug for Topic {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.debug_struct("Topic")
                .field("key", &self.key)
                .finish_non_exhaustive()
        }
    }

    impl RadarPublisher {
        /// Opens the session and declares the radar topics (`fft`: the per-azimuth topic
        /// too). Blocks while Zenoh opens: call it from a plain thread, not an async task.
        pub fn open(settings: &config::live::ZenohSettings, fft: bool) -> Result<Self, LiveError> {
            use ros_msgs::navtech::{RadarBScanMsg, RadarConfigurationMsg, RadarFftDataMsg};
            let session = zenoh::open(zenoh_config(settings)?)
                .wait()
                .map_err(|e| LiveError::Open(e.to_string()))?;
            let ns = settings.namespace.as_str();
            let configuration = declare::<RadarConfigurationMsg>(
                &session,
                ns,
                ros::TOPIC_RADAR_CONFIGURATION,
                false,
                false,
            )?;
            let bscan = declare::<RadarBScanMsg>(&session, ns, ros::TOPIC_BSCAN, false, false)?;
            let fft = if fft {
                Some(declare::<RadarFftDataMsg>(
                    &session,
                    ns,
                    super::TOPIC_FFT_DATA,
                    false,
                    false,
                )?)
            } else {
                None
            };
            info!(zid = %session.zid(), "publishing the radar live over Zenoh");
            Ok(Self {
                session,
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
                session,
                configuration,
                bscan,
                fft,
                ..
            } = self;
            drop((configuration, bscan, fft));
            if let Err(e) = session.close().wait() {
                warn!(error = %e, "closing the Zenoh session");
            }
            summary
        }
    }
}
