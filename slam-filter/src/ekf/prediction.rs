//! Odometry and time: each odometry sample predicts the state to its timestamp with the one
//! held before it (eq. 2); gaps in the odometry are bridged and clock changes absorbed by
//! growing the pose covariance; the pose is extrapolated (mean only) to any later time.

use radar_model::geometry::Pose2;

use super::Ekf;
use crate::error::FilterError;
use crate::lifecycle::TentativeList;
use crate::observation::BeamObservationModel;
use crate::predict::{corrected_input, predict_to, OdometrySample, ProcessModel};

impl<M: ProcessModel, O: BeamObservationModel> Ekf<M, O> {
    /// Takes a new odometry sample: predicts to its timestamp with the previous sample held, then
    /// holds this one. After a gap longer than
    /// [`FilterSettings::max_predict_gap_s`](crate::FilterSettings::max_predict_gap_s) the motion
    /// in between is unknown: the gap is bridged (see
    /// [`FilterSettings::gap_speed_mps`](crate::FilterSettings::gap_speed_mps)) and counted in
    /// [`FilterStats::bridged_gaps`](crate::FilterStats::bridged_gaps), never refused. The first
    /// sample only starts the clock (the vehicle is assumed still at the initial pose until then).
    /// A sample older than the state is held from the state's time (counted in
    /// [`FilterStats::late_odometry`](crate::FilterStats::late_odometry)).
    pub fn apply_odometry(&mut self, sample: OdometrySample) -> Result<(), FilterError> {
        sample.check()?;
        match self.odometry {
            None => {
                if sample.timestamp_s > self.state.time_s() {
                    self.state.set_time_s(sample.timestamp_s);
                }
            }
            Some(_)
                if sample.timestamp_s - self.state.time_s() > self.settings.max_predict_gap_s =>
            {
                self.bridge_gap(sample.timestamp_s)?;
            }
            Some(held) => {
                if sample.timestamp_s >= self.state.time_s() {
                    predict_to(
                        &mut self.state,
                        &self.motion,
                        &held,
                        sample.timestamp_s,
                        &self.settings,
                    )?;
                } else {
                    self.stats.late_odometry += 1;
                }
            }
        }
        self.odometry = Some(sample);
        Ok(())
    }

    /// The odometry sample the filter holds (the latest applied): the motion assumed from
    /// the state's time on.
    pub fn held_odometry(&self) -> Option<OdometrySample> {
        self.odometry
    }

    /// The pose extrapolated to `time_s` from the current estimate with the held odometry,
    /// mean only (the state is not touched); the current pose for a time at or before the
    /// state's. `None` without odometry or when the motion model fails.
    pub fn pose_at(&self, time_s: f64) -> Option<Pose2> {
        let held = self.odometry?;
        self.extrapolate_pose(&held, time_s).ok()
    }

    /// Predicts the state to `time_s` with the held odometry.
    pub fn predict_to(&mut self, time_s: f64) -> Result<(), FilterError> {
        let held = self.odometry.ok_or(FilterError::NoOdometry)?;
        predict_to(&mut self.state, &self.motion, &held, time_s, &self.settings)
    }

    /// Steps the mean pose from the state's time to `time_s` with `held`, in steps of at
    /// most `max_predict_step_s` (as the prediction does).
    pub(super) fn extrapolate_pose(
        &self,
        held: &OdometrySample,
        time_s: f64,
    ) -> Result<Pose2, FilterError> {
        self.extrapolate_from(self.pose(), held, time_s)
    }

    /// Steps `pose`, taken to hold at the state's time, to `time_s` with `held` (as
    /// [`Self::extrapolate_pose`]); unchanged for a time at or before the state's.
    pub(super) fn extrapolate_from(
        &self,
        mut pose: Pose2,
        held: &OdometrySample,
        time_s: f64,
    ) -> Result<Pose2, FilterError> {
        let gap_s = time_s - self.state.time_s();
        // A non-finite time would make the step count infinite: no extrapolation.
        if gap_s > 0.0 && gap_s.is_finite() {
            let steps = (gap_s / self.settings.max_predict_step_s).ceil().max(1.0);
            let dt = gap_s / steps;
            let (speed, steer) = corrected_input(held, self.state.odometry_bias());
            let mut done = 0.0;
            while done < steps {
                pose = self.motion.step(&pose, speed, steer, dt)?.pose;
                done += 1.0;
            }
        }
        Ok(pose)
    }

    /// Jumps the state to `time_s` across an odometry gap: the pose covariance grows by what the
    /// vehicle could have done meanwhile, once a map exists (see
    /// [`FilterSettings::gap_speed_mps`](crate::FilterSettings::gap_speed_mps)).
    fn bridge_gap(&mut self, time_s: f64) -> Result<(), FilterError> {
        // The motion across the gap is unknown: no tally spans it.
        self.state.tally = None;
        self.inflate_for_gap(time_s - self.state.time_s())?;
        self.state.set_time_s(time_s);
        self.stats.bridged_gaps += 1;
        self.start_relocalising();
        Ok(())
    }

    /// Grows the pose covariance by what the vehicle could do in `gap_s` of unknown motion.
    ///
    /// Unless there is no map to relocalise against: with no feature mapped, or (when
    /// relocalising is on) fewer than
    /// [`FilterSettings::relocalise_min_features`](crate::FilterSettings::relocalise_min_features),
    /// which are dropped, nothing is grown and the map frame is re-anchored at the pose
    /// estimate (counted in
    /// [`FilterStats::reanchored_gaps`](crate::FilterStats::reanchored_gaps)). Growing it
    /// instead left every feature mapped afterwards with the gap's uncertainty (20 m and
    /// 120 degrees of heading for a 10 s gap), which no later measurement can take back
    /// (nothing observes the frame), and whose linearisation turned a parked vehicle's
    /// heading by 100 degrees and more as the map formed; with one or two features mapped,
    /// too few to relocalise against, beam-by-beam association in the grown gates put it
    /// 24 m and 155 degrees off.
    fn inflate_for_gap(&mut self, gap_s: f64) -> Result<(), FilterError> {
        let mapped = self.state.feature_count();
        let too_few =
            self.settings.relocalise_after_gap && mapped < self.settings.relocalise_min_features;
        if mapped == 0 || too_few {
            let ids: Vec<_> = self.state.tracks().iter().map(|t| t.id).collect();
            self.retire(&ids)?;
            self.stats.reanchored_gaps += 1;
            // Tentatives were placed in the old frame.
            self.tentatives = TentativeList::default();
            return Ok(());
        }
        let s = &self.settings;
        let sigma_xy = (s.gap_speed_mps * gap_s).min(s.gap_max_sigma_m);
        let sigma_theta = (s.gap_yaw_rate_rps * gap_s).min(std::f64::consts::PI);
        self.state.inflate_pose_covariance([
            sigma_xy * sigma_xy,
            sigma_xy * sigma_xy,
            sigma_theta * sigma_theta,
        ]);
        Ok(())
    }

    /// Moves the filter onto a new clock at `time_s` (the sensor's clock was set, forwards or
    /// backwards): the map is kept, the pose covariance grows (once a map exists) as across a gap of
    /// [`FilterSettings::max_predict_gap_s`](crate::FilterSettings::max_predict_gap_s) of unknown
    /// motion, and the held odometry is dropped (it belongs to the old clock): beams are refused
    /// until odometry on the new clock arrives. Counted in
    /// [`FilterStats::bridged_gaps`](crate::FilterStats::bridged_gaps).
    pub fn resync_clock(&mut self, time_s: f64) -> Result<(), FilterError> {
        if !time_s.is_finite() {
            return Err(FilterError::NonFiniteObservation {
                what: "timestamp_s",
                value: time_s,
            });
        }
        self.inflate_for_gap(self.settings.max_predict_gap_s)?;
        self.state.set_time_s(time_s);
        self.state.tally = None;
        self.stats.bridged_gaps += 1;
        self.odometry = None;
        self.tentatives = TentativeList::default();
        self.start_relocalising();
        Ok(())
    }
}
