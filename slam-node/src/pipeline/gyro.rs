//! The gyro in the filter's prediction (radar-only driving with a yaw-rate source).
//!
//! Radar only, the process model's input is the motion the registration measured over the
//! last rotation, held for the next (constant velocity): a turn's onset is not foreseen, and
//! the registration, started from that prediction, misses part of it. With a gyro the turn
//! comes from the gyro instead: each sample, when the radar's clock reaches it, becomes the
//! filter's input from its time on (the speed held from the registration, the steering the
//! paper model's for the sample's yaw rate), so the prediction over a rotation integrates
//! the gyro over the samples' timestamps, the registration starts from that prediction (the
//! filter's motion since the rotation's mark) and still measures the whole motion.
//!
//! The gyro's errors are in the process model: its white noise (density `N`, rad/s/sqrt(Hz))
//! is the steering input's noise, `sigma_steer = N step_s / sqrt(correlation_s)`, so that the
//! heading's variance grows by `N^2` per second as the integrated rate's does (the filter's
//! input noise has spectral density `sigma^2 correlation_s`, `slam_filter::predict`); its
//! bias is the filter's steering offset `b` (`-bias step_s`), estimated from the
//! registrations with the configured prior and random walk. No IO.

use std::collections::VecDeque;

use radar_model::motion::MotionModel;
use slam_filter::OdometrySample;

use super::ekf::DaemonEkf;
use crate::source::gyro::GyroSample;

/// How the pipeline uses a gyro.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroUse {
    /// Samples turning faster than this (rad/s, either way) are refused.
    pub max_yaw_rate_rad_s: f64,
}

/// Radar only with a gyro: `[odometry]`'s steering noise, steering offset prior and walk
/// are the gyro's (see the module's documentation), in the paper model's steering units.
pub fn model_in_process_noise(
    o: &mut config::RawOdometry,
    gyro: &config::GyroSettings,
    correlation_s: f64,
) {
    let step_s = o.step_s.unwrap_or(config::odometry::DEFAULT_STEP_S);
    let density = gyro.noise_density_rad_s_per_sqrt_hz.get();
    o.sigma_steer_rad = density * step_s / correlation_s.max(1e-6).sqrt();
    o.steer_bias_std_rad = gyro.bias_std_rad_s.get() * step_s;
    o.steer_bias_walk_rad_per_sqrt_s = gyro.bias_walk_rad_s_per_sqrt_s.get() * step_s;
}

/// The filter's input for a gyro sample: the held speed, the steering that turns at the
/// sample's rate (the paper model's `rate * step_s`; the bicycle's at the held speed).
pub fn input_for(
    motion: &MotionModel,
    held: &OdometrySample,
    sample: &GyroSample,
) -> Option<OdometrySample> {
    // Over one second, the heading change is the rate.
    let input = motion.input_for(held.speed_mps, sample.yaw_rate_rad_s, 1.0)?;
    Some(OdometrySample {
        timestamp_s: sample.timestamp_s,
        speed_mps: held.speed_mps,
        steer_rad: input.steer_rad,
    })
}

/// Samples up to this many are held for the radar's clock to reach them (40 s at 100 Hz);
/// past it the oldest is dropped and counted.
pub const GYRO_QUEUE: usize = 4096;

/// Gives the filter every queued sample up to `time_s`: each is the input from its time
/// on. A sample before the filter has started (no speed yet) or older than its state is
/// dropped and counted.
pub fn apply_until(queue: &mut GyroQueue, ekf: &mut DaemonEkf, motion: &MotionModel, time_s: f64) {
    while let Some(s) = queue.pop_until(time_s) {
        let input = ekf
            .held_odometry()
            .filter(|_| s.timestamp_s >= ekf.state().time_s())
            .and_then(|held| input_for(motion, &held, &s));
        match input.map(|i| ekf.apply_odometry(i)) {
            Some(Ok(())) => queue.applied(),
            _ => queue.dropped(),
        }
    }
}

/// The gyro's figures for the summary.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct GyroSummary {
    /// What happened to its samples.
    pub counts: GyroCounts,
    /// The bias the filter estimated at the end and its standard deviation, rad/s (the
    /// paper model's steering offset over its step, sign reversed).
    pub bias_rad_s: Option<(f64, f64)>,
}

impl GyroSummary {
    /// From the queue's counts and the filter's odometry corrections.
    pub fn new(
        counts: GyroCounts,
        motion: &MotionModel,
        corrections: Option<([f64; 2], [f64; 2])>,
    ) -> Self {
        let bias_rad_s = match (motion, corrections) {
            (MotionModel::Paper { step_s }, Some(([_, b], [_, sb]))) if *step_s > 0.0 => {
                Some((-b / step_s, sb / step_s))
            }
            _ => None,
        };
        Self { counts, bias_rad_s }
    }
}

/// What happened to the gyro's samples.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct GyroCounts {
    /// Samples received.
    pub received: u64,
    /// Samples given to the filter.
    pub applied: u64,
    /// Refused: not finite, out of time order, or faster than the limit.
    pub refused: u64,
    /// Dropped: older than the filter (late), before it started, or the queue full.
    pub dropped: u64,
}

/// Samples not yet applied, in time order, bounded.
#[derive(Debug)]
pub struct GyroQueue {
    queue: VecDeque<GyroSample>,
    limit: GyroUse,
    latest_s: Option<f64>,
    counts: GyroCounts,
}

impl GyroQueue {
    /// An empty queue refusing samples past `limit`.
    pub fn new(limit: GyroUse) -> Self {
        Self {
            queue: VecDeque::new(),
            limit,
            latest_s: None,
            counts: GyroCounts::default(),
        }
    }

    /// Adds a sample; a sample not finite, older than the newest, or turning faster than
    /// the limit is refused and counted.
    pub fn push(&mut self, s: GyroSample) {
        self.counts.received += 1;
        let believable = s.timestamp_s.is_finite()
            && s.yaw_rate_rad_s.is_finite()
            && s.yaw_rate_rad_s.abs() <= self.limit.max_yaw_rate_rad_s
            && self.latest_s.is_none_or(|t| s.timestamp_s > t);
        if !believable {
            self.counts.refused += 1;
            return;
        }
        self.latest_s = Some(s.timestamp_s);
        self.queue.push_back(s);
        if self.queue.len() > GYRO_QUEUE {
            self.queue.pop_front();
            self.counts.dropped += 1;
        }
    }

    /// Removes and returns the next sample at or before `time_s`.
    pub fn pop_until(&mut self, time_s: f64) -> Option<GyroSample> {
        if self.queue.front().is_some_and(|s| s.timestamp_s <= time_s) {
            return self.queue.pop_front();
        }
        None
    }

    /// Newest sample time received.
    pub fn latest_s(&self) -> Option<f64> {
        self.latest_s
    }

    /// Counts a sample the filter could not take.
    pub fn dropped(&mut self) {
        self.counts.dropped += 1;
    }

    /// Counts a sample the filter took.
    pub fn applied(&mut self) {
        self.counts.applied += 1;
    }

    /// What happened so far.
    pub fn counts(&self) -> GyroCounts {
        self.counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn g(t: f64, w: f64) -> GyroSample {
        GyroSample {
            timestamp_s: t,
            yaw_rate_rad_s: w,
        }
    }

    #[test]
    fn samples_come_out_in_order_up_to_the_asked_time_and_bad_ones_are_refused() {
        let mut q = GyroQueue::new(GyroUse {
            max_yaw_rate_rad_s: 1.0,
        });
        q.push(g(1.0, 0.1));
        q.push(g(1.01, 0.2));
        q.push(g(1.005, 0.2)); // out of order
        q.push(g(1.02, f64::NAN));
        q.push(g(1.03, 5.0)); // too fast
        q.push(g(1.04, -0.3));
        assert_eq!(q.counts().refused, 3);
        assert_eq!(q.pop_until(1.015).map(|s| s.yaw_rate_rad_s), Some(0.1));
        assert_eq!(q.pop_until(1.015).map(|s| s.yaw_rate_rad_s), Some(0.2));
        assert!(q.pop_until(1.015).is_none());
        assert_eq!(q.latest_s(), Some(1.04));
    }

    #[test]
    fn the_queue_is_bounded() {
        let mut q = GyroQueue::new(GyroUse {
            max_yaw_rate_rad_s: 1.0,
        });
        for k in 0..(GYRO_QUEUE + 10) {
            q.push(g(k as f64, 0.0));
        }
        assert_eq!(q.counts().dropped, 10);
        assert_eq!(q.pop_until(1e9).map(|s| s.timestamp_s), Some(10.0));
    }

    #[test]
    fn the_paper_models_steering_turns_at_the_gyros_rate() {
        let motion = MotionModel::Paper { step_s: 0.05 };
        let held = OdometrySample {
            timestamp_s: 0.0,
            speed_mps: 8.0,
            steer_rad: 0.0,
        };
        let input = input_for(&motion, &held, &g(2.0, 0.3)).unwrap();
        assert_eq!(input.timestamp_s, 2.0);
        assert_eq!(input.speed_mps, 8.0);
        assert!((input.steer_rad - 0.015).abs() < 1e-12);
    }

    #[test]
    fn the_process_noise_grows_the_heading_as_the_gyros_white_noise_does() {
        let mut o = config::RawOdometry::default();
        let gyro = config::GyroSettings::default();
        model_in_process_noise(&mut o, &gyro, 0.05);
        // Heading variance rate of the paper model: sigma^2 correlation / step^2.
        let rate = o.sigma_steer_rad.powi(2) * 0.05 / 0.05f64.powi(2);
        let want = gyro.noise_density_rad_s_per_sqrt_hz.get().powi(2);
        assert!((rate / want - 1.0).abs() < 1e-9, "{rate} vs {want}");
        assert!((o.steer_bias_std_rad - 0.01 * 0.05).abs() < 1e-15);
    }
}
