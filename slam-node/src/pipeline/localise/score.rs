//! The published pose in the map's frame against the truth: along- and across-track and
//! heading errors, and the Boreas localisation benchmark's consistency score. No IO.

use nalgebra::{Matrix3, Vector3};
use radar_model::geometry::{wrap_angle, Pose2};
use serde::Serialize;

use crate::output::PoseSample;

/// Localisation errors over the published poses.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct LocaliseScore {
    /// Poses scored.
    pub poses: usize,
    /// RMS error along the true heading (m).
    pub along_rms_m: f64,
    /// RMS error across it (m).
    pub across_rms_m: f64,
    /// RMS heading error (rad).
    pub heading_rms_rad: f64,
    /// Largest position error (m).
    pub max_m: f64,
    /// Boreas' consistency score: `sqrt(e' inv(P) e / 3)` per pose (e the x, y, heading
    /// error, P the published covariance), averaged over the poses; 1 for an honest
    /// covariance.
    pub consistency: f64,
    /// The first published pose's position error (m): the error of the fix.
    pub first_error_m: f64,
    /// And its heading error (rad).
    pub first_heading_rad: f64,
}

/// Scores `published` poses against `truth` (same order and times).
pub fn score(published: &[(PoseSample, Pose2)]) -> Option<LocaliseScore> {
    let (first_est, first_true) = published.first()?;
    let mut s = LocaliseScore {
        poses: published.len(),
        first_error_m: (first_est.x_m - first_true.x).hypot(first_est.y_m - first_true.y),
        first_heading_rad: wrap_angle(first_est.theta_rad - first_true.theta),
        ..LocaliseScore::default()
    };
    let (mut along, mut across, mut heading, mut consistency, mut counted) =
        (0.0, 0.0, 0.0, 0.0, 0usize);
    for (e, t) in published {
        let (dx, dy) = (e.x_m - t.x, e.y_m - t.y);
        let dth = wrap_angle(e.theta_rad - t.theta);
        let (s_t, c_t) = t.theta.sin_cos();
        let a = c_t * dx + s_t * dy;
        let c = -s_t * dx + c_t * dy;
        along += a * a;
        across += c * c;
        heading += dth * dth;
        s.max_m = s.max_m.max(dx.hypot(dy));
        let p = Matrix3::from_fn(|r, k| e.covariance[r][k]);
        let err = Vector3::new(dx, dy, dth);
        if let Some(ch) = (0.5 * (p + p.transpose())).cholesky() {
            consistency += (err.dot(&ch.solve(&err)) / 3.0).sqrt();
            counted += 1;
        }
    }
    let n = published.len() as f64;
    s.along_rms_m = (along / n).sqrt();
    s.across_rms_m = (across / n).sqrt();
    s.heading_rms_rad = (heading / n).sqrt();
    s.consistency = if counted > 0 {
        consistency / counted as f64
    } else {
        f64::NAN
    };
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(x: f64, y: f64, theta: f64, var: [f64; 3]) -> PoseSample {
        PoseSample {
            timestamp_s: 0.0,
            x_m: x,
            y_m: y,
            theta_rad: theta,
            covariance: [[var[0], 0.0, 0.0], [0.0, var[1], 0.0], [0.0, 0.0, var[2]]],
        }
    }

    #[test]
    fn along_and_across_follow_the_true_heading_and_the_score_is_the_mahalanobis_mean() {
        // Truth heading north: an error in +y is along track, in -x across.
        let t = Pose2::new(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        let s = score(&[(sample(-0.3, 0.4, t.theta, [0.09, 0.16, 1.0]), t)]).unwrap();
        assert!((s.along_rms_m - 0.4).abs() < 1e-12);
        assert!((s.across_rms_m - 0.3).abs() < 1e-12);
        assert!(s.heading_rms_rad.abs() < 1e-12);
        // e' inv(P) e = 0.09/0.09 + 0.16/0.16 = 2: sqrt(2/3).
        assert!((s.consistency - (2.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert!((s.first_error_m - 0.5).abs() < 1e-12);
        assert!(score(&[]).is_none());
    }
}
