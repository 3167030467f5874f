//! Does the data set's ground truth agree with what the radar itself sees, scan to scan?
//!
//! An independent check of the recorded relative poses (`radar_odometry.csv`), with none of
//! the daemon's code: no detector, no landmark test, no point-to-line registration, no
//! filter. Each scan becomes a cloud of every bin well above its azimuth's median (weighted
//! by how far above), each point moved to the scan's pose time with a constant velocity
//! taken from the ground truth itself (so the check gives the ground truth every benefit),
//! its range corrected for the range-Doppler coupling. The earlier scan is drawn into a
//! blurred Cartesian image; the later scan's cloud is moved over it by a pose that
//! maximises the summed image under its points (dense correlation, power-weighted), found
//! by a pattern search from several starts. The pose found is the radar's own measure of
//! the motion between the two scans' pose times; it is set against the ground truth's.
//!
//! The same registration on halves of the scene (left of the car, right, near, far) tells
//! a disagreement that the whole scene shares (the ground truth's, or the sensor's) from
//! one that a moving car or one wall makes.

use radar_model::geometry::{wrap_angle, Pose2};
use sim_sensor::replay::truth::RelativePose;

use crate::scan::Scan;

/// How each scan becomes a cloud and an image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DenseSettings {
    /// A bin enters the cloud when it is this far above its azimuth's median (dB).
    pub threshold_db: f64,
    /// Bins nearer than this are left out (the radar's own near-range ringing) (m).
    pub min_range_m: f64,
    /// Bins further than this are left out (m).
    pub max_range_m: f64,
    /// Range of a bin: `(index + 0.5) x bin_m` (m).
    pub bin_m: f64,
    /// Range-Doppler coupling: a return closing at `v` m/s reads `v x this` short (s).
    pub doppler_coupling_s: f64,
    /// Move each azimuth's points to the scan's pose time (constant velocity).
    pub deskew: bool,
    /// Pixel of the Cartesian image (m).
    pub pixel_m: f64,
    /// Standard deviation of the image's Gaussian blur (m).
    pub blur_m: f64,
}

impl Default for DenseSettings {
    fn default() -> Self {
        Self {
            threshold_db: 15.0,
            min_range_m: 4.0,
            max_range_m: 60.0,
            bin_m: radar_model::profile::CTS350X.bin_size_m.value,
            doppler_coupling_s: radar_model::profile::CTS350X.doppler_range_coupling_s.value,
            deskew: true,
            pixel_m: 0.05,
            blur_m: 0.15,
        }
    }
}

impl DenseSettings {
    /// These settings with a simulated radar's range axis and range-Doppler coupling.
    pub fn for_radar(self, radar: &sim_sensor::radar::RadarParams) -> DenseSettings {
        DenseSettings {
            bin_m: f64::from(radar.range_gain) * radar.bin_size_m(),
            doppler_coupling_s: radar.doppler_range_coupling_s,
            ..self
        }
    }
}

/// Constant planar velocity in the vehicle's frame: forward, left (m/s), turn (rad/s, CCW).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Twist {
    /// Forward (m/s).
    pub vx: f64,
    /// Left (m/s).
    pub vy: f64,
    /// Counter-clockwise (rad/s).
    pub w: f64,
}

impl Twist {
    /// The constant velocity that moves by `pose` in `dt_s` seconds (the SE(2) logarithm).
    pub fn from_motion(pose: &Pose2, dt_s: f64) -> Twist {
        if dt_s <= 0.0 {
            return Twist::default();
        }
        let th = pose.theta;
        let (vx, vy) = if th.abs() < 1e-9 {
            (pose.x, pose.y)
        } else {
            // Solve V [vx vy]' = t with V = [[s, -(1-c)], [1-c, s]] / th.
            let (s, c) = th.sin_cos();
            let (a, b) = (s / th, (1.0 - c) / th);
            let det = a * a + b * b;
            (
                (a * pose.x + b * pose.y) / det,
                (-b * pose.x + a * pose.y) / det,
            )
        };
        Twist {
            vx: vx / dt_s,
            vy: vy / dt_s,
            w: th / dt_s,
        }
    }

    /// The motion after `dt_s` seconds (the SE(2) exponential).
    pub fn motion(&self, dt_s: f64) -> Pose2 {
        let th = self.w * dt_s;
        let (tx, ty) = (self.vx * dt_s, self.vy * dt_s);
        if th.abs() < 1e-9 {
            return Pose2::new(tx, ty, th);
        }
        let (s, c) = th.sin_cos();
        let (a, b) = (s / th, (1.0 - c) / th);
        Pose2::new(a * tx - b * ty, b * tx + a * ty, th)
    }
}

/// `pose` applied to a point of its own frame.
fn apply(pose: &Pose2, p: [f64; 2]) -> [f64; 2] {
    let (s, c) = pose.theta.sin_cos();
    [pose.x + c * p[0] - s * p[1], pose.y + s * p[0] + c * p[1]]
}

/// A scan's strong bins as points in its frame at its pose time, with their weights.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cloud {
    /// Points (m, x forward, y left).
    pub points: Vec<[f64; 2]>,
    /// Weights (dB above the threshold, plus one).
    pub weights: Vec<f64>,
}

impl Cloud {
    /// The points `keep` accepts, with their weights.
    pub fn filtered(&self, keep: impl Fn([f64; 2]) -> bool) -> Cloud {
        let mut out = Cloud::default();
        for (p, w) in self.points.iter().zip(&self.weights) {
            if keep(*p) {
                out.points.push(*p);
                out.weights.push(*w);
            }
        }
        out
    }
}

/// The cloud of `scan`, at time `pose_time_s`, the vehicle moving at `twist`.
pub fn cloud(scan: &Scan, pose_time_s: f64, twist: Twist, settings: &DenseSettings) -> Cloud {
    let mut out = Cloud::default();
    let mut sorted = Vec::new();
    for row in &scan.rows {
        if row.measured_db.is_empty() {
            continue;
        }
        sorted.clear();
        sorted.extend(row.measured_db.iter().copied().filter(|v| v.is_finite()));
        if sorted.is_empty() {
            continue;
        }
        let mid = sorted.len() / 2;
        let (_, median, _) = sorted.select_nth_unstable_by(mid, f64::total_cmp);
        let floor = *median + settings.threshold_db;
        // Bearing clockwise from forward: the beam's unit vector is (cos b, -sin b).
        let (sb, cb) = row.bearing_rad.sin_cos();
        let closing = twist.vx * cb - twist.vy * sb;
        let correction = settings.doppler_coupling_s * closing;
        let shift = if settings.deskew {
            twist.motion(row.timestamp_s - pose_time_s)
        } else {
            Pose2::default()
        };
        for (i, &db) in row.measured_db.iter().enumerate() {
            if db.is_nan() || db <= floor {
                continue;
            }
            let r = (i as f64 + 0.5) * settings.bin_m;
            if r < settings.min_range_m || r > settings.max_range_m {
                continue;
            }
            let r = r + correction;
            out.points.push(apply(&shift, [r * cb, -r * sb]));
            out.weights.push(db - floor + 1.0);
        }
    }
    out
}

/// A blurred Cartesian image of a cloud, centred on the scan's origin.
#[derive(Debug, Clone)]
pub struct Image {
    side: usize,
    half_m: f64,
    pixel_m: f64,
    data: Vec<f32>,
}

impl Image {
    /// Draws `cloud` (its weights summed per pixel) and blurs it.
    pub fn new(cloud: &Cloud, settings: &DenseSettings) -> Image {
        let half_m = settings.max_range_m + 5.0;
        let side = (2.0 * half_m / settings.pixel_m).ceil() as usize;
        let mut data = vec![0.0f32; side * side];
        for (p, &w) in cloud.points.iter().zip(&cloud.weights) {
            let i = ((p[0] + half_m) / settings.pixel_m).floor();
            let j = ((p[1] + half_m) / settings.pixel_m).floor();
            if i >= 0.0 && j >= 0.0 && (i as usize) < side && (j as usize) < side {
                data[i as usize * side + j as usize] += w as f32;
            }
        }
        let image = Image {
            side,
            half_m,
            pixel_m: settings.pixel_m,
            data,
        };
        image.blurred(settings.blur_m / settings.pixel_m)
    }

    /// Separable Gaussian blur of `sigma_px` pixels (kernel out to four sigma).
    fn blurred(mut self, sigma_px: f64) -> Image {
        if sigma_px <= 0.0 {
            return self;
        }
        let reach = (4.0 * sigma_px).ceil() as usize;
        let kernel: Vec<f32> = (0..=2 * reach)
            .map(|k| {
                let d = k as f64 - reach as f64;
                (-0.5 * d * d / (sigma_px * sigma_px)).exp() as f32
            })
            .collect();
        let n = self.side;
        let mut tmp = vec![0.0f32; n * n];
        // Along rows (j), then along columns (i).
        for i in 0..n {
            let row = &self.data[i * n..(i + 1) * n];
            let out = &mut tmp[i * n..(i + 1) * n];
            for (j, &v) in row.iter().enumerate() {
                if v == 0.0 {
                    continue;
                }
                let lo = j.saturating_sub(reach);
                let hi = (j + reach).min(n - 1);
                for (t, o) in out[lo..=hi].iter_mut().enumerate() {
                    *o += v * kernel[lo + t + reach - j];
                }
            }
        }
        self.data.iter_mut().for_each(|v| *v = 0.0);
        for i in 0..n {
            let lo = i.saturating_sub(reach);
            let hi = (i + reach).min(n - 1);
            for t in lo..=hi {
                let k = kernel[t + reach - i];
                let (src, dst) = (t * n, i * n);
                for j in 0..n {
                    self.data[dst + j] += k * tmp[src + j];
                }
            }
        }
        self
    }

    /// Bilinear value at `p` (m); zero outside.
    fn sample(&self, p: [f64; 2]) -> f64 {
        let u = (p[0] + self.half_m) / self.pixel_m - 0.5;
        let v = (p[1] + self.half_m) / self.pixel_m - 0.5;
        if !(u >= 0.0 && v >= 0.0) {
            return 0.0;
        }
        let (i, j) = (u.floor() as usize, v.floor() as usize);
        if i + 1 >= self.side || j + 1 >= self.side {
            return 0.0;
        }
        let (fu, fv) = (u - i as f64, v - j as f64);
        let at = |a: usize, b: usize| f64::from(self.data[a * self.side + b]);
        (1.0 - fu) * ((1.0 - fv) * at(i, j) + fv * at(i, j + 1))
            + fu * ((1.0 - fv) * at(i + 1, j) + fv * at(i + 1, j + 1))
    }

    /// The summed image under `cloud` moved by `pose`, weighted.
    pub fn score(&self, cloud: &Cloud, pose: &Pose2) -> f64 {
        cloud
            .points
            .iter()
            .zip(&cloud.weights)
            .map(|(p, w)| w * self.sample(apply(pose, *p)))
            .sum()
    }
}

/// The pose of `later` over `image` with the greatest score, by a pattern search from each
/// of `starts` (steps 20 mm and 2 mrad, halved down to 0.5 mm and 0.05 mrad).
pub fn register(image: &Image, later: &Cloud, starts: &[Pose2]) -> Option<(Pose2, f64)> {
    const FIRST: [f64; 3] = [0.02, 0.02, 0.002];
    const LAST: [f64; 3] = [0.0005, 0.0005, 0.00005];
    const MAX_EVALUATIONS: usize = 20_000;
    let mut best: Option<(Pose2, f64)> = None;
    for start in starts {
        let mut at = [start.x, start.y, start.theta];
        let pose = |q: &[f64; 3]| Pose2::new(q[0], q[1], q[2]);
        let mut score = image.score(later, &pose(&at));
        let mut step = FIRST;
        let mut evaluations = 1;
        while evaluations < MAX_EVALUATIONS {
            let mut moved = false;
            'axes: for axis in 0..3 {
                for sign in [1.0, -1.0] {
                    let mut q = at;
                    q[axis] += sign * step[axis];
                    let s = image.score(later, &pose(&q));
                    evaluations += 1;
                    if s > score {
                        (at, score, moved) = (q, s, true);
                        break 'axes;
                    }
                }
            }
            if !moved {
                if step.iter().zip(&LAST).all(|(s, l)| s <= l) {
                    break;
                }
                step.iter_mut().for_each(|s| *s *= 0.5);
            }
        }
        if best.as_ref().is_none_or(|b| score > b.1) {
            best = Some((Pose2::new(at[0], at[1], wrap_angle(at[2])), score));
        }
    }
    best
}

/// A part of the scene: its name and which points of a scan's own frame it holds.
pub type Subset = (&'static str, fn([f64; 2]) -> bool);

/// The parts of the scene registered on their own.
pub const SUBSETS: [Subset; 4] = [
    ("left of the car (y > 2 m)", |p| p[1] > 2.0),
    ("right of the car (y < -2 m)", |p| p[1] < -2.0),
    ("near (< 25 m)", |p| p[0].hypot(p[1]) < 25.0),
    ("far (>= 25 m)", |p| p[0].hypot(p[1]) >= 25.0),
];

/// One consecutive pair of scans.
#[derive(Debug, Clone, PartialEq)]
pub struct PairAgreement {
    /// The ground truth's row.
    pub truth: RelativePose,
    /// Seconds between the two pose times.
    pub dt_s: f64,
    /// The dense registration of the whole scene (the later scan's pose in the earlier's).
    pub dense: Pose2,
    /// The same on each of [`SUBSETS`], in order (`None` where too few points).
    pub subsets: Vec<Option<Pose2>>,
    /// Points in the later scan's cloud.
    pub points: usize,
}

/// Registers every consecutive pair of `scans` (file timestamps in µs with their rows) for
/// which `truth` has a row, in order.
pub fn agreement(
    scans: &[(i64, &Scan)],
    truth: &[RelativePose],
    settings: &DenseSettings,
) -> Vec<PairAgreement> {
    let row_between = |a: i64, b: i64| {
        truth
            .iter()
            .find(|r| r.destination_us == a && r.source_us == b)
    };
    let mut out = Vec::new();
    // The later scan's cloud of one pair is the earlier scan's of the next: the same scan at
    // the same pose time, moving as it did into it (the first scan moves as it does out).
    let mut previous: Option<(i64, i64, Cloud)> = None;
    for pair in scans.windows(2) {
        let (a_us, a) = pair[0];
        let (b_us, b) = pair[1];
        let Some(row) = row_between(a_us, b_us) else {
            previous = None;
            continue;
        };
        let dt_s = (row.source_pose_us - row.destination_pose_us) as f64 * 1e-6;
        let twist = Twist::from_motion(&row.pose, dt_s);
        let cloud_a = match previous.take() {
            Some((scan_us, pose_us, c))
                if scan_us == a_us && pose_us == row.destination_pose_us =>
            {
                c
            }
            _ => cloud(a, row.destination_pose_us as f64 * 1e-6, twist, settings),
        };
        let cloud_b = cloud(b, row.source_pose_us as f64 * 1e-6, twist, settings);
        let g = row.pose;
        let starts = [
            g,
            Pose2::new(g.x * 1.05, 0.0, g.theta),
            Pose2::new(g.x * 0.95, 0.05, 0.0),
        ];
        let Some((dense, _)) = register(&Image::new(&cloud_a, settings), &cloud_b, &starts) else {
            continue;
        };
        let subsets = SUBSETS
            .iter()
            .map(|(_, keep)| {
                let (sa, sb) = (cloud_a.filtered(keep), cloud_b.filtered(keep));
                if sa.points.len() < 100 || sb.points.len() < 100 {
                    return None;
                }
                register(&Image::new(&sa, settings), &sb, &[g]).map(|r| r.0)
            })
            .collect();
        out.push(PairAgreement {
            truth: *row,
            dt_s,
            dense,
            subsets,
            points: cloud_b.points.len(),
        });
        previous = Some((b_us, row.source_pose_us, cloud_b));
    }
    out
}

/// Scans with their start times (µs).
pub type TimedScans = Vec<(i64, Scan)>;

/// The same check where the truth is exact: `rotations` rotations of the simulator's
/// `scene` rendered as the daemon would receive them (motion during each rotation and the
/// scene radar's range-Doppler coupling included), with each rotation's true pose at its
/// middle as the ground truth. Returns the scans (each with its start time in µs) and the
/// relative poses, in the recorded data's form.
pub fn simulated(
    scene: &sim_sensor::scene::Scene,
    rotations: u64,
) -> Result<(TimedScans, Vec<RelativePose>), crate::error::EvalError> {
    use std::sync::Arc;
    let radar = &scene.radar;
    let n = u64::from(radar.azimuths);
    let horizon_s = (rotations + 2) as f64 / radar.rotation_hz() + 1.0;
    let renderer = Arc::new(sim_sensor::render::SceneRenderer::new(
        scene, None, horizon_s,
    )?);
    let mut cursor = renderer.cursor();
    let mut frame = bytes::BytesMut::new();
    let mut scans = Vec::new();
    let mut poses = Vec::new();
    for rot in 0..rotations {
        let mut rows = Vec::with_capacity(n as usize);
        for k in 0..n {
            let index = rot * n + k;
            frame.clear();
            cursor.render(index, 0, protocol::Timestamp::EPOCH, &mut frame)?;
            rows.push(crate::scan::Row {
                timestamp_s: sim_sensor::render::offset_ns(radar, index) as f64 * 1e-9,
                bearing_rad: wrap_angle(k as f64 * std::f64::consts::TAU / n as f64),
                measured_db: cursor.last_power_db().to_vec(),
            });
        }
        let start_us = (sim_sensor::render::offset_ns(radar, rot * n) / 1000) as i64;
        let middle_ns = sim_sensor::render::offset_ns(radar, rot * n + n / 2);
        let pose = renderer.trajectory().pose_at(middle_ns)?;
        scans.push((start_us, Scan { rows }));
        poses.push(((middle_ns / 1000) as i64, pose));
    }
    let truth = scans
        .windows(2)
        .zip(poses.windows(2))
        .map(|(s, p)| RelativePose {
            source_us: s[1].0,
            destination_us: s[0].0,
            source_pose_us: p[1].0,
            destination_pose_us: p[0].0,
            line: 0,
            pose: sim_sensor::replay::truth::between(&p[0].1, &p[1].1),
        })
        .collect();
    Ok((scans, truth))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scan::Row;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A scan of point scatterers (world positions) from `pose`, all azimuths at one time.
    fn render(scatterers: &[[f64; 2]], pose: &Pose2, settings: &DenseSettings) -> Scan {
        let bins = (settings.max_range_m / settings.bin_m) as usize + 20;
        let rows = (0..400)
            .map(|a| {
                let bearing = wrap_angle(a as f64 * std::f64::consts::TAU / 400.0);
                let mut db = vec![20.0; bins];
                for s in scatterers {
                    let (dx, dy) = (s[0] - pose.x, s[1] - pose.y);
                    let (sn, cs) = pose.theta.sin_cos();
                    let (lx, ly) = (cs * dx + sn * dy, -sn * dx + cs * dy);
                    let range = lx.hypot(ly);
                    let off = wrap_angle(-ly.atan2(lx) - bearing);
                    let beam = (-0.5 * (off / 0.6f64.to_radians()).powi(2)).exp();
                    if beam < 1e-3 {
                        continue;
                    }
                    for (i, v) in db.iter_mut().enumerate() {
                        let d = (i as f64 + 0.5) * settings.bin_m - range;
                        *v += 40.0 * beam * (-0.5 * (d / 0.1).powi(2)).exp();
                    }
                }
                Row {
                    timestamp_s: 0.0,
                    bearing_rad: bearing,
                    measured_db: db,
                }
            })
            .collect();
        Scan { rows }
    }

    #[test]
    fn on_the_simulated_street_the_dense_registration_finds_the_true_motion() {
        // The control for the recorded scans: the same registration where the truth is exact
        // (motion during the rotation and the range-Doppler coupling rendered).
        let scene = sim_sensor::scene::shipped::load("urban-street").expect("shipped scene");
        let (scans, truth) = simulated(&scene, 3).expect("renders");
        let settings = DenseSettings::default().for_radar(&scene.radar);
        let timed: Vec<(i64, &Scan)> = scans.iter().map(|(t, s)| (*t, s)).collect();
        let pairs = agreement(&timed, &truth, &settings);
        assert_eq!(pairs.len(), 2);
        for p in &pairs {
            let g = p.truth.pose;
            assert!(g.x > 1.0, "the vehicle moves: {g:?}");
            assert!(
                (p.dense.x - g.x).abs() < 0.03,
                "{:?} against {g:?}",
                p.dense
            );
            assert!(
                (p.dense.y - g.y).abs() < 0.03,
                "{:?} against {g:?}",
                p.dense
            );
            assert!(
                (p.dense.theta - g.theta).abs() < 0.01,
                "{:?} against {g:?}",
                p.dense
            );
        }
    }

    #[test]
    fn the_twist_round_trips_through_its_motion() {
        let motion = Pose2::new(2.1, 0.04, 0.012);
        let twist = Twist::from_motion(&motion, 0.25);
        let back = twist.motion(0.25);
        assert!((back.x - motion.x).abs() < 1e-12);
        assert!((back.y - motion.y).abs() < 1e-12);
        assert!((back.theta - motion.theta).abs() < 1e-12);
        let half = twist.motion(0.125);
        assert!((half.theta - 0.006).abs() < 1e-12);
    }

    #[test]
    fn dense_registration_finds_a_known_motion_from_a_start_five_percent_off() {
        let settings = DenseSettings {
            max_range_m: 30.0,
            doppler_coupling_s: 0.0,
            ..DenseSettings::default()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let scatterers: Vec<[f64; 2]> = (0..150)
            .map(|_| {
                let r = rng.gen_range(6.0..26.0);
                let a = rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI);
                [r * f64::cos(a), r * f64::sin(a)]
            })
            .collect();
        let truth = Pose2::new(2.0, 0.03, 0.01);
        let a = render(&scatterers, &Pose2::default(), &settings);
        let b = render(&scatterers, &truth, &settings);
        let still = Twist::default();
        let (ca, cb) = (
            cloud(&a, 0.0, still, &settings),
            cloud(&b, 0.0, still, &settings),
        );
        assert!(cb.points.len() > 1000, "{} points", cb.points.len());
        let start = Pose2::new(2.1, 0.0, 0.0);
        let (found, _) = register(&Image::new(&ca, &settings), &cb, &[start]).expect("a pose");
        assert!((found.x - truth.x).abs() < 0.005, "{found:?}");
        assert!((found.y - truth.y).abs() < 0.005, "{found:?}");
        assert!((found.theta - truth.theta).abs() < 0.0005, "{found:?}");
    }
}
