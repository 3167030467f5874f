//! Odometry drift as the radar odometry literature reports it: the KITTI odometry
//! benchmark's relative error over segments of 100, 200, ..., 800 m, in SE(2), as the KITTI
//! odometry development kit (`devkit/cpp/evaluate_odometry.cpp`) and the Boreas benchmark's
//! evaluator (pyboreas, `pyboreas/utils/odometry.py`: `calc_sequence_errors` and
//! `get_stats`, run by `pyboreas/eval/odometry.py --radar`) define it. No IO; the trajectory
//! file the Boreas evaluator reads is written by [`boreas`].
//!
//! The definition, with `P_k` the truth's pose of frame `k` and `Q_k` the estimate's (each in
//! its own world frame; the two slices are matched by index, the caller matches them by time):
//!
//! 1. **Distance travelled**, from the truth alone: `d_0 = 0`, `d_k = d_{k-1} + |p_k -
//!    p_{k-1}|` with `p_k` the truth's position.
//! 2. **Segments.** For every first frame `f = 0, s, 2 s, ...` (`s` the step: 10 frames in
//!    KITTI, one second at 10 Hz; pyboreas uses 4 for the radar benchmark, one second of a
//!    4 Hz Navtech) and every length `L` in 100, 200, ..., 800 m, the last frame `l` is the
//!    first frame at or after `f` with `d_l > d_f + L` (strictly greater). A pair with no such
//!    frame is skipped, so a drive of 100 m or less has no segment at all.
//! 3. **Relative pose error.** `E = (Q_f^-1 Q_l)^-1 (P_f^-1 P_l)`: the estimated motion from
//!    `f` to `l` undone from the true motion. The translation error is `|t(E)|` (m), the
//!    rotation error the angle of `E` (rad, in `[0, pi]`). pyboreas, holding world-to-vehicle
//!    transforms, computes the inverse of the same `E` (`T_gt_delta T_pred_delta^-1`), whose
//!    angle and translation norm are the same.
//! 4. **Per segment**, both are divided by the nominal length `L` (not by `d_l - d_f`):
//!    translation m/m, rotation rad/m.
//! 5. **Average** over every segment of the drive, all lengths pooled (KITTI's `saveStats`,
//!    pyboreas' `get_stats`): translation drift in % (x 100), rotation drift in deg/m
//!    (x 180 / pi), reported here per 100 m as the radar odometry papers and the Boreas
//!    leaderboard give it. The average per length ([`LengthDrift`]) is the curve both tools
//!    plot (KITTI plots a length only when it has at least three segments; every length with
//!    a segment is given here, with its count).
//!
//! Departures that change no figure beyond rounding: the computation is in `f64` (the devkit
//! uses `f32`); the rotation error of a planar `E` is `|wrap(theta(E))|`, which equals the
//! devkit's `acos((trace(R(E)) - 1) / 2)` for the rotation embedded about z, without the
//! precision `acos` loses near zero; the last frame is found by bisection, which returns the
//! devkit's linear scan's frame because the distance never decreases.
//!
//! The metric is invariant under a change of either trajectory's world frame, and under
//! mirroring both (a z-down sensor frame): only relative motions enter it.

pub mod boreas;

use radar_model::geometry::Pose2;
use thiserror::Error;

/// The segment lengths (m) of the KITTI and Boreas odometry benchmarks.
pub const SEGMENT_LENGTHS_M: [f64; 8] = [100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0];

/// Frames between first frames in the KITTI devkit (one second at 10 Hz): the default step.
pub const KITTI_STEP_FRAMES: usize = 10;

/// Frames between first frames in pyboreas' radar (SE(2)) benchmark: one second at 4 Hz.
pub const BOREAS_RADAR_STEP_FRAMES: usize = 4;

/// Why drift could not be computed (or a trajectory written).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DriftError {
    /// The truth and the estimate are not matched one to one.
    #[error(
        "the truth has {truth} poses and the estimate {estimate}; they must be matched by index"
    )]
    LengthMismatch {
        /// Poses of the truth.
        truth: usize,
        /// Poses of the estimate.
        estimate: usize,
    },
    /// A step of zero frames between first frames.
    #[error("the step between first frames must be at least one frame")]
    ZeroStep,
    /// A pose with a NaN or infinite component.
    #[error("the {which} pose at index {index} is not finite")]
    NonFinite {
        /// Which trajectory: "truth", "estimate" or "trajectory".
        which: &'static str,
        /// Its index.
        index: usize,
    },
}

/// One segment's errors (before division by its length).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentError {
    /// Its first frame.
    pub first_frame: usize,
    /// Its last frame: the first whose distance travelled exceeds the first's by `length_m`.
    pub last_frame: usize,
    /// The nominal segment length (m): one of [`SEGMENT_LENGTHS_M`].
    pub length_m: f64,
    /// Translation of the relative pose error (m).
    pub translation_error_m: f64,
    /// Angle of the relative pose error (rad, in `[0, pi]`).
    pub rotation_error_rad: f64,
}

/// The drift averaged over the segments of one length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LengthDrift {
    /// The segment length (m).
    pub length_m: f64,
    /// Segments of this length.
    pub segments: usize,
    /// Mean translation error over the length (%).
    pub translation_percent: f64,
    /// Mean rotation error over the length (deg per 100 m).
    pub rotation_deg_per_100m: f64,
}

/// KITTI-style odometry drift of one drive.
#[derive(Debug, Clone, PartialEq)]
pub struct OdometryDrift {
    /// Mean translation error over all segments (% of the segment length).
    pub translation_percent: f64,
    /// Mean rotation error over all segments (deg per 100 m).
    pub rotation_deg_per_100m: f64,
    /// Segments averaged (all lengths).
    pub segments: usize,
    /// The averages per segment length, in increasing length; lengths without a segment are
    /// left out.
    pub per_length: Vec<LengthDrift>,
}

/// [`odometry_drift_with_step`] with KITTI's step of [`KITTI_STEP_FRAMES`].
pub fn odometry_drift(
    truth: &[Pose2],
    estimate: &[Pose2],
) -> Result<Option<OdometryDrift>, DriftError> {
    odometry_drift_with_step(truth, estimate, KITTI_STEP_FRAMES)
}

/// KITTI-style drift of `estimate` against `truth` (matched by index), with first frames
/// every `step_frames` frames (see the module docs). `Ok(None)` when there is no segment:
/// the truth travels 100 m or less.
pub fn odometry_drift_with_step(
    truth: &[Pose2],
    estimate: &[Pose2],
    step_frames: usize,
) -> Result<Option<OdometryDrift>, DriftError> {
    let segments = segment_errors(truth, estimate, step_frames)?;
    if segments.is_empty() {
        return Ok(None);
    }
    let (mut t_sum, mut r_sum) = (0.0, 0.0);
    let mut per = [(0usize, 0.0, 0.0); SEGMENT_LENGTHS_M.len()];
    for s in &segments {
        let (t, r) = (
            s.translation_error_m / s.length_m,
            s.rotation_error_rad / s.length_m,
        );
        t_sum += t;
        r_sum += r;
        if let Some(i) = SEGMENT_LENGTHS_M.iter().position(|&l| l == s.length_m) {
            if let Some(slot) = per.get_mut(i) {
                slot.0 += 1;
                slot.1 += t;
                slot.2 += r;
            }
        }
    }
    let n = segments.len() as f64;
    let per_length = SEGMENT_LENGTHS_M
        .iter()
        .zip(per)
        .filter(|(_, (count, _, _))| *count > 0)
        .map(|(&length_m, (count, t, r))| LengthDrift {
            length_m,
            segments: count,
            translation_percent: percent(t / count as f64),
            rotation_deg_per_100m: deg_per_100m(r / count as f64),
        })
        .collect();
    Ok(Some(OdometryDrift {
        translation_percent: percent(t_sum / n),
        rotation_deg_per_100m: deg_per_100m(r_sum / n),
        segments: segments.len(),
        per_length,
    }))
}

/// Every segment's errors, in the devkit's order (by first frame, then by length). Empty
/// when the truth travels 100 m or less.
pub fn segment_errors(
    truth: &[Pose2],
    estimate: &[Pose2],
    step_frames: usize,
) -> Result<Vec<SegmentError>, DriftError> {
    if truth.len() != estimate.len() {
        return Err(DriftError::LengthMismatch {
            truth: truth.len(),
            estimate: estimate.len(),
        });
    }
    if step_frames == 0 {
        return Err(DriftError::ZeroStep);
    }
    check_finite(truth, "truth")?;
    check_finite(estimate, "estimate")?;
    let travelled = distance_travelled(truth);
    let mut out = Vec::new();
    for first in (0..truth.len()).step_by(step_frames) {
        let (Some(&d_first), Some(p_first), Some(q_first)) =
            (travelled.get(first), truth.get(first), estimate.get(first))
        else {
            continue;
        };
        for length_m in SEGMENT_LENGTHS_M {
            let Some(last) = last_frame(&travelled, first, d_first + length_m) else {
                continue;
            };
            let (Some(p_last), Some(q_last)) = (truth.get(last), estimate.get(last)) else {
                continue;
            };
            let true_motion = p_first.between(p_last);
            let estimated_motion = q_first.between(q_last);
            let error = estimated_motion.between(&true_motion);
            out.push(SegmentError {
                first_frame: first,
                last_frame: last,
                length_m,
                translation_error_m: error.x.hypot(error.y),
                rotation_error_rad: error.theta.abs(),
            });
        }
    }
    Ok(out)
}

/// Distance travelled along the truth to each frame (m), from the first frame.
pub fn distance_travelled(truth: &[Pose2]) -> Vec<f64> {
    let mut out = Vec::with_capacity(truth.len());
    let mut d = 0.0;
    let mut previous: Option<&Pose2> = None;
    for p in truth {
        if let Some(q) = previous {
            d += (p.x - q.x).hypot(p.y - q.y);
        }
        out.push(d);
        previous = Some(p);
    }
    out
}

/// The first frame at or after `first` whose distance exceeds `target` (strictly), as the
/// devkit's `lastFrameFromSegmentLength`; `travelled` never decreases, so bisection finds it.
fn last_frame(travelled: &[f64], first: usize, target: f64) -> Option<usize> {
    let rest = travelled.get(first..)?;
    let k = rest.partition_point(|&d| d <= target);
    (k < rest.len()).then_some(first + k)
}

fn check_finite(poses: &[Pose2], which: &'static str) -> Result<(), DriftError> {
    match poses
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.theta.is_finite()))
    {
        Some(index) => Err(DriftError::NonFinite { which, index }),
        None => Ok(()),
    }
}

fn percent(m_per_m: f64) -> f64 {
    100.0 * m_per_m
}

fn deg_per_100m(rad_per_m: f64) -> f64 {
    100.0 * rad_per_m.to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;
    use radar_model::geometry::wrap_angle;
    use std::f64::consts::PI;

    /// A straight drive along +x, one pose per metre, `metres + 1` poses.
    fn straight(metres: usize) -> Vec<Pose2> {
        (0..=metres)
            .map(|k| Pose2::new(k as f64, 0.0, 0.0))
            .collect()
    }

    /// A winding drive: a speed of 10 m/s at 10 Hz with a varying turn rate.
    fn winding(frames: usize) -> Vec<Pose2> {
        let mut p = Pose2::new(3.0, -7.0, 0.4);
        let mut out = vec![p];
        for k in 1..frames {
            let rate = 0.2 * (k as f64 * 0.01).sin();
            p = Pose2::new(
                p.x + p.theta.cos(),
                p.y + p.theta.sin(),
                wrap_angle(p.theta + rate * 0.1),
            );
            out.push(p);
        }
        out
    }

    /// The mean of `f(L)` over the segments of a straight drive with one pose per metre
    /// and first frames every `KITTI_STEP_FRAMES`: a segment of length L starting at `f`
    /// ends at `f + L + 1` (the first frame strictly beyond `L`), so first frames go up to
    /// `metres - L - 1`.
    fn straight_mean(metres: usize, f: impl Fn(f64) -> f64) -> (f64, usize) {
        let (mut sum, mut count) = (0.0, 0usize);
        for l in SEGMENT_LENGTHS_M {
            let last_first = metres as i64 - l as i64 - 1;
            if last_first < 0 {
                continue;
            }
            let firsts = last_first as usize / KITTI_STEP_FRAMES + 1;
            sum += firsts as f64 * f(l);
            count += firsts;
        }
        (sum / count as f64, count)
    }

    #[test]
    fn a_perfect_estimate_has_no_drift() {
        let truth = winding(3000);
        let drift = odometry_drift(&truth, &truth).unwrap().unwrap();
        assert_eq!(drift.translation_percent, 0.0);
        assert_eq!(drift.rotation_deg_per_100m, 0.0);
        assert!(drift.segments > 0);
        assert_eq!(drift.per_length.len(), 8);
        assert_eq!(
            drift.per_length.iter().map(|l| l.segments).sum::<usize>(),
            drift.segments
        );
    }

    #[test]
    fn the_estimates_own_world_frame_does_not_matter() {
        // The same estimate expressed in another world frame (rotated and shifted).
        let truth = winding(3000);
        let estimate: Vec<Pose2> = truth
            .iter()
            .enumerate()
            .map(|(k, p)| Pose2::new(p.x * 1.002, p.y, p.theta + 1e-4 * k as f64))
            .collect();
        let (s, c) = 2.0_f64.sin_cos();
        let moved: Vec<Pose2> = estimate
            .iter()
            .map(|p| {
                Pose2::new(
                    c * p.x - s * p.y + 40.0,
                    s * p.x + c * p.y - 12.0,
                    wrap_angle(p.theta + 2.0),
                )
            })
            .collect();
        let a = odometry_drift(&truth, &estimate).unwrap().unwrap();
        let b = odometry_drift(&truth, &moved).unwrap().unwrap();
        assert!(a.translation_percent > 0.1 && a.rotation_deg_per_100m > 0.1);
        assert!((a.translation_percent - b.translation_percent).abs() < 1e-9);
        assert!((a.rotation_deg_per_100m - b.rotation_deg_per_100m).abs() < 1e-9);
    }

    #[test]
    fn a_one_percent_speed_scale_on_a_straight_kilometre_is_one_percent() {
        let truth = straight(1000);
        let estimate: Vec<Pose2> = truth
            .iter()
            .map(|p| Pose2::new(1.01 * p.x, 0.0, 0.0))
            .collect();
        let drift = odometry_drift(&truth, &estimate).unwrap().unwrap();
        // Each segment of length L spans L + 1 m of truth, of which the estimate makes
        // 1.01 (L + 1): an error of 0.01 (L + 1) m, divided by the nominal L.
        let (expected, count) = straight_mean(1000, |l| 0.01 * (l + 1.0) / l);
        // 90 first frames for 100 m (0, 10, ..., 890), 80 for 200 m, ..., 20 for 800 m.
        assert_eq!(count, 440);
        assert_eq!(drift.segments, 440);
        assert!((drift.translation_percent - 100.0 * expected).abs() < 1e-9);
        assert_eq!(format!("{:.2}", drift.translation_percent), "1.00");
        assert_eq!(drift.rotation_deg_per_100m, 0.0);
        for (i, l) in drift.per_length.iter().enumerate() {
            assert_eq!(l.length_m, 100.0 * (i + 1) as f64);
            assert_eq!(l.segments, 90 - 10 * i);
            let want = (l.length_m + 1.0) / l.length_m;
            assert!((l.translation_percent - want).abs() < 1e-9, "{l:?}");
        }
    }

    #[test]
    fn a_heading_rate_bias_gives_its_rotation_drift() {
        // Truth: straight along +x at v = 10 m/s, 10 Hz (1 m per frame). The estimate's
        // heading integrates a bias b = 0.1 deg/s: over a segment of n frames (n dt seconds)
        // its heading is off by b n dt, and a segment of length L spans n = L + 1 frames
        // (L + 1 m, the first frame strictly beyond L). Rotation error per metre:
        // b (L + 1) dt / L = (b / v) (L + 1) / L; with b / v = 0.01 deg/m that is
        // 1 deg/100 m times (L + 1) / L, 1.004 deg/100 m over the kilometre's segments.
        let (v, dt, bias) = (10.0, 0.1, 0.1_f64.to_radians());
        let truth = straight(1000);
        let mut estimate = vec![Pose2::new(0.0, 0.0, 0.0)];
        for k in 1..truth.len() {
            let p = estimate[k - 1];
            estimate.push(Pose2::new(
                p.x + v * dt * p.theta.cos(),
                p.y + v * dt * p.theta.sin(),
                p.theta + bias * dt,
            ));
        }
        let drift = odometry_drift(&truth, &estimate).unwrap().unwrap();
        let (expected, count) = straight_mean(1000, |l| (l + 1.0) / l);
        assert_eq!(drift.segments, count);
        assert!(
            (drift.rotation_deg_per_100m - expected).abs() < 1e-9,
            "{} deg/100 m, expected {expected}",
            drift.rotation_deg_per_100m
        );
        assert_eq!(format!("{:.2}", drift.rotation_deg_per_100m), "1.00");
        for l in &drift.per_length {
            let want = (l.length_m + 1.0) / l.length_m;
            assert!((l.rotation_deg_per_100m - want).abs() < 1e-9, "{l:?}");
        }
        // The heading error bends the estimated path: translation drift too.
        assert!(drift.translation_percent > 0.1);
    }

    #[test]
    fn a_drive_of_100_m_or_less_has_no_segment() {
        let truth = straight(60);
        assert_eq!(odometry_drift(&truth, &truth).unwrap(), None);
        // Exactly 100 m: the devkit wants a frame strictly beyond the length.
        let truth = straight(100);
        assert_eq!(odometry_drift(&truth, &truth).unwrap(), None);
        assert!(segment_errors(&truth, &truth, 1).unwrap().is_empty());
        // 101 m: one segment, from the first frame to the last.
        let truth = straight(101);
        let segments = segment_errors(&truth, &truth, KITTI_STEP_FRAMES).unwrap();
        assert_eq!(segments.len(), 1);
        assert_eq!((segments[0].first_frame, segments[0].last_frame), (0, 101));
        assert_eq!(odometry_drift(&[], &[]).unwrap(), None);
    }

    #[test]
    fn a_hand_computed_segment() {
        // Truth: 0, 60 and 120 m along +x, then along +y for 100 m (frame 3).
        // Distances 0, 60, 120, 220. With a step of 1:
        //   f = 0: 100 m -> frame 2 (120 > 100), 200 m -> frame 3 (220 > 200);
        //   f = 1: 100 m -> frame 3 (220 > 160);  f = 2: 100 m -> none (220 - 120 = 100).
        let truth = [
            Pose2::new(0.0, 0.0, 0.0),
            Pose2::new(60.0, 0.0, 0.0),
            Pose2::new(120.0, 0.0, 0.0),
            Pose2::new(120.0, 100.0, PI / 2.0),
        ];
        // The estimate, in a world frame of its own: starts at (5, 5) facing +y.
        // Its motions in its first frame: (60, 0, 0), (119, 3, 0.02), (121, 98, pi/2 + 0.03).
        let to_world = |x: f64, y: f64, th: f64| Pose2::new(5.0 - y, 5.0 + x, PI / 2.0 + th);
        let estimate = [
            to_world(0.0, 0.0, 0.0),
            to_world(60.0, 0.0, 0.0),
            to_world(119.0, 3.0, 0.02),
            to_world(121.0, 98.0, PI / 2.0 + 0.03),
        ];
        let segs = segment_errors(&truth, &estimate, 1).unwrap();
        let frames: Vec<_> = segs
            .iter()
            .map(|s| (s.first_frame, s.last_frame, s.length_m))
            .collect();
        assert_eq!(frames, [(0, 2, 100.0), (0, 3, 200.0), (1, 3, 100.0)]);
        // 0 -> 2: E = D_est^-1 D_gt with D_gt = (120, 0, 0), D_est = (119, 3, 0.02):
        // rotation 0.02 rad; translation R(-0.02) ((120, 0) - (119, 3)) of norm sqrt(10).
        assert!((segs[0].translation_error_m - 10.0_f64.sqrt()).abs() < 1e-12);
        assert!((segs[0].rotation_error_rad - 0.02).abs() < 1e-12);
        // 0 -> 3: D_gt = (120, 100, pi/2), D_est = (121, 98, pi/2 + 0.03): sqrt(1 + 4) m, 0.03 rad.
        assert!((segs[1].translation_error_m - 5.0_f64.sqrt()).abs() < 1e-12);
        assert!((segs[1].rotation_error_rad - 0.03).abs() < 1e-12);
        // 1 -> 3: D_gt = (60, 100, pi/2), D_est = (61, 98, pi/2 + 0.03): sqrt(5) m, 0.03 rad.
        assert!((segs[2].translation_error_m - 5.0_f64.sqrt()).abs() < 1e-12);
        assert!((segs[2].rotation_error_rad - 0.03).abs() < 1e-12);

        let drift = odometry_drift_with_step(&truth, &estimate, 1)
            .unwrap()
            .unwrap();
        let t = (10.0_f64.sqrt() / 100.0 + 5.0_f64.sqrt() / 200.0 + 5.0_f64.sqrt() / 100.0) / 3.0;
        let r = (0.02 / 100.0 + 0.03 / 200.0 + 0.03 / 100.0) / 3.0;
        assert_eq!(drift.segments, 3);
        assert!((drift.translation_percent - 100.0 * t).abs() < 1e-9);
        assert!((drift.rotation_deg_per_100m - 100.0 * r * 180.0 / PI).abs() < 1e-9);
        assert_eq!(drift.per_length.len(), 2);
        let l100 = drift.per_length[0];
        assert_eq!((l100.length_m, l100.segments), (100.0, 2));
        let t100 = (10.0_f64.sqrt() + 5.0_f64.sqrt()) / 2.0; // % of 100 m
        assert!((l100.translation_percent - t100).abs() < 1e-9);
        assert!((l100.rotation_deg_per_100m - 0.025 * 180.0 / PI).abs() < 1e-9);

        // With a step of 2 the first frames are 0 and 2 only.
        let step2 = segment_errors(&truth, &estimate, 2).unwrap();
        assert_eq!(step2.len(), 2);
        assert!(step2.iter().all(|s| s.first_frame == 0));
    }

    #[test]
    fn bad_input_is_refused() {
        let truth = straight(200);
        assert_eq!(
            odometry_drift(&truth, &truth[..10]),
            Err(DriftError::LengthMismatch {
                truth: 201,
                estimate: 10
            })
        );
        assert_eq!(
            odometry_drift_with_step(&truth, &truth, 0),
            Err(DriftError::ZeroStep)
        );
        let mut bad = truth.clone();
        bad[7].theta = f64::NAN;
        assert_eq!(
            odometry_drift(&truth, &bad),
            Err(DriftError::NonFinite {
                which: "estimate",
                index: 7
            })
        );
    }

    #[test]
    fn distance_is_travelled_along_the_truth() {
        let truth = [
            Pose2::new(0.0, 0.0, 0.0),
            Pose2::new(3.0, 4.0, 1.0),
            Pose2::new(3.0, 4.0, 2.0),
            Pose2::new(0.0, 0.0, 0.0),
        ];
        assert_eq!(distance_travelled(&truth), [0.0, 5.0, 5.0, 10.0]);
        assert!(distance_travelled(&[]).is_empty());
    }
}
