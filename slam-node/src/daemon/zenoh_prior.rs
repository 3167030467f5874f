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

/// Priors waiting for the pipeline; more are dropped and counted (the localiser takes the
/// latest each rotation).
pub const CAPACITY: usize = 16;

/// Subscribes to prior poses on `topic` over `node`.
#[cfg(feature = "zenoh")]
pub fn subscribe(
    node: &crate::output::zenoh_node::ZenohNode,
    topic: &str,
) -> Result<
    super::zenoh_odometry::subscriber::Decoded<crate::pipeline::localise::PriorPose>,
    crate::output::live::LiveError,
> {
    use ros_msgs::RosMessage;
    super::zenoh_odometry::subscriber::Decoded::subscribe(
        node,
        topic,
        &ros_msgs::geometry::PoseWithCovarianceStamped::type_name(),
        CAPACITY,
        "prior poses",
        crate::output::ros::prior_pose,
    )
}
