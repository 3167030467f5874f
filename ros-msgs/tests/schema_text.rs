//! The `ros2msg` schema texts: own definition first, each dependency once after the
//! separator, as rosbag2 writes them.

use ros_msgs::geometry::TwistStamped;
use ros_msgs::nav::Odometry;
use ros_msgs::navtech::RadarBScanMsg;
use ros_msgs::visualization::MarkerArray;
use ros_msgs::RosMessage;

#[test]
fn twist_stamped_concatenates_header_time_twist_and_vector3_once_each() {
    let sep = "=".repeat(80);
    let expected = format!(
        "std_msgs/Header header\nTwist twist\n\
         {sep}\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
         {sep}\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n\
         {sep}\nMSG: geometry_msgs/Twist\nVector3 linear\nVector3 angular\n\
         {sep}\nMSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
    );
    assert_eq!(TwistStamped::schema_text(), expected);
    assert_eq!(TwistStamped::type_name(), "geometry_msgs/msg/TwistStamped");
}

#[test]
fn every_dependency_appears_exactly_once() {
    for (text, deps) in [
        (
            Odometry::schema_text(),
            &[
                "std_msgs/Header",
                "builtin_interfaces/Time",
                "geometry_msgs/PoseWithCovariance",
                "geometry_msgs/Pose",
                "geometry_msgs/Point",
                "geometry_msgs/Quaternion",
                "geometry_msgs/TwistWithCovariance",
                "geometry_msgs/Twist",
                "geometry_msgs/Vector3",
            ][..],
        ),
        (
            MarkerArray::schema_text(),
            &[
                "visualization_msgs/Marker",
                "std_msgs/Header",
                "std_msgs/ColorRGBA",
                "builtin_interfaces/Duration",
                "sensor_msgs/CompressedImage",
                "visualization_msgs/UVCoordinate",
                "visualization_msgs/MeshFile",
            ][..],
        ),
        (
            RadarBScanMsg::schema_text(),
            &[
                "sensor_msgs/Image",
                "std_msgs/Header",
                "builtin_interfaces/Time",
            ][..],
        ),
    ] {
        for dep in deps {
            let line = format!("\nMSG: {dep}\n");
            assert_eq!(text.matches(&line).count(), 1, "{dep} in\n{text}");
        }
        let sections = text.matches("\nMSG: ").count();
        assert_eq!(sections, text.matches(&"=".repeat(80)).count());
    }
}
