//! The filter as the daemon uses it: odometry in, one beam at a time in, estimates out.
//!
//! Per beam: reject non-finite input (state untouched), predict to the beam's timestamp,
//! find the features inside the beam (sorted by range), predict their `(R, beta, P)`,
//! associate (gate, nearest neighbour or JCBB), apply one batched update, count misses and
//! retire features not seen where they should be, and pass unclaimed targets to the
//! tentative list, initialising the ones it confirms.

mod init;
mod relocalise;

use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, Vector3};
use radar_model::geometry::{range_bearing, wrap_angle, Pose2};
use radar_model::layout::ObservationRow;
use radar_model::material::Material;

use super::association::{associate, innovation, rows_of, Association, BeamContext, GateTable};
use super::beam::{candidates_in_beam, predict_candidates, BeamCandidate};
use super::error::FilterError;
use super::fej::relinearise_at_first_estimates;
use super::health::{covariance_health, pose_nees, position_nees, CovarianceHealth};
use super::lifecycle::TentativeList;
use super::motion_tally::{relative_pose, MotionTally};
use super::observation::{
    row_indices, state_columns, BeamObservation, BeamObservationModel, BeamPrediction,
};
use super::predict::{corrected_input, predict_to, OdometrySample, ProcessModel};
use super::repeat_look::LookCell;
use super::settings::FilterSettings;
use super::state::{FeatureId, FeatureParams, SlamState, CLONE_INDEX, SPEED_SCALE_INDEX};
use super::submap::FrozenSubmap;
use super::update::{
    batched_update, batched_update_considering, LinearisedObservation, UpdateOutcome,
};
use relocalise::Relocalisation;

/// A feature as reported: position, material shares (not the logits), uncertainty.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureEstimate {
    /// Stable id.
    pub id: FeatureId,
    /// World x (m).
    pub x_m: f64,
    /// World y (m).
    pub y_m: f64,
    /// Reflected share.
    pub rho: f64,
    /// Absorbed share.
    pub alpha: f64,
    /// Position covariance (m^2).
    pub position_cov: Matrix2<f64>,
    /// Observations used.
    pub hits: u64,
}

/// What processing one beam did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BeamReport {
    /// The beam's features (in range order) that were candidates.
    pub candidates: Vec<FeatureId>,
    /// `(target index, feature)` pairs used in the update.
    pub associated: Vec<(usize, FeatureId)>,
    /// The batched update's NIS and dof, if one ran.
    pub update: Option<UpdateOutcome>,
    /// Features initialised from confirmed tentatives.
    pub initialised: Vec<FeatureId>,
    /// Features retired for repeated misses.
    pub retired: Vec<FeatureId>,
    /// Targets that started a new tentative.
    pub new_tentatives: usize,
    /// Unpaired targets inside some feature's exclusion gate (neither used nor tentative).
    pub excluded_targets: usize,
    /// Whether JCBB ran, and whether it exhausted its budget.
    pub used_jcbb: bool,
    /// JCBB stopped at its node budget.
    pub jcbb_budget_exhausted: bool,
}

/// Running totals.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FilterStats {
    /// Batched updates applied.
    pub updates: u64,
    /// Sum of NIS over updates.
    pub nis_sum: f64,
    /// Sum of their degrees of freedom (mean NIS / mean dof ~ 1 when consistent).
    pub nis_dof_sum: u64,
    /// Features initialised.
    pub initialised: u64,
    /// Features retired.
    pub retired: u64,
    /// Beams where JCBB ran.
    pub jcbb_runs: u64,
    /// Odometry samples older than the state (held from the state's time instead).
    pub late_odometry: u64,
    /// Targets dropped because the tentative list (or the state) was full.
    pub dropped_targets: u64,
    /// Unpaired targets inside some feature's exclusion gate.
    pub excluded_targets: u64,
    /// Odometry gaps bridged by re-initialising the pose covariance.
    pub bridged_gaps: u64,
    /// Relocalisations accepted after a gap (see [`FilterSettings::relocalise_after_gap`]).
    pub relocalisations: u64,
    /// Turns held and tried for a relocalisation (accepted or not).
    pub relocalisation_attempts: u64,
    /// Relocalisations given up after [`FilterSettings::relocalise_give_up_s`].
    pub relocalisations_abandoned: u64,
    /// Beams whose targets were kept from starting features because the target rate was a
    /// burst (see [`FilterSettings::burst_factor`]).
    pub burst_beams: u64,
    /// Measurements of the motion since a mark applied
    /// ([`Ekf::observe_motion_since_mark`]).
    pub motion_updates: u64,
    /// Features retired for being re-observed too rarely ([`Ekf::score_rotation`]; also
    /// counted in `retired`).
    pub retired_unrepeatable: u64,
}

/// What [`Ekf::score_rotation`] counted over one rotation.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RotationScore {
    /// Features mapped before the rotation and in view during it.
    pub in_view: u64,
    /// Of those, the ones a target was associated with.
    pub reobserved: u64,
    /// Features retired as unrepeatable.
    pub retired: Vec<FeatureId>,
}

/// What a measurement of the motion since a mark did ([`Ekf::observe_motion_since_mark`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotionOutcome {
    /// Applied, with its normalised innovation squared (3 dof).
    Applied {
        /// Normalised innovation squared.
        nis: f64,
    },
    /// Refused by the gate; nothing changed.
    Gated {
        /// Normalised innovation squared.
        nis: f64,
    },
    /// No mark to measure from; nothing changed.
    NoMark,
}

/// The short and learned rates of targets per second (see
/// [`FilterSettings::burst_factor`]): exponentially decayed target counts and elapsed times.
#[derive(Debug, Clone, Copy, Default)]
struct TargetRate {
    short_count: f64,
    long_count: f64,
    long_time_s: f64,
    last_s: Option<f64>,
}

impl TargetRate {
    /// Counts a beam's `targets` at `time_s`; returns whether the rate is now a burst.
    fn is_burst(&mut self, s: &FilterSettings, time_s: f64, targets: usize) -> bool {
        let dt = match self.last_s {
            Some(last) if time_s >= last => time_s - last,
            // A step back in time (a resynchronised clock): count from here.
            _ => 0.0,
        };
        self.last_s = Some(time_s);
        let n = targets as f64;
        self.short_count = self.short_count * (-dt / s.burst_window_s).exp() + n;
        let decay = (-dt / s.burst_norm_s).exp();
        self.long_count = self.long_count * decay + n;
        self.long_time_s = self.long_time_s * decay + dt;
        if !s.burst_factor.is_finite() || self.long_time_s < s.burst_norm_s.min(2.0) {
            return false;
        }
        let short = self.short_count / s.burst_window_s;
        let norm = self.long_count / self.long_time_s;
        short > s.burst_factor * norm + s.burst_floor_per_s
    }
}

/// A beam's prediction (step 2) and what the association and update need with it.
#[derive(Debug)]
struct PredictedBeam {
    /// The candidates' state slots, in range order.
    slots: Vec<usize>,
    /// Their parameters at prediction time.
    params: Vec<FeatureParams>,
    /// `(R, beta, P)` and the beam-local Jacobian.
    prediction: BeamPrediction,
    /// Whether each candidate's power row is used.
    use_power: Vec<bool>,
    /// State indices of the beam-local columns.
    columns: Vec<usize>,
    /// Covariance of those columns.
    p_cc: DMatrix<f64>,
}

/// The augmented-state EKF with its models.
#[derive(Debug, Clone)]
pub struct Ekf<M, O> {
    settings: FilterSettings,
    gates: GateTable,
    exclusion: GateTable,
    state: SlamState,
    motion: M,
    observer: O,
    odometry: Option<OdometrySample>,
    tentatives: TentativeList,
    stats: FilterStats,
    /// Set after a bridged gap until the pose is relocalised against the map.
    relocalising: Option<Relocalisation>,
    /// Targets per second, for the burst guard.
    target_rate: TargetRate,
    /// Time of the latest beam the filter mapped with (predicted to, or took as empty with
    /// odometry held; not refused, not held for a relocalisation): a rotation with none is
    /// not scored by [`Self::score_rotation`].
    last_mapped_beam_s: f64,
}

impl<M: ProcessModel, O: BeamObservationModel> Ekf<M, O> {
    /// A filter at `pose` (covariance `pose_cov`) at `time_s`, with no features.
    pub fn new(
        settings: FilterSettings,
        pose: Pose2,
        pose_cov: Matrix3<f64>,
        time_s: f64,
        motion: M,
        observer: O,
    ) -> Result<Self, FilterError> {
        settings.validate()?;
        let mut state = SlamState::new(
            pose,
            pose_cov,
            settings.initial_loss_db,
            settings.initial_loss_std_db.powi(2),
            time_s,
        )?;
        state.set_odometry_bias_prior([
            settings.speed_scale_std.powi(2),
            settings.steer_bias_std_rad.powi(2),
        ]);
        Ok(Self {
            gates: GateTable::new(settings.gate_probability, 24),
            exclusion: GateTable::new(
                settings
                    .exclusion_probability
                    .max(settings.gate_probability),
                3,
            ),
            settings,
            state,
            motion,
            observer,
            odometry: None,
            tentatives: TentativeList::default(),
            stats: FilterStats::default(),
            relocalising: None,
            target_rate: TargetRate::default(),
            last_mapped_beam_s: f64::NEG_INFINITY,
        })
    }

    /// The settings in force.
    pub fn settings(&self) -> &FilterSettings {
        &self.settings
    }

    /// The whole state (mean, covariance, tracks). The u, v variances of features not seen
    /// lately lag their random walk until [`Self::settle_material_noise`].
    pub fn state(&self) -> &SlamState {
        &self.state
    }

    /// Running totals.
    pub fn stats(&self) -> &FilterStats {
        &self.stats
    }

    /// The tentative targets.
    pub fn tentatives(&self) -> &TentativeList {
        &self.tentatives
    }

    /// Estimated pose.
    pub fn pose(&self) -> Pose2 {
        self.state.pose()
    }

    /// Pose covariance.
    pub fn pose_covariance(&self) -> Matrix3<f64> {
        self.state.pose_covariance()
    }

    /// Number of features in the state.
    pub fn feature_count(&self) -> usize {
        self.state.feature_count()
    }

    /// Every feature's estimate, in slot order.
    pub fn features(&self) -> Vec<FeatureEstimate> {
        (0..self.state.feature_count())
            .filter_map(|s| self.feature_estimate_at(s))
            .collect()
    }

    fn feature_estimate_at(&self, slot: usize) -> Option<FeatureEstimate> {
        let p = self.state.params(slot)?;
        let track = self.state.tracks().get(slot)?;
        let shares = Material::new(p.u, p.v).shares();
        Some(FeatureEstimate {
            id: track.id,
            x_m: p.x_m,
            y_m: p.y_m,
            rho: shares.rho,
            alpha: shares.alpha,
            position_cov: self.state.position_covariance(slot)?,
            hits: track.hits,
        })
    }

    /// One feature's estimate.
    pub fn feature(&self, id: FeatureId) -> Option<FeatureEstimate> {
        self.feature_estimate_at(self.state.slot_of(id)?)
    }

    /// Pose NEES against the true pose.
    pub fn pose_nees(&self, truth: &Pose2) -> Result<f64, FilterError> {
        pose_nees(&self.pose(), &self.pose_covariance(), truth)
    }

    /// Feature position NEES against its true position.
    pub fn feature_nees(&self, id: FeatureId, truth_xy: [f64; 2]) -> Result<f64, FilterError> {
        let f = self.feature(id).ok_or(FilterError::UnknownFeature(id))?;
        position_nees([f.x_m, f.y_m], &f.position_cov, truth_xy)
    }

    /// Covariance health (`with_eigenvalues` adds an O(n^3) eigen-decomposition) of the
    /// estimated part of the state: the clone (a copy of the pose at the last mark, exactly
    /// collinear with it at the mark) and odometry corrections that are not estimated (zero
    /// mean, zero variance, coupled to nothing) are left out.
    pub fn covariance_health(&self, with_eigenvalues: bool) -> CovarianceHealth {
        use crate::state::{FEATURE_BASE, SPEED_SCALE_INDEX, STEER_BIAS_INDEX};
        let cov = self.state.covariance();
        let kept: Vec<usize> = (0..cov.nrows())
            .filter(|&i| !(CLONE_INDEX..FEATURE_BASE).contains(&i))
            .filter(|&i| {
                !([SPEED_SCALE_INDEX, STEER_BIAS_INDEX].contains(&i) && cov[(i, i)] == 0.0)
            })
            .collect();
        let estimated = cov.select_rows(&kept).select_columns(&kept);
        covariance_health(&estimated, with_eigenvalues)
    }

    /// The odometry corrections `[k, b]` (see [`FilterSettings::speed_scale_std`]) and
    /// their standard deviations; `None` when they are not estimated.
    pub fn odometry_bias(&self) -> Option<([f64; 2], [f64; 2])> {
        if !self.state.estimates_odometry_bias() {
            return None;
        }
        let c = self.state.odometry_bias_covariance();
        Some((
            self.state.odometry_bias(),
            [c[(0, 0)].max(0.0).sqrt(), c[(1, 1)].max(0.0).sqrt()],
        ))
    }

    /// Takes a new odometry sample: predicts to its timestamp with the previous sample held,
    /// then holds this one. After a gap longer than
    /// [`FilterSettings::max_predict_gap_s`] the motion in between is unknown: the gap is
    /// bridged (see [`FilterSettings::gap_speed_mps`]) and counted in
    /// [`FilterStats::bridged_gaps`], never refused. The first sample only starts the clock (the vehicle is assumed
    /// still at the initial pose until then). A sample older than the state is held from
    /// the state's time (counted in [`FilterStats::late_odometry`]).
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
                self.bridge_gap(sample.timestamp_s);
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

    /// Steps the mean pose from the state's time to `time_s` with `held`, in steps of at
    /// most `max_predict_step_s` (as the prediction does).
    fn extrapolate_pose(&self, held: &OdometrySample, time_s: f64) -> Result<Pose2, FilterError> {
        self.extrapolate_from(self.pose(), held, time_s)
    }

    /// Steps `pose`, taken to hold at the state's time, to `time_s` with `held` (as
    /// [`Self::extrapolate_pose`]); unchanged for a time at or before the state's.
    fn extrapolate_from(
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

    /// Jumps the state to `time_s` across an odometry gap: the pose covariance grows by what
    /// the vehicle could have done meanwhile (see [`FilterSettings::gap_speed_mps`]).
    fn bridge_gap(&mut self, time_s: f64) {
        // The motion across the gap is unknown: no tally spans it.
        self.state.tally = None;
        self.inflate_for_gap(time_s - self.state.time_s());
        self.state.set_time_s(time_s);
        self.stats.bridged_gaps += 1;
        self.start_relocalising();
    }

    /// Grows the pose covariance by what the vehicle could do in `gap_s` of unknown motion.
    fn inflate_for_gap(&mut self, gap_s: f64) {
        let s = &self.settings;
        let sigma_xy = (s.gap_speed_mps * gap_s).min(s.gap_max_sigma_m);
        let sigma_theta = (s.gap_yaw_rate_rps * gap_s).min(std::f64::consts::PI);
        self.state.inflate_pose_covariance([
            sigma_xy * sigma_xy,
            sigma_xy * sigma_xy,
            sigma_theta * sigma_theta,
        ]);
    }

    /// Moves the filter onto a new clock at `time_s` (the sensor's clock was set, forwards or
    /// backwards): the map is kept, the pose covariance grows as across a gap of
    /// [`FilterSettings::max_predict_gap_s`] of unknown motion, and the held odometry is
    /// dropped (it belongs to the old clock): beams are refused until odometry on the new
    /// clock arrives. Counted in [`FilterStats::bridged_gaps`].
    pub fn resync_clock(&mut self, time_s: f64) -> Result<(), FilterError> {
        if !time_s.is_finite() {
            return Err(FilterError::NonFiniteObservation {
                what: "timestamp_s",
                value: time_s,
            });
        }
        self.inflate_for_gap(self.settings.max_predict_gap_s);
        self.state.set_time_s(time_s);
        self.state.tally = None;
        self.stats.bridged_gaps += 1;
        self.odometry = None;
        self.tentatives = TentativeList::default();
        self.start_relocalising();
        Ok(())
    }

    /// Marks the state's time as the reference for the next
    /// [`Self::observe_motion_since_mark`]: the pose is copied into the state's clone (see
    /// [`crate::state`]) and the odometry's tally of the motion starts (see
    /// [`crate::motion_tally`]). Any earlier mark is dropped.
    pub fn mark_motion(&mut self) {
        self.state.clone_pose();
        self.state.tally = Some(MotionTally::start(self.state.time_s()));
    }

    /// The tally since the last mark, up to the state's time; `None` without a mark (none
    /// was set, or a gap, a clock jump or a new submap dropped it).
    pub fn motion_tally(&self) -> Option<&MotionTally> {
        self.state.tally.as_ref()
    }

    /// The pose at `time_s` in the frame of the pose at the last mark, as the odometry
    /// drives it (the tally extrapolated with the held odometry, mean only; updates since
    /// the mark do not move it). `None` without a mark or odometry.
    pub fn motion_since_mark(&self, time_s: f64) -> Option<Pose2> {
        let tally = self.state.tally.as_ref()?;
        let held = self.odometry?;
        self.extrapolate_from(tally.rel, &held, time_s).ok()
    }

    /// Updates the state with a measurement of the motion since the last mark: `measured`
    /// is the pose at the state's time in the frame of the pose at the mark (for example
    /// from registering two radar rotations), `cov` its covariance. The prediction is the
    /// estimated pose in the frame of the estimated clone (the pose at the mark, corrected
    /// since by every update through its correlations): stochastic cloning, so the
    /// measurement holds the pose's change itself, and through their correlations the
    /// odometry corrections `k`, `b`, the pose at the mark and the map. The odometry's input
    /// noise since the mark is in the pose's covariance and not in the clone's, so it is
    /// counted once. A measurement whose normalised innovation exceeds `gate_chi2` (3 dof) is
    /// refused and changes nothing; so does one without a mark. The mark stays: call
    /// [`Self::mark_motion`] to start the next interval.
    pub fn observe_motion_since_mark(
        &mut self,
        measured: Pose2,
        cov: &Matrix3<f64>,
        gate_chi2: f64,
    ) -> Result<MotionOutcome, FilterError> {
        if ![measured.x, measured.y, measured.theta]
            .iter()
            .chain(cov.iter())
            .all(|v| v.is_finite())
        {
            return Err(FilterError::NonFiniteInput("measured motion"));
        }
        if self.state.tally.is_none() {
            return Ok(MotionOutcome::NoMark);
        }
        let (predicted, jacobian) = relative_pose(&self.state.clone_pose_mean(), &self.pose());
        let nu = Vector3::new(
            measured.x - predicted.x,
            measured.y - predicted.y,
            wrap_angle(measured.theta - predicted.theta),
        );
        let columns = [0, 1, 2, CLONE_INDEX, CLONE_INDEX + 1, CLONE_INDEX + 2];
        // The gate first, on S = H P H^T + R (3 x 3); then the filter's one batched update.
        let p = self.state.covariance_block(&columns);
        let h = DMatrix::from_fn(3, 6, |r, c| jacobian[(r, c)]);
        let s = &h * p * h.transpose() + DMatrix::from_fn(3, 3, |r, c| cov[(r, c)]);
        let chol = (0.5 * (&s + s.transpose()))
            .cholesky()
            .ok_or(FilterError::InnovationNotPositiveDefinite { dim: 3 })?;
        let nu_d = DVector::from_column_slice(nu.as_slice());
        let nis = nu_d.dot(&chol.solve(&nu_d));
        if !nis.is_finite() || nis > gate_chi2 {
            return Ok(MotionOutcome::Gated { nis });
        }
        batched_update(
            &mut self.state,
            &LinearisedObservation {
                columns: columns.to_vec(),
                jacobian: h,
                innovation: nu_d,
                noise: DMatrix::from_fn(3, 3, |r, c| 0.5 * (cov[(r, c)] + cov[(c, r)])),
            },
        )?;
        self.stats.motion_updates += 1;
        Ok(MotionOutcome::Applied { nis })
    }

    /// Predicts the state to `time_s` with the held odometry.
    pub fn predict_to(&mut self, time_s: f64) -> Result<(), FilterError> {
        let held = self.odometry.ok_or(FilterError::NoOdometry)?;
        predict_to(&mut self.state, &self.motion, &held, time_s, &self.settings)
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
    fn settle_feature_noise(&mut self, slot: usize) {
        self.state
            .settle_material(slot, self.settings.material_variance_per_s);
        self.state.settle_wander(
            slot,
            self.settings.feature_wander_m,
            self.settings.feature_wander_length_m,
        );
    }

    /// Retires every feature within the radar's range of the current pose that no target
    /// has been associated with for [`FilterSettings::retire_unseen_after_s`] (see there);
    /// returns their ids. Call once a rotation. O(N).
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
                let unseen = now - track.last_seen_s > limit;
                let in_range = (near..=far).contains(&rb.range_m);
                (unseen && in_range && in_view(rb.bearing_rad, rb.range_m)).then_some(track.id)
            })
            .collect();
        self.retire(&stale)?;
        Ok(stale)
    }

    /// Removes the features `ids` from the state and counts them retired.
    fn retire(&mut self, ids: &[FeatureId]) -> Result<(), FilterError> {
        for &id in ids {
            self.state.remove(id)?;
            self.stats.retired += 1;
        }
        Ok(())
    }

    /// Scores the rotation that began at `start_s` (call once, at its end): every feature
    /// mapped before it that is within the radar's range of the current pose and in view
    /// (`in_view(bearing_rad, range_m)` in the radar's frame, eq. 4's bearing) counts a
    /// rotation in view, and a re-observation if a target was associated with it since
    /// `start_s`. With [`FilterSettings::retire_unrepeatable_below`] set, a feature whose
    /// share of re-observations is below it once it has been in view for
    /// [`FilterSettings::repeatability_min_rotations`] is retired (not while relocalising).
    /// In view means in range, not predicted visible: a phantom the filter predicts hidden
    /// (occluded, or too weak) would never be judged otherwise. A rotation in which the
    /// filter mapped no beam (odometry missing or stale, beams held for a relocalisation)
    /// is not scored: nothing could be re-observed in it. O(N).
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

    /// Closes the current local map and starts a new one where the vehicle is (see
    /// [`crate::submap`]): the vehicle at the new frame's origin with zero covariance, no
    /// features, the radar loss and the held odometry kept, tentative targets re-expressed
    /// in the new frame. Returns the closed map's compact record (material noise settled
    /// first). O(N).
    pub fn start_submap(&mut self) -> FrozenSubmap {
        self.settle_material_noise();
        let origin = self.state.pose();
        let closed = self.state.restart_at_origin();
        self.tentatives.reframe(&origin);
        FrozenSubmap::from_state(&closed)
    }

    /// Removes a feature (map management); its id is never reused.
    pub fn remove_feature(&mut self, id: FeatureId) -> Result<(), FilterError> {
        self.state.remove(id)
    }

    /// The candidate features of a beam at `bearing_rad` (see [`candidates_in_beam`]).
    pub fn features_in_beam(&self, bearing_rad: f64) -> Vec<BeamCandidate> {
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

    /// The far end of a beam the radar covered out to `max_range_m` (`None`: its full
    /// range): never nearer than the minimum range, never beyond the full range.
    fn beam_far_m(&self, max_range_m: Option<f64>) -> f64 {
        let full = self.settings.max_range_m;
        match max_range_m.filter(|m| !m.is_nan() && *m < full) {
            Some(m) => m.max(self.settings.min_range_m),
            None => full,
        }
    }

    /// [`Self::process_beam`] for a beam the radar covered only out to `max_range_m` (a
    /// contoured azimuth): features beyond it are neither candidates nor missed there.
    pub fn process_beam_within(
        &mut self,
        beam: &BeamObservation,
        max_range_m: f64,
    ) -> Result<BeamReport, FilterError> {
        // Not finite, or not nearer than the full range: nothing to limit.
        let far_m = self.beam_far_m(Some(max_range_m));
        self.process_beam_inner(beam, None, far_m)
    }

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
    /// front end's weaker, less certain landmarks). `max_range_m` limits the beam as
    /// [`Self::process_beam_within`] does. A mask shorter than the beam lets the rest start.
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
        if burst {
            // A burst: the targets may re-observe (above) but start nothing.
            if !unclaimed.is_empty() {
                self.stats.burst_beams += 1;
            }
            unclaimed.clear();
        }
        self.handle_unclaimed(beam, &unclaimed, &mut report, far_m)?;
        self.tentatives
            .expire(beam.timestamp_s, self.settings.tentative_timeout_s);
        Ok(report)
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

    fn ids_of(&self, candidates: &[BeamCandidate]) -> Vec<FeatureId> {
        candidates
            .iter()
            .filter_map(|c| self.state.tracks().get(c.slot).map(|t| t.id))
            .collect()
    }

    fn beam_params(&self, slots: &[usize]) -> Vec<FeatureParams> {
        slots.iter().filter_map(|&s| self.state.params(s)).collect()
    }

    fn noise_var(&self) -> [f64; 3] {
        [
            self.settings.range_std_m.powi(2),
            self.settings.bearing_std_rad.powi(2),
            self.settings.power_std_db.powi(2),
        ]
    }

    /// Step 2: brings the candidates' material noise up to date and predicts their joint
    /// observation, with the covariance of the beam's columns.
    fn predict_observations(
        &mut self,
        candidates: &[BeamCandidate],
    ) -> Result<PredictedBeam, FilterError> {
        let slots: Vec<usize> = candidates.iter().map(|c| c.slot).collect();
        for &slot in &slots {
            self.settle_feature_noise(slot);
        }
        let params = self.beam_params(&slots);
        let prediction = predict_candidates(
            &self.observer,
            &self.pose(),
            self.state.loss_db(),
            candidates,
            &params,
        )?;
        let use_power: Vec<bool> = prediction
            .power_usable
            .iter()
            .map(|&u| u && self.settings.use_power)
            .collect();
        let columns = state_columns(&slots);
        let p_cc = self.state.covariance_block(&columns);
        Ok(PredictedBeam {
            slots,
            params,
            prediction,
            use_power,
            columns,
            p_cc,
        })
    }

    /// Step 3: gates, nearest neighbour or JCBB.
    fn associate_beam(
        &mut self,
        beam: &BeamObservation,
        predicted: &PredictedBeam,
        report: &mut BeamReport,
    ) -> Association {
        let ctx = BeamContext {
            prediction: &predicted.prediction,
            p_cc: &predicted.p_cc,
            use_power: &predicted.use_power,
            noise_var: self.noise_var(),
        };
        let association = associate(
            &ctx,
            &beam.targets,
            &self.gates,
            &self.exclusion,
            self.settings.jcbb_max_nodes,
        );
        report.used_jcbb = association.used_jcbb;
        report.jcbb_budget_exhausted = association.budget_exhausted;
        if association.used_jcbb {
            self.stats.jcbb_runs += 1;
        }
        association
    }

    /// Step 4: one batched update with every associated target; returns the claimed target
    /// indices (associated, or inside a feature's exclusion gate).
    fn update(
        &mut self,
        beam: &BeamObservation,
        predicted: &mut PredictedBeam,
        association: &Association,
        report: &mut BeamReport,
    ) -> Result<Vec<usize>, FilterError> {
        let mut rows: Vec<ObservationRow> = Vec::new();
        let mut inflation = Vec::new();
        let mut nu = Vec::new();
        let mut claimed = Vec::new();
        for (j, f) in association.pairs.iter().enumerate() {
            let (Some(i), Some(t)) = (*f, beam.targets.get(j)) else {
                continue;
            };
            let r = rows_of(i, predicted.use_power.get(i).copied().unwrap_or(false));
            nu.extend(innovation(&predicted.prediction, i, t, &r));
            let k = match (predicted.slots.get(i), predicted.prediction.z.get(i)) {
                (Some(&slot), Some(z)) => self.repeat_look(slot, [z[0], z[1]], beam.timestamp_s),
                _ => 1.0,
            };
            inflation.extend(std::iter::repeat(k).take(r.len()));
            rows.extend(r);
            claimed.push(j);
        }
        for (j, near) in association.near_feature.iter().enumerate() {
            if *near && !claimed.contains(&j) {
                claimed.push(j);
                report.excluded_targets += 1;
                self.stats.excluded_targets += 1;
            }
        }
        if rows.is_empty() {
            return Ok(claimed);
        }
        let var = self.noise_var();
        let noise = DMatrix::from_diagonal(&DVector::from_iterator(
            rows.len(),
            rows.iter()
                .zip(&inflation)
                .map(|(r, &k)| r.component.of(&var) * k),
        ));
        // Association is done: the prediction's Jacobian may now be re-linearised in place.
        let jacobian = &mut predicted.prediction.jacobian;
        if self.settings.first_estimate_jacobians {
            let current: Vec<[f64; 2]> = predicted.params.iter().map(|p| [p.x_m, p.y_m]).collect();
            let first: Vec<[f64; 2]> = predicted
                .slots
                .iter()
                .zip(&current)
                .map(|(&s, &c)| self.state.tracks().get(s).map_or(c, |t| t.first_xy_m))
                .collect();
            relinearise_at_first_estimates(jacobian, &self.pose(), &current, &first);
        }
        let obs = LinearisedObservation {
            columns: predicted.columns.clone(),
            jacobian: jacobian.select_rows(row_indices(&rows).iter()),
            innovation: DVector::from_vec(nu),
            noise,
        };
        let outcome = self.landmark_update(&obs)?;
        self.stats.updates += 1;
        self.stats.nis_sum += outcome.nis;
        self.stats.nis_dof_sum += outcome.dof as u64;
        report.update = Some(outcome);
        Ok(claimed)
    }

    /// One batched update from landmarks (a beam's targets, a new feature's power,
    /// relocalisation): the speed correction `k` is held as a consider parameter when
    /// [`FilterSettings::speed_scale_from_landmarks`] is off and `k` is estimated.
    pub(crate) fn landmark_update(
        &mut self,
        obs: &LinearisedObservation,
    ) -> Result<UpdateOutcome, FilterError> {
        let hold_k = !self.settings.speed_scale_from_landmarks
            && self
                .state
                .covariance_entry(SPEED_SCALE_INDEX, SPEED_SCALE_INDEX)
                > 0.0;
        let consider: &[usize] = if hold_k { &[SPEED_SCALE_INDEX] } else { &[] };
        batched_update_considering(&mut self.state, obs, consider)
    }

    /// Whether each predicted feature would be detectable (power above the threshold); all
    /// are when power is not used.
    fn visible(&self, prediction: &BeamPrediction) -> Vec<bool> {
        prediction
            .z
            .iter()
            .map(|z| !self.settings.use_power || z[2] >= self.settings.min_detectable_power_db)
            .collect()
    }

    /// Counts a look at the feature in `slot` and returns its noise inflation (see
    /// [`crate::repeat_look`]).
    fn repeat_look(&mut self, slot: usize, look: [f64; 2], now: f64) -> f64 {
        let cell = LookCell::from_settings(&self.settings);
        self.state
            .track_mut(slot)
            .map_or(1.0, |track| cell.inflation(track, look, now))
    }

    /// Hits for the candidates a target was paired with; a miss for each candidate expected
    /// in the beam and `visible` (predicted above the detection threshold) but not paired;
    /// retirement after too many consecutive misses.
    fn book_keep(
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
