//! Tracking in a saved map's scans once the search has a fix: a Kalman filter on the
//! vehicle's pose in the map's frame, predicted by the local filter's motion and updated by
//! registering each rotation's cloud against the map's scans.
//!
//! - **Predict**: the local filter (which maps in a frame of its own, as while searching)
//!   moved by `u` since the last rotation; the map pose is composed with `u` and its
//!   covariance grows by the Jacobians of the composition and a motion noise
//!   ([`TrackSettings`]) in the vehicle's frame, growing with the distance and the turn.
//! - **Update**: the rotation's cloud (radar odometry's, in the vehicle's frame at the
//!   rotation's end) is laid on the map's score grid over a window of 2 m and 0.02 rad
//!   around the prediction (correlative search: no basin), then registered against the
//!   map's scans ([`super::scan_map::ScanMap`]) from the best, by radar odometry's point-to-line ICP, with a pair gate of three
//!   of the prediction's standard deviations (at least [`TrackSettings::min_gate_m`]). The registered pose is a measurement of the
//!   pose with the registration's covariance (its information, a floor; inflated along a
//!   direction the scene does not pin), tested against the prediction (chi-square, 3 dof)
//!   and fused (Joseph form).
//! - **Re-anchored**: registrations outside the gate that agree with each other on their
//!   offset from the prediction ([`TrackSettings::reanchor_after`] in a row) are right about
//!   the map and the prediction is not: the pose is taken from the registration.
//! - **Lost**: [`TrackSettings::lost_after`] rotations in a row without an accepted update,
//!   or the position's standard deviation past [`TrackSettings::lost_sigma_m`].
//!
//! The state is three numbers: nothing of the map enters a filter, so tracking costs one
//! registration a rotation whatever the map's size. No IO.

use nalgebra::{Matrix3, Vector3};
use radar_model::geometry::{wrap_angle, Pose2};
use radar_odometry::{covariance, register, Constraint, HEADING_LENGTH_M};
use slam_graph::correlate::{correlate, Window};
use slam_graph::se2::{compose, inverse};

use super::scan_map::ScanMap;

/// Tracking's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackSettings {
    /// Motion noise per rotation: a standard deviation along the motion (m) of this much...
    pub along_m: f64,
    /// ... plus this fraction of the distance moved.
    pub along_per_m: f64,
    /// Across the motion (m), and per metre moved.
    pub across_m: f64,
    /// See `across_m`.
    pub across_per_m: f64,
    /// Heading (rad), and per radian turned.
    pub heading_rad: f64,
    /// See `heading_rad`.
    pub heading_per_rad: f64,
    /// The registration's floor: standard deviation of a fit on a well-constrained scene,
    /// each axis (m) and in heading (rad).
    pub floor_m: f64,
    /// See `floor_m`.
    pub floor_rad: f64,
    /// Pairs counted as one independent error in the registration's covariance.
    pub correlated_pairs: f64,
    /// Fewest pairs for a registration.
    pub min_pairs: usize,
    /// A registration with a residual above this (m, RMS) is not used.
    pub max_rms_m: f64,
    /// The gate of a registration against the prediction: chi-square, 3 dof.
    pub gate_chi2: f64,
    /// Rotations in a row without an accepted registration that lose the fix.
    pub lost_after: u32,
    /// A position standard deviation past this (m) loses the fix.
    pub lost_sigma_m: f64,
    /// A rotation's cloud is registered with at most this many of its points (evenly).
    pub max_points: usize,
    /// The registration's first pair gate is three of the prediction's standard deviations
    /// and half a metre, at least this (m) and at most 4 m. Along a street the walls pair
    /// at any offset along it: the posts, trees, parked cars and cross streets that pin it
    /// must be within the gate to be paired, or an offset the prediction carries (out of a
    /// turn) is never taken out. The gate narrows to a fifth as the registration converges.
    pub min_gate_m: f64,
    /// Before ICP, a correlative search on the map's score grid over this window around
    /// the prediction (m either way, rad either way, in steps of `search_step_rad`), with at
    /// most `search_points` of the cloud: ICP starts from its best. A single rotation's
    /// ICP does not leave the basin it starts in, and along a street of walls an offset
    /// of a metre or two (out of a turn) is such a basin: the posts, trees and parked cars
    /// that pin the street are then beyond the narrowing gate.
    pub search_half_m: f64,
    /// See `search_half_m`.
    pub search_half_rad: f64,
    /// See `search_half_m`.
    pub search_step_rad: f64,
    /// See `search_half_m`.
    pub search_points: usize,
    /// Registrations outside the gate that agree on their offset from the prediction
    /// (within `reanchor_agree_m` and `reanchor_agree_rad`) this many times in a row move
    /// the pose to the registration (fewer than `lost_after`).
    pub reanchor_after: u32,
    /// See `reanchor_after`.
    pub reanchor_agree_m: f64,
    /// See `reanchor_after`.
    pub reanchor_agree_rad: f64,
}

impl Default for TrackSettings {
    fn default() -> Self {
        Self {
            along_m: 0.02,
            along_per_m: 0.03,
            across_m: 0.02,
            across_per_m: 0.02,
            heading_rad: 0.002,
            heading_per_rad: 0.3,
            floor_m: 0.03,
            floor_rad: 0.0012,
            correlated_pairs: 10.0,
            min_pairs: 100,
            max_rms_m: 0.6,
            // 0.999 of chi-square with 3 dof.
            gate_chi2: 16.27,
            lost_after: 12,
            lost_sigma_m: 5.0,
            max_points: 1500,
            min_gate_m: 2.5,
            search_half_m: 2.0,
            search_half_rad: 0.02,
            search_step_rad: 0.005,
            search_points: 400,
            reanchor_after: 4,
            reanchor_agree_m: 0.3,
            reanchor_agree_rad: 0.01,
        }
    }
}

/// The heading's motion noise per rotation when a gyro gives the turn (rad, and per radian
/// turned): the local filter's heading then follows the gyro, whose increments erred 0.0004
/// rad RMS a rotation on the realistic city (0.00026 through its turns) against the 0.002
/// rad of radar odometry alone. With the default's noise the tracker took each rotation's
/// registration nearly whole; with this one it averages several: the return route's
/// heading 0.108 -> 0.097 deg RMS, the same route's 0.081 -> 0.071 (slam-node/README.md,
/// "By the map's scans").
pub const GYRO_HEADING_RAD: f64 = 0.0007;
/// See [`GYRO_HEADING_RAD`].
pub const GYRO_HEADING_PER_RAD: f64 = 0.1;

impl TrackSettings {
    /// The settings for a local filter whose turn comes from a gyro (`gyro`) or from radar
    /// odometry alone (the default's).
    pub fn for_turn_source(gyro: bool) -> Self {
        let default = Self::default();
        if gyro {
            Self {
                heading_rad: GYRO_HEADING_RAD,
                heading_per_rad: GYRO_HEADING_PER_RAD,
                ..default
            }
        } else {
            default
        }
    }
}

/// What one rotation's update did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Update {
    /// The registration was fused.
    Fused {
        /// Its squared Mahalanobis distance from the prediction.
        d2: f64,
    },
    /// No registration (too few pairs, an empty cloud, a poor fit).
    NoRegistration,
    /// A registration with too large a residual (m, RMS): not used.
    PoorFit {
        /// Its residual.
        rms_m: f64,
    },
    /// A registration outside the gate: not fused.
    Gated {
        /// Its squared Mahalanobis distance.
        d2: f64,
    },
    /// Outside the gate, but the last registrations agreed on the offset: the pose was
    /// taken from the registration.
    Reanchored {
        /// Its squared Mahalanobis distance.
        d2: f64,
    },
}

/// The pose filter in the map's frame.
#[derive(Debug, Clone)]
pub struct ScanTracker {
    settings: TrackSettings,
    pose: Pose2,
    cov: Matrix3<f64>,
    /// The local filter's pose at the last rotation (in its frame).
    last_local: Pose2,
    misses: u32,
    /// The last gated registration's offset from its prediction (in the prediction's
    /// frame), and how many in a row agreed with it.
    gated_offset: Option<(Pose2, u32)>,
}

fn symmetric(m: Matrix3<f64>) -> Matrix3<f64> {
    0.5 * (m + m.transpose())
}

impl ScanTracker {
    /// Starts at `pose` in the map with covariance `cov`, the local filter at `local`.
    pub fn new(settings: TrackSettings, pose: Pose2, cov: Matrix3<f64>, local: Pose2) -> Self {
        Self {
            settings,
            pose,
            cov: symmetric(cov),
            last_local: local,
            misses: 0,
            gated_offset: None,
        }
    }

    /// The pose in the map and its covariance.
    pub fn estimate(&self) -> (Pose2, Matrix3<f64>) {
        (self.pose, self.cov)
    }

    /// The local frame restarted at `origin` (in the old frame).
    pub fn reframe(&mut self, origin: &Pose2) {
        self.last_local = compose(&inverse(origin), &self.last_local);
    }

    /// The position's standard deviation along its worst direction (m).
    fn position_sigma(&self) -> f64 {
        self.cov
            .fixed_view::<2, 2>(0, 0)
            .symmetric_eigenvalues()
            .max()
            .max(0.0)
            .sqrt()
    }

    /// Whether the fix is lost.
    pub fn lost(&self) -> bool {
        let sigma = self.position_sigma();
        self.misses >= self.settings.lost_after
            || sigma.is_nan()
            || sigma > self.settings.lost_sigma_m
    }

    /// The motion noise of a step `u` (in the vehicle's frame).
    fn motion_noise(&self, u: &Pose2) -> Matrix3<f64> {
        let s = &self.settings;
        let d = u.x.hypot(u.y);
        let along = s.along_m + s.along_per_m * d;
        let across = s.across_m + s.across_per_m * d;
        let heading = s.heading_rad + s.heading_per_rad * u.theta.abs();
        // Along and across the step's direction (forward when it is too short to have one).
        let (sn, cs) = if d > 1e-6 {
            (u.y / d, u.x / d)
        } else {
            (0.0, 1.0)
        };
        let r = nalgebra::Matrix2::new(cs, -sn, sn, cs);
        let xy =
            r * nalgebra::Matrix2::new(along * along, 0.0, 0.0, across * across) * r.transpose();
        let mut q = Matrix3::zeros();
        q.fixed_view_mut::<2, 2>(0, 0).copy_from(&xy);
        q[(2, 2)] = heading * heading;
        q
    }

    /// Predicts by the local filter's motion to `local` (its pose now, in its frame).
    pub fn predict(&mut self, local: &Pose2) {
        let u = self.last_local.between(local);
        self.last_local = *local;
        let (j_pose, j_u) = self.pose.compose_jacobians(&u);
        let q = self.motion_noise(&u);
        self.pose = compose(&self.pose, &u);
        self.cov = symmetric(j_pose * self.cov * j_pose.transpose() + j_u * q * j_u.transpose());
    }

    /// A rotation without a cloud to register (radar odometry had none): a miss.
    pub fn skip(&mut self) -> Update {
        self.misses += 1;
        Update::NoRegistration
    }

    /// Registers `cloud` (in the vehicle's frame) against `map` from the prediction and
    /// fuses it when it passes.
    pub fn update(&mut self, map: &ScanMap, cloud: &[[f64; 2]]) -> Update {
        let s = self.settings;
        let stride = cloud.len().div_ceil(s.max_points.max(1)).max(1);
        let points: Vec<[f64; 2]> = cloud.iter().step_by(stride).copied().collect();
        let sigma = self.position_sigma();
        let gate = (3.0 * sigma + 0.5).clamp(s.min_gate_m, 4.0);
        let start = map
            .grid
            .as_ref()
            .and_then(|grid| {
                let stride = cloud.len().div_ceil(s.search_points.max(1)).max(1);
                let sample: Vec<[f64; 2]> = cloud.iter().step_by(stride).copied().collect();
                let window = Window {
                    half_m: s.search_half_m,
                    half_rad: s.search_half_rad,
                    step_rad: s.search_step_rad,
                };
                correlate(grid, &sample, &self.pose, &window, 1.0, 0)
            })
            .map_or(self.pose, |(best, _)| best.pose);
        let registered = register(&map.cloud, &points, start, gate, s.min_pairs);
        if let Some(reg) = registered.filter(|reg| reg.rms_m > s.max_rms_m) {
            self.misses += 1;
            return Update::PoorFit { rms_m: reg.rms_m };
        }
        let outcome = registered.and_then(|reg| {
            let floor = Matrix3::from_diagonal(&Vector3::new(
                s.floor_m.powi(2),
                s.floor_m.powi(2),
                s.floor_rad.powi(2),
            ));
            // Each kept point stands for `stride` of the cloud's: the same information.
            let mut r = covariance(&reg, &floor, s.correlated_pairs, 0.05)?;
            if let Some(c) = Constraint::of(&reg).filter(|c| c.weakest < 0.02) {
                let d = c.direction;
                let v = Vector3::new(d[0], d[1], d[2] / HEADING_LENGTH_M);
                r += v * v.transpose() * 100.0;
            }
            Some((reg.pose, symmetric(r)))
        });
        let Some((z, r)) = outcome else {
            self.misses += 1;
            return Update::NoRegistration;
        };
        let nu = Vector3::new(
            z.x - self.pose.x,
            z.y - self.pose.y,
            wrap_angle(z.theta - self.pose.theta),
        );
        let innovation_cov = symmetric(self.cov + r);
        let Some(chol) = innovation_cov.cholesky() else {
            self.misses += 1;
            return Update::NoRegistration;
        };
        let d2 = nu.dot(&chol.solve(&nu));
        if d2.is_nan() || d2 > s.gate_chi2 {
            self.misses += 1;
            // Registrations that keep disagreeing with the prediction by the same offset
            // are right about the map and the prediction is not (a turn it got wrong, or a
            // street the map holds twice, a metre or two apart, and the tracker on the
            // other copy): after `reanchor_after` in a row the pose is taken from the
            // registration, its covariance the registration's grown by the offset.
            let offset = self.pose.between(&z);
            let agreeing = match self.gated_offset {
                Some((o, n))
                    if (o.x - offset.x).hypot(o.y - offset.y) <= s.reanchor_agree_m
                        && wrap_angle(o.theta - offset.theta).abs() <= s.reanchor_agree_rad =>
                {
                    n + 1
                }
                _ => 1,
            };
            self.gated_offset = Some((offset, agreeing));
            if agreeing >= s.reanchor_after {
                self.pose = z;
                let grow = Vector3::new(offset.x, offset.y, offset.theta);
                self.cov = symmetric(r + Matrix3::from_diagonal(&grow.component_mul(&grow)));
                self.misses = 0;
                self.gated_offset = None;
                return Update::Reanchored { d2 };
            }
            return Update::Gated { d2 };
        }
        self.gated_offset = None;
        // K = P S^-1 (S symmetric): solve S K' = P.
        let k = chol.solve(&self.cov).transpose();
        let dx = k * nu;
        self.pose = Pose2::new(
            self.pose.x + dx[0],
            self.pose.y + dx[1],
            wrap_angle(self.pose.theta + dx[2]),
        );
        let i_k = Matrix3::identity() - k;
        self.cov = symmetric(i_k * self.cov * i_k.transpose() + k * r * k.transpose());
        self.misses = 0;
        Update::Fused { d2 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prediction_composes_the_local_motion_and_grows_the_covariance() {
        let mut t = ScanTracker::new(
            TrackSettings::default(),
            Pose2::new(10.0, 5.0, std::f64::consts::FRAC_PI_2),
            Matrix3::from_diagonal(&Vector3::new(0.01, 0.01, 1e-4)),
            Pose2::new(0.0, 0.0, 0.0),
        );
        t.predict(&Pose2::new(2.0, 0.0, 0.1));
        let (p, c) = t.estimate();
        assert!(
            (p.x - 10.0).abs() < 1e-12 && (p.y - 7.0).abs() < 1e-12,
            "{p:?}"
        );
        assert!((p.theta - (std::f64::consts::FRAC_PI_2 + 0.1)).abs() < 1e-12);
        // Along the step (north in the map) it grew by (0.02 + 0.03 * 2)^2.
        assert!((c[(1, 1)] - (0.01 + 0.08f64.powi(2))).abs() < 1e-9, "{c}");
        assert!((c - c.transpose()).norm() < 1e-15);
        assert!(c.cholesky().is_some());
        // The local frame restarted at its current pose: no motion follows from it.
        t.reframe(&Pose2::new(2.0, 0.0, 0.1));
        t.predict(&Pose2::new(0.0, 0.0, 0.0));
        assert!((t.estimate().0.y - 7.0).abs() < 1e-12);
    }

    /// With a gyro giving the turn, a rotation's prediction grows the heading's variance by
    /// the gyro's smaller noise (a straight step) and a tenth of the turn (a turning one);
    /// on radar odometry alone by the default's.
    #[test]
    fn a_gyros_turn_grows_the_heading_less_than_radar_odometrys() {
        let grown = |gyro: bool, turn: f64| {
            let mut t = ScanTracker::new(
                TrackSettings::for_turn_source(gyro),
                Pose2::new(0.0, 0.0, 0.0),
                Matrix3::from_diagonal(&Vector3::new(0.01, 0.01, 1e-6)),
                Pose2::new(0.0, 0.0, 0.0),
            );
            t.predict(&Pose2::new(2.5, 0.0, turn));
            t.estimate().1[(2, 2)] - 1e-6
        };
        assert!((grown(true, 0.0) - GYRO_HEADING_RAD.powi(2)).abs() < 1e-12);
        let turning = GYRO_HEADING_RAD + GYRO_HEADING_PER_RAD * 0.1;
        assert!((grown(true, 0.1) - turning.powi(2)).abs() < 1e-12);
        let alone = TrackSettings::default();
        assert!((grown(false, 0.0) - alone.heading_rad.powi(2)).abs() < 1e-12);
        assert!(grown(true, 0.1) < grown(false, 0.1));
    }
}
