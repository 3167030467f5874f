//! A gyro made from a recording's ground truth (`--gyro-from-truth`): the yaw rate the true
//! trajectory turns at, with the simulator's gyro bias and white noise
//! ([`sim_sensor::gyro::GyroNoise`]), so that a recording without an IMU runs with the gyro a
//! vehicle would have. Sample `k`, stamped `start + k / rate`, carries the true heading's
//! change over `[t_k, t_k + 1 / rate]` divided by the period (the rate the filter holds over
//! that interval), plus the bias and the noise (drawn from `seed` and `k`). No IO.

use std::time::Duration;

use radar_model::geometry::wrap_angle;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::{GyroError, GyroPoll, GyroSample, GyroSource};
use crate::pipeline::TruthOracle;

/// Random stream of the truth gyro's noise.
const STREAM: u64 = (1 << 62) + 2;

/// Samples of a truth trajectory, made as they are asked for.
#[derive(Debug)]
pub struct TruthGyro {
    truth: Box<dyn TruthOracle>,
    start_s: f64,
    end_s: f64,
    period_s: f64,
    sample_sigma: f64,
    bias_rad_s: f64,
    seed: u64,
    next: u64,
}

impl TruthGyro {
    /// Samples of `truth` from `start_s` to `end_s` at `noise.rate_hz`, with its bias and
    /// noise density.
    pub fn new(
        truth: Box<dyn TruthOracle>,
        start_s: f64,
        end_s: f64,
        noise: sim_sensor::gyro::GyroNoise,
        seed: u64,
    ) -> Self {
        let rate = if noise.rate_hz.is_finite() && noise.rate_hz > 0.0 {
            noise.rate_hz
        } else {
            100.0
        };
        Self {
            truth,
            start_s,
            end_s,
            period_s: 1.0 / rate,
            sample_sigma: noise.noise_density_rad_s_per_sqrt_hz * rate.sqrt(),
            bias_rad_s: noise.bias_rad_s,
            seed,
            next: 0,
        }
    }

    fn sample(&self, k: u64) -> Option<GyroSample> {
        let t = self.start_s + k as f64 * self.period_s;
        let (a, b) = (
            self.truth.pose_at(t)?,
            self.truth.pose_at(t + self.period_s)?,
        );
        let rate = wrap_angle(b.theta - a.theta) / self.period_s;
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ k.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        rng.set_stream(STREAM);
        let n: f64 = StandardNormal.sample(&mut rng);
        Some(GyroSample {
            timestamp_s: t,
            yaw_rate_rad_s: rate + self.bias_rad_s + n * self.sample_sigma,
        })
    }
}

impl GyroSource for TruthGyro {
    fn poll_next(&mut self, _timeout: Duration) -> Result<GyroPoll, GyroError> {
        loop {
            let t = self.start_s + self.next as f64 * self.period_s;
            if !(t.is_finite() && t <= self.end_s) {
                return Ok(GyroPoll::Ended);
            }
            let k = self.next;
            self.next += 1;
            // A time the truth does not cover (a gap) gives no sample.
            if let Some(s) = self.sample(k) {
                return Ok(GyroPoll::Sample(s));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::truth::TrueFeature;
    use radar_model::geometry::Pose2;

    /// A vehicle turning at 0.2 rad/s.
    #[derive(Debug)]
    struct Turning;

    impl TruthOracle for Turning {
        fn pose_at(&self, t: f64) -> Option<Pose2> {
            (0.0..=100.0)
                .contains(&t)
                .then(|| Pose2::new(t, 0.0, wrap_angle(0.2 * t)))
        }
        fn features(&self) -> &[TrueFeature] {
            &[]
        }
    }

    #[test]
    fn the_samples_are_the_true_rate_plus_the_bias_and_noise() {
        let noise = sim_sensor::gyro::GyroNoise {
            rate_hz: 100.0,
            noise_density_rad_s_per_sqrt_hz: 1e-3,
            bias_rad_s: 0.005,
        };
        let mut g = TruthGyro::new(Box::new(Turning), 1.0, 60.0, noise, 7);
        let mut rates = Vec::new();
        while let Ok(GyroPoll::Sample(s)) = g.poll_next(Duration::ZERO) {
            rates.push(s.yaw_rate_rad_s);
        }
        assert_eq!(rates.len(), 5901);
        let mean = rates.iter().sum::<f64>() / rates.len() as f64;
        // 0.2 + 0.005; per-sample sigma 0.01, standard error 1.3e-4.
        assert!((mean - 0.205).abs() < 6e-4, "{mean}");
    }
}
