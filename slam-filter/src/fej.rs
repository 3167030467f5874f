//! First-estimates Jacobians (FEJ-EKF; Huang, Mourikis and Roumeliotis).
//!
//! The standard EKF linearises each feature's observation at its current estimate, which
//! moves with every update: the linearisations then disagree about which directions of the
//! state are unobservable, and the filter gains information on the map's global heading that
//! no measurement carries. Here every feature's range, bearing and power Jacobians are
//! evaluated at the position the feature entered the state with, so every linearisation
//! agrees that a rotation of the whole world is unobservable. The propagation's side of FEJ
//! (the heading column at the pose as last predicted) is in [`crate::predict`].
//! Switched by [`crate::FilterSettings::first_estimate_jacobians`].

use nalgebra::DMatrix;
use radar_model::geometry::{range_bearing_with_jacobian, Pose2};
use radar_model::layout::{self, Component, ObservationRow};

/// Re-linearises the geometric part of a beam prediction's Jacobian at each feature's first
/// estimate (first-estimates Jacobians, see
/// [`crate::FilterSettings::first_estimate_jacobians`]). `current` and `first` are the features'
/// present and first positions in the prediction's candidate order.
///
/// - range and bearing rows of feature `i`: the pose and `(x_i, y_i)` columns are replaced
///   by eq. 3 and 4's Jacobians at `(pose, first_i)`;
/// - power rows: the power depends on the pose and the positions only through the ranges,
///   so `dP_i/dR_k = dP_i/d(x_k, y_k) . u_k` with `u_k` the current unit vector from the
///   radar to feature `k`; the geometric columns are rebuilt as `dP_i/dR_k` times the range
///   Jacobian at the first estimate. The u, v and L columns are left as they are.
///
/// A feature on top of the radar (zero range) keeps its current Jacobian.
pub fn relinearise_at_first_estimates(
    jacobian: &mut DMatrix<f64>,
    pose: &Pose2,
    current: &[[f64; 2]],
    first: &[[f64; 2]],
) {
    let k = current.len().min(first.len());
    if jacobian.nrows() < layout::rows(k) || jacobian.ncols() < layout::loss_column(k) {
        return;
    }
    let unit = |p: [f64; 2]| -> Option<[f64; 2]> {
        let (dx, dy) = (p[0] - pose.x, p[1] - pose.y);
        let r = dx.hypot(dy);
        (r > 1e-9 && r.is_finite()).then(|| [dx / r, dy / r])
    };
    let units: Vec<Option<([f64; 2], [f64; 2])>> = (0..k)
        .map(|i| Some((unit(current[i])?, unit(first[i])?)))
        .collect();
    for i in 0..k {
        if units[i].is_some() {
            if let Ok((_, jac)) = range_bearing_with_jacobian(pose, first[i]) {
                jac.write_rows(
                    jacobian,
                    ObservationRow::new(i, Component::Range).index(),
                    layout::feature_column(i),
                );
            }
        }
        let row = ObservationRow::new(i, Component::Power).index();
        let mut pose_x = jacobian[(row, 0)];
        let mut pose_y = jacobian[(row, 1)];
        for (q, u) in units.iter().enumerate() {
            let Some((now, then)) = u else { continue };
            let qc = layout::feature_column(q);
            let d_range = jacobian[(row, qc)] * now[0] + jacobian[(row, qc + 1)] * now[1];
            // Remove this feature's current contribution to the pose columns, add the FEJ one.
            pose_x += d_range * (now[0] - then[0]);
            pose_y += d_range * (now[1] - then[1]);
            jacobian[(row, qc)] = d_range * then[0];
            jacobian[(row, qc + 1)] = d_range * then[1];
        }
        jacobian[(row, 0)] = pose_x;
        jacobian[(row, 1)] = pose_y;
    }
}
