//! The live view over Foxglove's WebSocket protocol (`[output.foxglove]`, slam-node's
//! `foxglove` feature), served by the `foxglove` SDK behind a door of our own ([`gate`]), and
//! on request a page drawing it in any browser (`[output.view]`, [`view`]). Network IO on a
//! thread and a one-worker runtime of its own.
//!
//! The channels (Foxglove's built-in schemas are protobuf, each channel carrying its schema's
//! `FileDescriptorSet`; ours are JSON with a JSON Schema):
//!
//! | topic | schema | what |
//! |---|---|---|
//! | `/radar/image` | `foxglove.RawImage` (`mono8`) | the latest rotation, Cartesian, forward up |
//! | `/slam/detections` | `foxglove.PointCloud` | the rotation's detections in `radar` |
//! | `/slam/map` | `foxglove.SceneUpdate` | features: 3-sigma ellipses and dots coloured by material |
//! | `/slam/pose` | `foxglove.PoseInFrame` | each pose in `map` |
//! | `/slam/pose_covariance` | JSON `slam_node.PoseWithCovariance` | each pose with its 3x3 covariance |
//! | `/slam/pose_uncertainty` | `foxglove.SceneUpdate` | the pose's 3-sigma position ellipse |
//! | `/slam/trajectory` | `foxglove.PosesInFrame` | the online trajectory, once a second of stream |
//! | `/slam/trajectory_optimised` | `foxglove.PosesInFrame` | the global layer's trajectory (end of a run on submaps) |
//! | `/tf` | `foxglove.FrameTransforms` | `map` to `base_link`, `base_link` to `radar` |
//! | `/slam/counters` | JSON `slam_node.Counters` | each rotation's diagnostics and this output's counters |
//!
//! Never blocking the pipeline: [`FoxglovePublisher::offer`] clones the event into a bounded
//! queue with `try_send`, dropping and counting it when the queue is full; the publisher
//! thread encodes and hands messages to the SDK, whose queue per client drops its oldest when
//! a client falls behind.

use std::collections::BTreeMap;
use std::net::SocketAddr;

use config::output::FoxgloveSettings;

#[cfg(feature = "foxglove")]
pub mod gate;
#[cfg(feature = "foxglove")]
pub mod image;
#[cfg(feature = "foxglove")]
pub mod messages;
#[cfg(feature = "foxglove")]
mod publisher;
#[cfg(feature = "foxglove")]
pub mod view;

#[cfg(feature = "foxglove")]
pub use publisher::FoxglovePublisher;

/// The radar's latest rotation.
pub const TOPIC_IMAGE: &str = "/radar/image";
/// The rotation's detections.
pub const TOPIC_DETECTIONS: &str = "/slam/detections";
/// The map.
pub const TOPIC_MAP: &str = "/slam/map";
/// Each pose.
pub const TOPIC_POSE: &str = "/slam/pose";
/// Each pose with its covariance (JSON).
pub const TOPIC_POSE_COVARIANCE: &str = "/slam/pose_covariance";
/// The pose's ellipse.
pub const TOPIC_POSE_UNCERTAINTY: &str = "/slam/pose_uncertainty";
/// The online trajectory.
pub const TOPIC_TRAJECTORY: &str = "/slam/trajectory";
/// The optimised trajectory.
pub const TOPIC_TRAJECTORY_OPTIMISED: &str = "/slam/trajectory_optimised";
/// Frame transforms.
pub const TOPIC_TF: &str = "/tf";
/// Counters (JSON).
pub const TOPIC_COUNTERS: &str = "/slam/counters";

/// What the Foxglove output should do.
#[derive(Debug, Clone)]
pub struct FoxgloveOutput {
    /// The validated `[output.foxglove]` table.
    pub settings: FoxgloveSettings,
    /// Serve the view page too (`[output.view]`).
    pub view: bool,
}

/// Why the Foxglove output could not start.
#[derive(Debug, thiserror::Error)]
pub enum FoxgloveError {
    /// `[output.foxglove]` or `[output.view]` is on in a build without the feature.
    #[error("[output.foxglove] or [output.view] is enabled but this slam-node was built without its `foxglove` feature (cargo build --release -p slam-node --features foxglove)")]
    NotBuilt,
    /// The configured address could not be bound.
    #[error("binding the live view to {address}")]
    Bind {
        /// The address.
        address: SocketAddr,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The SDK's server or the runtime could not start.
    #[error("starting the Foxglove server: {0}")]
    Server(String),
    /// The publisher thread could not be started or did not answer.
    #[error("the Foxglove publisher thread: {0}")]
    Thread(String),
}

/// What the Foxglove output did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FoxgloveSummary {
    /// Where it listened.
    pub address: Option<SocketAddr>,
    /// Messages handed to the server for at least one subscriber, per topic.
    pub published: BTreeMap<String, u64>,
    /// Events dropped because the publisher's queue was full.
    pub dropped: u64,
    /// Radar azimuths that could not be drawn (a geometry too large to keep).
    pub failed: u64,
    /// WebSocket connections served.
    pub connections: u64,
    /// Subscriptions to channels.
    pub subscriptions: u64,
    /// Subscriptions to channels that do not exist (answered by the SDK with an error
    /// status, otherwise ignored).
    pub unknown_subscriptions: u64,
    /// Connections refused (`max_clients` already served).
    pub refused: u64,
    /// Requests refused as garbage, too slow, too long, or for another path.
    pub bad_requests: u64,
    /// Clients cut off for sending more than a client sends.
    pub cut_off: u64,
    /// View pages served.
    pub pages: u64,
    /// Bytes sent to clients.
    pub bytes_sent: u64,
    /// How long the server ran, seconds.
    pub served_s: f64,
}

impl FoxgloveSummary {
    /// Messages published over all topics.
    pub fn total(&self) -> u64 {
        self.published.values().sum()
    }

    /// Bytes sent to clients per second the server ran.
    pub fn bytes_per_s(&self) -> f64 {
        if self.served_s > 0.0 {
            self.bytes_sent as f64 / self.served_s
        } else {
            0.0
        }
    }
}
