//! Prior poses over Zenoh (`[map] initial_pose_topic`, feature `zenoh`): a
//! `geometry_msgs/msg/PoseWithCovarianceStamped` in the `map` frame on a ROS 2 topic (RViz's
//! "2D Pose Estimate" publishes one on `/initialpose`), keyed by `[output.zenoh] convention`,
//! decoded by [`crate::output::ros::prior_pose`] and handed to the pipeline's localiser,
//! which starts (or restarts) tracking from it.
//!
//! A peer's bad input costs that message only, as on the odometry subscription (the same
//! counters, [`super::zenoh_odometry::ZenohOdometryCounts`]): a payload that does not decode,
//! a pose in another frame or with a covariance that is not one is counted as malformed and
//! logged (the first ten, then every power of two); decoding runs in Zenoh's callback and
//! never blocks; a full channel drops the prior and counts it.

#[cfg(feature = "zenoh")]
pub use subscriber::ZenohPriors;

#[cfg(feature = "zenoh")]
mod subscriber {
    use std::sync::atomic::Ordering;
    use std::sync::Arc;

    use crossbeam_channel::{bounded, Receiver};
    use ros_msgs::geometry::PoseWithCovarianceStamped;
    use ros_msgs::RosMessage;
    use tracing::{info, warn};

    use super::super::zenoh_odometry::subscriber::{deliver, names_other_than};
    use super::super::zenoh_odometry::{SharedStats, ZenohOdometryStats};
    use crate::output::live::LiveError;
    use crate::output::zenoh_node::{Subscription, ZenohNode};
    use crate::pipeline::localise::PriorPose;

    /// Priors waiting for the pipeline; more are dropped and counted (the localiser takes
    /// the latest each rotation).
    pub const CAPACITY: usize = 16;

    /// The subscription: the pipeline's end of its channel, and its counters.
    #[derive(Debug)]
    pub struct ZenohPriors {
        /// Decoded priors.
        pub rx: Receiver<PriorPose>,
        stats: SharedStats,
        _subscription: Subscription,
    }

    fn log_lost(stats: &ZenohOdometryStats, what: &str, detail: &str) {
        let n = stats.malformed.load(Ordering::Relaxed)
            + stats.wrong_type.load(Ordering::Relaxed)
            + stats.dropped.load(Ordering::Relaxed);
        if n <= 10 || n.is_power_of_two() {
            warn!(key = %stats.key, what, detail, refused = n, "prior pose from Zenoh refused");
        }
    }

    impl ZenohPriors {
        /// Subscribes to `topic` on `node`.
        pub fn subscribe(node: &ZenohNode, topic: &str) -> Result<Self, LiveError> {
            let ros_type = PoseWithCovarianceStamped::type_name();
            let (tx, rx) = bounded(CAPACITY);
            let stats = Arc::new(ZenohOdometryStats {
                key: node.key(topic, &ros_type)?,
                ..ZenohOdometryStats::default()
            });
            let counters = Arc::clone(&stats);
            let expected = ros_type.clone();
            let subscription = node.subscriber(topic, &ros_type, move |sample| {
                let s = &counters;
                s.received.fetch_add(1, Ordering::Relaxed);
                if names_other_than(sample.encoding(), &expected) {
                    s.wrong_type.fetch_add(1, Ordering::Relaxed);
                    log_lost(s, "another type", &sample.encoding().to_string());
                    return;
                }
                let decoded = crate::output::ros::prior_pose(&sample.payload().to_bytes());
                deliver(s, &tx, decoded, log_lost);
            })?;
            info!(key = %subscription.key, message = %ros_type, "prior poses from Zenoh");
            Ok(Self {
                rx,
                stats,
                _subscription: subscription,
            })
        }

        /// The counters (live).
        pub fn stats(&self) -> SharedStats {
            Arc::clone(&self.stats)
        }
    }
}
