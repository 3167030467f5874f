//! Beam geometry: the vehicle pose, angle wrapping, range and bearing to a feature
//! (the paper's eq. 3 and 4) with their Jacobians, and which features a beam contains.
//!
//! Bearing follows the paper's eq. 4 and `docs/contracts.md`: `beta = wrap(theta -
//! atan2(y_f - y, x_f - x))`, measured clockwise from the vehicle's forward axis, so a
//! Navtech azimuth angle is a bearing. The radar sits at the vehicle's origin.

use crate::error::{finite, ModelError};
use nalgebra::Matrix3;
use std::f64::consts::PI;

/// Below this range (m) a feature is "at the sensor": its bearing is undefined.
pub const MIN_JACOBIAN_RANGE_M: f64 = 1e-6;

/// The paper's pencil beam width, 1.8 degrees, in radians.
pub const DEFAULT_BEAM_WIDTH_RAD: f64 = 1.8 * PI / 180.0;

/// Vehicle pose in the world frame: position (m) and heading (rad, counter-clockwise from +x).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose2 {
    /// East-ish position (m).
    pub x: f64,
    /// North-ish position (m).
    pub y: f64,
    /// Heading (rad), counter-clockwise from +x.
    pub theta: f64,
}

impl Pose2 {
    /// A pose from its three components.
    pub fn new(x: f64, y: f64, theta: f64) -> Self {
        Self { x, y, theta }
    }

    /// `other` in the frame of this pose (`self^-1 other`, both in one world frame), its
    /// heading wrapped.
    pub fn between(&self, other: &Pose2) -> Pose2 {
        let (s, c) = self.theta.sin_cos();
        let (dx, dy) = (other.x - self.x, other.y - self.y);
        Pose2::new(
            c * dx + s * dy,
            -s * dx + c * dy,
            wrap_angle(other.theta - self.theta),
        )
    }

    /// `other` (a pose in this pose's frame) in this pose's parent frame (`self other`),
    /// its heading wrapped: the inverse of [`Self::between`].
    pub fn compose(&self, other: &Pose2) -> Pose2 {
        let (s, c) = self.theta.sin_cos();
        Pose2::new(
            self.x + c * other.x - s * other.y,
            self.y + s * other.x + c * other.y,
            wrap_angle(self.theta + other.theta),
        )
    }

    /// The Jacobians of [`Self::compose`] with respect to this pose and to `other` (rows and
    /// columns x, y, theta).
    pub fn compose_jacobians(&self, other: &Pose2) -> (Matrix3<f64>, Matrix3<f64>) {
        let (s, c) = self.theta.sin_cos();
        let j_self = Matrix3::new(
            1.0,
            0.0,
            -s * other.x - c * other.y,
            0.0,
            1.0,
            c * other.x - s * other.y,
            0.0,
            0.0,
            1.0,
        );
        let j_other = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
        (j_self, j_other)
    }

    /// World position of a point seen at range `range_m` and bearing `bearing_rad`
    /// (the inverse of eq. 3 and 4).
    pub fn point_at(&self, range_m: f64, bearing_rad: f64) -> [f64; 2] {
        let a = self.theta - bearing_rad;
        [self.x + range_m * a.cos(), self.y + range_m * a.sin()]
    }

    /// [`point_at`](Self::point_at) and its Jacobian, for initialising a feature from an
    /// observation: rows `[x_f, y_f]`, columns `[x, y, theta, R, beta]`. With
    /// `a = theta - beta`: `d/dtheta = (-R sin a, R cos a)`, `d/dR = (cos a, sin a)`,
    /// `d/dbeta = (R sin a, -R cos a)`.
    pub fn point_at_with_jacobian(
        &self,
        range_m: f64,
        bearing_rad: f64,
    ) -> ([f64; 2], [[f64; 5]; 2]) {
        let a = self.theta - bearing_rad;
        let (sin_a, cos_a) = a.sin_cos();
        let xy = [self.x + range_m * cos_a, self.y + range_m * sin_a];
        let jac = [
            [1.0, 0.0, -range_m * sin_a, cos_a, range_m * sin_a],
            [0.0, 1.0, range_m * cos_a, sin_a, -range_m * cos_a],
        ];
        (xy, jac)
    }

    fn check(&self) -> Result<(), ModelError> {
        finite(self.x, "pose x")?;
        finite(self.y, "pose y")?;
        finite(self.theta, "pose theta")?;
        Ok(())
    }
}

/// Wraps an angle to (-pi, pi]. Non-finite input comes back unchanged (NaN stays NaN).
pub fn wrap_angle(angle_rad: f64) -> f64 {
    if !angle_rad.is_finite() {
        return angle_rad;
    }
    let two_pi = 2.0 * PI;
    let mut a = angle_rad.rem_euclid(two_pi); // [0, 2 pi)
    if a > PI {
        a -= two_pi;
    }
    // rem_euclid may round up to exactly 2 pi for tiny negative inputs.
    if a <= -PI {
        a += two_pi;
    }
    a
}

/// Range (m) from the radar to a feature: the paper's eq. 3.
pub fn range_eq3(pose: &Pose2, feature_xy: [f64; 2]) -> f64 {
    (feature_xy[0] - pose.x).hypot(feature_xy[1] - pose.y)
}

/// Bearing (rad, clockwise from forward, wrapped) of a feature: the paper's eq. 4.
pub fn bearing_eq4(pose: &Pose2, feature_xy: [f64; 2]) -> f64 {
    wrap_angle(pose.theta - (feature_xy[1] - pose.y).atan2(feature_xy[0] - pose.x))
}

/// A beam's axis from a pose: rejects the features that surely lie more than a limit off
/// the axis with a few multiply-adds, no trigonometry (a beam holds a few of a map's
/// features; testing every feature with [`range_bearing`] costs a `hypot` and an `atan2`
/// each). Conservative: what it keeps is decided by the exact test.
#[derive(Debug, Clone, Copy)]
pub struct BeamAxis {
    origin: [f64; 2],
    /// Unit vector along the beam in the map.
    axis: [f64; 2],
}

impl BeamAxis {
    /// The beam at `bearing_rad` (clockwise from forward, as eq. 4) from `pose`.
    pub fn new(pose: &Pose2, bearing_rad: f64) -> Self {
        let (s, c) = (pose.theta - bearing_rad).sin_cos();
        Self {
            origin: [pose.x, pose.y],
            axis: [c, s],
        }
    }

    /// The squared distance from the radar to `xy` (m^2).
    pub fn squared_range(&self, xy: [f64; 2]) -> f64 {
        let (dx, dy) = (xy[0] - self.origin[0], xy[1] - self.origin[1]);
        dx * dx + dy * dy
    }

    /// False only when the feature at `xy` is surely more than `limit_rad` off the axis
    /// (behind the radar, or wider than the limit in front of it). The limit is widened by
    /// a relative 1e-6 and `tan` bounded from above by Becker and Stark's
    /// `pi^2 x / (pi^2 - 4 x^2)`; a limit of 1.5 rad or more, or not a number, keeps all.
    pub fn may_hold(&self, xy: [f64; 2], limit_rad: f64) -> bool {
        if !(0.0..1.5).contains(&limit_rad) {
            return true;
        }
        let (dx, dy) = (xy[0] - self.origin[0], xy[1] - self.origin[1]);
        let along = dx * self.axis[0] + dy * self.axis[1];
        let across = dx * self.axis[1] - dy * self.axis[0];
        if !(along.is_finite() && across.is_finite()) || (dx == 0.0 && dy == 0.0) {
            return true;
        }
        let x = limit_rad * (1.0 + 1e-6) + 1e-12;
        let pi2 = std::f64::consts::PI * std::f64::consts::PI;
        let tan_bound = pi2 * x / (pi2 - 4.0 * x * x);
        along > 0.0 && across.abs() <= along * tan_bound
    }
}

/// Range and bearing of one feature.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeBearing {
    /// Eq. 3 (m).
    pub range_m: f64,
    /// Eq. 4 (rad).
    pub bearing_rad: f64,
}

/// Range and bearing of a feature (eq. 3 and 4).
pub fn range_bearing(pose: &Pose2, feature_xy: [f64; 2]) -> RangeBearing {
    RangeBearing {
        range_m: range_eq3(pose, feature_xy),
        bearing_rad: bearing_eq4(pose, feature_xy),
    }
}

/// Jacobian of `[R, beta]` (eq. 3, 4) with respect to the pose `[x, y, theta]` and the
/// feature `[x_f, y_f]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeBearingJacobian {
    /// `d R / d [x, y, theta]`.
    pub range_wrt_pose: [f64; 3],
    /// `d R / d [x_f, y_f]`.
    pub range_wrt_feature: [f64; 2],
    /// `d beta / d [x, y, theta]`.
    pub bearing_wrt_pose: [f64; 3],
    /// `d beta / d [x_f, y_f]`.
    pub bearing_wrt_feature: [f64; 2],
}

impl RangeBearingJacobian {
    /// Writes the range row into `jacobian` row `row` and the bearing row into `row + 1`:
    /// the pose derivatives into columns 0..3, the feature's into `feature_column` and the
    /// one after. Other columns are left as they are.
    ///
    /// # Panics
    /// If those rows or columns lie outside `jacobian` (a caller's layout error).
    pub fn write_rows(
        &self,
        jacobian: &mut nalgebra::DMatrix<f64>,
        row: usize,
        feature_column: usize,
    ) {
        for c in 0..3 {
            jacobian[(row, c)] = self.range_wrt_pose[c];
            jacobian[(row + 1, c)] = self.bearing_wrt_pose[c];
        }
        for c in 0..2 {
            jacobian[(row, feature_column + c)] = self.range_wrt_feature[c];
            jacobian[(row + 1, feature_column + c)] = self.bearing_wrt_feature[c];
        }
    }
}

/// Range, bearing and their Jacobian (eq. 3, 4). With `dx = x_f - x`, `dy = y_f - y`:
/// `dR/d(x, y, theta) = (-dx/R, -dy/R, 0)`, `dR/d(x_f, y_f) = (dx/R, dy/R)`,
/// `dbeta/d(x, y, theta) = (-dy/R^2, dx/R^2, 1)`, `dbeta/d(x_f, y_f) = (dy/R^2, -dx/R^2)`.
///
/// # Errors
/// Non-finite inputs, or a feature within [`MIN_JACOBIAN_RANGE_M`] of the sensor.
pub fn range_bearing_with_jacobian(
    pose: &Pose2,
    feature_xy: [f64; 2],
) -> Result<(RangeBearing, RangeBearingJacobian), ModelError> {
    pose.check()?;
    finite(feature_xy[0], "feature x")?;
    finite(feature_xy[1], "feature y")?;
    let dx = feature_xy[0] - pose.x;
    let dy = feature_xy[1] - pose.y;
    let r = dx.hypot(dy);
    if r < MIN_JACOBIAN_RANGE_M {
        return Err(ModelError::FeatureAtSensor { range_m: r });
    }
    let r2 = r * r;
    let rb = RangeBearing {
        range_m: r,
        bearing_rad: wrap_angle(pose.theta - dy.atan2(dx)),
    };
    let jac = RangeBearingJacobian {
        range_wrt_pose: [-dx / r, -dy / r, 0.0],
        range_wrt_feature: [dx / r, dy / r],
        bearing_wrt_pose: [-dy / r2, dx / r2, 1.0],
        bearing_wrt_feature: [dy / r2, -dx / r2],
    };
    Ok((rb, jac))
}

/// One beam: where it points and what it can see.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Beam {
    /// Bearing of the beam's axis (rad, clockwise from forward, like eq. 4).
    pub bearing_rad: f64,
    /// Full width (rad); a feature is inside when `|wrap(beta - bearing)| <= width / 2`.
    pub width_rad: f64,
    /// Features nearer than this (m) are not seen.
    pub min_range_m: f64,
    /// Features farther than this (m) are not seen.
    pub max_range_m: f64,
}

impl Beam {
    /// A beam of the default 1.8 degree width seeing from `min_range_m` to `max_range_m`.
    pub fn new(bearing_rad: f64, min_range_m: f64, max_range_m: f64) -> Self {
        Self {
            bearing_rad,
            width_rad: DEFAULT_BEAM_WIDTH_RAD,
            min_range_m,
            max_range_m,
        }
    }

    /// Whether a feature at this range and bearing lies inside the beam.
    pub fn contains(&self, rb: &RangeBearing) -> bool {
        rb.range_m >= self.min_range_m
            && rb.range_m <= self.max_range_m
            && wrap_angle(rb.bearing_rad - self.bearing_rad).abs() <= 0.5 * self.width_rad
    }
}

/// A feature found inside a beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamHit {
    /// Index of the feature in the caller's sequence.
    pub index: usize,
    /// Its range (m), eq. 3.
    pub range_m: f64,
    /// Its bearing (rad), eq. 4.
    pub bearing_rad: f64,
}

/// Collects into `out` (cleared first) the features inside `beam`, sorted by range
/// (ties by index, so the order is deterministic). Features with non-finite coordinates
/// are skipped. Allocates only if `out` must grow.
pub fn features_in_beam<I>(pose: &Pose2, beam: &Beam, features: I, out: &mut Vec<BeamHit>)
where
    I: IntoIterator<Item = [f64; 2]>,
{
    out.clear();
    for (index, xy) in features.into_iter().enumerate() {
        if !(xy[0].is_finite() && xy[1].is_finite()) {
            continue;
        }
        let rb = range_bearing(pose, xy);
        if beam.contains(&rb) {
            out.push(BeamHit {
                index,
                range_m: rb.range_m,
                bearing_rad: rb.bearing_rad,
            });
        }
    }
    out.sort_by(|a, b| a.range_m.total_cmp(&b.range_m).then(a.index.cmp(&b.index)));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compose_undoes_between_and_its_jacobians_match_finite_differences() {
        let a = Pose2::new(1.0, 2.0, 3.0);
        let b = Pose2::new(-4.0, 0.5, -2.9);
        let back = a.compose(&a.between(&b));
        assert!((back.x - b.x).abs() < 1e-12 && (back.y - b.y).abs() < 1e-12);
        assert!(wrap_angle(back.theta - b.theta).abs() < 1e-12);
        let (ja, jb) = a.compose_jacobians(&b);
        let v = |p: Pose2| [p.x, p.y, p.theta];
        let h = 1e-6;
        for k in 0..3 {
            let nudge = |p: &Pose2, d: f64| {
                let mut q = v(*p);
                q[k] += d;
                Pose2::new(q[0], q[1], q[2])
            };
            let (fa, ra) = (v(nudge(&a, h).compose(&b)), v(nudge(&a, -h).compose(&b)));
            let (fb, rb) = (v(a.compose(&nudge(&b, h))), v(a.compose(&nudge(&b, -h))));
            for r in 0..3 {
                assert!((wrap_angle(fa[r] - ra[r]) / (2.0 * h) - ja[(r, k)]).abs() < 1e-7);
                assert!((wrap_angle(fb[r] - rb[r]) / (2.0 * h) - jb[(r, k)]).abs() < 1e-7);
            }
        }
    }

    #[test]
    fn wrap_angle_maps_into_the_half_open_interval() {
        assert_eq!(wrap_angle(PI), PI);
        assert_eq!(wrap_angle(-PI), PI);
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-3.5 * PI) - 0.5 * PI).abs() < 1e-12);
        assert_eq!(wrap_angle(0.0), 0.0);
        for k in -1000..1000 {
            let a = wrap_angle(f64::from(k) * 0.37);
            assert!(a > -PI && a <= PI);
        }
        assert!(wrap_angle(f64::NAN).is_nan());
    }

    #[test]
    fn bearing_is_clockwise_from_the_forward_axis() {
        // Facing north (+y), a feature to the east is 90 degrees clockwise.
        let pose = Pose2::new(0.0, 0.0, 0.5 * PI);
        let rb = range_bearing(&pose, [3.0, 0.0]);
        assert!((rb.range_m - 3.0).abs() < 1e-12);
        assert!((rb.bearing_rad - 0.5 * PI).abs() < 1e-12);
        // point_at inverts it.
        let p = pose.point_at(rb.range_m, rb.bearing_rad);
        assert!((p[0] - 3.0).abs() < 1e-12 && p[1].abs() < 1e-12);
    }

    #[test]
    fn features_in_beam_keeps_only_the_beam_sorted_by_range() {
        let pose = Pose2::new(0.0, 0.0, 0.0);
        let beam = Beam::new(0.0, 0.5, 100.0);
        let half = 0.5 * DEFAULT_BEAM_WIDTH_RAD;
        let features = [
            pose.point_at(30.0, 0.0),
            pose.point_at(10.0, 0.5 * half),
            pose.point_at(20.0, 1.1 * half),  // outside the width
            pose.point_at(150.0, 0.0),        // beyond max range
            pose.point_at(0.2, 0.0),          // inside min range
            [f64::NAN, 0.0],                  // skipped
            pose.point_at(10.0, -0.5 * half), // tie at 10 m: index order
        ];
        let mut out = Vec::new();
        features_in_beam(&pose, &beam, features, &mut out);
        let idx: Vec<usize> = out.iter().map(|h| h.index).collect();
        assert_eq!(idx, vec![1, 6, 0]);
    }

    /// Whatever the exact test keeps (offset from the beam's bearing within the limit), the
    /// axis keeps too; most of what lies well off the axis it rejects.
    #[test]
    fn the_beam_axis_never_rejects_a_feature_within_the_limit() {
        let mut rejected = 0;
        let mut total = 0;
        for i in 0..60u32 {
            let t = f64::from(i);
            let pose = Pose2 {
                x: 10.0 * (t * 0.37).sin(),
                y: -5.0 * (t * 0.71).cos(),
                theta: 7.0 * (t * 0.13).sin(),
            };
            let bearing = 3.1 * (t * 0.29).cos();
            for limit in [0.0, 0.004, 0.02, 0.3, 1.2, 1.4999, 1.6] {
                let axis = BeamAxis::new(&pose, bearing);
                for j in 0..400u32 {
                    let u = f64::from(j);
                    // Features all around, some exactly on the axis or at the radar.
                    let xy = match j % 50 {
                        0 => [pose.x, pose.y],
                        1 => {
                            let phi = pose.theta - bearing;
                            [pose.x + 20.0 * phi.cos(), pose.y + 20.0 * phi.sin()]
                        }
                        _ => [
                            pose.x + 80.0 * (u * 0.618).fract() - 40.0,
                            pose.y + 60.0 * (u * 0.382).fract() - 30.0,
                        ],
                    };
                    let offset = wrap_angle(range_bearing(&pose, xy).bearing_rad - bearing).abs();
                    total += 1;
                    if offset <= limit {
                        assert!(
                            axis.may_hold(xy, limit),
                            "{pose:?} {bearing} {limit} {xy:?}"
                        );
                    } else if !axis.may_hold(xy, limit) {
                        rejected += 1;
                    }
                }
            }
        }
        assert!(rejected > total / 2, "{rejected} of {total} rejected");
    }
}
