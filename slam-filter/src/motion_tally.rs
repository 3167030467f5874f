//! The motion since a mark: as the odometry drives it (the tally: the vehicle's pose
//! relative to where it was at the mark, mean only, from the same inputs as every prediction
//! step, in O(1)), and as the state holds it (the pose in the frame of the state's clone of
//! the pose at the mark, [`relative_pose`], with its Jacobian).
//!
//! A relative-motion measurement from the radar itself (scan-to-scan registration of two
//! rotations, see [`crate::Ekf::observe_motion_since_mark`]) is `z = T_mark^-1 T_now + e`,
//! predicted from the state as [`relative_pose`] of the clone and the pose: an update on
//! both (stochastic cloning). The tally is the registration's starting guess.

use nalgebra::Matrix3x6;
use radar_model::geometry::{wrap_angle, Pose2};

use super::error::FilterError;
use super::process::{corrected_input, OdometrySample, ProcessModel};

/// The motion since a mark (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionTally {
    /// The state's time at the mark (s).
    pub since_s: f64,
    /// The pose now in the frame of the pose at the mark, as the odometry drives it.
    pub rel: Pose2,
}

impl MotionTally {
    /// A tally that starts at `time_s`: no motion yet.
    pub fn start(time_s: f64) -> Self {
        Self {
            since_s: time_s,
            rel: Pose2::new(0.0, 0.0, 0.0),
        }
    }

    /// Advances the tally by one prediction step of `dt_s` with the raw odometry `input`
    /// and the corrections `bias`.
    pub fn step<M: ProcessModel + ?Sized>(
        &mut self,
        model: &M,
        input: &OdometrySample,
        bias: [f64; 2],
        dt_s: f64,
    ) -> Result<(), FilterError> {
        let (speed, steer) = corrected_input(input, bias);
        let step = model.step(&self.rel, speed, steer, dt_s)?;
        if !(step.pose.x.is_finite() && step.pose.y.is_finite() && step.pose.theta.is_finite()) {
            return Err(FilterError::NonFiniteInput("motion tally step"));
        }
        self.rel = Pose2::new(step.pose.x, step.pose.y, wrap_angle(step.pose.theta));
        Ok(())
    }
}

/// `pose` in the frame of `origin` (`origin^-1 pose`, heading wrapped), with its Jacobian
/// with respect to `[pose x, y, heading, origin x, y, heading]` (3 x 6).
pub fn relative_pose(origin: &Pose2, pose: &Pose2) -> (Pose2, Matrix3x6<f64>) {
    let (s, c) = origin.theta.sin_cos();
    let (dx, dy) = (pose.x - origin.x, pose.y - origin.y);
    let rel = Pose2::new(
        c * dx + s * dy,
        -s * dx + c * dy,
        wrap_angle(pose.theta - origin.theta),
    );
    #[rustfmt::skip]
    let jacobian = Matrix3x6::new(
        c,   s,   0.0, -c,  -s,  rel.y,
        -s,  c,   0.0,  s,  -c, -rel.x,
        0.0, 0.0, 1.0, 0.0, 0.0, -1.0,
    );
    (rel, jacobian)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_relative_pose_jacobian_matches_finite_differences() {
        // Headings either side of the wrap, so the heading row's wrap is exercised too.
        for (origin, pose) in [
            (Pose2::new(1.0, -2.0, 0.7), Pose2::new(4.5, 1.0, 1.1)),
            (Pose2::new(-3.0, 5.0, 3.1), Pose2::new(-9.0, 4.0, -3.05)),
            (Pose2::new(0.0, 0.0, -1.5), Pose2::new(0.2, -0.1, -1.52)),
        ] {
            let (_, j) = relative_pose(&origin, &pose);
            let h = 1e-7;
            let at = |x: [f64; 6]| {
                relative_pose(&Pose2::new(x[3], x[4], x[5]), &Pose2::new(x[0], x[1], x[2])).0
            };
            let x0 = [pose.x, pose.y, pose.theta, origin.x, origin.y, origin.theta];
            for col in 0..6 {
                let (mut plus, mut minus) = (x0, x0);
                plus[col] += h;
                minus[col] -= h;
                let (p, m) = (at(plus), at(minus));
                let fd = [
                    (p.x - m.x) / (2.0 * h),
                    (p.y - m.y) / (2.0 * h),
                    wrap_angle(p.theta - m.theta) / (2.0 * h),
                ];
                for (row, v) in fd.iter().enumerate() {
                    let a = j[(row, col)];
                    assert!(
                        (a - v).abs() <= 1e-6 * (1.0 + v.abs()),
                        "d rel[{row}] / d x[{col}]: analytic {a}, finite differences {v}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_relative_pose_undoes_composition() {
        let origin = Pose2::new(2.0, -1.0, 2.5);
        let (rel, _) = relative_pose(&origin, &Pose2::new(2.0, -1.0, 2.5));
        assert_eq!([rel.x, rel.y, rel.theta], [0.0, 0.0, 0.0]);
        // One metre ahead of a vehicle facing +y is (1, 0) in its frame.
        let (rel, _) = relative_pose(
            &Pose2::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
            &Pose2::new(0.0, 1.0, std::f64::consts::FRAC_PI_2),
        );
        assert!((rel.x - 1.0).abs() < 1e-12 && rel.y.abs() < 1e-12 && rel.theta.abs() < 1e-12);
    }
}
