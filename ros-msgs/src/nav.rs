//! `nav_msgs/Odometry` and `tf2_msgs/TFMessage`.

use serde::{Deserialize, Serialize};

use crate::geometry::{
    PoseWithCovariance, TransformStamped, TwistWithCovariance, POSE_WITH_COVARIANCE,
    TRANSFORM_STAMPED, TWIST_WITH_COVARIANCE,
};
use crate::schema::{MsgDef, RosMessage};
use crate::std_msgs::{Header, HEADER};

/// `nav_msgs/Odometry`: pose in `header.frame_id`, twist in `child_frame_id`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    /// Time and the pose's frame.
    pub header: Header,
    /// The twist's frame.
    pub child_frame_id: String,
    /// Pose with covariance.
    pub pose: PoseWithCovariance,
    /// Twist with covariance.
    pub twist: TwistWithCovariance,
}

/// Definition of [`Odometry`].
pub static ODOMETRY: MsgDef = MsgDef {
    name: "nav_msgs/Odometry",
    text: "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n",
    uses: &[&HEADER, &POSE_WITH_COVARIANCE, &TWIST_WITH_COVARIANCE],
};

impl RosMessage for Odometry {
    const DEF: &'static MsgDef = &ODOMETRY;
}

/// `tf2_msgs/TFMessage`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[allow(clippy::upper_case_acronyms)]
pub struct TFMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

/// Definition of [`TFMessage`].
pub static TF_MESSAGE: MsgDef = MsgDef {
    name: "tf2_msgs/TFMessage",
    text: "geometry_msgs/TransformStamped[] transforms\n",
    uses: &[&TRANSFORM_STAMPED],
};

impl RosMessage for TFMessage {
    const DEF: &'static MsgDef = &TF_MESSAGE;
}
