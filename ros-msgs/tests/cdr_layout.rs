//! CDR bytes worked by hand, round trips of every message, and hostile payloads.

use proptest::prelude::*;
use ros_msgs::builtin::{secs_to_nanos, Time};
use ros_msgs::geometry::{
    Point, Pose, PoseWithCovariance, Quaternion, Transform, TransformStamped, Twist, TwistStamped,
    TwistWithCovariance, Vector3,
};
use ros_msgs::nav::{Odometry, TFMessage};
use ros_msgs::navtech::{RadarBScanMsg, RadarConfigurationMsg, RadarFftDataMsg};
use ros_msgs::sensor::{Image, PointCloud2};
use ros_msgs::std_msgs::Header;
use ros_msgs::visualization::{Marker, MarkerArray};
use ros_msgs::{from_cdr, to_cdr, CdrError, RosMessage};

fn header(frame: &str) -> Header {
    Header::new(
        Time {
            sec: 1_700_000_000,
            nanosec: 250_000_000,
        },
        frame,
    )
}

fn round_trip<T: RosMessage + PartialEq + std::fmt::Debug>(msg: &T) {
    let bytes = to_cdr(msg).unwrap();
    assert_eq!(
        &bytes[..4],
        &[0, 1, 0, 0],
        "CDR little-endian encapsulation"
    );
    let back: T = from_cdr(&bytes).unwrap();
    assert_eq!(&back, msg, "{}", T::type_name());
}

#[test]
fn a_header_is_the_encapsulation_then_sec_nanosec_and_a_nul_terminated_string() {
    let h = Header::new(Time { sec: 1, nanosec: 2 }, "map");
    let bytes = to_cdr(&h).unwrap();
    assert_eq!(
        bytes,
        [
            0x00, 0x01, 0x00, 0x00, // encapsulation: CDR LE, no options
            0x01, 0x00, 0x00, 0x00, // stamp.sec
            0x02, 0x00, 0x00, 0x00, // stamp.nanosec
            0x04, 0x00, 0x00, 0x00, // frame_id length, with the NUL
            b'm', b'a', b'p', 0x00,
        ]
    );
}

#[test]
fn a_float64_after_an_odd_length_string_is_aligned_to_8_counting_from_after_the_encapsulation() {
    let msg = TwistStamped {
        header: Header::new(Time { sec: 1, nanosec: 2 }, "a"),
        twist: Twist {
            linear: Vector3 {
                x: 1.0,
                y: 0.0,
                z: 0.0,
            },
            angular: Vector3::default(),
        },
    };
    let bytes = to_cdr(&msg).unwrap();
    // body: sec(4) nanosec(4) len(4)=2 'a' NUL -> 14 bytes, 2 bytes of padding, 6 x f64.
    assert_eq!(bytes.len(), 4 + 16 + 48);
    assert_eq!(&bytes[4 + 8..4 + 16], &[2, 0, 0, 0, b'a', 0, 0, 0]);
    assert_eq!(&bytes[4 + 16..4 + 24], &1.0f64.to_le_bytes());
    round_trip(&msg);
}

#[test]
fn a_bool_then_a_uint32_takes_three_bytes_of_padding() {
    // PointField: string name, uint32 offset, uint8 datatype, uint32 count.
    let f = ros_msgs::sensor::PointField::float32("x", 4);
    let bytes = to_cdr(&f).unwrap();
    assert_eq!(
        &bytes[4..],
        &[2, 0, 0, 0, b'x', 0, 0, 0, 4, 0, 0, 0, 7, 0, 0, 0, 1, 0, 0, 0]
    );
}

#[test]
fn every_message_reads_back_as_written() {
    let pose = Pose {
        position: Point {
            x: 1.5,
            y: -2.0,
            z: 0.0,
        },
        orientation: Quaternion::from_yaw(0.3),
    };
    let mut covariance = [0.0; 36];
    covariance[0] = 0.01;
    covariance[35] = 0.002;
    let odom = Odometry {
        header: header("map"),
        child_frame_id: "base_link".into(),
        pose: PoseWithCovariance { pose, covariance },
        twist: TwistWithCovariance {
            twist: Twist {
                linear: Vector3 {
                    x: 3.0,
                    y: 0.0,
                    z: 0.0,
                },
                angular: Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: 0.1,
                },
            },
            covariance,
        },
    };
    round_trip(&odom);
    round_trip(&TFMessage {
        transforms: vec![TransformStamped {
            header: header("map"),
            child_frame_id: "base_link".into(),
            transform: Transform {
                translation: Vector3 {
                    x: 1.0,
                    y: 2.0,
                    z: 0.0,
                },
                rotation: Quaternion::from_yaw(-1.0),
            },
        }],
    });
    let cloud = PointCloud2::from_f32_points(
        header("map"),
        &["x", "y", "z", "reflectivity", "absorption"],
        &[
            vec![1.0, 2.0, 0.0, 0.3, 0.4],
            vec![-5.0, 7.5, 0.0, 0.1, 0.8],
        ],
    );
    assert_eq!(cloud.point_step, 20);
    assert_eq!(
        cloud.f32_points().unwrap()[1],
        vec![-5.0, 7.5, 0.0, 0.1, 0.8]
    );
    round_trip(&cloud);
    let mut marker = Marker {
        header: header("map"),
        ns: "covariance".into(),
        id: 7,
        type_: Marker::CYLINDER,
        action: Marker::ADD,
        pose,
        ..Marker::default()
    };
    marker.points.push(Point::default());
    round_trip(&MarkerArray {
        markers: vec![marker.clone(), marker],
    });
    let image = Image {
        header: header("radar"),
        height: 2,
        width: 3,
        encoding: "8UC1".into(),
        is_bigendian: 0,
        step: 3,
        data: vec![1, 2, 3, 4, 5, 6],
    };
    round_trip(&RadarBScanMsg {
        b_scan_img: image,
        encoder_values: vec![0, 14],
        timestamps: vec![1_700_000_000_000_000_000, 1_700_000_000_000_625_000],
    });
    round_trip(&RadarFftDataMsg {
        header: header("radar"),
        angle: 0.9,
        azimuth: 14,
        sweep_counter: 3,
        ntp_seconds: 1_700_000_000,
        ntp_split_seconds: 625_000,
        data: vec![9; 17],
        data_length: 17,
    });
    round_trip(&RadarConfigurationMsg {
        header: header("radar"),
        azimuth_samples: 400,
        encoder_size: 5600,
        azimuth_offset: 0,
        bin_size: 0.0438,
        range_in_bins: 2856,
        expected_rotation_rate: 4000,
        range_gain: 1.0,
        range_offset: 0.0,
    });
}

#[test]
fn a_payload_shorter_than_the_encapsulation_is_refused() {
    assert!(matches!(
        from_cdr::<Header>(&[0, 1]),
        Err(CdrError::TooShort(2))
    ));
}

#[test]
fn a_parameter_list_or_xcdr2_representation_is_refused() {
    let mut bytes = to_cdr(&Header::default()).unwrap();
    bytes[1] = 0x07;
    assert!(matches!(
        from_cdr::<Header>(&bytes),
        Err(CdrError::Representation(0, 7))
    ));
}

#[test]
fn a_truncated_message_is_an_error() {
    let bytes = to_cdr(&header("base_link")).unwrap();
    for cut in 4..bytes.len() {
        assert!(from_cdr::<Header>(&bytes[..cut]).is_err(), "cut at {cut}");
    }
}

#[test]
fn a_sequence_length_of_four_billion_is_an_error_not_an_allocation() {
    // RadarBScanMsg after its image: uint16[] encoder_values with length 0xFFFFFFF0.
    let mut bytes = to_cdr(&RadarBScanMsg::default()).unwrap();
    let image_len = to_cdr(&Image::default()).unwrap().len();
    bytes.truncate(image_len);
    while (bytes.len() - 4) % 4 != 0 {
        bytes.push(0);
    }
    bytes.extend_from_slice(&0xFFFF_FFF0u32.to_le_bytes());
    assert!(from_cdr::<RadarBScanMsg>(&bytes).is_err());
    let mut image = to_cdr(&Image::default()).unwrap();
    let data_len_at = image.len() - 4;
    image[data_len_at..].copy_from_slice(&0xFFFF_FFF0u32.to_le_bytes());
    assert!(from_cdr::<Image>(&image).is_err());
}

#[test]
fn trailing_bytes_beyond_padding_are_refused() {
    let mut bytes = to_cdr(&Time { sec: 1, nanosec: 2 }).unwrap();
    bytes.extend_from_slice(&[0, 0, 0]);
    assert!(from_cdr::<Time>(&bytes).is_ok(), "up to 3 bytes of padding");
    bytes.push(0);
    assert!(matches!(
        from_cdr::<Time>(&bytes),
        Err(CdrError::Trailing { extra: 4 })
    ));
}

#[test]
fn a_wire_time_in_seconds_converts_back_to_nanoseconds_that_reproduce_it_bit_for_bit() {
    for (s, n) in [
        (1_700_000_000u64, 0u32),
        (1_700_000_000, 1),
        (1_764_000_000, 999_999_999),
        (1_764_000_123, 123_456_789),
    ] {
        let t = std::time::Duration::new(s, n).as_secs_f64();
        let ns = secs_to_nanos(t);
        assert_eq!(std::time::Duration::from_nanos(ns).as_secs_f64(), t);
        assert_eq!(Time::from_nanos(ns).as_secs_f64(), t);
    }
    assert_eq!(secs_to_nanos(f64::NAN), 0);
    assert_eq!(secs_to_nanos(-1.0), 0);
}

proptest! {
    #[test]
    fn random_bytes_never_panic_the_decoder(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
        let _ = from_cdr::<Odometry>(&bytes);
        let _ = from_cdr::<RadarBScanMsg>(&bytes);
        let _ = from_cdr::<MarkerArray>(&bytes);
        let _ = from_cdr::<PointCloud2>(&bytes);
    }

    #[test]
    fn any_odometry_reads_back_as_written(
        x in -1e6f64..1e6, y in -1e6f64..1e6, yaw in -3.2f64..3.2,
        sec in 0i32..i32::MAX, nanosec in 0u32..1_000_000_000, frame in "[a-z_]{0,12}",
    ) {
        let mut m = Odometry {
            header: Header::new(Time { sec, nanosec }, &frame),
            child_frame_id: "base_link".into(),
            ..Odometry::default()
        };
        m.pose.pose.position.x = x;
        m.pose.pose.position.y = y;
        m.pose.pose.orientation = Quaternion::from_yaw(yaw);
        m.pose.covariance[7] = x.abs();
        let back: Odometry = from_cdr(&to_cdr(&m).unwrap()).unwrap();
        prop_assert_eq!(back, m);
    }
}
