//! `geometry_msgs`: points, poses, twists and transforms (the subset the daemon speaks).

use serde::{Deserialize, Serialize};
use serde_big_array::BigArray;

use crate::schema::{MsgDef, RosMessage};
use crate::std_msgs::{Header, HEADER};

macro_rules! def {
    ($ty:ident, $def:ident, $name:literal, $text:literal, [$($dep:expr),*]) => {
        #[doc = concat!("Definition of [`", stringify!($ty), "`].")]
        pub static $def: MsgDef = MsgDef { name: $name, text: $text, uses: &[$(&$dep),*] };
        impl RosMessage for $ty {
            const DEF: &'static MsgDef = &$def;
        }
    };
}

/// `geometry_msgs/Point`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}
def!(
    Point,
    POINT,
    "geometry_msgs/Point",
    "float64 x\nfloat64 y\nfloat64 z\n",
    []
);

/// `geometry_msgs/Vector3`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}
def!(
    Vector3,
    VECTOR3,
    "geometry_msgs/Vector3",
    "float64 x\nfloat64 y\nfloat64 z\n",
    []
);

/// `geometry_msgs/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}
def!(
    Quaternion,
    QUATERNION,
    "geometry_msgs/Quaternion",
    "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    []
);

impl Default for Quaternion {
    fn default() -> Self {
        Self::from_yaw(0.0)
    }
}

impl Quaternion {
    /// A rotation by `yaw_rad` about +z (counter-clockwise seen from above).
    pub fn from_yaw(yaw_rad: f64) -> Self {
        let half = 0.5 * yaw_rad;
        Self {
            x: 0.0,
            y: 0.0,
            z: half.sin(),
            w: half.cos(),
        }
    }

    /// The rotation about +z (for a quaternion that is one).
    pub fn yaw(&self) -> f64 {
        2.0 * self.z.atan2(self.w)
    }
}

/// `geometry_msgs/Pose`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position.
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}
def!(
    Pose,
    POSE,
    "geometry_msgs/Pose",
    "Point position\nQuaternion orientation\n",
    [POINT, QUATERNION]
);

/// Row-major 6x6 covariance over (x, y, z, rotation about x, about y, about z).
pub type Covariance6 = [f64; 36];

/// `geometry_msgs/PoseWithCovariance`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// Row-major 6x6 over (x, y, z, roll, pitch, yaw).
    #[serde(with = "BigArray")]
    pub covariance: Covariance6,
}
def!(
    PoseWithCovariance,
    POSE_WITH_COVARIANCE,
    "geometry_msgs/PoseWithCovariance",
    "Pose pose\nfloat64[36] covariance\n",
    [POSE]
);

impl Default for PoseWithCovariance {
    fn default() -> Self {
        Self {
            pose: Pose::default(),
            covariance: [0.0; 36],
        }
    }
}

/// `geometry_msgs/PoseWithCovarianceStamped`: a pose with its covariance in
/// `header.frame_id` (RViz's "2D Pose Estimate" publishes one on `/initialpose`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovarianceStamped {
    /// Time and frame.
    pub header: Header,
    /// The pose and its covariance.
    pub pose: PoseWithCovariance,
}
def!(
    PoseWithCovarianceStamped,
    POSE_WITH_COVARIANCE_STAMPED,
    "geometry_msgs/PoseWithCovarianceStamped",
    "std_msgs/Header header\nPoseWithCovariance pose\n",
    [HEADER, POSE_WITH_COVARIANCE]
);

/// `geometry_msgs/Twist`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity, m/s.
    pub linear: Vector3,
    /// Angular velocity, rad/s.
    pub angular: Vector3,
}
def!(
    Twist,
    TWIST,
    "geometry_msgs/Twist",
    "Vector3 linear\nVector3 angular\n",
    [VECTOR3]
);

/// `geometry_msgs/TwistWithCovariance`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// The twist.
    pub twist: Twist,
    /// Row-major 6x6 over (vx, vy, vz, wx, wy, wz).
    #[serde(with = "BigArray")]
    pub covariance: Covariance6,
}
def!(
    TwistWithCovariance,
    TWIST_WITH_COVARIANCE,
    "geometry_msgs/TwistWithCovariance",
    "Twist twist\nfloat64[36] covariance\n",
    [TWIST]
);

impl Default for TwistWithCovariance {
    fn default() -> Self {
        Self {
            twist: Twist::default(),
            covariance: [0.0; 36],
        }
    }
}

/// `geometry_msgs/TwistStamped`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TwistStamped {
    /// Time and frame.
    pub header: Header,
    /// The twist.
    pub twist: Twist,
}
def!(
    TwistStamped,
    TWIST_STAMPED,
    "geometry_msgs/TwistStamped",
    "std_msgs/Header header\nTwist twist\n",
    [HEADER, TWIST]
);

/// `geometry_msgs/Transform`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Translation.
    pub translation: Vector3,
    /// Rotation.
    pub rotation: Quaternion,
}
def!(
    Transform,
    TRANSFORM,
    "geometry_msgs/Transform",
    "Vector3 translation\nQuaternion rotation\n",
    [VECTOR3, QUATERNION]
);

/// `geometry_msgs/TransformStamped`: the pose of `child_frame_id` in `header.frame_id`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// Time and parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// The transform.
    pub transform: Transform,
}
def!(
    TransformStamped,
    TRANSFORM_STAMPED,
    "geometry_msgs/TransformStamped",
    "std_msgs/Header header\nstring child_frame_id\nTransform transform\n",
    [HEADER, TRANSFORM]
);
