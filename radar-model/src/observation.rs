//! The observation of every feature in one beam (the paper's eq. 14):
//! `z_i = [R_i, beta_i, P_i]` from eq. 3, 4 and 13, with the dense analytic Jacobian with
//! respect to `[pose (3), (x, y, u, v) per beam feature (4 each), L (1)]`, in the caller's
//! (beam-local) order of features.
//!
//! The power of a feature depends on every feature in front of it, so the power rows are
//! dense to the left of the diagonal in range order. The caller may pass the features in
//! any order: they are ranked by their predicted range here (ties by position in the
//! slice), and rows and columns follow the caller's order.

use crate::error::ModelError;
use crate::geometry::{range_bearing_with_jacobian, Pose2, RangeBearingJacobian};
use crate::material::Material;
use crate::power::{beam_powers_with_jacobian, PowerModel, PowerTarget};
use nalgebra::DMatrix;

use crate::layout::{self, Component, ObservationRow};
pub use crate::layout::{FEATURE_COLUMNS, POSE_COLUMNS};

/// A feature in a beam, as held in the state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamFeature {
    /// World position `[x, y]` (m).
    pub xy: [f64; 2],
    /// Material `(u, v)`.
    pub material: Material,
}

/// One predicted observation `[R, beta, P]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Range (m), eq. 3.
    pub range_m: f64,
    /// Bearing (rad), eq. 4.
    pub bearing_rad: f64,
    /// Uncompensated received power (dBm), eq. 13 minus `L`.
    pub power_db: f64,
}

impl Observation {
    /// As the array `[R, beta, P]`.
    pub fn as_array(&self) -> [f64; 3] {
        [self.range_m, self.bearing_rad, self.power_db]
    }
}

/// The observation of one beam.
#[derive(Debug, Clone, PartialEq)]
pub struct BeamObservation {
    /// `z_i` per feature, in the caller's order.
    pub z: Vec<Observation>,
    /// Whether feature `i` is closer than the range resolution to a neighbour down the beam.
    pub unresolvable: Vec<bool>,
    /// `(3 n) x (3 + 4 n + 1)`: rows `[R_i, beta_i, P_i]` per feature; columns
    /// `[x, y, theta, (x_k, y_k, u_k, v_k) per feature, L]`.
    pub jacobian: DMatrix<f64>,
}

impl BeamObservation {
    /// Column index of feature `k`'s first (`x`) column.
    pub fn feature_column(k: usize) -> usize {
        layout::feature_column(k)
    }

    /// Column index of `L` for a beam of `n` features.
    pub fn loss_column(n: usize) -> usize {
        layout::loss_column(n)
    }
}

/// Predicts `[R_i, beta_i, P_i]` for every feature in one beam and the dense Jacobian
/// (eq. 3, 4, 13, 14), rows and columns as [`crate::layout`] lays them out.
///
/// # Errors
/// Non-finite inputs, a feature at the sensor, or an invalid power model.
pub fn observe_beam(
    pose: &Pose2,
    features: &[BeamFeature],
    loss_db: f64,
    model: &PowerModel,
) -> Result<BeamObservation, ModelError> {
    let n = features.len();
    let mut geometry: Vec<RangeBearingJacobian> = Vec::with_capacity(n);
    let mut z = Vec::with_capacity(n);
    for f in features {
        let (rb, jac) = range_bearing_with_jacobian(pose, f.xy)?;
        geometry.push(jac);
        z.push(Observation {
            range_m: rb.range_m,
            bearing_rad: rb.bearing_rad,
            power_db: 0.0,
        });
    }
    // Rank by range: order[r] is the caller index of the r-th nearest feature.
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| z[a].range_m.total_cmp(&z[b].range_m).then(a.cmp(&b)));
    let targets: Vec<PowerTarget> = order
        .iter()
        .map(|&k| PowerTarget {
            range_m: z[k].range_m,
            material: features[k].material,
        })
        .collect();
    let powers = beam_powers_with_jacobian(model, &targets, loss_db)?;

    let cols = layout::columns(n);
    let mut jacobian = DMatrix::zeros(layout::rows(n), cols);
    let mut unresolvable = vec![false; n];
    for (k, g) in geometry.iter().enumerate() {
        g.write_rows(
            &mut jacobian,
            ObservationRow::new(k, Component::Range).index(),
            layout::feature_column(k),
        );
    }
    for (ri, &i) in order.iter().enumerate() {
        z[i].power_db = powers.power_db[ri];
        unresolvable[i] = powers.unresolvable[ri];
        let row = ObservationRow::new(i, Component::Power).index();
        for (rk, &k) in order.iter().enumerate().take(ri + 1) {
            let d_range = powers.wrt_range[(ri, rk)];
            let g = &geometry[k];
            for c in 0..POSE_COLUMNS {
                jacobian[(row, c)] += d_range * g.range_wrt_pose[c];
            }
            let fc = layout::feature_column(k);
            jacobian[(row, fc)] = d_range * g.range_wrt_feature[0];
            jacobian[(row, fc + 1)] = d_range * g.range_wrt_feature[1];
            jacobian[(row, fc + 2)] = powers.wrt_u[(ri, rk)];
            jacobian[(row, fc + 3)] = powers.wrt_v[(ri, rk)];
        }
        jacobian[(row, layout::loss_column(n))] = -1.0;
    }
    Ok(BeamObservation {
        z,
        unresolvable,
        jacobian,
    })
}
