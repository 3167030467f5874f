//! Map management: hits and misses of a beam's features and retirement after repeated
//! misses, retirement of features unseen for too long or re-observed too rarely, the noise
//! added lazily to features (material random walk, positional wander), and closing a submap.

use radar_model::geometry::range_bearing;

use super::{BeamReport, Ekf, RotationScore};
use crate::beam::BeamCandidate;
use crate::error::FilterError;
use crate::observation::BeamObservationModel;
use crate::predict::ProcessModel;
use crate::state::FeatureId;
use crate::submap::FrozenSubmap;

impl<M: ProcessModel, O: BeamObservationModel> Ekf<M, O> {
    /// Hits for the candidates a target was paired with; a miss for each candidate expected
    /// in the beam and `visible` (predicted above the detection threshold) but not paired;
    /// retirement after too many consecutive misses.
    pub(super) fn book_keep(
        &mut self,
        candidates: &[BeamCandidate],
        visible: &[bool],
        pairs: &[Option<usize>],
        now: f64,
        report: &mut BeamReport,
    ) -> Result<(), FilterError> {
        let mut retire = Vec::new();
        for (i, c) in candidates.iter().enumerate() {
            let expected = c.expected && visible.get(i).copied().unwrap_or(true);
            let Some(track) = self.state.track_mut(c.slot) else {
                continue;
            };
            let paired: Vec<usize> = pairs
                .iter()
                .enumerate()
                .filter(|(_, f)| **f == Some(i))
                .map(|(j, _)| j)
                .collect();
            if !paired.is_empty() {
                track.hits += 1;
                track.consecutive_misses = 0;
                track.last_seen_s = now;
                report
                    .associated
                    .extend(paired.iter().map(|&j| (j, track.id)));
            } else if expected {
                track.consecutive_misses += 1;
                if track.consecutive_misses >= self.settings.retire_after_misses {
                    retire.push(track.id);
                }
            }
        }
        self.retire(&retire)?;
        report.retired.extend(retire);
        Ok(())
    }

    /// Removes the features `ids` from the state and counts them retired.
    pub(super) fn retire(&mut self, ids: &[FeatureId]) -> Result<(), FilterError> {
        for &id in ids {
            self.state.remove(id)?;
            self.stats.retired += 1;
        }
        Ok(())
    }

    /// Retires every feature within the radar's range of the current pose that no target has been
    /// associated with for
    /// [`FilterSettings::retire_unseen_after_s`](crate::FilterSettings::retire_unseen_after_s) (see
    /// there); returns their ids. Call once a rotation. O(N).
    pub fn retire_unseen(&mut self) -> Result<Vec<FeatureId>, FilterError> {
        self.retire_unseen_in_view(|_, _| true)
    }

    /// As [`Self::retire_unseen`], for a radar whose view is limited (contours, blanked
    /// sectors): only features for which `in_view(bearing_rad, range_m)` (in the radar's
    /// frame, eq. 4's bearing) holds can be retired for going unseen.
    pub fn retire_unseen_in_view(
        &mut self,
        in_view: impl Fn(f64, f64) -> bool,
    ) -> Result<Vec<FeatureId>, FilterError> {
        let limit = self.settings.retire_unseen_after_s;
        if limit <= 0.0 || self.relocalising.is_some() {
            return Ok(Vec::new());
        }
        let now = self.state.time_s();
        let pose = self.pose();
        let (near, far) = (self.settings.min_range_m, self.settings.max_range_m);
        let stale: Vec<FeatureId> = (0..self.state.feature_count())
            .filter_map(|slot| {
                let p = self.state.params(slot)?;
                let track = self.state.tracks().get(slot)?;
                let rb = range_bearing(&pose, [p.x_m, p.y_m]);
                // A burst blinds the radar: the unseen time counts from its end.
                let unseen = now - track.last_seen_s.max(self.last_burst_beam_s) > limit;
                let in_range = (near..=far).contains(&rb.range_m);
                (unseen && in_range && in_view(rb.bearing_rad, rb.range_m)).then_some(track.id)
            })
            .collect();
        self.retire(&stale)?;
        Ok(stale)
    }

    /// Scores the rotation that began at `start_s` (call once, at its end): every feature mapped
    /// before it that is within the radar's range of the current pose and in view
    /// (`in_view(bearing_rad, range_m)` in the radar's frame, eq. 4's bearing) counts a rotation in
    /// view, and a re-observation if a target was associated with it since `start_s`. With
    /// [`FilterSettings::retire_unrepeatable_below`](crate::FilterSettings::retire_unrepeatable_below)
    /// set, a feature whose share of re-observations is below it once it has been in view for
    /// [`FilterSettings::repeatability_min_rotations`](crate::FilterSettings::repeatability_min_rotations)
    /// is retired (not while relocalising). In view means in range, not predicted visible: a
    /// phantom the filter predicts hidden (occluded, or too weak) would never be judged otherwise.
    /// A rotation in which the filter mapped no beam (odometry missing or stale, beams held for a
    /// relocalisation) is not scored: nothing could be re-observed in it. O(N).
    pub fn score_rotation(
        &mut self,
        start_s: f64,
        in_view: impl Fn(f64, f64) -> bool,
    ) -> Result<RotationScore, FilterError> {
        let mut score = RotationScore::default();
        if self.last_mapped_beam_s < start_s {
            return Ok(score);
        }
        let pose = self.pose();
        let (near, far) = (self.settings.min_range_m, self.settings.max_range_m);
        let below = self.settings.retire_unrepeatable_below;
        let after = self.settings.repeatability_min_rotations.max(1);
        let judge = below > 0.0 && self.relocalising.is_none();
        let mut unrepeatable = Vec::new();
        for slot in 0..self.state.feature_count() {
            let Some(p) = self.state.params(slot) else {
                continue;
            };
            let rb = range_bearing(&pose, [p.x_m, p.y_m]);
            let Some(track) = self.state.track_mut(slot) else {
                continue;
            };
            if track.created_s >= start_s
                || !(near..=far).contains(&rb.range_m)
                || !in_view(rb.bearing_rad, rb.range_m)
            {
                continue;
            }
            score.in_view += 1;
            track.rotations_in_view = track.rotations_in_view.saturating_add(1);
            if track.last_seen_s >= start_s {
                score.reobserved += 1;
                track.rotations_reobserved = track.rotations_reobserved.saturating_add(1);
            }
            if judge
                && track.rotations_in_view >= after
                && f64::from(track.rotations_reobserved)
                    < below * f64::from(track.rotations_in_view)
            {
                unrepeatable.push(track.id);
            }
        }
        self.retire(&unrepeatable)?;
        self.stats.retired_unrepeatable += unrepeatable.len() as u64;
        score.retired = unrepeatable;
        Ok(score)
    }

    /// Brings every feature's u, v variance (the material random walk) and x, y variance
    /// (the positional wander) up to date: both are added lazily, when a feature is next
    /// in a beam. Call before reading the covariance for output; O(N).
    pub fn settle_material_noise(&mut self) {
        for slot in 0..self.state.feature_count() {
            self.settle_feature_noise(slot);
        }
    }

    /// Brings the feature in `slot` up to date with the noise added lazily: its material
    /// random walk and its positional wander.
    pub(super) fn settle_feature_noise(&mut self, slot: usize) {
        self.state
            .settle_material(slot, self.settings.material_variance_per_s);
        self.state.settle_wander(
            slot,
            self.settings.feature_wander_m,
            self.settings.feature_wander_length_m,
        );
    }

    /// Closes the current local map and starts a new one where the vehicle is (see
    /// [`crate::submap`]): the vehicle at the new frame's origin with zero covariance, no
    /// features, the radar loss and the held odometry kept, tentative targets re-expressed
    /// in the new frame. A mark ([`Self::mark_motion`]) is set again at the vehicle: the
    /// motion since the old one is not carried into the new frame, but the motion from here
    /// on is measured as before (radar odometry registers the next rotation against the
    /// last; dropped, it lost the rotation after every switch and searched the one after).
    /// Returns the closed map's compact record (material noise settled first). O(N).
    pub fn start_submap(&mut self) -> FrozenSubmap {
        self.settle_material_noise();
        let origin = self.state.pose();
        let marked = self.state.tally.is_some();
        let closed = self.state.restart_at_origin();
        self.tentatives.reframe(&origin);
        if marked {
            self.mark_motion();
        }
        FrozenSubmap::from_state(&closed)
    }
}
