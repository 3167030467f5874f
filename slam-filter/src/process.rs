//! What the vehicle's odometry gives the filter and how a process model steps with it: the
//! odometry sample, the process model's step and Jacobians, and the input corrected for the
//! estimated speed scale and steering offset. A leaf, used by the prediction
//! ([`super::predict`]) and the motion tally ([`super::motion_tally`]) alike.

use nalgebra::{Matrix3, Matrix3x2};
use radar_model::geometry::Pose2;

use super::error::FilterError;

/// One odometry sample: what the vehicle reports at `timestamp_s`, held until the next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometrySample {
    /// Unix time (s).
    pub timestamp_s: f64,
    /// Forward speed (m/s).
    pub speed_mps: f64,
    /// Steering input (rad), interpreted by the process model.
    pub steer_rad: f64,
}

impl OdometrySample {
    /// Rejects NaN and infinities.
    pub fn check(&self) -> Result<(), FilterError> {
        for (what, value) in [
            ("timestamp_s", self.timestamp_s),
            ("speed_mps", self.speed_mps),
            ("steer_rad", self.steer_rad),
        ] {
            if !value.is_finite() {
                return Err(FilterError::NonFiniteOdometry { what, value });
            }
        }
        Ok(())
    }
}

/// The pose after one step and the step's Jacobians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionStep {
    /// The new pose (heading wrapped).
    pub pose: Pose2,
    /// `d f / d [x, y, theta]`.
    pub wrt_pose: Matrix3<f64>,
    /// `d f / d [speed, steer]`.
    pub wrt_input: Matrix3x2<f64>,
}

/// A vehicle process model with its Jacobians (implemented for radar-model's
/// [`radar_model::motion::MotionModel`] in [`super::radar`]).
pub trait ProcessModel {
    /// Moves `pose` by `speed_mps`, `steer_rad` over `dt_s`.
    fn step(
        &self,
        pose: &Pose2,
        speed_mps: f64,
        steer_rad: f64,
        dt_s: f64,
    ) -> Result<MotionStep, FilterError>;
}

/// The inputs the process model is driven by: the odometry corrected by the state's
/// `[k, b]` (see [`crate::state::SPEED_SCALE_INDEX`]).
pub fn corrected_input(input: &OdometrySample, bias: [f64; 2]) -> (f64, f64) {
    (input.speed_mps * (1.0 + bias[0]), input.steer_rad + bias[1])
}
