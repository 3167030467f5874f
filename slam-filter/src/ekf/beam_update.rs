//! Steps 2 to 4 of a beam: the joint prediction of the beam's features (range, bearing and
//! the multi-target power of eq. 13) with the covariance of its columns, the association of
//! the beam's targets with it, and one batched update (eq. 14) with every associated target,
//! its noise inflated for repeated looks and its Jacobian re-linearised at the first
//! estimates when set.

use nalgebra::{DMatrix, DVector};
use radar_model::layout::ObservationRow;

use super::{BeamReport, Ekf};
use crate::association::{associate, innovation, rows_of, Association, BeamContext};
use crate::beam::{predict_candidates, BeamCandidate};
use crate::error::FilterError;
use crate::fej::relinearise_at_first_estimates;
use crate::observation::{
    row_indices, state_columns, BeamObservation, BeamObservationModel, BeamPrediction,
};
use crate::predict::ProcessModel;
use crate::repeat_look::LookCell;
use crate::state::{FeatureId, FeatureParams, SPEED_SCALE_INDEX, STEER_BIAS_INDEX};
use crate::update::{batched_update_considering, LinearisedObservation, UpdateOutcome};

/// A beam's prediction (step 2) and what the association and update need with it.
#[derive(Debug)]
pub(super) struct PredictedBeam {
    /// The candidates' state slots, in range order.
    slots: Vec<usize>,
    /// Their parameters at prediction time.
    params: Vec<FeatureParams>,
    /// `(R, beta, P)` and the beam-local Jacobian.
    pub(super) prediction: BeamPrediction,
    /// Whether each candidate's power row is used.
    use_power: Vec<bool>,
    /// State indices of the beam-local columns.
    columns: Vec<usize>,
    /// Covariance of those columns.
    p_cc: DMatrix<f64>,
}

impl<M: ProcessModel, O: BeamObservationModel> Ekf<M, O> {
    pub(super) fn ids_of(&self, candidates: &[BeamCandidate]) -> Vec<FeatureId> {
        candidates
            .iter()
            .filter_map(|c| self.state.tracks().get(c.slot).map(|t| t.id))
            .collect()
    }

    pub(super) fn beam_params(&self, slots: &[usize]) -> Vec<FeatureParams> {
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
    pub(super) fn predict_observations(
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
    pub(super) fn associate_beam(
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
    pub(super) fn update(
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
            inflation.extend(std::iter::repeat_n(k, r.len()));
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

    /// One batched update from landmarks (a beam's targets, a new feature's power, relocalisation):
    /// the speed correction `k` is held as a consider parameter when
    /// [`FilterSettings::speed_scale_from_landmarks`](crate::FilterSettings::speed_scale_from_landmarks)
    /// is off and `k` is estimated, and the steering offset `b` likewise
    /// ([`FilterSettings::steer_bias_from_landmarks`](crate::FilterSettings::steer_bias_from_landmarks)).
    pub(super) fn landmark_update(
        &mut self,
        obs: &LinearisedObservation,
    ) -> Result<UpdateOutcome, FilterError> {
        let hold_k = !self.settings.speed_scale_from_landmarks
            && self
                .state
                .covariance_entry(SPEED_SCALE_INDEX, SPEED_SCALE_INDEX)
                > 0.0;
        let hold_b = !self.settings.steer_bias_from_landmarks
            && self
                .state
                .covariance_entry(STEER_BIAS_INDEX, STEER_BIAS_INDEX)
                > 0.0;
        let consider: &[usize] = match (hold_k, hold_b) {
            (true, true) => &[SPEED_SCALE_INDEX, STEER_BIAS_INDEX],
            (true, false) => &[SPEED_SCALE_INDEX],
            (false, true) => &[STEER_BIAS_INDEX],
            (false, false) => &[],
        };
        batched_update_considering(&mut self.state, obs, consider)
    }

    /// Whether each predicted feature would be detectable (power above the threshold); all
    /// are when power is not used.
    pub(super) fn visible(&self, prediction: &BeamPrediction) -> Vec<bool> {
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
}
