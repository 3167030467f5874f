//! Which features a beam concerns, and their joint prediction.
//!
//! The radar reports the beam's azimuth exactly; the filter knows each feature's bearing
//! only as an estimate with a standard deviation `sigma_beta` (pose, feature and their
//! correlation). So:
//!
//! - a feature is a **candidate** for association when its estimated bearing is within
//!   `beam_half_width + association_margin + candidate_sigmas * sqrt(sigma_beta^2 +
//!   bearing_std^2)` of the beam: a target lands in the beam its *measured* bearing falls in,
//!   so the measurement's bearing noise widens the arc too (without it a precise estimate, as
//!   at a standstill, loses its noisier sightings one azimuth over to duplicate features);
//! - it is **expected** in the beam (an occluder for the features behind it, and a miss if
//!   not seen) when its estimated bearing is inside the beam's half width;
//! - its membership is **ambiguous** when its estimated bearing is within
//!   `candidate_sigmas * sigma_beta` of the beam's edge.
//!
//! The multi-target power (eq. 13) of a feature depends on exactly which features lie in
//! front of it in the beam, and a wrong guess changes it by tens of dB (the paper's form
//! spreads over the separation to the nearest one in front). So each candidate's power is
//! predicted with the expected features in front of it as occluders, and its power row is
//! dropped (range and bearing still used) when any nearer candidate's membership is
//! ambiguous, or when it is not resolvable in range from another candidate (the radar sees
//! one merged peak there).

use nalgebra::DMatrix;
use radar_model::geometry::{range_bearing, range_bearing_with_jacobian, wrap_angle, Pose2};

use super::error::FilterError;
use super::observation::{beam_columns, BeamObservationModel, BeamPrediction};
use super::settings::FilterSettings;
use super::state::{feature_index, FeatureParams, SlamState, FEATURE_DIM, POSE_DIM};

/// A feature considered for one beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamCandidate {
    /// Its slot in the state.
    pub slot: usize,
    /// Its predicted range (m).
    pub range_m: f64,
    /// `|wrap(beta_hat - beam)|` (rad).
    pub offset_rad: f64,
    /// Standard deviation of its predicted bearing (rad).
    pub sigma_rad: f64,
    /// Estimated bearing inside the beam: an occluder, and a miss if not seen.
    pub expected: bool,
    /// Estimated bearing within `candidate_sigmas` standard deviations of the beam's edge.
    pub ambiguous: bool,
}

/// The candidates of a beam at `bearing_rad` seen from `pose` (the state's, or a mean-only
/// extrapolation of it), sorted by range. O(N) in the number of features, O(1) each.
pub fn candidates_in_beam(
    state: &SlamState,
    settings: &FilterSettings,
    pose: &Pose2,
    bearing_rad: f64,
) -> Vec<BeamCandidate> {
    let pose = *pose;
    let cov = state.covariance();
    let half = settings.beam_half_width_rad;
    let base = half + settings.association_margin_rad;
    let k = settings.candidate_sigmas;
    let mut out = Vec::new();
    for slot in 0..state.feature_count() {
        let Some(p) = state.params(slot) else {
            continue;
        };
        let rb = range_bearing(&pose, [p.x_m, p.y_m]);
        if rb.range_m < settings.min_range_m || rb.range_m > settings.max_range_m {
            continue;
        }
        let offset = wrap_angle(rb.bearing_rad - bearing_rad).abs();
        let fi = feature_index(slot);
        // Cheap bound first: sigma_beta <= |h| sqrt(trace), |h|^2 = 1 + 2 / R^2.
        let trace = cov[(0, 0)] + cov[(1, 1)] + cov[(2, 2)] + cov[(fi, fi)] + cov[(fi + 1, fi + 1)];
        let bound = ((1.0 + 2.0 / (rb.range_m * rb.range_m)) * trace)
            .max(0.0)
            .sqrt();
        // A target from this feature lands in this beam when the feature's bearing plus the
        // measurement's bearing noise does: the arc is sized on the innovation's bearing
        // sigma, not the estimate's alone (or a precise estimate, as at a standstill, loses
        // its noisier sightings to a duplicate).
        let meas_var = settings.bearing_std_rad * settings.bearing_std_rad;
        if offset > base + k * (bound * bound + meas_var).sqrt() {
            continue;
        }
        let Ok((_, jac)) = range_bearing_with_jacobian(&pose, [p.x_m, p.y_m]) else {
            continue;
        };
        let cols = [0, 1, 2, fi, fi + 1];
        let h = [
            jac.bearing_wrt_pose[0],
            jac.bearing_wrt_pose[1],
            jac.bearing_wrt_pose[2],
            jac.bearing_wrt_feature[0],
            jac.bearing_wrt_feature[1],
        ];
        let mut var = 0.0;
        for (a, &ca) in cols.iter().enumerate() {
            for (b, &cb) in cols.iter().enumerate() {
                var += h[a] * cov[(ca, cb)] * h[b];
            }
        }
        let sigma = var.max(0.0).sqrt();
        if offset <= base + k * (sigma * sigma + meas_var).sqrt() {
            out.push(BeamCandidate {
                slot,
                range_m: rb.range_m,
                offset_rad: offset,
                sigma_rad: sigma,
                expected: offset <= half,
                ambiguous: (offset - half).abs() <= k * sigma,
            });
        }
    }
    out.sort_by(|a, b| a.range_m.total_cmp(&b.range_m).then(a.slot.cmp(&b.slot)));
    out
}

/// Copies rows `3 src..3 src + 3` of `from` (columns in the order of `members`, candidate
/// indices) into rows `3 dst..` of `to` (columns in candidate order).
fn copy_rows(
    from: &DMatrix<f64>,
    src: usize,
    members: &[usize],
    to: &mut DMatrix<f64>,
    dst: usize,
) {
    let n_to = to.ncols();
    let n_from = from.ncols();
    for r in 0..3 {
        for c in 0..POSE_DIM {
            to[(3 * dst + r, c)] = from[(3 * src + r, c)];
        }
        for (q, &cand) in members.iter().enumerate() {
            for e in 0..FEATURE_DIM {
                to[(3 * dst + r, POSE_DIM + FEATURE_DIM * cand + e)] =
                    from[(3 * src + r, POSE_DIM + FEATURE_DIM * q + e)];
            }
        }
        to[(3 * dst + r, n_to - 1)] = from[(3 * src + r, n_from - 1)];
    }
}

/// Predicts every candidate (sorted by range, `params` in the same order), each with the
/// expected features in front of it as occluders. Columns: `[pose, candidates, L]`.
pub fn predict_candidates<O: BeamObservationModel + ?Sized>(
    observer: &O,
    pose: &Pose2,
    loss_db: f64,
    candidates: &[BeamCandidate],
    params: &[FeatureParams],
) -> Result<BeamPrediction, FilterError> {
    let k = candidates.len();
    if params.len() != k {
        return Err(FilterError::Shape("one parameter set per candidate"));
    }
    let occluders: Vec<usize> = (0..k).filter(|&i| candidates[i].expected).collect();
    let mut z = vec![[0.0; 3]; k];
    let mut usable = vec![false; k];
    let mut jacobian = DMatrix::zeros(3 * k, beam_columns(k));
    let check = |p: &BeamPrediction, m: usize| {
        if p.z.len() != m
            || p.power_usable.len() != m
            || p.jacobian.nrows() != 3 * m
            || p.jacobian.ncols() != beam_columns(m)
        {
            Err(FilterError::Shape(
                "beam prediction does not match its features",
            ))
        } else {
            Ok(())
        }
    };
    if !occluders.is_empty() {
        let ps: Vec<FeatureParams> = occluders.iter().map(|&i| params[i]).collect();
        let pred = observer.predict_beam(pose, &ps, loss_db)?;
        check(&pred, occluders.len())?;
        for (q, &i) in occluders.iter().enumerate() {
            z[i] = pred.z[q];
            usable[i] = pred.power_usable[q];
            copy_rows(&pred.jacobian, q, &occluders, &mut jacobian, i);
        }
    }
    for i in (0..k).filter(|&i| !candidates[i].expected) {
        let mut members: Vec<usize> = occluders.iter().copied().filter(|&j| j < i).collect();
        members.push(i);
        let ps: Vec<FeatureParams> = members.iter().map(|&j| params[j]).collect();
        let pred = observer.predict_beam(pose, &ps, loss_db)?;
        check(&pred, members.len())?;
        let last = members.len() - 1;
        z[i] = pred.z[last];
        usable[i] = pred.power_usable[last];
        copy_rows(&pred.jacobian, last, &members, &mut jacobian, i);
    }
    // Resolvability is a property of the ranges of every candidate, whichever group
    // predicted it: one more prediction of the whole set supplies the flags.
    if k > 1 {
        let all = observer.predict_beam(pose, params, loss_db)?;
        check(&all, k)?;
        for (u, a) in usable.iter_mut().zip(&all.power_usable) {
            *u &= *a;
        }
    }
    for i in 0..k {
        if candidates[..i].iter().any(|c| c.ambiguous) {
            usable[i] = false;
        }
    }
    Ok(BeamPrediction {
        z,
        jacobian,
        power_usable: usable,
    })
}

/// Re-linearises the geometric part of a beam prediction's Jacobian at each feature's first
/// estimate (first-estimates Jacobians, see
/// [`FilterSettings::first_estimate_jacobians`]). `current` and `first` are the features'
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
    if jacobian.nrows() < 3 * k || jacobian.ncols() < POSE_DIM + FEATURE_DIM * k {
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
        let fc = POSE_DIM + FEATURE_DIM * i;
        if units[i].is_some() {
            if let Ok((_, jac)) = range_bearing_with_jacobian(pose, first[i]) {
                jac.write_rows(jacobian, 3 * i, fc);
            }
        }
        // Power row of feature i.
        let row = 3 * i + 2;
        let mut pose_x = jacobian[(row, 0)];
        let mut pose_y = jacobian[(row, 1)];
        for (q, u) in units.iter().enumerate() {
            let Some((now, then)) = u else { continue };
            let qc = POSE_DIM + FEATURE_DIM * q;
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
