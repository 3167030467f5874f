//! The Boreas odometry benchmark's trajectory format, so that its public evaluator
//! (pyboreas, `python eval/odometry.py --radar`) scores a drive without conversion. A pure
//! formatting function: the caller writes the text to `<sequence>.txt`.
//!
//! The format, as checked in pyboreas (utiasASRL/pyboreas): `pyboreas/eval/odometry.md`
//! ("File format") and `pyboreas/utils/odometry.py` (`read_traj_file`, `write_traj_file`,
//! `get_sequence_poses_gt`, `read_traj_file_gt`):
//!
//! - one row per radar frame (the 2D benchmark wants the radar's own timestamps), space
//!   separated, 13 columns;
//! - the first column is the time, an integer in microseconds (`int(line_split[0])`; an
//!   earlier pyboreas used nanoseconds, the current one and the benchmark's description say
//!   microseconds);
//! - then the upper 3 x 4 of a 4 x 4 SE(3) transform, row-major (`pose[0, 0:4] =
//!   values[0:4]`, ...), read with `float()`;
//! - row `k` is `T_vk_v0`: the transform that takes a point's coordinates in the first
//!   frame `v0` into frame `vk` (`p_vk = T_vk_v0 p_v0`), so the first row is the identity.
//!   It is the **inverse** of the pose of frame `k` in the first frame's coordinates
//!   (pyboreas holds world-to-vehicle transforms `T_vk_i` throughout and inverts its own
//!   ground truth, `T_iv`, on reading it).
//!
//! **Axes.** The evaluator compares these rows with the truth in the radar frame, as
//! `applanix/radar_poses.csv` gives it: in Boreas that frame has z down (roll close to pi in
//! every row of pyboreas' demo sequence `test/demo/gt/boreas-2021-08-05-13-34`), so x is
//! forward and y is to the right. The daemon's poses have z up (x forward, y left, heading
//! counter-clockwise). The drift is the same in either, but the estimate and the truth must
//! use the same axes: [`VerticalAxis::Down`] against Boreas' own ground truth,
//! [`VerticalAxis::Up`] against a truth file written with these functions in z-up axes.

use radar_model::geometry::{wrap_angle, Pose2};

use super::DriftError;

/// Which way the z axis of the written frames points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VerticalAxis {
    /// z up: the daemon's frame (x forward, y left, heading counter-clockwise seen from
    /// above).
    Up,
    /// z down: Boreas' radar frame (x forward, y right); `y` and the heading change sign.
    Down,
}

/// The upper 3 x 4 of `T_vk_v0`, row-major, for the frame at `pose` when the first frame was
/// at `first` (both in the same world frame): the inverse of `first^-1 pose`, in `axes`.
pub fn transform_3x4(first: &Pose2, pose: &Pose2, axes: VerticalAxis) -> [f64; 12] {
    // The pose of frame k in the first frame's coordinates (z up).
    let (s0, c0) = first.theta.sin_cos();
    let (dx, dy) = (pose.x - first.x, pose.y - first.y);
    let (x, mut y, mut theta) = (
        c0 * dx + s0 * dy,
        -s0 * dx + c0 * dy,
        wrap_angle(pose.theta - first.theta),
    );
    if axes == VerticalAxis::Down {
        // Conjugation by diag(1, -1, -1): the same motion in the mirrored axes.
        y = -y;
        theta = -theta;
    }
    // Its inverse: rotation R(theta)^T, translation -R(theta)^T (x, y).
    let (s, c) = theta.sin_cos();
    [
        c,
        s,
        0.0,
        -(c * x + s * y),
        -s,
        c,
        0.0,
        s * x - c * y,
        0.0,
        0.0,
        1.0,
        0.0,
    ]
    .map(positive_zero)
}

/// One row of the file (no line end): the time in microseconds, then
/// [`transform_3x4`] of `pose` from `first`, each number in the shortest form that reads
/// back to the same `f64`.
pub fn odometry_row(time_us: i64, first: &Pose2, pose: &Pose2, axes: VerticalAxis) -> String {
    let mut row = time_us.to_string();
    for v in transform_3x4(first, pose, axes) {
        row.push(' ');
        row.push_str(&v.to_string());
    }
    row
}

/// The whole file for one sequence: a row per frame (time in microseconds, pose in any
/// world frame), in the order given, each ended by a newline; the first frame is the
/// reference `v0`. Refuses a pose with a NaN or infinite component (the evaluator would
/// read it and score NaN).
pub fn odometry_file(frames: &[(i64, Pose2)], axes: VerticalAxis) -> Result<String, DriftError> {
    if let Some(index) = frames
        .iter()
        .position(|(_, p)| !(p.x.is_finite() && p.y.is_finite() && p.theta.is_finite()))
    {
        return Err(DriftError::NonFinite {
            which: "trajectory",
            index,
        });
    }
    let Some((_, first)) = frames.first() else {
        return Ok(String::new());
    };
    let mut out = String::new();
    for (time_us, pose) in frames {
        out.push_str(&odometry_row(*time_us, first, pose, axes));
        out.push('\n');
    }
    Ok(out)
}

/// `-0.0` as `0.0`, so that the identity prints without signs.
fn positive_zero(v: f64) -> f64 {
    if v == 0.0 {
        0.0
    } else {
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    /// A row read as pyboreas' `read_traj_file` reads it: the time, and the 4 x 4.
    fn read_row(line: &str) -> (i64, [[f64; 4]; 4]) {
        let mut fields = line.split_whitespace();
        let time = fields.next().unwrap().parse().unwrap();
        let v: Vec<f64> = fields.map(|f| f.parse().unwrap()).collect();
        assert_eq!(v.len(), 12, "{line}");
        let m = [
            [v[0], v[1], v[2], v[3]],
            [v[4], v[5], v[6], v[7]],
            [v[8], v[9], v[10], v[11]],
            [0.0, 0.0, 0.0, 1.0],
        ];
        (time, m)
    }

    fn close(a: &[f64; 12], b: &[f64; 12]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
    }

    #[test]
    fn the_first_frame_is_the_identity() {
        let first = Pose2::new(12.5, -3.0, 2.2);
        for axes in [VerticalAxis::Up, VerticalAxis::Down] {
            let row = odometry_row(1_631_021_758_565_325, &first, &first, axes);
            assert_eq!(row, "1631021758565325 1 0 0 0 0 1 0 0 0 0 1 0");
        }
    }

    #[test]
    fn a_known_pose_becomes_its_inverse_transform() {
        // 10 m ahead of the first frame, turned left by 90 degrees: the vehicle faces the
        // first frame's +y, so the first frame's origin, 10 m along its -x, is 10 m to its
        // left: (0, 10) in frame k. The rotation takes the first frame's x axis to -y.
        let first = Pose2::new(0.0, 0.0, 0.0);
        let pose = Pose2::new(10.0, 0.0, FRAC_PI_2);
        #[rustfmt::skip]
        let up = [
            0.0,  1.0, 0.0, 0.0,
            -1.0, 0.0, 0.0, 10.0,
            0.0,  0.0, 1.0, 0.0,
        ];
        assert!(close(&transform_3x4(&first, &pose, VerticalAxis::Up), &up));
        // z down: the turn is to the right (-90 degrees about z down) and the origin is at
        // y = -10 (y points right).
        #[rustfmt::skip]
        let down = [
            0.0, -1.0, 0.0, 0.0,
            1.0,  0.0, 0.0, -10.0,
            0.0,  0.0, 1.0, 0.0,
        ];
        assert!(close(
            &transform_3x4(&first, &pose, VerticalAxis::Down),
            &down
        ));
        // The same motion from another first pose (the world frame does not matter):
        // start at (5, 5) facing +y, drive 10 m along +y, turn left.
        let first = Pose2::new(5.0, 5.0, FRAC_PI_2);
        let pose = Pose2::new(5.0, 15.0, FRAC_PI_2 + FRAC_PI_2);
        assert!(close(&transform_3x4(&first, &pose, VerticalAxis::Up), &up));
    }

    #[test]
    fn a_row_maps_points_from_the_first_frame_into_the_frame() {
        // p_vk = T_vk_v0 p_v0: the vehicle's own origin at frame k, written in the first
        // frame's coordinates, maps to (0, 0, 0); a point 1 m ahead of it to (1, 0, 0).
        let first = Pose2::new(-4.0, 7.0, -0.6);
        let pose = Pose2::new(20.0, 31.0, 1.3);
        let line = odometry_row(42, &first, &pose, VerticalAxis::Up);
        let (time, m) = read_row(&line);
        assert_eq!(time, 42);
        let (s0, c0) = first.theta.sin_cos();
        let in_first = |x: f64, y: f64| {
            let (dx, dy) = (x - first.x, y - first.y);
            [c0 * dx + s0 * dy, -s0 * dx + c0 * dy, 0.0, 1.0]
        };
        let apply = |p: [f64; 4]| -> [f64; 4] {
            let mut out = [0.0; 4];
            for (r, row) in m.iter().enumerate() {
                out[r] = row.iter().zip(p).map(|(a, b)| a * b).sum();
            }
            out
        };
        let o = apply(in_first(pose.x, pose.y));
        assert!(
            o[0].abs() < 1e-12 && o[1].abs() < 1e-12 && o[2] == 0.0,
            "{o:?}"
        );
        let ahead = apply(in_first(
            pose.x + pose.theta.cos(),
            pose.y + pose.theta.sin(),
        ));
        assert!(
            (ahead[0] - 1.0).abs() < 1e-12 && ahead[1].abs() < 1e-12,
            "{ahead:?}"
        );
    }

    #[test]
    fn the_file_has_a_row_per_frame_and_reads_back_exactly() {
        let frames = [
            (1_000_000, Pose2::new(1.0, 2.0, 0.3)),
            (1_250_000, Pose2::new(3.5, 2.7, 0.35)),
            (1_500_000, Pose2::new(6.1, 3.9, 0.5)),
        ];
        let text = odometry_file(&frames, VerticalAxis::Down).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3);
        assert!(text.ends_with('\n'));
        assert!(lines[0].starts_with("1000000 1 0 0 0 0 1 0 0 0 0 1 0"));
        for ((time, pose), line) in frames.iter().zip(&lines) {
            let (t, m) = read_row(line);
            assert_eq!(t, *time);
            let want = transform_3x4(&frames[0].1, pose, VerticalAxis::Down);
            let got: Vec<f64> = m[..3].iter().flatten().copied().collect();
            assert_eq!(got, want, "the numbers read back bit for bit");
        }
        assert_eq!(odometry_file(&[], VerticalAxis::Up).unwrap(), "");
        let bad = [
            (0, Pose2::new(0.0, 0.0, 0.0)),
            (1, Pose2::new(f64::NAN, 0.0, 0.0)),
        ];
        assert_eq!(
            odometry_file(&bad, VerticalAxis::Up),
            Err(DriftError::NonFinite {
                which: "trajectory",
                index: 1
            })
        );
    }
}
