//! The accepted pairings of a relocalisation as one iterated EKF update: Gauss-Newton on the
//! pose and the paired features from the corrected pose, the joint-compatibility gate, and
//! the pairings dropped worst first until it passes.

use nalgebra::{DMatrix, DVector};
use radar_model::geometry::{range_bearing, range_bearing_with_jacobian, wrap_angle, Pose2};

use super::{Attempt, Correction, HeldTarget, MapPoint};
use crate::error::FilterError;
use crate::observation::BeamObservationModel;
use crate::predict::ProcessModel;
use crate::state::feature_index;
use crate::update::LinearisedObservation;
use crate::Ekf;

/// Gauss-Newton iterations of the relocalisation update.
const ITERATIONS: usize = 10;

impl<M: ProcessModel, O: BeamObservationModel> Ekf<M, O> {
    /// The accepted pairings as one iterated update from the corrected pose, once they are
    /// jointly compatible there: while the stacked innovation fails its chi-square gate, the
    /// pairing with the largest residual is dropped (a clutter point or a phantom that the
    /// coarse isotropic gate let in), down to `relocalise_min_features` pairings.
    pub(super) fn relocalisation_update(
        &mut self,
        correction: &Correction,
        pairing: &[(usize, usize)],
        held: &[HeldTarget],
        map: &[MapPoint],
    ) -> Result<Attempt, FilterError> {
        let start = correction.apply_pose(&self.pose());
        let mut pairs = self.observations(pairing, held, map);
        while pairs.len() >= self.settings.relocalise_min_features {
            let Some(fit) = self.fit(&pairs, &start) else {
                return Ok(Attempt::Refused);
            };
            if fit.nis <= self.gates.threshold(fit.obs.innovation.len()) {
                let outcome = self.landmark_update(&fit.obs)?;
                self.stats.updates += 1;
                self.stats.nis_sum += outcome.nis;
                self.stats.nis_dof_sum += outcome.dof as u64;
                let now = self.state.time_s();
                for &(slot, _) in &pairs {
                    if let Some(track) = self.state.track_mut(slot) {
                        track.hits += 1;
                        track.consecutive_misses = 0;
                        track.last_seen_s = now;
                    }
                }
                return Ok(Attempt::Accepted);
            }
            let Some(worst) = fit
                .residuals
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1))
                .map(|(k, _)| k)
            else {
                break;
            };
            pairs.remove(worst);
        }
        Ok(Attempt::Refused)
    }

    /// The pairings `(map index, held index)` as `(slot, [R, beta])`: each held point as an
    /// observation made now from the mean pose.
    pub(super) fn observations(
        &self,
        pairing: &[(usize, usize)],
        held: &[HeldTarget],
        map: &[MapPoint],
    ) -> Vec<(usize, [f64; 2])> {
        let now_pose = self.pose();
        pairing
            .iter()
            .map(|&(m, j)| {
                let rb = range_bearing(&now_pose, held[j].xy);
                (map[m].slot, [rb.range_m, rb.bearing_rad])
            })
            .collect()
    }

    /// Whether `pairs` fitted from `start` pass the chi-square gate of their dimension.
    pub(super) fn jointly_compatible(&self, pairs: &[(usize, [f64; 2])], start: &Pose2) -> bool {
        self.fit(pairs, start)
            .is_some_and(|fit| fit.nis <= self.gates.threshold(fit.obs.innovation.len()))
    }

    /// Gauss-Newton on the pose and the paired features' positions (the other columns
    /// follow through the covariance), started at `start` with the features at their
    /// means; then the ordinary update's observation at the last linearisation, its NIS,
    /// and each pairing's residual there (squared, in measurement-noise units).
    fn fit(&self, pairs: &[(usize, [f64; 2])], start: &Pose2) -> Option<Fit> {
        let mut columns = vec![0, 1, 2];
        for &(slot, _) in pairs {
            let fi = feature_index(slot);
            columns.extend([fi, fi + 1]);
        }
        let x0: Vec<f64> = columns.iter().map(|&c| self.state.mean()[c]).collect();
        let p_cc = self.state.covariance_block(&columns);
        let var = [
            self.settings.range_std_m.powi(2),
            self.settings.bearing_std_rad.powi(2),
        ];
        let m = 2 * pairs.len();
        let noise = DMatrix::from_diagonal(&DVector::from_iterator(m, (0..m).map(|r| var[r % 2])));
        let mut x = x0.clone();
        x[0] = start.x;
        x[1] = start.y;
        x[2] = start.theta;
        let mut last: Option<(DMatrix<f64>, DVector<f64>, Vec<f64>)> = None;
        for _ in 0..ITERATIONS {
            let pose = Pose2::new(x[0], x[1], x[2]);
            let mut h = DMatrix::zeros(m, columns.len());
            let mut nu = DVector::zeros(m);
            let mut residuals = Vec::with_capacity(pairs.len());
            for (k, (_, zk)) in pairs.iter().enumerate() {
                let f = [x[3 + 2 * k], x[4 + 2 * k]];
                let (rb, jac) = range_bearing_with_jacobian(&pose, f).ok()?;
                for c in 0..3 {
                    h[(2 * k, c)] = jac.range_wrt_pose[c];
                    h[(2 * k + 1, c)] = jac.bearing_wrt_pose[c];
                }
                for c in 0..2 {
                    h[(2 * k, 3 + 2 * k + c)] = jac.range_wrt_feature[c];
                    h[(2 * k + 1, 3 + 2 * k + c)] = jac.bearing_wrt_feature[c];
                }
                nu[2 * k] = zk[0] - rb.range_m;
                nu[2 * k + 1] = wrap_angle(zk[1] - rb.bearing_rad);
                residuals.push(nu[2 * k].powi(2) / var[0] + nu[2 * k + 1].powi(2) / var[1]);
            }
            // The innovation about the prior mean x0, linearised at x (the bearing rows are
            // wrapped where measured; the linear term is not an angle to wrap).
            let mut dx = DVector::from_iterator(x.len(), x0.iter().zip(&x).map(|(a, b)| a - b));
            dx[2] = wrap_angle(dx[2]);
            let nu0 = &nu - &h * &dx;
            let pht = &p_cc * h.transpose();
            let chol = (&h * &pht + &noise).cholesky()?;
            let step = &pht * chol.solve(&nu0);
            let mut moved: f64 = 0.0;
            for (k, xk) in x.iter_mut().enumerate() {
                let next = x0[k] + step[k];
                moved = moved.max((next - *xk).abs());
                *xk = next;
            }
            x[2] = wrap_angle(x[2]);
            last = Some((h, nu0, residuals));
            if moved < 1e-9 {
                break;
            }
        }
        let (h, nu, residuals) = last?;
        let chol = (&h * (&p_cc * h.transpose()) + &noise).cholesky()?;
        let nis = nu.dot(&chol.solve(&nu));
        nis.is_finite().then_some(Fit {
            obs: LinearisedObservation {
                columns,
                jacobian: h,
                innovation: nu,
                noise,
            },
            nis,
            residuals,
        })
    }
}

/// A relocalisation fit: the observation to apply, its NIS, and each pairing's residual.
struct Fit {
    obs: LinearisedObservation,
    nis: f64,
    residuals: Vec<f64>,
}
