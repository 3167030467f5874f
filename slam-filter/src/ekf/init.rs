//! Turning unclaimed targets into features: the tentative list, then initialisation with
//! full cross-covariances and a power-only update.

use nalgebra::{DMatrix, DVector, Matrix2, Matrix4};
use radar_model::geometry::{range_bearing, wrap_angle, Pose2};
use radar_model::layout::{self, Component, ObservationRow};
use radar_model::material::Material;

use super::{BeamReport, Ekf};
use crate::beam::{predict_candidates, BeamCandidate};
use crate::error::FilterError;
use crate::lifecycle::{inverse_observation, Sighting};
use crate::observation::{state_columns, BeamObservation, BeamObservationModel, Target};
use crate::predict::ProcessModel;
use crate::state::{FeatureId, FeatureParams, FEATURE_DIM};
use crate::update::LinearisedObservation;

/// Gauss-Newton iterations of a new feature's power update.
const INIT_POWER_ITERATIONS: usize = 10;

/// Pose, feature parameters and L from values in beam-column order
/// `[x, y, theta, (x, y, u, v) per feature, L]`.
fn unpack_beam_columns(x: &[f64], features: usize) -> (Pose2, Vec<FeatureParams>, f64) {
    let get = |i: usize| x.get(i).copied().unwrap_or(0.0);
    let pose = Pose2::new(get(0), get(1), get(2));
    let params = (0..features)
        .map(|k| {
            let b = layout::feature_column(k);
            FeatureParams {
                x_m: get(b),
                y_m: get(b + 1),
                u: get(b + 2),
                v: get(b + 3),
            }
        })
        .collect();
    (pose, params, get(layout::loss_column(features)))
}

impl<M: ProcessModel, O: BeamObservationModel> Ekf<M, O> {
    pub(super) fn handle_unclaimed(
        &mut self,
        beam: &BeamObservation,
        unclaimed: &[usize],
        report: &mut BeamReport,
        far_m: f64,
    ) -> Result<(), FilterError> {
        if !self.settings.add_features {
            self.stats.dropped_targets += unclaimed.len() as u64;
            return Ok(());
        }
        let gate2 = self.gates.threshold(2);
        for &j in unclaimed {
            let Some(t) = beam.targets.get(j) else {
                continue;
            };
            if t.range_m < self.settings.min_range_m || t.range_m > far_m {
                continue;
            }
            let sighting = self.tentatives.offer(
                &self.pose(),
                &self.state.pose_churn,
                [
                    self.settings.range_std_m.powi(2),
                    self.settings.bearing_std_rad.powi(2),
                ],
                t,
                beam.timestamp_s,
                gate2,
                self.settings.confirm_min_separation_s,
                self.settings.confirm_after,
                self.settings.max_tentatives,
            );
            match sighting {
                Sighting::New => report.new_tentatives += 1,
                Sighting::Refreshed => {}
                Sighting::Dropped => self.stats.dropped_targets += 1,
                Sighting::Confirmed => {
                    if self.state.feature_count() >= self.settings.max_features {
                        self.stats.dropped_targets += 1;
                        continue;
                    }
                    let id = self.initialise_feature(t, beam.bearing_rad, beam.timestamp_s)?;
                    report.initialised.push(id);
                }
            }
        }
        Ok(())
    }

    /// Adds a feature from target `t` (eq. 3, 4 inverted, with full cross-covariances); u, v
    /// start from the prior shares with no correlation; then, if power is used, the target's
    /// power alone updates the state (range and bearing were spent on the position).
    pub fn initialise_feature(
        &mut self,
        t: &Target,
        beam_bearing_rad: f64,
        time_s: f64,
    ) -> Result<FeatureId, FilterError> {
        t.check()?;
        if t.range_m < self.settings.min_range_m {
            // At zero range the bearing carries no information: the new feature's position
            // would be perfectly correlated with the pose across the line of sight.
            return Err(FilterError::TargetTooClose {
                range_m: t.range_m,
                min_range_m: self.settings.min_range_m,
            });
        }
        let pose = self.pose();
        let (p, g_pose, g_rb) = inverse_observation(&pose, t);
        let material =
            Material::from_rho_alpha(self.settings.initial_rho, self.settings.initial_alpha)
                .map_err(FilterError::Model)?;
        let n = self.state.dim();
        // The pose rows are read whole: bring the upper triangle up to date (augment
        // would next).
        self.state.sync_upper();
        let cov = &self.state.cov;
        let mut cross = DMatrix::zeros(FEATURE_DIM, n);
        let pose_rows = cov.rows(0, 3);
        let gx = g_pose * pose_rows; // 2 x n
        cross.rows_mut(0, 2).copy_from(&gx);
        let rz = Matrix2::new(
            self.settings.range_std_m.powi(2),
            0.0,
            0.0,
            self.settings.bearing_std_rad.powi(2),
        );
        let p_vv = self.state.pose_covariance();
        let p_ff = g_pose * p_vv * g_pose.transpose() + g_rb * rz * g_rb.transpose();
        let mut block = Matrix4::zeros();
        block.fixed_view_mut::<2, 2>(0, 0).copy_from(&p_ff);
        let m_var = self.settings.initial_material_std.powi(2);
        block[(2, 2)] = m_var;
        block[(3, 3)] = m_var;
        let id = self.state.augment(
            [p.x, p.y, material.u, material.v],
            &cross,
            &block,
            time_s,
            self.settings.max_features,
        )?;
        self.stats.initialised += 1;
        if self.settings.use_power {
            self.power_update_new(id, t, beam_bearing_rad)?;
        }
        Ok(id)
    }

    /// The power-only update of a feature just initialised, within its beam.
    fn power_update_new(
        &mut self,
        id: FeatureId,
        t: &Target,
        beam_bearing_rad: f64,
    ) -> Result<(), FilterError> {
        let Some(new_slot) = self.state.slot_of(id) else {
            return Err(FilterError::UnknownFeature(id));
        };
        let mut candidates = self.features_in_beam(beam_bearing_rad);
        if !candidates.iter().any(|c| c.slot == new_slot) {
            // The target's noisy bearing put it outside the candidate arc: predict it with
            // the beam's expected features in front of it.
            let Some(p) = self.state.params(new_slot) else {
                return Err(FilterError::UnknownFeature(id));
            };
            let rb = range_bearing(&self.pose(), [p.x_m, p.y_m]);
            if rb.range_m < self.settings.min_range_m {
                return Ok(()); // On top of the radar: no bearing, no power prediction.
            }
            candidates.push(BeamCandidate {
                slot: new_slot,
                range_m: rb.range_m,
                offset_rad: wrap_angle(rb.bearing_rad - beam_bearing_rad).abs(),
                sigma_rad: 0.0,
                expected: false,
                ambiguous: false,
            });
            candidates.sort_by(|a, b| a.range_m.total_cmp(&b.range_m).then(a.slot.cmp(&b.slot)));
        }
        let slots: Vec<usize> = candidates.iter().map(|c| c.slot).collect();
        for &slot in &slots {
            self.settle_feature_noise(slot);
        }
        let Some(local) = slots.iter().position(|&s| s == new_slot) else {
            return Ok(());
        };
        let row = ObservationRow::new(local, Component::Power).index();
        let columns = state_columns(&slots);
        let x0: Vec<f64> = columns.iter().map(|&c| self.state.mean()[c]).collect();
        let p_cc = self.state.covariance_block(&columns);
        let r = self.settings.power_std_db.powi(2);
        // Iterated EKF (Gauss-Newton on the beam's columns): a new feature's material starts
        // from a prior that may be tens of dB from what it shows, and one linearisation there
        // overshoots. Iterate the mean on the beam's columns, then apply one ordinary update
        // with the last linearisation: mean x0 + K nu, covariance P - K S K^T.
        let mut x = x0.clone();
        let mut last: Option<(DMatrix<f64>, f64)> = None;
        for _ in 0..INIT_POWER_ITERATIONS {
            let (pose, params, loss_db) = unpack_beam_columns(&x, slots.len());
            let pred = predict_candidates(&self.observer, &pose, loss_db, &candidates, &params)?;
            let usable = pred.power_usable.get(local).copied().unwrap_or(false);
            let Some(zhat) = pred.z.get(local).filter(|_| usable) else {
                break;
            };
            let h = pred.jacobian.select_rows([row].iter());
            let mut dx = DVector::from_iterator(x.len(), x0.iter().zip(&x).map(|(a, b)| a - b));
            dx[2] = wrap_angle(dx[2]);
            let nu = t.power_db - Component::Power.of(zhat) - (&h * &dx)[0];
            let pht = &p_cc * h.transpose();
            let s_val = (&h * &pht)[0] + r;
            if !(s_val.is_finite() && s_val > 0.0 && nu.is_finite()) {
                break;
            }
            let mut step: f64 = 0.0;
            for (k, xk) in x.iter_mut().enumerate() {
                let next = x0[k] + pht[k] * nu / s_val;
                step = step.max((next - *xk).abs());
                *xk = next;
            }
            last = Some((h, nu));
            if step < 1e-9 {
                break;
            }
        }
        let Some((h, nu)) = last else {
            return Ok(());
        };
        let obs = LinearisedObservation {
            columns,
            jacobian: h,
            innovation: DVector::from_element(1, nu),
            noise: DMatrix::from_element(1, 1, r),
        };
        self.landmark_update(&obs)?;
        Ok(())
    }
}
