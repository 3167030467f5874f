//! What the stages count over a run, parts of the run's summary: the beams the filter did
//! not take, and what radar odometry did. Plain counters, a leaf: the stages that count and
//! the summary that reports both import them from here.

use radar_odometry::MatcherCounts;
use serde::Serialize;
use slam_filter::MotionOutcome;

/// Beams the filter did not take, by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct RefusalCounts {
    /// No odometry had been received yet.
    pub no_odometry: u64,
    /// The odometry was older than the stale limit.
    pub stale_odometry: u64,
    /// The beam was older than the filter's state.
    pub late_beams: u64,
}

/// Consecutive pairs of heading errors [`ScanMatchCounts::heading_error_lag_one`] needs: a
/// correlation over n pairs is uncertain by about 1/sqrt(n), 0.18 at 30.
pub const MIN_LAG_PAIRS: u64 = 30;

/// What radar odometry did over a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ScanMatchCounts {
    /// What the registrations did (tried, failed, retried, probed ...): the matcher's own
    /// counts, flattened into the summary's JSON.
    #[serde(flatten)]
    pub registrations: MatcherCounts,
    /// Measurements the filter applied.
    pub applied: u64,
    /// Measurements the filter's gate refused.
    pub gated: u64,
    /// Whether radar odometry drove the filter's prediction (no wheel odometry).
    pub drives: bool,
    /// Driving: rotations with no beam for the filter, whose end the filter's clock was
    /// brought to by the motion held before the registration.
    pub still_clock: u64,
    /// On the radar alone without a gyro: rotations whose registration turned more than
    /// `MANOEUVRE_HEADING_RAD` away from the held motion (a turn's onset or end), whose
    /// heading process noise was widened by the difference.
    pub manoeuvres: u64,
    /// Sum of the applied measurements' NIS (3 dof each).
    pub nis_sum: f64,
    /// Registrations compared with the true motion over the same interval (with ground
    /// truth only).
    pub truth_compared: u64,
    /// Sum of `measured - true` motion, `[x m, y m, heading rad]` in the frame at the mark.
    pub truth_error_sum: [f64; 3],
    /// Sum of its squares.
    pub truth_error_sq_sum: [f64; 3],
    /// Sum of each component's squared error over the variance the registration was taken
    /// with (the diagonal of the covariance given to the filter): about one per
    /// registration when a registration is as good as it says.
    pub truth_normalised_sq_sum: [f64; 3],
    /// Consecutive rotations' heading errors (rad) both compared with the truth: pairs,
    /// the sum of their products, and the sums of the later and of the earlier of each
    /// pair, for their lag-one correlation ([`Self::heading_error_lag_one`]).
    pub heading_lag_pairs: u64,
    /// See [`Self::heading_lag_pairs`].
    pub heading_lag_product_sum: f64,
    /// See [`Self::heading_lag_pairs`].
    pub heading_lag_sums: [f64; 2],
    /// The previous rotation's heading error, while the rotations compared run on without
    /// a gap (not reported).
    #[serde(skip)]
    pub last_heading_error: Option<f64>,
    /// Radar odometry alone against the truth (with ground truth, over 100 m or more):
    /// each registration's motion chained from the first, nothing fused.
    pub chained: Option<ChainedDrift>,
}

/// KITTI-style drift (`slam_filter::drift`) of radar odometry's own trajectory: each
/// registration's motion chained from the first (the odometry's prediction over a rotation
/// whose registration failed), against the truth chained over the same intervals. What the
/// registrations alone would give, as the radar odometry literature scores its methods,
/// beside the filter's odometry that fuses them with the map and the prediction.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ChainedDrift {
    /// Mean translation error over the segments (% of their length).
    pub translation_percent: f64,
    /// Mean rotation error (deg per 100 m).
    pub rotation_deg_per_100m: f64,
    /// Segments averaged.
    pub segments: usize,
}

impl ScanMatchCounts {
    /// Mean and standard deviation of the registrations' error against the true motion,
    /// per component `[x m, y m, heading rad]`; `None` with fewer than two comparisons.
    pub fn truth_error(&self) -> Option<[(f64, f64); 3]> {
        if self.truth_compared < 2 {
            return None;
        }
        let n = self.truth_compared as f64;
        Some(std::array::from_fn(|i| {
            let mean = self.truth_error_sum[i] / n;
            let var = (self.truth_error_sq_sum[i] - n * mean * mean) / (n - 1.0);
            (mean, var.max(0.0).sqrt())
        }))
    }

    /// Each component's error over the standard deviation the registrations were taken
    /// with, as an RMS over the registrations compared, `[x, y, heading]`: 1 for
    /// registrations as good as they say, above 1 where the filter was told they were
    /// better than they are. `None` with fewer than two comparisons.
    pub fn truth_normalised_rms(&self) -> Option<[f64; 3]> {
        if self.truth_compared < 2 {
            return None;
        }
        let n = self.truth_compared as f64;
        Some(std::array::from_fn(|i| {
            (self.truth_normalised_sq_sum[i] / n).max(0.0).sqrt()
        }))
    }

    /// The correlation of consecutive rotations' heading errors against the truth (lag
    /// one): 0 for independent errors, -0.5 for errors that are the difference of two
    /// independent placement errors (each rotation's cloud placed a little off and
    /// registered against the previous one), which cancel when chained. `None` with fewer
    /// than [`MIN_LAG_PAIRS`] pairs or no spread.
    pub fn heading_error_lag_one(&self) -> Option<f64> {
        if self.heading_lag_pairs < MIN_LAG_PAIRS {
            return None;
        }
        let (mean, std) = self.truth_error()?[2];
        let var = std * std;
        // No spread beyond rounding (errors all alike) has nothing to correlate.
        if var <= 1e-9 * mean * mean || var <= 0.0 {
            return None;
        }
        let pairs = self.heading_lag_pairs as f64;
        let [later, earlier] = self.heading_lag_sums;
        let cov = (self.heading_lag_product_sum - mean * (later + earlier)) / pairs + mean * mean;
        Some((cov / var).clamp(-1.0, 1.0))
    }

    /// Records a registration's error against the true motion `[x, y, heading]` and the
    /// covariance it was given to the filter with (scores only; changes nothing).
    pub(super) fn record_truth_error(
        &mut self,
        error: [f64; 3],
        covariance: &nalgebra::Matrix3<f64>,
    ) {
        if error.iter().any(|e| !e.is_finite()) {
            self.break_heading_run();
            return;
        }
        self.truth_compared += 1;
        for (i, e) in error.iter().enumerate() {
            self.truth_error_sum[i] += e;
            self.truth_error_sq_sum[i] += e * e;
            let var = covariance[(i, i)];
            if var.is_finite() && var > 0.0 {
                self.truth_normalised_sq_sum[i] += e * e / var;
            }
        }
        let heading = error[2];
        if let Some(previous) = self.last_heading_error {
            self.heading_lag_pairs += 1;
            self.heading_lag_product_sum += heading * previous;
            self.heading_lag_sums[0] += heading;
            self.heading_lag_sums[1] += previous;
        }
        self.last_heading_error = Some(heading);
    }

    /// A rotation with no registration compared with the truth: the next one's heading
    /// error is not paired with the one before it.
    pub(super) fn break_heading_run(&mut self) {
        self.last_heading_error = None;
    }

    /// Records what the filter did with a measurement.
    pub(super) fn record(&mut self, outcome: MotionOutcome) {
        match outcome {
            MotionOutcome::Applied { nis } => {
                self.applied += 1;
                self.nis_sum += nis;
            }
            MotionOutcome::Gated { .. } => self.gated += 1,
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    /// Registrations whose heading errs by the difference of two independent placement
    /// errors of 1 mrad (std sqrt(2) mrad), taken at 1 mrad: the lag-one correlation
    /// comes out near -0.5 and the heading's normalised RMS near sqrt(2); the positions,
    /// exact, at 0.
    #[test]
    fn placement_errors_read_as_a_negative_lag_one_and_an_over_claim() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(35);
        let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(
            0.05f64.powi(2),
            0.05f64.powi(2),
            1e-6,
        ));
        let mut counts = ScanMatchCounts::default();
        let mut previous: f64 = StandardNormal.sample(&mut rng);
        for _ in 0..20_000 {
            let placement: f64 = StandardNormal.sample(&mut rng);
            counts.record_truth_error([0.0, 0.0, 1e-3 * (placement - previous)], &cov);
            previous = placement;
        }
        let r = counts.heading_error_lag_one().unwrap();
        assert!((r + 0.5).abs() < 0.03, "lag one {r}");
        let [x, y, h] = counts.truth_normalised_rms().unwrap();
        assert_eq!((x, y), (0.0, 0.0));
        assert!((h - 2f64.sqrt()).abs() < 0.03, "heading normalised RMS {h}");
    }

    /// A rotation with no registration compared breaks the run: errors either side of it
    /// are not paired, and too few pairs give no correlation.
    #[test]
    fn a_gap_is_not_paired_across() {
        let cov = Matrix3::identity();
        let mut counts = ScanMatchCounts::default();
        counts.record_truth_error([0.0, 0.0, 0.1], &cov);
        counts.record_truth_error([0.0, 0.0, 0.2], &cov);
        counts.break_heading_run();
        counts.record_truth_error([0.0, 0.0, -0.1], &cov);
        counts.record_truth_error([f64::NAN, 0.0, 0.0], &cov);
        counts.record_truth_error([0.0, 0.0, 0.3], &cov);
        assert_eq!(counts.heading_lag_pairs, 1);
        assert_eq!(counts.truth_compared, 4);
        assert_eq!(counts.heading_error_lag_one(), None);
        // Constant errors have no spread to correlate.
        let mut flat = ScanMatchCounts::default();
        for _ in 0..10 {
            flat.record_truth_error([0.0, 0.0, 0.001], &cov);
        }
        assert_eq!(flat.heading_error_lag_one(), None);
    }
}
