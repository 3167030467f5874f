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
//! registered against the previous rotation's with robust point-to-line ICP ([`register`]),
//! started at the odometry's motion. A registration with too few pairs is not used.
//!
//! Memory: two clouds of at most `points_per_azimuth` x azimuths points (16 bytes each),
//! bounded by [`MAX_POINTS`], and over the previous cloud a k-d tree (for the normals) and
//! a pair grid of at most 2^18 cells, rebuilt once a rotation.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Matrix3, Vector3};
use radar_model::geometry::{wrap_angle, Pose2};

use super::point_grid::PointGrid;
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
    /// A reference point's normal is fitted to its neighbours within this distance (m).
    pub normal_radius_m: f64,
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
            normal_radius_m: 1.5,
        }
    }
}

/// The previous rotation's cloud as registrations use it: its points, a k-d tree over them,
/// and each point's surface normal where its neighbours lie along a line (a wall, a fence,
/// a car's side), so that points on a surface pair with the surface, not with whichever
/// sample of it the radar happened to take in the other rotation.
#[derive(Debug)]
pub struct ReferenceCloud {
    points: Vec<[f64; 2]>,
    tree: ImmutableKdTree<f64, 2>,
    /// A uniform grid over the points for the registration's gated nearest-neighbour
    /// queries (the k-d tree answers the normals' radius queries).
    grid: PointGrid,
    /// Unit normal of the local line through each point, `None` where the neighbourhood is
    /// not line-like (an isolated return, a corner, a blob).
    normals: Vec<Option<[f64; 2]>>,
}

/// Neighbours (the point itself included) a normal is fitted to at most.
const NORMAL_NEIGHBOURS: usize = 8;
/// Fewest neighbours (the point itself included) for a normal.
const NORMAL_MIN_NEIGHBOURS: usize = 4;
/// A neighbourhood is a line when its spread across is at most this fraction of its
/// spread along (the ratio of the scatter matrix's eigenvalues).
const LINE_EIGEN_RATIO: f64 = 0.05;

/// A gate reaching more cells than this either side is searched with the k-d tree.
const GRID_MAX_REACH: i64 = 4;

impl ReferenceCloud {
    /// Builds the tree, the pair grid (cells half `pair_gate_m` wide; none when that is not
    /// positive, and every pair query goes to the tree) and the normals: O(n log n), once a
    /// rotation. Neighbours for the normals are taken within `radius_m`.
    pub fn new(points: Vec<[f64; 2]>, radius_m: f64, pair_gate_m: f64) -> Self {
        let tree = ImmutableKdTree::new_from_slice(&points);
        let grid = PointGrid::new(&points, 0.5 * pair_gate_m);
        let k = std::num::NonZero::new(NORMAL_NEIGHBOURS).expect("non-zero constant");
        let normals = points
            .iter()
            .map(|p| {
                let near =
                    tree.nearest_n_within::<SquaredEuclidean>(p, radius_m * radius_m, k, false);
                if near.len() < NORMAL_MIN_NEIGHBOURS {
                    return None;
                }
                line_normal(near.iter().filter_map(|nb| points.get(nb.item as usize)))
            })
            .collect();
        Self {
            points,
            tree,
            grid,
            normals,
        }
    }

    /// The points.
    pub fn points(&self) -> &[[f64; 2]] {
        &self.points
    }

    /// How many points have a normal (lie on a line-like surface).
    pub fn with_normals(&self) -> usize {
        self.normals.iter().filter(|n| n.is_some()).count()
    }
}

/// The unit normal of the line fitted to `points` (principal axes of their scatter), or
/// `None` when they are not line-like.
fn line_normal<'a>(points: impl Iterator<Item = &'a [f64; 2]>) -> Option<[f64; 2]> {
    let (mut n, mut s, mut sxx, mut sxy, mut syy) = (0.0, [0.0; 2], 0.0, 0.0, 0.0);
    for p in points {
        n += 1.0;
        s = [s[0] + p[0], s[1] + p[1]];
        sxx += p[0] * p[0];
        sxy += p[0] * p[1];
        syy += p[1] * p[1];
    }
    if n < 2.0 {
        return None;
    }
    let m = [s[0] / n, s[1] / n];
    let (a, b, c) = (
        sxx / n - m[0] * m[0],
        sxy / n - m[0] * m[1],
        syy / n - m[1] * m[1],
    );
    // Eigenvalues of [[a, b], [b, c]].
    let half_trace = 0.5 * (a + c);
    let root = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let (large, small) = (half_trace + root, half_trace - root);
    if large.is_nan() || large <= 0.0 || small > LINE_EIGEN_RATIO * large {
        return None;
    }
    // The eigenvector of the small eigenvalue: (b, small - a) or (small - c, b).
    let v = if (small - a).abs() + b.abs() > (small - c).abs() + b.abs() {
        [b, small - a]
    } else {
        [small - c, b]
    };
    let norm = v[0].hypot(v[1]);
    (norm > 0.0 && norm.is_finite()).then(|| [v[0] / norm, v[1] / norm])
}

/// A registration's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Registration {
    /// The current cloud's frame in the reference cloud's frame.
    pub pose: Pose2,
    /// Pairs used at the last iteration.
    pub pairs: usize,
    /// Of those, pairs with a point on a line-like surface (point-to-line).
    pub line_pairs: usize,
    /// Root-mean-square residual of those pairs (m): distance to the line, or to the point.
    pub rms_m: f64,
    /// Iterations run.
    pub iterations: usize,
}

/// Trimmed, robust point-to-line ICP in the plane (points on a line-like surface of the
/// reference are pulled onto the surface, the others onto the nearest point): the pose `T`
/// of `current`'s frame in `reference`'s frame such that `T (p) ~ q` for paired points,
/// started at `initial`, by Gauss-Newton with Cauchy weights. Pairs farther apart than the
/// gate are not paired; the gate narrows from `gate_m` to a fifth of it. `None` when fewer
/// than `min_pairs` pairs survive, the clouds are empty, or the pairs do not constrain all
/// three degrees of freedom.
pub fn register(
    reference: &ReferenceCloud,
    current: &[[f64; 2]],
    initial: Pose2,
    gate_m: f64,
    min_pairs: usize,
) -> Option<Registration> {
    const ITERATIONS: usize = 40;
    if reference.points.is_empty() || current.is_empty() {
        return None;
    }
    let mut t = initial;
    let mut last = None;
    for it in 0..ITERATIONS {
        let gate = gate_m * (0.85f64.powi(it as i32)).max(0.2);
        let gate2 = gate * gate;
        // Cauchy weights with a scale of half the gate: pairs near the gate count little.
        let scale2 = 0.25 * gate2;
        // The grid while the gate spans a few of its cells; the k-d tree for a gate far
        // wider than the cells it was built for.
        let use_grid = reference
            .grid
            .reach(gate)
            .is_some_and(|r| r <= GRID_MAX_REACH);
        let (s, c) = t.theta.sin_cos();
        let mut h = Matrix3::<f64>::zeros();
        let mut g = Vector3::<f64>::zeros();
        let (mut n, mut lines, mut sum_r2) = (0usize, 0usize, 0.0);
        for p in current {
            let moved = [t.x + c * p[0] - s * p[1], t.y + s * p[0] + c * p[1]];
            let nearest = if use_grid {
                reference
                    .grid
                    .nearest_within(&reference.points, &moved, gate)
            } else {
                let nn = reference.tree.nearest_one::<SquaredEuclidean>(&moved);
                Some((nn.item as usize, nn.distance))
            };
            let Some((i, distance2)) = nearest else {
                continue;
            };
            if distance2 > gate2 {
                continue;
            }
            let (Some(q), Some(normal)) = (reference.points.get(i), reference.normals.get(i))
            else {
                continue;
            };
            // d(moved)/d(theta).
            let dm = [-s * p[0] - c * p[1], c * p[0] - s * p[1]];
            let d = [moved[0] - q[0], moved[1] - q[1]];
            n += 1;
            match normal {
                Some(nv) => {
                    lines += 1;
                    let r = nv[0] * d[0] + nv[1] * d[1];
                    let j = Vector3::new(nv[0], nv[1], nv[0] * dm[0] + nv[1] * dm[1]);
                    let w = 1.0 / (1.0 + r * r / scale2);
                    h += w * j * j.transpose();
                    g += w * r * j;
                    sum_r2 += r * r;
                }
                None => {
                    let r2 = d[0] * d[0] + d[1] * d[1];
                    let w = 1.0 / (1.0 + r2 / scale2);
                    for (axis, r) in d.iter().enumerate() {
                        let j = if axis == 0 {
                            Vector3::new(1.0, 0.0, dm[0])
                        } else {
                            Vector3::new(0.0, 1.0, dm[1])
                        };
                        h += w * j * j.transpose();
                        g += w * r * j;
                    }
                    sum_r2 += r2;
                }
            }
        }
        if n < min_pairs.max(3) {
            return None;
        }
        let delta = -h.cholesky()?.solve(&g);
        if !delta.iter().all(|v| v.is_finite()) {
            return None;
        }
        t = Pose2::new(
            t.x + delta[0],
            t.y + delta[1],
            wrap_angle(t.theta + delta[2]),
        );
        let step = delta[0].hypot(delta[1]) + delta[2].abs();
        last = Some(Registration {
            pose: t,
            pairs: n,
            line_pairs: lines,
            rms_m: (sum_r2 / n as f64).sqrt(),
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
    /// Registrations compared with the true motion over the same interval (with ground
    /// truth only).
    pub truth_compared: u64,
    /// Sum of `measured - true` motion, `[x m, y m, heading rad]` in the frame at the mark.
    pub truth_error_sum: [f64; 3],
    /// Sum of its squares.
    pub truth_error_sq_sum: [f64; 3],
}

impl ScanMatchCounts {
    /// Mean and standard deviation of the registrations' error against the true motion,
    /// per component `[x m, y m, heading rad]`; `None` with fewer than two comparisons.
    pub fn truth_error(&self) -> Option<[(f64, f64); 3]> {
        if self.truth_compared < 2 {
            return None;
        }
        let n = self.truth_compared as f64;
        Some(std::array::from_fn(|i| {
            let mean = self.truth_error_sum[i] / n;
            let var = (self.truth_error_sq_sum[i] - n * mean * mean) / (n - 1.0);
            (mean, var.max(0.0).sqrt())
        }))
    }
}

/// The clouds of the current and previous rotation.
#[derive(Debug, Default)]
pub struct ScanMatcher {
    settings: ScanMatchSettings,
    /// This rotation's points in the frame at the last mark.
    current: Vec<[f64; 2]>,
    /// The previous rotation's points in the vehicle's frame at its end.
    previous: Option<ReferenceCloud>,
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
        if let Some(reference) = self.previous.as_ref() {
            self.counts.tried += 1;
            match register(
                reference,
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
            Some(ReferenceCloud::new(
                local,
                self.settings.normal_radius_m,
                self.settings.pair_gate_m,
            ))
        };
        out
    }

    /// Records a registration's error against the true motion `[x, y, heading]` (scores
    /// only; changes nothing).
    pub fn record_truth_error(&mut self, error: [f64; 3]) {
        if error.iter().any(|e| !e.is_finite()) {
            return;
        }
        let c = &mut self.counts;
        c.truth_compared += 1;
        for (i, e) in error.iter().enumerate() {
            c.truth_error_sum[i] += e;
            c.truth_error_sq_sum[i] += e * e;
        }
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
        let reference = ReferenceCloud::new(in_frame_of(&a, &world), 1.5, 0.6);
        assert!(
            reference.with_normals() > world.len() / 2,
            "walls have normals"
        );
        let current = in_frame_of(&b, &world);
        let reg = register(
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
        assert!(reg.line_pairs > 0 && reg.line_pairs < reg.pairs, "{reg:?}");
    }

    /// Two walls sampled at fixed bearings from each pose (as a radar samples them): the
    /// samples move with the sensor, so pairing points with points pulls the motion along
    /// the walls towards zero; pairing them with the walls' lines does not. A few posts fix
    /// the along-track motion.
    #[test]
    fn walls_sampled_at_fixed_bearings_do_not_shrink_the_motion() {
        let scan = |pose: &Pose2| -> Vec<[f64; 2]> {
            let mut pts = Vec::new();
            for k in 0..400 {
                let bearing = std::f64::consts::TAU * f64::from(k) / 400.0;
                let (s, c) = (pose.theta + bearing).sin_cos();
                // Walls y = 8 and y = -7.5 (world), where the beam meets them within 60 m.
                for wall_y in [8.0, -7.5] {
                    if s.abs() > 1e-9 {
                        let r = (wall_y - pose.y) / s;
                        if r > 4.0 && r < 60.0 {
                            let world = [pose.x + r * c, pose.y + r * s];
                            pts.push(world);
                        }
                    }
                }
            }
            for k in 0..8 {
                pts.push([-20.0 + 6.0 * f64::from(k), 5.0 - 0.7 * f64::from(k % 3)]);
            }
            in_frame_of(pose, &pts)
        };
        let a = Pose2::new(0.0, 0.0, 0.0);
        let b = Pose2::new(2.0, 0.0, 0.0);
        let reference = ReferenceCloud::new(scan(&a), 1.5, 0.6);
        let reg =
            register(&reference, &scan(&b), Pose2::new(2.1, 0.0, 0.0), 0.6, 50).expect("registers");
        assert!((reg.pose.x - b.x).abs() < 0.01, "{reg:?}");
        assert!(
            reg.pose.y.abs() < 0.01 && reg.pose.theta.abs() < 1e-3,
            "{reg:?}"
        );
    }

    #[test]
    fn a_straight_line_has_a_normal_and_a_blob_has_none() {
        let line: Vec<[f64; 2]> = (0..8).map(|i| [f64::from(i) * 0.2, 1.0]).collect();
        let n = line_normal(line.iter()).expect("a line");
        assert!(
            n[0].abs() < 1e-9 && (n[1].abs() - 1.0).abs() < 1e-9,
            "{n:?}"
        );
        let tilted: Vec<[f64; 2]> = (0..8).map(|i| [f64::from(i), f64::from(i)]).collect();
        let n = line_normal(tilted.iter()).expect("a line");
        assert!((n[0] + n[1]).abs() < 1e-9, "{n:?}");
        let blob = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
        assert!(line_normal(blob.iter()).is_none());
    }

    #[test]
    fn the_pair_grid_finds_the_k_d_trees_nearest_point_within_the_gate() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut uniform = move || rng.gen::<f64>();
        let mut points = street();
        points.extend((0..500).map(|_| [-70.0 + 140.0 * uniform(), -20.0 + 40.0 * uniform()]));
        let gate = 0.6;
        let cloud = ReferenceCloud::new(points.clone(), 1.5, gate);
        assert!(cloud.grid.reach(gate).is_some_and(|r| r <= GRID_MAX_REACH));
        let (mut within, mut beyond) = (0, 0);
        for _ in 0..20_000 {
            let q = [-90.0 + 180.0 * uniform(), -30.0 + 60.0 * uniform()];
            let nn = cloud.tree.nearest_one::<SquaredEuclidean>(&q);
            let grid = cloud.grid.nearest_within(&points, &q, gate);
            if nn.distance <= gate * gate {
                within += 1;
                let (i, d2) = grid.expect("a point within the gate is in a neighbouring cell");
                assert_eq!(d2, nn.distance, "query {q:?}");
                assert_eq!(points[i], points[nn.item as usize]);
            } else {
                beyond += 1;
                assert!(grid.is_none(), "query {q:?}");
            }
        }
        assert!(
            within > 1000 && beyond > 1000,
            "{within} within, {beyond} beyond"
        );
    }

    #[test]
    fn the_truth_comparison_gives_mean_and_sample_std_and_skips_non_finite() {
        let mut m = ScanMatcher::new(ScanMatchSettings::default());
        assert_eq!(m.counts().truth_error(), None);
        m.record_truth_error([0.1, -0.02, 0.001]);
        m.record_truth_error([f64::NAN, 0.0, 0.0]);
        assert_eq!(
            m.counts().truth_error(),
            None,
            "one comparison gives no spread"
        );
        m.record_truth_error([0.3, -0.04, 0.003]);
        let [x, y, h] = m.counts().truth_error().expect("two comparisons");
        assert_eq!(m.counts().truth_compared, 2);
        assert!((x.0 - 0.2).abs() < 1e-12 && (x.1 - 0.1 * 2f64.sqrt()).abs() < 1e-12);
        assert!((y.0 + 0.03).abs() < 1e-12 && (y.1 - 0.01 * 2f64.sqrt()).abs() < 1e-12);
        assert!((h.0 - 0.002).abs() < 1e-12 && (h.1 - 0.001 * 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn too_few_pairs_is_no_registration() {
        let points = vec![[0.0, 0.0], [1.0, 0.0]];
        let reference = ReferenceCloud::new(points.clone(), 1.5, 1.0);
        assert!(register(&reference, &points, Pose2::new(0.0, 0.0, 0.0), 1.0, 3).is_none());
        assert!(register(&reference, &[], Pose2::new(0.0, 0.0, 0.0), 1.0, 1).is_none());
    }
}
