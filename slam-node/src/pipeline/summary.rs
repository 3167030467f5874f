//! Running totals of a run and the end-of-run summary.

use std::collections::VecDeque;

use serde::Serialize;

use super::counts::{RefusalCounts, ScanMatchCounts};
use super::scores::{MapScore, ObservationErrorStats, PoseErrorStats};
use super::spectrum::SpectrumTally;
use crate::output::RotationDiagnostics;

/// Rotation times kept for percentiles (the most recent ones).
const TIMES_KEPT: usize = 10_000;

/// Totals over a run.
#[derive(Debug, Clone, Default, Serialize)]
pub struct PipelineSummary {
    /// Rotations completed.
    pub rotations: u64,
    /// Azimuths processed.
    pub azimuths: u64,
    /// Azimuths dropped as malformed (non-finite or backwards time).
    pub bad_azimuths: u64,
    /// Targets detected.
    pub detections: u64,
    /// Observations after grouping.
    pub observations: u64,
    /// Beams the filter processed.
    pub beams: u64,
    /// Beams refused, by reason.
    pub refused: RefusalCounts,
    /// Filter errors (logged).
    pub filter_errors: u64,
    /// Observation-feature associations.
    pub associations: u64,
    /// Associations whose observation came from another scene feature than the one the
    /// mapped feature stands for (truth known only).
    pub association_errors: u64,
    /// Associations of observations near no scene feature (clutter), truth known only.
    pub clutter_associations: u64,
    /// Odometry samples received.
    pub odometry_samples: u64,
    /// Odometry samples dropped (out of order or not finite).
    pub odometry_out_of_order: u64,
    /// Odometry records refused: past the physical limits, or stamped far from the
    /// odometry's clock.
    pub odometry_refused: u64,
    /// Odometry records sent again (stamped at or before the newest one taken, within the
    /// replay window: a reconnected source replaying), dropped as duplicates.
    pub odometry_duplicates: u64,
    /// Odometry clock jumps resynchronised to (pending records dropped on a jump back, kept
    /// on a jump forward).
    pub odometry_clock_jumps: u64,
    /// Azimuths dropped for a timestamp far from the radar's clock.
    pub clock_outliers: u64,
    /// Radar clock jumps the pipeline resynchronised to.
    pub clock_jumps: u64,
    /// Features in the final map.
    pub map_size: usize,
    /// Saved maps (`[map]`) handed to the writer.
    pub saved_maps: u64,
    /// What went into the last one.
    pub saved_map: Option<super::saved_map::SavedMapCounts>,
    /// Localisation in a saved map, when the run localised.
    pub localise: Option<super::localise::LocaliseSummary>,
    /// Extending a saved map, when the run extended one.
    pub extend: Option<super::extend::ExtendSummary>,
    /// Stream time of the first azimuth on the radar's current clock (since its last jump).
    pub first_time_s: Option<f64>,
    /// Last azimuth's time.
    pub last_time_s: Option<f64>,
    /// Stream time covered on the clocks before the radar's last jump, seconds.
    pub stream_before_jumps_s: f64,
    /// Processing time summed over rotations, ms.
    pub processing_ms: f64,
    /// Detection time summed, ms.
    pub detect_ms: f64,
    /// Filter time summed, ms.
    pub filter_ms: f64,
    /// Spectrum comparison time summed, ms.
    pub spectrum_ms: f64,
    /// Slowest rotation, ms.
    pub max_rotation_ms: f64,
    /// Rotations that took longer to process than the radar took to send them.
    pub rotations_behind: u64,
    /// Spectrum comparison over the run.
    #[serde(skip)]
    pub spectrum: SpectrumTally,
    /// The spectrum comparison's bound when it is learned per bin (three sigma of the
    /// learned floor): its smallest and largest value, dB. `None`: the configured constant.
    pub spectrum_bound_db: Option<(f64, f64)>,
    /// The learned receiver compensation slope, dB per decade.
    pub learned_gain_db_per_decade: Option<f64>,
    /// The odometry corrections `[k, b]` the filter estimated at the end (speed times
    /// `1 + k`, steering plus `b` rad) with their standard deviations; `None` when they are
    /// not estimated (`[odometry] speed_scale_std` and `steer_bias_std_rad` zero).
    pub odometry_corrections: Option<([f64; 2], [f64; 2])>,
    /// What radar odometry did (`[odometry] radar_odometry`); `None` when it is off.
    pub scan_match: Option<ScanMatchCounts>,
    /// What the gyro did (radar only with a gyro); `None` without one.
    pub gyro: Option<super::gyro::GyroSummary>,
    /// Observations kept out of the map as extended returns (walls, fences, cars).
    pub extended_returns: u64,
    /// Feature-rotations in which a mapped feature (mapped before the rotation began) was in
    /// the radar's view.
    pub features_in_view: u64,
    /// Of those, the ones in which it was associated again.
    pub features_reobserved: u64,
    /// Features retired for being re-observed too rarely (`[filter]
    /// retire_unrepeatable_below`).
    pub features_retired_unrepeatable: u64,
    /// Beams not used because they came in a burst of targets far above the learned rate
    /// (the filter's burst guard: a swamped receiver, interference).
    pub burst_beams: u64,
    /// Rotations with no beam for the filter whose end was reached with the odometry
    /// received (wheel odometry, a recording's; `PipelineCore::reach_a_still_clocks_end`).
    pub still_clock_caught_up: u64,
    /// The submap the filter runs in now (0 with one dense map); poses in progress lines
    /// are in its frame.
    pub current_submap: usize,
    /// Local submaps and the global layer (`None`: one dense map).
    #[serde(skip)]
    pub submaps: Option<super::submaps::SubmapSummary>,
    /// With ground truth: the pose published each rotation (the online pose) scored as a
    /// trajectory (its drift over 100-800 m segments).
    #[serde(skip)]
    pub online: Option<super::submaps::TrajectoryScore>,
    /// With ground truth and submaps: the filter's pose chained through the submaps'
    /// switch poses alone, the global layer's corrections left out (the odometry), scored
    /// as a trajectory.
    #[serde(skip)]
    pub odometry_track: Option<super::submaps::TrajectoryScore>,
    /// Pose error against truth.
    pub pose: Option<PoseErrorStats>,
    /// Associated observations against the true geometry (truth known only).
    pub observation_errors: Option<ObservationErrorStats>,
    /// Map against the scene.
    pub map: Option<MapScore>,
    #[serde(skip)]
    recent_ms: VecDeque<f64>,
    /// CPU time of the pipeline's thread summed over the rotations it was measured for, ms:
    /// its own work, without the time it waited for a core (see [`Self::add_cpu_ms`]).
    pub cpu_ms: f64,
    /// Rotations whose CPU time was measured.
    pub cpu_rotations: u64,
    #[serde(skip)]
    recent_cpu_ms: VecDeque<f64>,
    /// Every rotation's CPU time over the whole run, thinned evenly to a bound, so the
    /// first and last tenths of a run of any length can be compared.
    #[serde(skip)]
    cpu_over_run: super::thinned::Thinned,
}

impl PipelineSummary {
    /// Adds one rotation's diagnostics.
    pub fn add_rotation(&mut self, d: &RotationDiagnostics) {
        self.rotations += 1;
        self.azimuths += u64::from(d.azimuths);
        self.detections += u64::from(d.detections);
        self.observations += u64::from(d.observations);
        self.processing_ms += d.total_ms;
        self.detect_ms += d.detect_ms;
        self.filter_ms += d.filter_ms;
        self.spectrum_ms += d.spectrum_ms;
        self.max_rotation_ms = self.max_rotation_ms.max(d.total_ms);
        keep_recent(&mut self.recent_ms, d.total_ms);
    }

    /// Stream time covered, seconds: summed over the radar's clocks, so a clock that jumps
    /// (back, or ahead) neither cancels nor inflates it (issue 38: after a jump back the
    /// summary read "0.0 s of stream").
    pub fn stream_s(&self) -> f64 {
        self.stream_before_jumps_s + self.current_clock_s()
    }

    fn current_clock_s(&self) -> f64 {
        match (self.first_time_s, self.last_time_s) {
            (Some(a), Some(b)) => (b - a).max(0.0),
            _ => 0.0,
        }
    }

    /// The radar's clock has jumped: what was covered on the old clock is kept, and the
    /// next azimuth starts the new one.
    pub fn clock_jumped(&mut self) {
        self.stream_before_jumps_s += self.current_clock_s();
        self.first_time_s = None;
        self.last_time_s = None;
    }

    /// Stream seconds processed per second of processing time (one thread).
    pub fn real_time_factor(&self) -> f64 {
        if self.processing_ms > 0.0 {
            self.stream_s() / (self.processing_ms * 1e-3)
        } else {
            0.0
        }
    }

    /// Mean processing time per rotation, ms.
    pub fn mean_rotation_ms(&self) -> f64 {
        if self.rotations == 0 {
            0.0
        } else {
            self.processing_ms / self.rotations as f64
        }
    }

    /// Adds one rotation's CPU time of the pipeline's thread, ms. Unlike the stage times
    /// (wall clock, which count the time the thread waited for a core while another process
    /// or the embedded simulator ran), this is the work itself.
    pub fn add_cpu_ms(&mut self, ms: f64) {
        if !(ms.is_finite() && ms >= 0.0) {
            return;
        }
        self.cpu_ms += ms;
        self.cpu_rotations += 1;
        keep_recent(&mut self.recent_cpu_ms, ms);
        self.cpu_over_run.push(ms);
    }

    /// The CPU time per rotation's median and 99th percentile (ms) in each tenth of the run,
    /// in order (a tenth without a measured rotation is left out).
    pub fn cpu_ms_by_tenth(&self) -> Vec<[f64; 2]> {
        self.cpu_over_run
            .percentiles_by_share(10, &[50.0, 99.0])
            .into_iter()
            .filter_map(|p| Some([*p.first()?, *p.get(1)?]))
            .collect()
    }

    /// Mean CPU time per measured rotation, ms (`None`: none measured).
    pub fn mean_cpu_ms(&self) -> Option<f64> {
        (self.cpu_rotations > 0).then(|| self.cpu_ms / self.cpu_rotations as f64)
    }

    /// A percentile (0-100) of the recent rotations' CPU times, ms.
    pub fn cpu_ms_percentile(&self, p: f64) -> f64 {
        percentile(&self.recent_cpu_ms, p)
    }

    /// A percentile (0-100) of the recent rotation times, ms.
    pub fn rotation_ms_percentile(&self, p: f64) -> f64 {
        percentile(&self.recent_ms, p)
    }
}

/// Appends `value`, dropping the oldest beyond [`TIMES_KEPT`].
fn keep_recent(values: &mut VecDeque<f64>, value: f64) {
    if values.len() == TIMES_KEPT {
        values.pop_front();
    }
    values.push_back(value);
}

/// A percentile (0-100) of `values` (nearest rank), 0 when empty.
fn percentile(values: &VecDeque<f64>, p: f64) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let k = ((p / 100.0) * (v.len() - 1) as f64).round();
    let k = if k.is_finite() && k >= 0.0 {
        k as usize
    } else {
        0
    };
    v.get(k.min(v.len() - 1)).copied().unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_times_skip_nonsense_and_give_nearest_rank_percentiles() {
        let mut s = PipelineSummary::default();
        assert_eq!(s.mean_cpu_ms(), None);
        for ms in [3.0, f64::NAN, 1.0, -2.0, 2.0, f64::INFINITY, 10.0] {
            s.add_cpu_ms(ms);
        }
        assert_eq!(s.cpu_rotations, 4);
        assert_eq!(s.mean_cpu_ms(), Some(4.0));
        assert_eq!(s.cpu_ms_percentile(50.0), 3.0);
        assert_eq!(s.cpu_ms_percentile(99.0), 10.0);
        assert_eq!(s.cpu_ms_percentile(0.0), 1.0);
    }
}
