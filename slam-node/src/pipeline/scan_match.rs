//! Radar odometry: each rotation's detections, walls and fences included, registered against
//! the previous rotation's, measure the vehicle's motion between the two; the filter uses the
//! measurement to estimate the odometry's speed scale and steering offset
//! ([`slam_filter::Ekf::observe_motion_since_mark`]). Extended returns never enter the map
//! as features; this is where they help.
//!
//! Per azimuth the strongest detections (by SNR, at most
//! [`ScanMatchSettings::points_per_azimuth`], between the minimum and maximum range) are
//! placed in the frame of the vehicle at the last mark with the motion the odometry gives
//! since (the filter's tally: updates during the rotation do not distort the cloud). At the
//! end of a rotation the cloud is moved into the vehicle's frame at the state's time and
//! registered against the previous rotation's with trimmed point-to-point ICP, started at
//! the odometry's motion. A registration with too few pairs is not used.
//!
//! Memory: two clouds of at most `points_per_azimuth` x azimuths points (16 bytes each),
//! bounded by [`MAX_POINTS`], and a k-d tree of the previous cloud, rebuilt once a
//! rotation.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Matrix3;
use radar_model::geometry::{wrap_angle, Pose2};

use crate::detect::Detection;

/// Points a rotation's cloud holds at most, whatever the radar's geometry.
pub const MAX_POINTS: usize = 1 << 15;

/// Radar odometry's settings (`[odometry] radar_odometry*`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanMatchSettings {
    /// Whether rotations are registered and the result given to the filter.
    pub enabled: bool,
    /// Strongest detections kept per azimuth.
    pub points_per_azimuth: usize,
    /// Detections nearer than this are not used (m): the vehicle's own body and the
    /// antenna's leakage.
    pub min_range_m: f64,
    /// Detections farther than this are not used (m): the beam's width makes them coarse.
    pub max_range_m: f64,
    /// Standard deviation of a registration's translation, each axis (m).
    pub sigma_xy_m: f64,
    /// Standard deviation of a registration's rotation (rad).
    pub sigma_theta_rad: f64,
    /// Pairs farther apart than this are not paired at the first iteration (m); the gate
    /// narrows to a fifth of it.
    pub pair_gate_m: f64,
    /// A registration with fewer pairs is not used.
    pub min_pairs: usize,
}

impl Default for ScanMatchSettings {
    fn default() -> Self {
        Self {
            enabled: false,
            points_per_azimuth: 6,
            min_range_m: 4.0,
            max_range_m: 80.0,
            sigma_xy_m: 0.05,
            sigma_theta_rad: 0.003,
            pair_gate_m: 0.6,
            min_pairs: 100,
        }
    }
}

/// A registration's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Registration {
    /// The current cloud's frame in the reference cloud's frame.
    pub pose: Pose2,
    /// Pairs used at the last iteration.
    pub pairs: usize,
    /// Root-mean-square distance of those pairs (m).
    pub rms_m: f64,
    /// Iterations run.
    pub iterations: usize,
}

/// Trimmed point-to-point ICP in the plane: the pose `T` of `current`'s frame in
/// `reference`'s frame such that `T (p) ~ q` for paired points, started at `initial`.
/// `None` when fewer than `min_pairs` pairs survive or the clouds are empty.
pub fn register(
    reference: &ImmutableKdTree<f64, 2>,
    reference_points: &[[f64; 2]],
    current: &[[f64; 2]],
    initial: Pose2,
    gate_m: f64,
    min_pairs: usize,
) -> Option<Registration> {
    const ITERATIONS: usize = 40;
    if reference_points.is_empty() || current.is_empty() {
        return None;
    }
    let mut t = initial;
    let mut last = None;
    for it in 0..ITERATIONS {
        // The gate narrows from `gate_m` to a fifth of it over the first iterations.
        let gate = gate_m * (0.85f64.powi(it as i32)).max(0.2);
        let gate2 = gate * gate;
        let (s, c) = t.theta.sin_cos();
        // Sums over the pairs: n, p, q, and the raw cross-products for the centred ones.
        let (mut n, mut sp, mut sq) = (0usize, [0.0; 2], [0.0; 2]);
        let (mut sdot, mut scross, mut sum_d2) = (0.0, 0.0, 0.0);
        for p in current {
            let moved = [t.x + c * p[0] - s * p[1], t.y + s * p[0] + c * p[1]];
            let nn = reference.nearest_one::<SquaredEuclidean>(&moved);
            if nn.distance > gate2 {
                continue;
            }
            let Some(q) = reference_points.get(nn.item as usize) else {
                continue;
            };
            n += 1;
            sum_d2 += nn.distance;
            sp = [sp[0] + p[0], sp[1] + p[1]];
            sq = [sq[0] + q[0], sq[1] + q[1]];
            sdot += p[0] * q[0] + p[1] * q[1];
            scross += p[0] * q[1] - p[1] * q[0];
        }
        if n < min_pairs.max(3) {
            return None;
        }
        let nf = n as f64;
        let (mp, mq) = ([sp[0] / nf, sp[1] / nf], [sq[0] / nf, sq[1] / nf]);
        // Closed-form rotation: atan2 of the cross- and dot-sums of the centred pairs.
        let dot = sdot - nf * (mp[0] * mq[0] + mp[1] * mq[1]);
        let cross = scross - nf * (mp[0] * mq[1] - mp[1] * mq[0]);
        let theta = cross.atan2(dot);
        let (s, c) = theta.sin_cos();
        let next = Pose2::new(
            mq[0] - (c * mp[0] - s * mp[1]),
            mq[1] - (s * mp[0] + c * mp[1]),
            wrap_angle(theta),
        );
        let step = (next.x - t.x).hypot(next.y - t.y) + wrap_angle(next.theta - t.theta).abs();
        t = next;
        last = Some(Registration {
            pose: t,
            pairs: n,
            rms_m: (sum_d2 / nf).sqrt(),
            iterations: it + 1,
        });
        if step < 1e-6 && gate <= 0.2 * gate_m + 1e-12 {
            break;
        }
    }
    last
}

/// `points` (in some frame) expressed in the frame of `pose` (a pose in that frame).
pub fn in_frame_of(pose: &Pose2, points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let (s, c) = pose.theta.sin_cos();
    points
        .iter()
        .map(|p| {
            let (dx, dy) = (p[0] - pose.x, p[1] - pose.y);
            [c * dx + s * dy, -s * dx + c * dy]
        })
        .collect()
}

/// What radar odometry did over a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct ScanMatchCounts {
    /// Registrations tried (a rotation with a previous one to register against).
    pub tried: u64,
    /// Registrations with too few pairs.
    pub failed: u64,
    /// Measurements the filter applied.
    pub applied: u64,
    /// Measurements the filter's gate refused.
    pub gated: u64,
    /// Sum of the applied measurements' NIS (3 dof each).
    pub nis_sum: f64,
}

/// The clouds of the current and previous rotation.
#[derive(Debug, Default)]
pub struct ScanMatcher {
    settings: ScanMatchSettings,
    /// This rotation's points in the frame at the last mark.
    current: Vec<[f64; 2]>,
    /// The previous rotation's points in the vehicle's frame at its end, and its tree.
    previous: Option<(Vec<[f64; 2]>, ImmutableKdTree<f64, 2>)>,
    /// Scratch for one azimuth's strongest detections.
    order: Vec<usize>,
    counts: ScanMatchCounts,
}

impl ScanMatcher {
    /// A matcher with `settings`.
    pub fn new(settings: ScanMatchSettings) -> Self {
        Self {
            settings,
            ..Self::default()
        }
    }

    /// Whether it runs.
    pub fn enabled(&self) -> bool {
        self.settings.enabled
    }

    /// What it did so far.
    pub fn counts(&self) -> ScanMatchCounts {
        self.counts
    }

    /// Adds one azimuth's detections at `bearing_rad`, the sensor at `sensor` (the frame at
    /// the last mark; `None` when there is none: nothing is added).
    pub fn add_azimuth(
        &mut self,
        sensor: Option<Pose2>,
        bearing_rad: f64,
        detections: &[Detection],
    ) {
        let Some(sensor) = sensor else {
            return;
        };
        let s = &self.settings;
        self.order.clear();
        self.order.extend(
            detections
                .iter()
                .enumerate()
                .filter(|(_, d)| {
                    d.range_m >= s.min_range_m && d.range_m <= s.max_range_m && d.snr_db.is_finite()
                })
                .map(|(i, _)| i),
        );
        let keep = s.points_per_azimuth.min(self.order.len());
        if keep < self.order.len() {
            self.order.select_nth_unstable_by(keep, |&a, &b| {
                detections[b].snr_db.total_cmp(&detections[a].snr_db)
            });
        }
        let room = MAX_POINTS.saturating_sub(self.current.len());
        for &i in self.order.iter().take(keep.min(room)) {
            self.current
                .push(sensor.point_at(detections[i].range_m, bearing_rad));
        }
    }

    /// Closes a rotation: `end` is the vehicle's pose at the state's time in the frame at
    /// the last mark (the tally), `None` without a mark. Registers the cloud against the
    /// previous rotation's and returns the measured motion with its covariance when the
    /// registration holds; the caller gives it to the filter and marks the filter anew.
    pub fn end_rotation(
        &mut self,
        end: Option<Pose2>,
    ) -> Option<(Pose2, Matrix3<f64>, Registration)> {
        let points = std::mem::take(&mut self.current);
        let Some(end) = end else {
            self.previous = None;
            return None;
        };
        let local = in_frame_of(&end, &points);
        let mut out = None;
        if let Some((reference_points, tree)) = self.previous.as_ref() {
            self.counts.tried += 1;
            match register(
                tree,
                reference_points,
                &local,
                end,
                self.settings.pair_gate_m,
                self.settings.min_pairs,
            ) {
                Some(reg) => {
                    let sxy = self.settings.sigma_xy_m.powi(2);
                    let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(
                        sxy,
                        sxy,
                        self.settings.sigma_theta_rad.powi(2),
                    ));
                    out = Some((reg.pose, cov, reg));
                }
                None => self.counts.failed += 1,
            }
        }
        self.previous = if local.is_empty() {
            None
        } else {
            let tree = ImmutableKdTree::new_from_slice(&local);
            Some((local, tree))
        };
        out
    }

    /// Records what the filter did with a measurement.
    pub fn record(&mut self, outcome: slam_filter::MotionOutcome) {
        match outcome {
            slam_filter::MotionOutcome::Applied { nis } => {
                self.counts.applied += 1;
                self.counts.nis_sum += nis;
            }
            slam_filter::MotionOutcome::Gated { .. } => self.counts.gated += 1,
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A street: two walls and a few posts, seen from the origin.
    fn street() -> Vec<[f64; 2]> {
        let mut pts = Vec::new();
        for i in 0..200 {
            let x = -40.0 + 0.4 * f64::from(i);
            pts.push([x, 8.0 + 0.3 * (0.2 * x).sin()]);
            pts.push([x, -7.5]);
        }
        for k in 0..10 {
            pts.push([-30.0 + 7.0 * f64::from(k), 5.0 + 0.5 * f64::from(k % 3)]);
        }
        pts
    }

    #[test]
    fn icp_recovers_a_motion_started_five_per_cent_off() {
        let world = street();
        let a = Pose2::new(0.0, 0.0, 0.0);
        let b = Pose2::new(2.2, 0.05, 0.012);
        let reference = in_frame_of(&a, &world);
        let current = in_frame_of(&b, &world);
        let tree = ImmutableKdTree::new_from_slice(&reference);
        let reg = register(
            &tree,
            &reference,
            &current,
            Pose2::new(2.2 * 1.05, 0.0, 0.0),
            1.5,
            50,
        )
        .expect("registers");
        assert!((reg.pose.x - b.x).abs() < 1e-3, "{reg:?}");
        assert!((reg.pose.y - b.y).abs() < 1e-3, "{reg:?}");
        assert!((reg.pose.theta - b.theta).abs() < 1e-4, "{reg:?}");
    }

    #[test]
    fn too_few_pairs_is_no_registration() {
        let reference = vec![[0.0, 0.0], [1.0, 0.0]];
        let tree = ImmutableKdTree::new_from_slice(&reference);
        assert!(register(
            &tree,
            &reference,
            &reference,
            Pose2::new(0.0, 0.0, 0.0),
            1.0,
            3
        )
        .is_none());
        assert!(register(&tree, &reference, &[], Pose2::new(0.0, 0.0, 0.0), 1.0, 1).is_none());
    }
}
