//! ROS 2 messages built from the daemon's outputs, shared by the MCAP recording
//! ([`super::recording`]) and the live Zenoh topics (`super::live`, feature `zenoh`).
//!
//! | topic | type | built by |
//! |---|---|---|
//! | `/radar_data/b_scan_msg` | `navtech_msgs/msg/RadarBScanMsg` | [`BScan`] |
//! | `/radar_data/configuration_data` | `navtech_msgs/msg/RadarConfigurationMsg` | [`radar_configuration`] |
//! | `/odom/twist` | `geometry_msgs/msg/TwistStamped` | [`odometry_input`] |
//! | `/slam/odometry`, `/tf` | `nav_msgs/msg/Odometry`, `tf2_msgs/msg/TFMessage` | [`pose_messages`] |
//! | `/tf_static` | `tf2_msgs/msg/TFMessage` | [`tf_static`] |
//! | `/slam/map`, `/slam/map_covariance` | `sensor_msgs/msg/PointCloud2`, `visualization_msgs/msg/MarkerArray` | [`map_messages`] |
//! | `/slam/detections` | `sensor_msgs/msg/PointCloud2` | [`detections_message`] |

use std::sync::Arc;

use protocol::Geometry;
use radar_driver::Azimuth;
use radar_model::motion::MotionModel;
use ros_msgs::builtin::{secs_to_nanos, Time};
use ros_msgs::geometry::{
    Point, Pose, PoseWithCovariance, Quaternion, Transform, TransformStamped, Twist, TwistStamped,
    TwistWithCovariance, Vector3,
};
use ros_msgs::nav::{Odometry, TFMessage};
use ros_msgs::navtech::{RadarBScanMsg, RadarConfigurationMsg, RadarFftDataMsg};
use ros_msgs::sensor::{Image, PointCloud2};
use ros_msgs::std_msgs::{ColorRGBA, Header};
use ros_msgs::visualization::{Marker, MarkerArray};
use slam_filter::OdometrySample;

use super::detections::RotationDetections;
use super::map::MapSnapshot;
use super::trajectory::PoseSample;

/// Topic of the radar's rotations.
pub const TOPIC_BSCAN: &str = "/radar_data/b_scan_msg";
/// Topic of the radar's configuration.
pub const TOPIC_RADAR_CONFIGURATION: &str = "/radar_data/configuration_data";
/// Topic of the odometry the pipeline took.
pub const TOPIC_ODOMETRY_INPUT: &str = "/odom/twist";
/// Topic of the estimated pose.
pub const TOPIC_POSE: &str = "/slam/odometry";
/// Topic of the transforms.
pub const TOPIC_TF: &str = "/tf";
/// Topic of the static transforms.
pub const TOPIC_TF_STATIC: &str = "/tf_static";
/// Topic of the map's features.
pub const TOPIC_MAP: &str = "/slam/map";
/// Topic of the map's covariance ellipses.
pub const TOPIC_MAP_COVARIANCE: &str = "/slam/map_covariance";
/// Topic of each rotation's detections.
pub const TOPIC_DETECTIONS: &str = "/slam/detections";

/// The world frame.
pub const MAP_FRAME: &str = "map";
/// The vehicle's frame.
pub const BASE_FRAME: &str = "base_link";
/// The radar's frame.
pub const RADAR_FRAME: &str = "radar";

/// A B-scan larger than this (from a radar configuration claiming absurd sizes) is not
/// assembled: the rotation is counted as skipped.
pub const MAX_BSCAN_BYTES: usize = 64 << 20;
/// Chi-square 95% quantile with 2 degrees of freedom: the ellipses' scale.
const CHI2_2DOF_95: f64 = 5.991;

/// One rotation's azimuths being laid out as a B-scan (Navtech's `RadarBScanMsg`).
#[derive(Debug)]
pub struct BScan {
    rotation: u64,
    geometry: Arc<Geometry>,
    bytes_per_bin: usize,
    width: usize,
    data: Vec<u8>,
    encoders: Vec<u16>,
    stamps: Vec<u64>,
    last_time_s: f64,
    rows: usize,
}

impl BScan {
    /// A B-scan for `az`'s rotation and geometry (nothing pushed yet); `None` when the
    /// geometry is empty or larger than 64 MiB.
    pub fn new(az: &Azimuth) -> Option<Self> {
        let g = &az.geometry;
        let height = usize::from(g.azimuth_samples);
        let width = usize::from(g.range_in_bins);
        let bytes_per_bin = az.width.bytes_per_bin();
        let size = height.checked_mul(width)?.checked_mul(bytes_per_bin)?;
        if size == 0 || size > MAX_BSCAN_BYTES {
            return None;
        }
        Some(Self {
            rotation: az.rotation,
            geometry: Arc::clone(&az.geometry),
            bytes_per_bin,
            width,
            data: vec![0; size],
            encoders: vec![0; height],
            stamps: vec![0; height],
            last_time_s: az.timestamp_s,
            rows: 0,
        })
    }

    /// Whether `az` belongs to this B-scan (same rotation, width and geometry).
    pub fn fits(&self, az: &Azimuth) -> bool {
        az.rotation == self.rotation
            && az.width.bytes_per_bin() == self.bytes_per_bin
            && (Arc::ptr_eq(&az.geometry, &self.geometry) || *az.geometry == *self.geometry)
    }

    /// Lays `az` into its row (by encoder); an encoder outside the geometry is ignored.
    pub fn push(&mut self, az: &Azimuth) {
        let Some(row) = self.geometry.azimuth_index(az.encoder).map(usize::from) else {
            return;
        };
        let step = self.width * self.bytes_per_bin;
        let (Some(dst), Some(enc), Some(stamp)) = (
            self.data.get_mut(row * step..(row + 1) * step),
            self.encoders.get_mut(row),
            self.stamps.get_mut(row),
        ) else {
            return;
        };
        let n = az.bins.len().min(step);
        dst[..n].copy_from_slice(&az.bins[..n]);
        dst[n..].fill(0);
        *enc = az.encoder;
        *stamp = secs_to_nanos(az.timestamp_s);
        self.last_time_s = self.last_time_s.max(az.timestamp_s);
        self.rows += 1;
    }

    /// Rows filled so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The latest azimuth time, seconds.
    pub fn last_time_s(&self) -> f64 {
        self.last_time_s
    }

    /// The radar's rotation rate, Hz.
    pub fn rotation_hz(&self) -> f64 {
        self.geometry.rotation_hz
    }

    /// The message, stamped at the latest azimuth, in the `radar` frame.
    pub fn into_message(self) -> RadarBScanMsg {
        let step = self.width * self.bytes_per_bin;
        RadarBScanMsg {
            b_scan_img: Image {
                header: Header::new(Time::from_secs_f64(self.last_time_s), RADAR_FRAME),
                height: u32::from(self.geometry.azimuth_samples),
                width: u32::from(self.geometry.range_in_bins),
                encoding: if self.bytes_per_bin == 2 {
                    "16UC1".into()
                } else {
                    "8UC1".into()
                },
                is_bigendian: 0,
                step: u32::try_from(step).unwrap_or(u32::MAX),
                data: self.data,
            },
            encoder_values: self.encoders,
            timestamps: self.stamps,
        }
    }
}

/// The yaw rate (rad/s) an odometry sample stands for under `motion`. With the paper's
/// model the value is chosen among the nearest floats so that [`steer_from_yaw_rate`] gives
/// the sample's steering back bit for bit (a recording replays to the same trajectory).
pub fn yaw_rate(motion: &MotionModel, s: &OdometrySample) -> f64 {
    match *motion {
        MotionModel::Paper { step_s } if step_s > 0.0 => {
            let guess = s.steer_rad / step_s;
            if !guess.is_finite() {
                return guess;
            }
            (0..=8i64)
                .flat_map(|d| [d, -d])
                .map(|d| f64::from_bits(guess.to_bits().wrapping_add_signed(d)))
                .find(|y| y.is_finite() && y * step_s == s.steer_rad)
                .unwrap_or(guess)
        }
        MotionModel::Bicycle { wheelbase_m } if wheelbase_m > 0.0 => {
            s.speed_mps * s.steer_rad.tan() / wheelbase_m
        }
        _ => 0.0,
    }
}

/// The steering input a yaw rate stands for under `motion` (the inverse of [`yaw_rate`]):
/// `yaw_rate * step_s` for the paper's model, `atan(yaw_rate * wheelbase / speed)` for the
/// bicycle (0 when the speed is below 1 mm/s).
pub fn steer_from_yaw_rate(motion: &MotionModel, speed_mps: f64, yaw_rate_rps: f64) -> f64 {
    match *motion {
        MotionModel::Paper { step_s } => yaw_rate_rps * step_s,
        MotionModel::Bicycle { wheelbase_m } => {
            if speed_mps.abs() < 1e-3 {
                0.0
            } else {
                (yaw_rate_rps * wheelbase_m / speed_mps).atan()
            }
        }
    }
}

/// The ROS 2 messages the daemon takes its odometry from (an MCAP replay's odometry topic, a
/// Zenoh subscription): the vehicle's forward speed and yaw rate, the yaw rate turned into
/// the motion model's steering input ([`steer_from_yaw_rate`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum OdometryMessage {
    /// `nav_msgs/msg/Odometry`: `twist.twist.linear.x` and `twist.twist.angular.z`, stamped
    /// by its header.
    Odometry,
    /// `geometry_msgs/msg/TwistStamped`: `twist.linear.x` and `twist.angular.z`.
    TwistStamped,
}

impl OdometryMessage {
    /// The message named `name` (`package/msg/Type` or `package/Type`), if it is one of them.
    pub fn from_type_name(name: &str) -> Option<Self> {
        let same = |full: String| name == full || name == full.replacen("/msg/", "/", 1);
        if same(<Odometry as ros_msgs::RosMessage>::type_name()) {
            Some(Self::Odometry)
        } else if same(<TwistStamped as ros_msgs::RosMessage>::type_name()) {
            Some(Self::TwistStamped)
        } else {
            None
        }
    }

    /// The ROS 2 type name, `package/msg/Type`.
    pub fn type_name(self) -> String {
        match self {
            Self::Odometry => <Odometry as ros_msgs::RosMessage>::type_name(),
            Self::TwistStamped => <TwistStamped as ros_msgs::RosMessage>::type_name(),
        }
    }

    /// Decodes one CDR payload of this type into an odometry record under `motion`. A
    /// payload that does not decode (truncated, garbage, another type's longer or shorter
    /// layout) is an error; the values are checked later by the pipeline's odometry gate.
    pub fn decode(
        self,
        payload: &[u8],
        motion: &MotionModel,
    ) -> Result<radar_driver::OdometryRecord, ros_msgs::CdrError> {
        let (stamp, speed_mps, yaw_rate_rps) = match self {
            Self::Odometry => {
                let m: Odometry = ros_msgs::from_cdr(payload)?;
                (
                    m.header.stamp,
                    m.twist.twist.linear.x,
                    m.twist.twist.angular.z,
                )
            }
            Self::TwistStamped => {
                let m: TwistStamped = ros_msgs::from_cdr(payload)?;
                (m.header.stamp, m.twist.linear.x, m.twist.angular.z)
            }
        };
        Ok(radar_driver::OdometryRecord {
            timestamp_s: stamp.as_secs_f64(),
            speed_mps,
            steer_rad: steer_from_yaw_rate(motion, speed_mps, yaw_rate_rps),
        })
    }
}

/// Why a prior pose message (`[map] initial_pose_topic`) was refused.
#[derive(Debug, thiserror::Error)]
pub enum PriorError {
    /// The payload did not decode as `geometry_msgs/msg/PoseWithCovarianceStamped`.
    #[error("not a geometry_msgs/msg/PoseWithCovarianceStamped: {0}")]
    Decode(#[from] ros_msgs::CdrError),
    /// The pose is in another frame than the map's.
    #[error("the pose is in frame {0:?}, not {MAP_FRAME:?}")]
    Frame(String),
    /// A position or orientation that is not finite, or a zero quaternion.
    #[error("the pose is not finite, or its orientation is not a rotation")]
    Pose,
    /// The x, y, yaw block of the covariance is not symmetric positive definite (and not
    /// all zero).
    #[error("its covariance's x, y and yaw block is not symmetric positive definite")]
    Covariance,
}

/// The prior pose a `geometry_msgs/msg/PoseWithCovarianceStamped` payload in the map's frame
/// stands for (RViz's "2D Pose Estimate"): the position's x and y, the yaw of its
/// orientation, and the covariance's x, y and yaw block (`None` when it is all zero: the
/// configured sigmas apply). A zero stamp is "now" (the latest rotation).
pub fn prior_pose(payload: &[u8]) -> Result<crate::pipeline::localise::PriorPose, PriorError> {
    let m: ros_msgs::geometry::PoseWithCovarianceStamped = ros_msgs::from_cdr(payload)?;
    if m.header.frame_id.trim_start_matches('/') != MAP_FRAME {
        return Err(PriorError::Frame(m.header.frame_id));
    }
    let p = m.pose.pose;
    let q = p.orientation;
    let norm2 = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w;
    let values = [p.position.x, p.position.y, q.x, q.y, q.z, q.w];
    if !values.iter().all(|v| v.is_finite()) || norm2 < 1e-12 {
        return Err(PriorError::Pose);
    }
    let yaw = (2.0 * (q.w * q.z + q.x * q.y)).atan2(norm2 - 2.0 * (q.y * q.y + q.z * q.z));
    let at = [0usize, 1, 5];
    let c = &m.pose.covariance;
    let block = nalgebra::Matrix3::from_fn(|r, k| c[at[r] * 6 + at[k]]);
    let covariance = if block.iter().all(|v| *v == 0.0) {
        None
    } else {
        let symmetric = (block - block.transpose()).amax() <= 1e-9 * block.amax();
        if !block.iter().all(|v| v.is_finite()) || !symmetric || block.cholesky().is_none() {
            return Err(PriorError::Covariance);
        }
        Some(block)
    };
    let stamp = m.header.stamp;
    Ok(crate::pipeline::localise::PriorPose {
        stamp_s: (stamp != Time::default()).then(|| stamp.as_secs_f64()),
        pose: radar_model::geometry::Pose2::new(
            p.position.x,
            p.position.y,
            radar_model::geometry::wrap_angle(yaw),
        ),
        covariance,
    })
}

/// The pose's 3x3 covariance over (x, y, theta) placed in ROS's 6x6 over (x, y, z, roll,
/// pitch, yaw); the plane's other three are left 0.
fn covariance6(c: &[[f64; 3]; 3]) -> [f64; 36] {
    let mut out = [0.0; 36];
    let at = [0usize, 1, 5];
    for (r, row) in c.iter().enumerate() {
        for (k, v) in row.iter().enumerate() {
            out[at[r] * 6 + at[k]] = *v;
        }
    }
    out
}

/// Semi-axes (1 sigma) and the major axis's angle of a 2x2 covariance.
pub(crate) fn ellipse(c: &[[f64; 4]; 4]) -> (f64, f64, f64) {
    let (a, b, d) = (c[0][0], c[0][1], c[1][1]);
    let mean = 0.5 * (a + d);
    let diff = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let major = (mean + diff).max(0.0).sqrt();
    let minor = (mean - diff).max(0.0).sqrt();
    let angle = 0.5 * (2.0 * b).atan2(a - d);
    (major, minor, angle)
}

/// The twist an odometry sample stands for: speed along x, yaw rate about z.
pub fn twist(motion: &MotionModel, s: &OdometrySample) -> Twist {
    Twist {
        linear: Vector3 {
            x: s.speed_mps,
            y: 0.0,
            z: 0.0,
        },
        angular: Vector3 {
            x: 0.0,
            y: 0.0,
            z: yaw_rate(motion, s),
        },
    }
}

/// `/odom/twist`: one odometry sample, in `base_link`.
pub fn odometry_input(motion: &MotionModel, s: &OdometrySample) -> TwistStamped {
    TwistStamped {
        header: Header::new(Time::from_secs_f64(s.timestamp_s), BASE_FRAME),
        twist: twist(motion, s),
    }
}

/// `/radar_data/configuration_data` for `az`'s geometry, as Navtech's driver fills it.
pub fn radar_configuration(az: &Azimuth) -> RadarConfigurationMsg {
    let g = &az.geometry;
    RadarConfigurationMsg {
        header: Header::new(Time::from_secs_f64(az.timestamp_s), RADAR_FRAME),
        azimuth_samples: g.azimuth_samples,
        encoder_size: g.encoder_size,
        azimuth_offset: 0,
        // As Navtech's driver fills it: the wire's tenths of a millimetre.
        bin_size: (g.bin_size_m * 1e4).round() as f32,
        range_in_bins: g.range_in_bins,
        expected_rotation_rate: (g.rotation_hz * 1000.0).round().clamp(0.0, 65535.0) as u16,
        range_gain: g.range_gain as f32,
        range_offset: g.range_offset_m as f32,
    }
}

/// `/radar_data/fft_data`: one azimuth as Navtech's ROS 2 driver publishes it (angle in
/// degrees from the encoder, the radar's time split into seconds and nanoseconds, the bins
/// as received).
pub fn fft_data(az: &Azimuth) -> RadarFftDataMsg {
    let ns = secs_to_nanos(az.timestamp_s);
    let encoder_size = f64::from(az.geometry.encoder_size.max(1));
    RadarFftDataMsg {
        header: Header::new(Time::from_nanos(ns), RADAR_FRAME),
        angle: f64::from(az.encoder) * 360.0 / encoder_size,
        azimuth: az.encoder,
        sweep_counter: az.sweep_counter,
        ntp_seconds: u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX),
        ntp_split_seconds: (ns % 1_000_000_000) as u32,
        data: az.bins.to_vec(),
        data_length: u16::try_from(az.bins.len()).unwrap_or(u16::MAX),
    }
}

/// `/tf_static`: `base_link` to `radar`, identity (the radar at the vehicle's origin).
pub fn tf_static(stamp: Time) -> TFMessage {
    TFMessage {
        transforms: vec![TransformStamped {
            header: Header::new(stamp, BASE_FRAME),
            child_frame_id: RADAR_FRAME.into(),
            transform: Transform::default(),
        }],
    }
}

/// `/slam/odometry` and `/tf` for one pose: the pose with its covariance in `map`, the
/// twist the odometry input in force (`input`; covariance 0), and `map` to `base_link`.
pub fn pose_messages(
    p: &PoseSample,
    input: Option<&OdometrySample>,
    motion: &MotionModel,
) -> (Odometry, TFMessage) {
    let stamp = Time::from_secs_f64(p.timestamp_s);
    let pose = Pose {
        position: Point {
            x: p.x_m,
            y: p.y_m,
            z: 0.0,
        },
        orientation: Quaternion::from_yaw(p.theta_rad),
    };
    let odometry = Odometry {
        header: Header::new(stamp, MAP_FRAME),
        child_frame_id: BASE_FRAME.into(),
        pose: PoseWithCovariance {
            pose,
            covariance: covariance6(&p.covariance),
        },
        twist: TwistWithCovariance {
            twist: input.map_or(Twist::default(), |s| twist(motion, s)),
            covariance: [0.0; 36],
        },
    };
    let tf = TFMessage {
        transforms: vec![TransformStamped {
            header: Header::new(stamp, MAP_FRAME),
            child_frame_id: BASE_FRAME.into(),
            transform: Transform {
                translation: Vector3 {
                    x: p.x_m,
                    y: p.y_m,
                    z: 0.0,
                },
                rotation: pose.orientation,
            },
        }],
    };
    (odometry, tf)
}

/// `/slam/map` and `/slam/map_covariance` for one snapshot: the features as float32 `x, y,
/// z, reflectivity, absorption` in `map`; a `DELETEALL` then a flat cylinder per feature,
/// its 95% position ellipse, coloured by rho and alpha.
pub fn map_messages(m: &MapSnapshot) -> (PointCloud2, MarkerArray) {
    let stamp = Time::from_secs_f64(m.timestamp_s);
    let points: Vec<Vec<f32>> = m
        .features
        .iter()
        .map(|f| {
            vec![
                f.x_m as f32,
                f.y_m as f32,
                0.0,
                f.rho as f32,
                f.alpha as f32,
            ]
        })
        .collect();
    let cloud = PointCloud2::from_f32_points(
        Header::new(stamp, MAP_FRAME),
        &["x", "y", "z", "reflectivity", "absorption"],
        &points,
    );
    let header = Header::new(stamp, MAP_FRAME);
    let mut markers = Vec::with_capacity(m.features.len() + 1);
    markers.push(Marker {
        header: header.clone(),
        ns: "covariance".into(),
        action: Marker::DELETEALL,
        ..Marker::default()
    });
    let k = CHI2_2DOF_95.sqrt();
    for f in &m.features {
        let (major, minor, angle) = ellipse(&f.covariance);
        markers.push(Marker {
            header: header.clone(),
            ns: "covariance".into(),
            id: i32::try_from(f.id).unwrap_or(i32::MAX),
            type_: Marker::CYLINDER,
            action: Marker::ADD,
            pose: Pose {
                position: Point {
                    x: f.x_m,
                    y: f.y_m,
                    z: 0.0,
                },
                orientation: Quaternion::from_yaw(angle),
            },
            scale: Vector3 {
                x: (2.0 * k * major).max(1e-3),
                y: (2.0 * k * minor).max(1e-3),
                z: 0.05,
            },
            color: ColorRGBA {
                r: f.rho.clamp(0.0, 1.0) as f32,
                g: f.alpha.clamp(0.0, 1.0) as f32,
                b: 0.3,
                a: 0.6,
            },
            ..Marker::default()
        });
    }
    (cloud, MarkerArray { markers })
}

/// `/slam/detections`: float32 `x, y, z, power_db` in `radar` (x forward, y left), stamped
/// at the rotation's end.
pub fn detections_message(d: &RotationDetections) -> PointCloud2 {
    let points: Vec<Vec<f32>> = d
        .detections
        .iter()
        .map(|t| {
            let (x, y) = t.xy_ros();
            vec![x as f32, y as f32, 0.0, t.power_db as f32]
        })
        .collect();
    PointCloud2::from_f32_points(
        Header::new(Time::from_secs_f64(d.timestamp_s), RADAR_FRAME),
        &["x", "y", "z", "power_db"],
        &points,
    )
}

#[cfg(test)]
mod prior_tests {
    use super::*;
    use ros_msgs::geometry::PoseWithCovarianceStamped;

    /// RViz's "2D Pose Estimate": a yaw-only quaternion, 0.25 m² on x and y, 0.0685 rad² on
    /// yaw.
    fn estimate(frame: &str, yaw: f64) -> PoseWithCovarianceStamped {
        let mut covariance = [0.0; 36];
        covariance[0] = 0.25;
        covariance[7] = 0.25;
        covariance[35] = 0.068_538_919_452_190_42;
        PoseWithCovarianceStamped {
            header: Header::new(Time::from_nanos(1_704_067_205_500_000_000), frame),
            pose: PoseWithCovariance {
                pose: Pose {
                    position: Point {
                        x: 12.5,
                        y: -3.0,
                        z: 0.0,
                    },
                    orientation: Quaternion {
                        x: 0.0,
                        y: 0.0,
                        z: (0.5 * yaw).sin(),
                        w: (0.5 * yaw).cos(),
                    },
                },
                covariance,
            },
        }
    }

    #[test]
    fn a_pose_estimate_in_the_map_frame_is_a_prior() {
        let bytes = ros_msgs::to_cdr(&estimate("map", 2.5)).unwrap();
        let p = prior_pose(&bytes).unwrap();
        assert_eq!(p.stamp_s, Some(1_704_067_205.5));
        assert!((p.pose.x - 12.5).abs() < 1e-12 && (p.pose.y + 3.0).abs() < 1e-12);
        assert!((p.pose.theta - 2.5).abs() < 1e-12, "{}", p.pose.theta);
        let c = p.covariance.unwrap();
        assert_eq!((c[(0, 0)], c[(1, 1)]), (0.25, 0.25));
        assert!((c[(2, 2)] - 0.0685).abs() < 1e-3 && c[(0, 2)] == 0.0);
        // No covariance: the configured sigmas; a zero stamp: now.
        let mut m = estimate("/map", -1.0);
        m.pose.covariance = [0.0; 36];
        m.header.stamp = Time::default();
        let p = prior_pose(&ros_msgs::to_cdr(&m).unwrap()).unwrap();
        assert_eq!((p.stamp_s, p.covariance), (None, None));
        assert!((p.pose.theta + 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_prior_in_another_frame_or_with_bad_values_is_refused_by_name() {
        let refused = |m: &PoseWithCovarianceStamped| {
            prior_pose(&ros_msgs::to_cdr(m).unwrap())
                .unwrap_err()
                .to_string()
        };
        assert!(refused(&estimate("odom", 0.0)).contains("\"odom\""));
        let mut m = estimate("map", 0.0);
        m.pose.pose.position.x = f64::NAN;
        assert!(refused(&m).contains("not finite"));
        let mut m = estimate("map", 0.0);
        m.pose.pose.orientation = Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 0.0,
        };
        assert!(refused(&m).contains("not a rotation"));
        for (i, v) in [(0, -1.0), (1, 0.3), (35, f64::INFINITY)] {
            let mut m = estimate("map", 0.0);
            m.pose.covariance[i] = v;
            assert!(refused(&m).contains("positive definite"), "{i}");
        }
        let bytes = ros_msgs::to_cdr(&estimate("map", 0.0)).unwrap();
        for cut in [0, 3, 20, bytes.len() - 8] {
            assert!(prior_pose(&bytes[..cut])
                .unwrap_err()
                .to_string()
                .starts_with("not a geometry_msgs"));
        }
    }
}
