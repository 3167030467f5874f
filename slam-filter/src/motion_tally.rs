//! The motion since a mark, as the odometry drives it: the vehicle's pose relative to where
//! it was at the mark, with its Jacobian with respect to the odometry corrections `k`, `b`
//! and the covariance the odometry's white input noise has added to it since.
//!
//! A relative-motion measurement from the radar itself (scan-to-scan registration of two
//! rotations, see [`crate::Ekf::observe_motion_since_mark`]) is compared with this tally:
//! `z = T_mark^-1 T_now + e`, predicted as `h(k, b) = tally.rel`, so that
//! `z - h = J (k - k^, b - b^) + w + e` with `J` = [`MotionTally::wrt_bias`], `w` the input
//! noise since the mark ([`MotionTally::noise`]) and `e` the registration's error. The
//! measurement observes the corrections only; the pose follows through its correlation with
//! them. The input noise `w` is also in the pose's own covariance; the update treats it as
//! independent of the state, which leaves the pose's share of it uncorrected (conservative)
//! instead of counting it twice.
//!
//! The tally is book-keeping next to the estimate, advanced by every prediction step
//! ([`crate::predict::predict_step`]) with the same inputs, in O(1).

use nalgebra::{Matrix2, Matrix3, Matrix3x2};
use radar_model::geometry::{wrap_angle, Pose2};

use super::error::FilterError;
use super::predict::{corrected_input, OdometrySample, ProcessModel};

/// The motion since a mark (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionTally {
    /// The state's time at the mark (s).
    pub since_s: f64,
    /// The pose now in the frame of the pose at the mark.
    pub rel: Pose2,
    /// `d rel / d [k, b]`.
    pub wrt_bias: Matrix3x2<f64>,
    /// Covariance of `rel` from the odometry's input noise since the mark.
    pub noise: Matrix3<f64>,
}

impl MotionTally {
    /// A tally that starts at `time_s`: no motion yet.
    pub fn start(time_s: f64) -> Self {
        Self {
            since_s: time_s,
            rel: Pose2::new(0.0, 0.0, 0.0),
            wrt_bias: Matrix3x2::zeros(),
            noise: Matrix3::zeros(),
        }
    }

    /// Advances the tally by one prediction step of `dt_s` with the raw odometry `input`,
    /// the corrections `bias` and the inputs' covariance `q` over the step.
    pub fn step<M: ProcessModel + ?Sized>(
        &mut self,
        model: &M,
        input: &OdometrySample,
        bias: [f64; 2],
        q: &Matrix2<f64>,
        dt_s: f64,
    ) -> Result<(), FilterError> {
        let (speed, steer) = corrected_input(input, bias);
        let step = model.step(&self.rel, speed, steer, dt_s)?;
        let f = step.wrt_pose;
        let g = step.wrt_input;
        // d speed / d k = raw speed, d steer / d b = 1.
        let f_b = Matrix3x2::from_columns(&[g.column(0) * input.speed_mps, g.column(1).into()]);
        let wrt_bias = f * self.wrt_bias + f_b;
        let noise = f * self.noise * f.transpose() + g * q * g.transpose();
        if wrt_bias.iter().chain(noise.iter()).any(|v| !v.is_finite()) {
            return Err(FilterError::NonFiniteInput("motion tally step"));
        }
        self.wrt_bias = wrt_bias;
        self.noise = 0.5 * (noise + noise.transpose());
        self.rel = Pose2::new(step.pose.x, step.pose.y, wrap_angle(step.pose.theta));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use radar_model::motion::MotionModel;

    fn drive(k: f64, b: f64, samples: &[OdometrySample]) -> MotionTally {
        let model = MotionModel::Bicycle { wheelbase_m: 2.7 };
        let mut t = MotionTally::start(0.0);
        for w in samples.windows(2) {
            t.step(
                &model,
                &w[0],
                [k, b],
                &Matrix2::identity(),
                w[1].timestamp_s - w[0].timestamp_s,
            )
            .unwrap();
        }
        t
    }

    #[test]
    fn the_jacobian_with_respect_to_the_corrections_matches_finite_differences() {
        let samples: Vec<OdometrySample> = (0..=25)
            .map(|i| OdometrySample {
                timestamp_s: f64::from(i) * 0.01,
                speed_mps: 8.0 + 0.1 * f64::from(i),
                steer_rad: 0.05 - 0.004 * f64::from(i),
            })
            .collect();
        let (k, b) = (0.03, -0.004);
        let t = drive(k, b, &samples);
        let h = 1e-7;
        for (col, (dk, db)) in [(h, 0.0), (0.0, h)].into_iter().enumerate() {
            let plus = drive(k + dk, b + db, &samples).rel;
            let minus = drive(k - dk, b - db, &samples).rel;
            let fd = [
                (plus.x - minus.x) / (2.0 * h),
                (plus.y - minus.y) / (2.0 * h),
                wrap_angle(plus.theta - minus.theta) / (2.0 * h),
            ];
            for (row, v) in fd.iter().enumerate() {
                let a = t.wrt_bias[(row, col)];
                assert!(
                    (a - v).abs() <= 1e-5 * (1.0 + v.abs()),
                    "d rel[{row}] / d bias[{col}]: analytic {a}, finite differences {v}"
                );
            }
        }
        // The noise grew and is symmetric positive definite after a curved drive.
        assert_eq!(t.noise, t.noise.transpose());
        assert!(t.noise.cholesky().is_some());
    }
}
