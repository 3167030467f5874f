//! Which places a drive comes back to, from its ground-truth trajectory: true revisits (for
//! judging loop closures found) and, on a grid of identical blocks, look-alike places (an
//! earlier pose shifted by whole blocks: where a loop closer matching geometry alone would
//! close a wrong loop).
//!
//! Works on any scene's trajectory; IO: none.

use radar_model::geometry::{wrap_angle, Pose2};

use crate::error::SimError;
use crate::scene::Scene;
use crate::trajectory::Trajectory;

/// One sample of a drive.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DriveSample {
    /// Seconds after the start.
    pub t_s: f64,
    /// The true pose.
    pub pose: Pose2Serde,
    /// Distance driven so far, metres.
    pub travelled_m: f64,
}

/// A pose that serialises (`x_m`, `y_m`, `theta_rad`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Pose2Serde {
    /// x, metres.
    pub x_m: f64,
    /// y, metres.
    pub y_m: f64,
    /// Heading, radians counter-clockwise from +x.
    pub theta_rad: f64,
}

impl From<Pose2> for Pose2Serde {
    fn from(p: Pose2) -> Self {
        Self {
            x_m: p.x,
            y_m: p.y,
            theta_rad: p.theta,
        }
    }
}

/// The scene's true trajectory every `every_s` seconds for `duration_s` seconds.
///
/// # Errors
/// The process model rejects a control.
pub fn drive_samples(
    scene: &Scene,
    duration_s: f64,
    every_s: f64,
) -> Result<Vec<DriveSample>, SimError> {
    let duration_s = if duration_s.is_finite() {
        duration_s.clamp(0.0, 86_400.0)
    } else {
        0.0
    };
    let every_s = if every_s.is_finite() && every_s >= 0.01 {
        every_s
    } else {
        0.5
    };
    let trajectory = Trajectory::new(scene, duration_s + 1.0)?;
    let mut cursor = trajectory.cursor();
    let n = (duration_s / every_s).floor() as u64;
    let mut out = Vec::with_capacity(usize::try_from(n + 1).unwrap_or(0));
    let mut travelled = 0.0;
    let mut last: Option<Pose2> = None;
    for k in 0..=n {
        let t_s = k as f64 * every_s;
        let pose = trajectory.pose_with(&mut cursor, (t_s * 1e9).round() as u64)?;
        if let Some(prev) = last {
            travelled += (pose.x - prev.x).hypot(pose.y - prev.y);
        }
        last = Some(pose);
        out.push(DriveSample {
            t_s,
            pose: pose.into(),
            travelled_m: travelled,
        });
    }
    Ok(out)
}

/// A stretch of the drive within `radius_m` of where the vehicle was at least `min_gap_m` of
/// driving earlier.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Revisit {
    /// First time of the stretch, seconds after the start.
    pub start_s: f64,
    /// Last time of the stretch.
    pub end_s: f64,
    /// The earliest earlier time matching the stretch's middle sample.
    pub earlier_s: f64,
    /// Where the stretch's middle sample is, metres.
    pub at: [f64; 2],
    /// Heading now minus heading then at the middle sample, degrees (about 0: driven the
    /// same way; about 180: the other way).
    pub heading_change_deg: f64,
}

/// A stretch of the drive where the pose equals an earlier one shifted by a whole number of
/// blocks (not zero) within `radius_m`, with the same heading within `heading_tol_deg`: on a
/// grid of identical blocks the radar sees the same thing there.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LookAlike {
    /// First time of the stretch, seconds after the start.
    pub start_s: f64,
    /// Last time of the stretch.
    pub end_s: f64,
    /// The earlier time matching the stretch's first sample.
    pub earlier_s: f64,
    /// The shift, blocks along x and y (now minus then).
    pub shift_blocks: [i64; 2],
}

/// The true revisits of a sampled drive (see [`Revisit`]).
pub fn revisits(samples: &[DriveSample], radius_m: f64, min_gap_m: f64) -> Vec<Revisit> {
    // Each sample's earliest match, then runs of consecutive matched samples.
    let matched: Vec<Option<usize>> = samples
        .iter()
        .enumerate()
        .map(|(i, now)| {
            samples.iter().take(i).position(|then| {
                now.travelled_m - then.travelled_m >= min_gap_m
                    && (now.pose.x_m - then.pose.x_m).hypot(now.pose.y_m - then.pose.y_m)
                        <= radius_m
            })
        })
        .collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < samples.len() {
        if matched.get(i).copied().flatten().is_none() {
            i += 1;
            continue;
        }
        let first = i;
        while matched.get(i + 1).copied().flatten().is_some() {
            i += 1;
        }
        let mid = (first + i) / 2;
        if let (Some(a), Some(b), Some(now), Some(Some(j))) = (
            samples.get(first),
            samples.get(i),
            samples.get(mid),
            matched.get(mid),
        ) {
            if let Some(then) = samples.get(*j) {
                out.push(Revisit {
                    start_s: a.t_s,
                    end_s: b.t_s,
                    earlier_s: then.t_s,
                    at: [now.pose.x_m, now.pose.y_m],
                    heading_change_deg: wrap_angle(now.pose.theta_rad - then.pose.theta_rad)
                        .to_degrees(),
                });
            }
        }
        i += 1;
    }
    out
}

/// The look-alike places of a sampled drive on a grid of pitch `pitch_m` (see [`LookAlike`]).
pub fn look_alikes(
    samples: &[DriveSample],
    pitch_m: [f64; 2],
    radius_m: f64,
    heading_tol_deg: f64,
    min_gap_m: f64,
) -> Vec<LookAlike> {
    let mut out: Vec<LookAlike> = Vec::new();
    let mut last: Option<(usize, [i64; 2])> = None;
    let tol = heading_tol_deg.to_radians();
    for (i, now) in samples.iter().enumerate() {
        let found = samples.iter().take(i).find_map(|then| {
            if now.travelled_m - then.travelled_m < min_gap_m
                || wrap_angle(now.pose.theta_rad - then.pose.theta_rad).abs() > tol
            {
                return None;
            }
            let dx = now.pose.x_m - then.pose.x_m;
            let dy = now.pose.y_m - then.pose.y_m;
            let shift = [(dx / pitch_m[0]).round(), (dy / pitch_m[1]).round()];
            let residual = (dx - shift[0] * pitch_m[0]).hypot(dy - shift[1] * pitch_m[1]);
            (shift != [0.0, 0.0] && residual <= radius_m)
                .then_some((then.t_s, [shift[0] as i64, shift[1] as i64]))
        });
        let Some((earlier_s, shift)) = found else {
            continue;
        };
        let continues = last == Some((i.wrapping_sub(1), shift));
        last = Some((i, shift));
        if continues {
            if let Some(a) = out.last_mut() {
                a.end_s = now.t_s;
                continue;
            }
        }
        out.push(LookAlike {
            start_s: now.t_s,
            end_s: now.t_s,
            earlier_s,
            shift_blocks: shift,
        });
    }
    out
}
