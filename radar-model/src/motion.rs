//! The vehicle process model shared by the simulator and the filter (the paper's eq. 1-2,
//! and a bicycle model beside it), with Jacobians with respect to the pose and the inputs.
//!
//! Inputs are `u = [v, steer]` (speed m/s, steering rad). Two models:
//!
//! - [`MotionModel::Paper`]: eq. 2 as written. The steering input acts as the heading
//!   change over one step of `step_s` seconds: `a' = steer * dt / step_s`,
//!   `dx = v dt cos(theta + a')`, `dy = v dt sin(theta + a')`, `dtheta = a'`. For
//!   `dt = step_s` this is eq. 2 exactly; other `dt` scale the turn linearly.
//! - [`MotionModel::Bicycle`]: heading rate `v tan(steer) / wheelbase`, so
//!   `dtheta = v dt tan(steer) / wheelbase`; the translation follows the mid-step heading
//!   `theta + dtheta / 2` (second-order accurate in `dt`). Steering must satisfy
//!   `|steer| < MAX_BICYCLE_STEER_RAD`.
//!
//! The heading is wrapped to (-pi, pi] after every step.

use crate::error::{finite, ModelError};
use crate::geometry::{wrap_angle, Pose2};
use nalgebra::{Matrix3, Matrix3x2};

/// Largest steering magnitude (rad) the bicycle model accepts (80 degrees), keeping
/// `tan(steer)` and its derivative bounded.
pub const MAX_BICYCLE_STEER_RAD: f64 = 80.0 * std::f64::consts::PI / 180.0;

/// Control input `u = [v, steer]`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ControlInput {
    /// Forward speed (m/s).
    pub speed_mps: f64,
    /// Steering (rad), interpreted by the model.
    pub steer_rad: f64,
}

impl ControlInput {
    /// An input from speed and steering.
    pub fn new(speed_mps: f64, steer_rad: f64) -> Self {
        Self {
            speed_mps,
            steer_rad,
        }
    }
}

/// Which process model drives the pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotionModel {
    /// The paper's eq. 2; `step_s` is the sampling time over which `steer` is the heading change.
    Paper {
        /// The paper's sampling time (s).
        step_s: f64,
    },
    /// Kinematic bicycle model.
    Bicycle {
        /// Distance between the axles (m).
        wheelbase_m: f64,
    },
}

/// Jacobians of the motion step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionJacobian {
    /// `d pose' / d pose` (3 x 3).
    pub wrt_pose: Matrix3<f64>,
    /// `d pose' / d [v, steer]` (3 x 2).
    pub wrt_input: Matrix3x2<f64>,
}

impl MotionModel {
    fn check(&self, pose: &Pose2, input: &ControlInput, dt_s: f64) -> Result<(), ModelError> {
        finite(pose.x, "pose x")?;
        finite(pose.y, "pose y")?;
        finite(pose.theta, "pose theta")?;
        finite(input.speed_mps, "speed")?;
        finite(input.steer_rad, "steer")?;
        finite(dt_s, "dt")?;
        if dt_s < 0.0 {
            return Err(ModelError::InvalidSetting {
                what: "dt",
                reason: "must not be negative",
            });
        }
        match *self {
            MotionModel::Paper { step_s } => {
                if !(step_s.is_finite() && step_s > 0.0) {
                    return Err(ModelError::InvalidSetting {
                        what: "step_s",
                        reason: "must be finite and positive",
                    });
                }
            }
            MotionModel::Bicycle { wheelbase_m } => {
                if !(wheelbase_m.is_finite() && wheelbase_m > 0.0) {
                    return Err(ModelError::InvalidSetting {
                        what: "wheelbase_m",
                        reason: "must be finite and positive",
                    });
                }
                if input.steer_rad.abs() >= MAX_BICYCLE_STEER_RAD {
                    return Err(ModelError::InvalidSetting {
                        what: "steer",
                        reason: "bicycle steering must be below 80 degrees in magnitude",
                    });
                }
            }
        }
        Ok(())
    }

    /// The input that drives this model through a motion of `distance_m` forward (negative:
    /// backward) and `heading_change_rad` over `dt_s` seconds: the inverse of
    /// [`MotionModel::predict`] for the speed and the turn, used to drive the filter with a
    /// motion measured by other means (radar odometry). The bicycle cannot turn standing
    /// still: below 1 cm of travel its steering is 0, and it is clamped inside
    /// [`MAX_BICYCLE_STEER_RAD`]. `None` for a non-finite argument or `dt_s <= 0`.
    pub fn input_for(
        &self,
        distance_m: f64,
        heading_change_rad: f64,
        dt_s: f64,
    ) -> Option<ControlInput> {
        if !(distance_m.is_finite() && heading_change_rad.is_finite() && dt_s.is_finite())
            || dt_s <= 0.0
        {
            return None;
        }
        let speed_mps = distance_m / dt_s;
        let steer_rad = match *self {
            MotionModel::Paper { step_s } => heading_change_rad * step_s / dt_s,
            MotionModel::Bicycle { wheelbase_m } => {
                if distance_m.abs() < 0.01 {
                    0.0
                } else {
                    let limit = MAX_BICYCLE_STEER_RAD - 1e-6;
                    (heading_change_rad * wheelbase_m / distance_m)
                        .atan()
                        .clamp(-limit, limit)
                }
            }
        };
        steer_rad
            .is_finite()
            .then(|| ControlInput::new(speed_mps, steer_rad))
    }

    /// Moves `pose` by `input` over `dt_s` seconds (eq. 2 or the bicycle model).
    ///
    /// # Errors
    /// Non-finite inputs, negative `dt_s`, invalid model settings or bicycle steering.
    pub fn predict(
        &self,
        pose: &Pose2,
        input: &ControlInput,
        dt_s: f64,
    ) -> Result<Pose2, ModelError> {
        self.predict_with_jacobian(pose, input, dt_s)
            .map(|(p, _)| p)
    }

    /// Moves `pose` and returns the Jacobians with respect to the pose and `[v, steer]`.
    ///
    /// # Errors
    /// As [`MotionModel::predict`].
    pub fn predict_with_jacobian(
        &self,
        pose: &Pose2,
        input: &ControlInput,
        dt_s: f64,
    ) -> Result<(Pose2, MotionJacobian), ModelError> {
        self.check(pose, input, dt_s)?;
        let v = input.speed_mps;
        let s = input.steer_rad;
        // Heading change, its derivatives wrt (v, steer), and the fraction of it that sets
        // the translation direction (1 for the paper's eq. 2, 1/2 for the bicycle midpoint).
        let (dtheta, d_dtheta_dv, d_dtheta_ds, frac) = match *self {
            MotionModel::Paper { step_s } => (s * dt_s / step_s, 0.0, dt_s / step_s, 1.0),
            MotionModel::Bicycle { wheelbase_m } => {
                let t = s.tan();
                let sec2 = 1.0 + t * t;
                (
                    v * dt_s * t / wheelbase_m,
                    dt_s * t / wheelbase_m,
                    v * dt_s * sec2 / wheelbase_m,
                    0.5,
                )
            }
        };
        let phi = pose.theta + frac * dtheta;
        let (sin_phi, cos_phi) = phi.sin_cos();
        let dist = v * dt_s;
        let next = Pose2 {
            x: pose.x + dist * cos_phi,
            y: pose.y + dist * sin_phi,
            theta: wrap_angle(pose.theta + dtheta),
        };
        let wrt_pose = Matrix3::new(
            1.0,
            0.0,
            -dist * sin_phi,
            0.0,
            1.0,
            dist * cos_phi,
            0.0,
            0.0,
            1.0,
        );
        let wrt_input = Matrix3x2::new(
            dt_s * cos_phi - dist * sin_phi * frac * d_dtheta_dv,
            -dist * sin_phi * frac * d_dtheta_ds,
            dt_s * sin_phi + dist * cos_phi * frac * d_dtheta_dv,
            dist * cos_phi * frac * d_dtheta_ds,
            d_dtheta_dv,
            d_dtheta_ds,
        );
        Ok((
            next,
            MotionJacobian {
                wrt_pose,
                wrt_input,
            },
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_input_for_a_motion_drives_the_model_through_that_motion() {
        for model in [
            MotionModel::Paper { step_s: 0.05 },
            MotionModel::Bicycle { wheelbase_m: 2.7 },
        ] {
            for (d, dth) in [(2.5, 0.04), (-0.8, -0.01), (3.0, 0.0), (1.0, -0.3)] {
                let u = model.input_for(d, dth, 0.25).expect("finite");
                let end = model
                    .predict(&Pose2::new(0.0, 0.0, 0.0), &u, 0.25)
                    .expect("valid");
                assert!(
                    (end.theta - dth).abs() < 1e-9,
                    "{model:?} {d} {dth}: {end:?}"
                );
                assert!((end.x.hypot(end.y) - d.abs()).abs() < 1e-9, "{end:?}");
            }
            assert_eq!(model.input_for(1.0, 0.1, 0.0), None);
            assert_eq!(model.input_for(f64::NAN, 0.1, 0.25), None);
        }
        let still = MotionModel::Bicycle { wheelbase_m: 2.7 }
            .input_for(0.0, 0.2, 0.25)
            .expect("finite");
        assert_eq!(still.steer_rad, 0.0, "a bicycle cannot turn standing still");
    }
}
