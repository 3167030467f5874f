//! ROS 2 messages as serde structs laid out exactly as their `.msg` definitions, with CDR
//! (little-endian, 4-byte encapsulation header) through the `cdr-encoding` crate and each
//! message's schema text in MCAP's `ros2msg` encoding. No IO, no clock.
//!
//! The types: `builtin_interfaces` Time/Duration, `std_msgs` Header/ColorRGBA,
//! `geometry_msgs` Point, Vector3, Quaternion, Pose, PoseWithCovariance,
//! PoseWithCovarianceStamped, Twist,
//! TwistWithCovariance, TwistStamped, Transform, TransformStamped, `nav_msgs/Odometry`,
//! `tf2_msgs/TFMessage`, `sensor_msgs` PointField, PointCloud2, Image, CompressedImage,
//! `visualization_msgs` Marker, MarkerArray (Humble layout), and Navtech's `navtech_msgs`
//! RadarFftDataMsg, RadarBScanMsg, RadarConfigurationMsg.
//!
//! ```
//! use ros_msgs::{from_cdr, to_cdr, RosMessage};
//! use ros_msgs::builtin::Time;
//!
//! let t = Time { sec: 1, nanosec: 2 };
//! let bytes = to_cdr(&t).unwrap();
//! assert_eq!(bytes, [0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
//! assert_eq!(from_cdr::<Time>(&bytes).unwrap(), t);
//! assert_eq!(Time::type_name(), "builtin_interfaces/msg/Time");
//! ```

pub mod builtin;
pub mod cdr;
pub mod geometry;
pub mod nav;
pub mod navtech;
pub mod schema;
pub mod sensor;
pub mod std_msgs;
pub mod visualization;

pub use cdr::{from_cdr, to_cdr, CdrError};
pub use schema::{MsgDef, RosMessage};
