//! A beam through the filter in the paper's steps: the entry points, the order of the
//! steps, the range a beam covers, and a beam with no targets (its misses counted without
//! predicting the state).

use super::{BeamReport, Ekf};
use crate::beam::{candidates_in_beam, predict_candidates, BeamCandidate};
use crate::error::FilterError;
use crate::observation::{BeamObservation, BeamObservationModel};
use crate::predict::ProcessModel;

impl<M: ProcessModel, O: BeamObservationModel> Ekf<M, O> {
    /// Processes every target detected down one beam, in the paper's steps:
    ///
    /// 1. **prediction**: the vehicle (and the state's time) to the beam's timestamp with the
    ///    held odometry (eq. 2);
    /// 2. **observation prediction**: the features the beam concerns, in range order, and
    ///    their joint `(R, beta, P)` with the multi-target power of eq. 13;
    /// 3. **data association** of the beam's targets with those predictions;
    /// 4. **update**: one batched EKF update with every associated target (eq. 14);
    /// 5. **map management**: hits, misses where a feature should have been seen, retirement;
    /// 6. **augmentation**: unclaimed targets start or confirm tentatives, and confirmed ones
    ///    enter the state with their reflectivity and absorption.
    ///
    /// A beam inside a burst of targets (see
    /// [`FilterSettings::burst_factor`](crate::FilterSettings::burst_factor)) is only predicted
    /// to: the radar is taken to be blind.
    ///
    /// Non-finite input, too many targets, a time before the state's or a gap past the limit
    /// are rejected before the state is touched. If the batched update fails (S not positive
    /// definite, or a variance would go non-positive) the state has been predicted to the
    /// beam's time but not updated. If initialising a confirmed target fails, the updates
    /// before it stand and the remaining unclaimed targets of the beam are not processed.
    pub fn process_beam(&mut self, beam: &BeamObservation) -> Result<BeamReport, FilterError> {
        let far_m = self.settings.max_range_m;
        self.process_beam_inner(beam, None, far_m)
    }

    /// [`Self::process_beam`] where only the targets with `may_start[j]` true may start (or
    /// confirm) a tentative feature; the others may only re-observe mapped features (a
    /// front end's weaker, less certain landmarks). A mask shorter than the beam lets the
    /// rest start. `Some(max_range_m)` is a beam the radar covered only out to there (a
    /// contoured azimuth): features beyond it are neither candidates nor missed there, and
    /// targets beyond it start nothing; `None` (or NaN, or not nearer than the full range) is
    /// the full range.
    pub fn process_beam_offered(
        &mut self,
        beam: &BeamObservation,
        max_range_m: Option<f64>,
        may_start: &[bool],
    ) -> Result<BeamReport, FilterError> {
        let far_m = self.beam_far_m(max_range_m);
        self.process_beam_inner(beam, Some(may_start), far_m)
    }

    /// The beam's steps (see [`Self::process_beam`]) for the features and targets between
    /// the minimum range and `far_m`.
    fn process_beam_inner(
        &mut self,
        beam: &BeamObservation,
        may_start: Option<&[bool]>,
        far_m: f64,
    ) -> Result<BeamReport, FilterError> {
        self.check_beam(beam)?;
        let burst = self
            .target_rate
            .is_burst(&self.settings, beam.timestamp_s, beam.targets.len());
        if self.relocalising.is_some() {
            return self.relocalise_beam(beam, far_m);
        }
        if burst {
            return self.burst_beam(beam);
        }
        if beam.targets.is_empty() && self.settings.defer_empty_beams {
            return self.empty_beam(beam, far_m);
        }
        // 1. Prediction.
        self.predict_to(beam.timestamp_s)?;
        self.last_mapped_beam_s = beam.timestamp_s;
        let mut report = BeamReport::default();
        let in_beam = self.features_in_beam_within(beam.bearing_rad, far_m);
        report.candidates = self.ids_of(&in_beam);
        let mut unclaimed: Vec<usize> = (0..beam.targets.len()).collect();
        if !in_beam.is_empty() {
            // 2. Observation prediction.
            let mut predicted = self.predict_observations(&in_beam)?;
            // 3. Data association.
            let association = self.associate_beam(beam, &predicted, &mut report);
            // 4. Update.
            let claimed = self.update(beam, &mut predicted, &association, &mut report)?;
            unclaimed.retain(|j| !claimed.contains(j));
            // 5. Map management.
            let visible = self.visible(&predicted.prediction);
            self.book_keep(
                &in_beam,
                &visible,
                &association.pairs,
                beam.timestamp_s,
                &mut report,
            )?;
        }
        // 6. Augmentation (of the targets allowed to start features).
        if let Some(mask) = may_start {
            unclaimed.retain(|&j| mask.get(j).copied().unwrap_or(true));
        }
        self.handle_unclaimed(beam, &unclaimed, &mut report, far_m)?;
        self.tentatives
            .expire(beam.timestamp_s, self.settings.tentative_timeout_s);
        Ok(report)
    }

    /// A beam inside a burst of targets (see [`FilterSettings::burst_factor`]): the radar was
    /// blind (a swamped receiver, interference), so the beam is evidence of nothing. The state
    /// is predicted to its time, and nothing else: no update (noise inside the gates of
    /// mapped features dragged a parked vehicle's heading 38 degrees in a 6 s burst), no
    /// misses and no unseen time (the real features were retired during the burst and the
    /// map re-made from the drifted pose), no new features.
    ///
    /// [`FilterSettings::burst_factor`]: crate::FilterSettings::burst_factor
    fn burst_beam(&mut self, beam: &BeamObservation) -> Result<BeamReport, FilterError> {
        self.predict_to(beam.timestamp_s)?;
        self.stats.burst_beams += 1;
        self.last_burst_beam_s = beam.timestamp_s;
        self.tentatives
            .expire(beam.timestamp_s, self.settings.tentative_timeout_s);
        Ok(BeamReport::default())
    }

    /// Rejects non-finite values and too many targets before anything is touched.
    fn check_beam(&self, beam: &BeamObservation) -> Result<(), FilterError> {
        beam.check()?;
        if beam.targets.len() > self.settings.max_targets_per_beam {
            return Err(FilterError::TooManyTargets {
                count: beam.targets.len(),
                limit: self.settings.max_targets_per_beam,
            });
        }
        Ok(())
    }

    /// The far end of a beam the radar covered out to `max_range_m` (`None`: its full
    /// range): never nearer than the minimum range, never beyond the full range.
    fn beam_far_m(&self, max_range_m: Option<f64>) -> f64 {
        let full = self.settings.max_range_m;
        match max_range_m.filter(|m| !m.is_nan() && *m < full) {
            Some(m) => m.max(self.settings.min_range_m),
            None => full,
        }
    }

    /// The candidate features of a beam at `bearing_rad` (see [`candidates_in_beam`]).
    pub(super) fn features_in_beam(&self, bearing_rad: f64) -> Vec<BeamCandidate> {
        self.features_in_beam_within(bearing_rad, self.settings.max_range_m)
    }

    /// [`Self::features_in_beam`] out to `far_m` only.
    fn features_in_beam_within(&self, bearing_rad: f64, far_m: f64) -> Vec<BeamCandidate> {
        candidates_in_beam(
            &self.state,
            &self.settings,
            &self.pose(),
            bearing_rad,
            far_m,
        )
    }

    /// A beam with no targets, when `defer_empty_beams` is set: the state is not predicted
    /// (nothing is updated, so nothing needs it); its candidates are found from a mean-only
    /// extrapolation of the pose to the beam's time, and their misses counted. The next
    /// beam with targets, or odometry, predicts the state across the gap in one go.
    fn empty_beam(
        &mut self,
        beam: &BeamObservation,
        far_m: f64,
    ) -> Result<BeamReport, FilterError> {
        let held = self.odometry.ok_or(FilterError::NoOdometry)?;
        let from_s = self.state.time_s();
        let gap_s = beam.timestamp_s - from_s;
        if gap_s < 0.0 {
            return Err(FilterError::TimeWentBackwards {
                state_s: from_s,
                requested_s: beam.timestamp_s,
            });
        }
        if gap_s > self.settings.max_predict_gap_s {
            return Err(FilterError::GapTooLong {
                gap_s,
                limit_s: self.settings.max_predict_gap_s,
            });
        }
        let pose = self.extrapolate_pose(&held, beam.timestamp_s)?;
        self.last_mapped_beam_s = beam.timestamp_s;
        let candidates =
            candidates_in_beam(&self.state, &self.settings, &pose, beam.bearing_rad, far_m);
        let mut report = BeamReport {
            candidates: candidates
                .iter()
                .filter_map(|c| self.state.tracks().get(c.slot).map(|t| t.id))
                .collect(),
            ..BeamReport::default()
        };
        if candidates.iter().any(|c| c.expected) {
            let visible: Vec<bool> = if self.settings.use_power {
                let slots: Vec<usize> = candidates.iter().map(|c| c.slot).collect();
                let params = self.beam_params(&slots);
                let pred = predict_candidates(
                    &self.observer,
                    &pose,
                    self.state.loss_db(),
                    &candidates,
                    &params,
                )?;
                pred.z
                    .iter()
                    .map(|z| z[2] >= self.settings.min_detectable_power_db)
                    .collect()
            } else {
                vec![true; candidates.len()]
            };
            self.book_keep(&candidates, &visible, &[], beam.timestamp_s, &mut report)?;
        }
        self.tentatives
            .expire(beam.timestamp_s, self.settings.tentative_timeout_s);
        Ok(report)
    }
}
