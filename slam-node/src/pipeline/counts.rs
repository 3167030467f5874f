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

    /// Records a registration's error against the true motion `[x, y, heading]` (scores
    /// only; changes nothing).
    pub(super) fn record_truth_error(&mut self, error: [f64; 3]) {
        if error.iter().any(|e| !e.is_finite()) {
            return;
        }
        self.truth_compared += 1;
        for (i, e) in error.iter().enumerate() {
            self.truth_error_sum[i] += e;
            self.truth_error_sq_sum[i] += e * e;
        }
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
