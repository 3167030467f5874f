//! The vehicle's gyro (its yaw rate), served on its own TCP port in the gyro line format of
//! `docs/contracts.md`: ASCII, one sample a line, a header line
//! `# gyro v1 timestamp_s yaw_rate_rad_s`, then `<timestamp_s> <yaw_rate_rad_s>` with the
//! timestamp in Unix seconds (9 decimals, exact from integer nanoseconds).
//!
//! Sample `j` is stamped `start + j / rate` and carries the true yaw rate then (the scene's
//! motion model applied to the controls in force: the rate the truth turns at), plus the
//! configured constant bias and white noise of density `noise_density_rad_s_per_sqrt_hz`
//! (each sample's standard deviation is the density times `sqrt(rate_hz)`, so the heading
//! integrated from the samples random-walks by the density per sqrt(s) whatever the rate),
//! drawn from the scene's seed and `j`: every client reads identical samples. The port is
//! paced, replayed on reconnect and slotted as the odometry port is ([`crate::odometry`]).

use std::fmt::Write as _;

use radar_model::geometry::Pose2;
use radar_model::motion::{ControlInput, MotionModel};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::odometry::{LineStream, REPLAY_ON_CONNECT_S};
use crate::trajectory::Trajectory;

/// The header line (without its newline).
pub const HEADER: &str = "# gyro v1 timestamp_s yaw_rate_rad_s";
/// Random stream reserved for gyro noise.
const GYRO_STREAM: u64 = (1 << 62) + 1;
/// The interval over which the true yaw rate is read from the motion model, s.
const RATE_DT_S: f64 = 1e-3;

/// The simulated gyro's errors and rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroNoise {
    /// Samples per second.
    pub rate_hz: f64,
    /// White-noise density, rad/s/sqrt(Hz).
    pub noise_density_rad_s_per_sqrt_hz: f64,
    /// Constant bias, rad/s.
    pub bias_rad_s: f64,
}

impl Default for GyroNoise {
    /// 100 Hz, 1.75e-4 rad/s/sqrt(Hz), 0.005 rad/s bias (`config::gyro`'s defaults: a
    /// rate-grade MEMS part, uncalibrated).
    fn default() -> Self {
        Self {
            rate_hz: 100.0,
            noise_density_rad_s_per_sqrt_hz: 1.75e-4,
            bias_rad_s: 0.005,
        }
    }
}

/// One gyro sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroRecord {
    /// Unix time, nanoseconds.
    pub unix_ns: u64,
    /// Measured yaw rate, rad/s (counter-clockwise positive).
    pub yaw_rate_rad_s: f64,
}

impl GyroRecord {
    /// Appends the sample's line (with its newline) to `out`.
    pub fn write_line(&self, out: &mut String) {
        let _ = writeln!(
            out,
            "{}.{:09} {:.7}",
            self.unix_ns / 1_000_000_000,
            self.unix_ns % 1_000_000_000,
            self.yaw_rate_rad_s
        );
    }
}

/// The yaw rate `model` turns at under `controls` (speed, steer), rad/s; 0 when the model
/// refuses them.
pub fn yaw_rate_of(model: &MotionModel, controls: (f64, f64)) -> f64 {
    model
        .predict(
            &Pose2::new(0.0, 0.0, 0.0),
            &ControlInput::new(controls.0, controls.1),
            RATE_DT_S,
        )
        .map_or(0.0, |p| p.theta / RATE_DT_S)
}

/// Generates the samples of one scene.
#[derive(Debug, Clone)]
pub struct GyroGenerator {
    noise: GyroNoise,
    seed: u64,
    period_ns: u64,
    start_unix_ns: u64,
}

impl GyroGenerator {
    /// A generator for a scene starting at `start_unix_ns`.
    pub fn new(noise: GyroNoise, seed: u64, start_unix_ns: u64) -> Self {
        let period_ns = (1e9 / noise.rate_hz).round().max(1.0) as u64;
        Self {
            noise,
            seed,
            period_ns,
            start_unix_ns,
        }
    }

    /// One sample's noise standard deviation, rad/s.
    pub fn sample_sigma_rad_s(&self) -> f64 {
        self.noise.noise_density_rad_s_per_sqrt_hz * (1e9 / self.period_ns as f64).sqrt()
    }

    /// Sample `j`, given the true yaw rate at its time.
    pub fn record(&self, j: u64, true_rate_rad_s: f64) -> GyroRecord {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ j.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        rng.set_stream(GYRO_STREAM);
        let n: f64 = StandardNormal.sample(&mut rng);
        GyroRecord {
            unix_ns: self
                .start_unix_ns
                .saturating_add(j.saturating_mul(self.period_ns)),
            yaw_rate_rad_s: true_rate_rad_s + self.noise.bias_rad_s + n * self.sample_sigma_rad_s(),
        }
    }
}

impl LineStream for GyroGenerator {
    const WHAT: &'static str = "gyro";

    fn header(&self) -> &'static str {
        HEADER
    }

    fn period_ns(&self) -> u64 {
        self.period_ns
    }

    fn replay_records(&self) -> u64 {
        (REPLAY_ON_CONNECT_S * 1e9 / self.period_ns as f64).ceil() as u64
    }

    fn write_line(&self, j: u64, trajectory: &Trajectory, t_ns: u64, out: &mut String) {
        let rate = yaw_rate_of(&trajectory.model(), trajectory.controls_at(t_ns));
        self.record(j, rate).write_line(out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sample_line_has_nine_exact_decimals_and_one_space() {
        let r = GyroRecord {
            unix_ns: 1_704_067_200_010_000_001,
            yaw_rate_rad_s: -0.0125,
        };
        let mut s = String::new();
        r.write_line(&mut s);
        assert_eq!(s, "1704067200.010000001 -0.0125000\n");
    }

    #[test]
    fn the_true_rate_is_the_motion_models() {
        let paper = MotionModel::Paper { step_s: 0.05 };
        assert!((yaw_rate_of(&paper, (5.0, 0.01)) - 0.2).abs() < 1e-9);
        let bicycle = MotionModel::Bicycle { wheelbase_m: 2.5 };
        let want = 5.0 * 0.1f64.tan() / 2.5;
        assert!((yaw_rate_of(&bicycle, (5.0, 0.1)) - want).abs() < 1e-6);
    }

    #[test]
    fn samples_are_reproducible_and_carry_the_configured_bias_and_noise_density() {
        let noise = GyroNoise {
            rate_hz: 100.0,
            noise_density_rad_s_per_sqrt_hz: 2e-3,
            bias_rad_s: 0.005,
        };
        let g = GyroGenerator::new(noise, 3, 0);
        assert_eq!(g.record(5, 0.1), g.record(5, 0.1));
        let n = 20_000;
        let (mut sum, mut sum2) = (0.0, 0.0);
        for j in 0..n {
            let r = g.record(j, 0.1).yaw_rate_rad_s - 0.1;
            sum += r;
            sum2 += r * r;
        }
        let nf = n as f64;
        let mean = sum / nf;
        let sd = (sum2 / nf - mean * mean).sqrt();
        // Per sample 2e-3 * sqrt(100) = 0.02 rad/s; mean within 4 standard errors.
        assert!((mean - 0.005).abs() < 4.0 * 0.02 / nf.sqrt(), "{mean}");
        assert!((sd - 0.02).abs() < 0.0006, "{sd}");
    }
}
