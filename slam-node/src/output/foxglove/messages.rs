//! The daemon's outputs as Foxglove's built-in schemas (protobuf, with their descriptors in
//! each channel's schema): no IO, pure conversions.
//!
//! Frames as in the ROS 2 outputs ([`crate::output::ros`]): `map` (the world, x east, y
//! north), `base_link` (the vehicle) and `radar` (at the vehicle's origin, x forward, y left).

use foxglove::schemas::{
    packed_element_field::NumericType, Color, CylinderPrimitive, FrameTransform, FrameTransforms,
    PackedElementField, PointCloud, Pose, PoseInFrame, PosesInFrame, Quaternion, SceneEntity,
    SceneUpdate, SpherePrimitive, Timestamp, Vector3,
};

use crate::output::detections::RotationDetections;
use crate::output::map::{MapFeature, MapSnapshot};
use crate::output::ros::{ellipse, BASE_FRAME, MAP_FRAME, RADAR_FRAME};
use crate::output::trajectory::PoseSample;

/// Ellipses are drawn at this many standard deviations (a 2-D Gaussian puts 98.9% of its
/// mass inside).
pub const ELLIPSE_SIGMAS: f64 = 3.0;
/// Thickness of the flat cylinders drawing ellipses, metres.
const ELLIPSE_HEIGHT_M: f64 = 0.05;
/// Diameter of the sphere at a feature's mean, metres.
const FEATURE_DOT_M: f64 = 0.6;
/// The smallest drawn ellipse axis, metres (a feature known to a millimetre stays visible).
const MIN_AXIS_M: f64 = 1e-3;

/// Unix seconds as Foxglove's timestamp (saturating outside 1970..2106).
pub fn timestamp(unix_s: f64) -> Timestamp {
    Timestamp::saturating_from_epoch_secs_f64(unix_s)
}

/// Unix seconds as nanoseconds for a message's log time (0 before 1970 or for NaN).
pub fn log_time_ns(unix_s: f64) -> u64 {
    let t = timestamp(unix_s);
    t.total_nanos()
}

/// A rotation by `yaw` about +z.
pub fn yaw_quaternion(yaw: f64) -> Quaternion {
    let half = 0.5 * yaw;
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: half.sin(),
        w: half.cos(),
    }
}

fn planar_pose(x: f64, y: f64, yaw: f64) -> Pose {
    Pose {
        position: Some(Vector3 { x, y, z: 0.0 }),
        orientation: Some(yaw_quaternion(yaw)),
    }
}

/// `/slam/pose`: the pose in `map`, stamped at its time.
pub fn pose_in_frame(p: &PoseSample) -> PoseInFrame {
    PoseInFrame {
        timestamp: Some(timestamp(p.timestamp_s)),
        frame_id: MAP_FRAME.into(),
        pose: Some(planar_pose(p.x_m, p.y_m, p.theta_rad)),
    }
}

/// `/tf`: `map` to `base_link` at the pose, and `base_link` to `radar` (identity: the radar
/// at the vehicle's origin, as the ROS 2 outputs' `/tf_static` says).
pub fn transforms(p: &PoseSample) -> FrameTransforms {
    let stamp = timestamp(p.timestamp_s);
    FrameTransforms {
        transforms: vec![
            FrameTransform {
                timestamp: Some(stamp),
                parent_frame_id: MAP_FRAME.into(),
                child_frame_id: BASE_FRAME.into(),
                translation: Some(Vector3 {
                    x: p.x_m,
                    y: p.y_m,
                    z: 0.0,
                }),
                rotation: Some(yaw_quaternion(p.theta_rad)),
            },
            FrameTransform {
                timestamp: Some(stamp),
                parent_frame_id: BASE_FRAME.into(),
                child_frame_id: RADAR_FRAME.into(),
                translation: Some(Vector3::default()),
                rotation: Some(yaw_quaternion(0.0)),
            },
        ],
    }
}

/// `/slam/trajectory` or `/slam/trajectory_optimised`: poses in `map`, stamped at the last.
/// At most `max_poses` are sent, evenly spaced, the last always among them.
pub fn poses_in_frame(poses: &[PoseSample], max_poses: usize) -> PosesInFrame {
    let stride = poses.len().div_ceil(max_poses.max(1)).max(1);
    let mut chosen: Vec<Pose> = poses
        .iter()
        .rev()
        .step_by(stride)
        .map(|p| planar_pose(p.x_m, p.y_m, p.theta_rad))
        .collect();
    chosen.reverse();
    PosesInFrame {
        timestamp: poses.last().map(|p| timestamp(p.timestamp_s)),
        frame_id: MAP_FRAME.into(),
        poses: chosen,
    }
}

/// A material's colour: red its reflectivity, green its absorption, blue its transmitted
/// share (they sum to one), with opacity `a`.
pub fn material_colour(f: &MapFeature, a: f64) -> Color {
    Color {
        r: f.rho.clamp(0.0, 1.0),
        g: f.alpha.clamp(0.0, 1.0),
        b: f.tau.clamp(0.0, 1.0),
        a,
    }
}

/// A flat cylinder drawing the `ELLIPSE_SIGMAS` ellipse of a 2x2 position covariance (the
/// top-left block of `c`) at `(x, y)`.
fn ellipse_cylinder(x: f64, y: f64, c: &[[f64; 4]; 4], color: Color) -> CylinderPrimitive {
    let (major, minor, angle) = ellipse(c);
    CylinderPrimitive {
        pose: Some(planar_pose(x, y, angle)),
        size: Some(Vector3 {
            x: (2.0 * ELLIPSE_SIGMAS * major).max(MIN_AXIS_M),
            y: (2.0 * ELLIPSE_SIGMAS * minor).max(MIN_AXIS_M),
            z: ELLIPSE_HEIGHT_M,
        }),
        bottom_scale: 1.0,
        top_scale: 1.0,
        color: Some(color),
    }
}

/// `/slam/map`: one entity `map` in `map` (replacing the previous snapshot), a flat cylinder
/// per feature drawing its 3-sigma position ellipse and a sphere at its mean, both coloured
/// by its material ([`material_colour`]).
pub fn map_scene(m: &MapSnapshot) -> SceneUpdate {
    let mut cylinders = Vec::with_capacity(m.features.len());
    let mut spheres = Vec::with_capacity(m.features.len());
    for f in &m.features {
        cylinders.push(ellipse_cylinder(
            f.x_m,
            f.y_m,
            &f.covariance,
            material_colour(f, 0.35),
        ));
        spheres.push(SpherePrimitive {
            pose: Some(planar_pose(f.x_m, f.y_m, 0.0)),
            size: Some(Vector3 {
                x: FEATURE_DOT_M,
                y: FEATURE_DOT_M,
                z: FEATURE_DOT_M,
            }),
            color: Some(material_colour(f, 1.0)),
        });
    }
    SceneUpdate {
        deletions: Vec::new(),
        entities: vec![SceneEntity {
            timestamp: Some(timestamp(m.timestamp_s)),
            frame_id: MAP_FRAME.into(),
            id: "map".into(),
            cylinders,
            spheres,
            ..SceneEntity::default()
        }],
    }
}

/// `/slam/pose_uncertainty`: one entity `pose` in `map`, a flat cylinder drawing the pose's
/// 3-sigma position ellipse.
pub fn pose_scene(p: &PoseSample) -> SceneUpdate {
    let c = &p.covariance;
    let block = [
        [c[0][0], c[0][1], 0.0, 0.0],
        [c[1][0], c[1][1], 0.0, 0.0],
        [0.0; 4],
        [0.0; 4],
    ];
    SceneUpdate {
        deletions: Vec::new(),
        entities: vec![SceneEntity {
            timestamp: Some(timestamp(p.timestamp_s)),
            frame_id: MAP_FRAME.into(),
            id: "pose".into(),
            cylinders: vec![ellipse_cylinder(
                p.x_m,
                p.y_m,
                &block,
                Color {
                    r: 0.2,
                    g: 0.6,
                    b: 1.0,
                    a: 0.4,
                },
            )],
            ..SceneEntity::default()
        }],
    }
}

/// Bytes per detection: float32 x, y, z, power_db.
const DETECTION_STRIDE: u32 = 16;

/// `/slam/detections`: the rotation's detections in `radar` (x forward, y left), float32
/// `x, y, z, power_db`.
pub fn detections_cloud(d: &RotationDetections) -> PointCloud {
    let mut data = Vec::with_capacity(d.detections.len() * DETECTION_STRIDE as usize);
    for t in &d.detections {
        let (x, y) = t.xy_ros();
        for v in [x as f32, y as f32, 0.0, t.power_db as f32] {
            data.extend_from_slice(&v.to_le_bytes());
        }
    }
    let field = |name: &str, offset: u32| PackedElementField {
        name: name.into(),
        offset,
        r#type: NumericType::Float32 as i32,
    };
    PointCloud {
        timestamp: Some(timestamp(d.timestamp_s)),
        frame_id: RADAR_FRAME.into(),
        pose: Some(planar_pose(0.0, 0.0, 0.0)),
        point_stride: DETECTION_STRIDE,
        fields: vec![
            field("x", 0),
            field("y", 4),
            field("z", 8),
            field("power_db", 12),
        ],
        data: data.into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::detections::Detection;

    fn pose(t: f64, x: f64, y: f64, th: f64) -> PoseSample {
        PoseSample {
            timestamp_s: t,
            x_m: x,
            y_m: y,
            theta_rad: th,
            covariance: [[0.04, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 1e-4]],
        }
    }

    #[test]
    fn a_pose_keeps_its_time_position_and_heading() {
        let p = pose(1_700_000_000.25, 3.0, -4.0, 2.5);
        let m = pose_in_frame(&p);
        let t = m.timestamp.unwrap();
        assert_eq!((t.sec(), t.nsec()), (1_700_000_000, 250_000_000));
        let q = m.pose.unwrap().orientation.unwrap();
        assert!((2.0 * q.z.atan2(q.w) - 2.5).abs() < 1e-12);
        let tf = transforms(&p);
        assert_eq!(tf.transforms[0].parent_frame_id, "map");
        assert_eq!(tf.transforms[0].child_frame_id, "base_link");
        assert_eq!(tf.transforms[1].child_frame_id, "radar");
    }

    #[test]
    fn a_trajectory_is_thinned_to_the_limit_keeping_the_last_pose() {
        let poses: Vec<_> = (0..1001)
            .map(|i| pose(f64::from(i), f64::from(i), 0.0, 0.0))
            .collect();
        let m = poses_in_frame(&poses, 100);
        assert!(m.poses.len() <= 100, "{}", m.poses.len());
        assert!(m.poses.len() >= 50, "{}", m.poses.len());
        let last = m.poses.last().unwrap().position.unwrap();
        assert_eq!(last.x, 1000.0);
        assert_eq!(poses_in_frame(&poses[..10], 100).poses.len(), 10);
        assert!(poses_in_frame(&[], 100).poses.is_empty());
    }

    #[test]
    fn the_pose_ellipse_is_three_sigma_along_its_axes() {
        let p = pose(0.0, 1.0, 2.0, 0.0);
        let s = pose_scene(&p);
        let c = &s.entities[0].cylinders[0];
        let size = c.size.unwrap();
        // sigma_x = 0.2 m, sigma_y = 0.1 m.
        assert!((size.x - 2.0 * 3.0 * 0.2).abs() < 1e-12, "{size:?}");
        assert!((size.y - 2.0 * 3.0 * 0.1).abs() < 1e-12, "{size:?}");
    }

    #[test]
    fn detections_pack_as_little_endian_float32_in_the_radar_frame() {
        let d = RotationDetections {
            rotation: 1,
            timestamp_s: 10.0,
            detections: vec![Detection {
                timestamp_s: 10.0,
                range_m: 10.0,
                bearing_rad: std::f64::consts::FRAC_PI_2,
                power_db: 55.0,
            }],
        };
        let c = detections_cloud(&d);
        assert_eq!(c.data.len(), 16);
        let f = |i: usize| f32::from_le_bytes(c.data[i * 4..i * 4 + 4].try_into().unwrap());
        // 90 degrees clockwise from forward: to the right, y = -10.
        assert!(f(0).abs() < 1e-5 && (f(1) + 10.0).abs() < 1e-5);
        assert_eq!(f(3), 55.0);
    }

    #[test]
    fn the_map_draws_each_feature_in_its_material_colour() {
        let m = MapSnapshot {
            format: MapSnapshot::FORMAT.into(),
            timestamp_s: 5.0,
            loss_db: 0.0,
            loss_var_db2: 0.0,
            features: vec![MapFeature {
                id: 1,
                x_m: 1.0,
                y_m: 2.0,
                rho: 0.6,
                alpha: 0.3,
                tau: 0.1,
                covariance: [
                    [1.0, 0.0, 0.0, 0.0],
                    [0.0, 0.25, 0.0, 0.0],
                    [0.0; 4],
                    [0.0; 4],
                ],
                observations: 3,
            }],
            global: None,
        };
        let s = map_scene(&m);
        let e = &s.entities[0];
        assert_eq!((e.cylinders.len(), e.spheres.len()), (1, 1));
        let size = e.cylinders[0].size.unwrap();
        assert!((size.x - 6.0).abs() < 1e-12 && (size.y - 3.0).abs() < 1e-12);
        let c = e.spheres[0].color.unwrap();
        assert_eq!((c.r, c.g, c.b), (0.6, 0.3, 0.1));
    }
}
