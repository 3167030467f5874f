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
use radar_model::geometry::{
    range_bearing, range_bearing_with_jacobian, wrap_angle, BeamAxis, Pose2,
};
use radar_model::layout::{self, Component, ObservationRow};

use super::error::FilterError;
use super::observation::{beam_columns, BeamObservationModel, BeamPrediction};
use super::settings::FilterSettings;
use super::state::{feature_index, FeatureParams, SlamState};

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
/// extrapolation of it), between the minimum range and `far_m` (the radar's range, or less
/// where the beam was covered only so far), sorted by range. O(N) in the number of
/// features, O(1) each.
pub fn candidates_in_beam(
    state: &SlamState,
    settings: &FilterSettings,
    pose: &Pose2,
    bearing_rad: f64,
    far_m: f64,
) -> Vec<BeamCandidate> {
    let pose = *pose;
    let entry = |i: usize, j: usize| state.covariance_entry(i, j);
    let half = settings.beam_half_width_rad;
    let base = half + settings.association_margin_rad;
    let k = settings.candidate_sigmas;
    let meas_var = settings.bearing_std_rad * settings.bearing_std_rad;
    let axis = BeamAxis::new(&pose, bearing_rad);
    let mut out = Vec::new();
    for slot in 0..state.feature_count() {
        let Some(p) = state.params(slot) else {
            continue;
        };
        let fi = feature_index(slot);
        // Cheap bound first: sigma_beta <= |h| sqrt(trace), |h|^2 = 1 + 2 / R^2.
        let trace = entry(0, 0) + entry(1, 1) + entry(2, 2) + entry(fi, fi) + entry(fi + 1, fi + 1);
        // Without trigonometry: the arc that bound allows, off the beam's axis.
        let r2 = axis.squared_range([p.x_m, p.y_m]);
        let arc = base + k * (((1.0 + 2.0 / r2) * trace).max(0.0) + meas_var).sqrt();
        if !axis.may_hold([p.x_m, p.y_m], arc) {
            continue;
        }
        let rb = range_bearing(&pose, [p.x_m, p.y_m]);
        if rb.range_m < settings.min_range_m || rb.range_m > far_m {
            continue;
        }
        let offset = wrap_angle(rb.bearing_rad - bearing_rad).abs();
        let bound = ((1.0 + 2.0 / (rb.range_m * rb.range_m)) * trace)
            .max(0.0)
            .sqrt();
        // A target from this feature lands in this beam when the feature's bearing plus the
        // measurement's bearing noise does: the arc is sized on the innovation's bearing
        // sigma, not the estimate's alone (or a precise estimate, as at a standstill, loses
        // its noisier sightings to a duplicate).
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
                var += h[a] * entry(ca, cb) * h[b];
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

/// Copies feature `src`'s rows of `from` (columns in the order of `members`, candidate
/// indices) into feature `dst`'s rows of `to` (columns in candidate order).
fn copy_rows(
    from: &DMatrix<f64>,
    src: usize,
    members: &[usize],
    to: &mut DMatrix<f64>,
    dst: usize,
) {
    let k_to = (to.ncols() - layout::columns(0)) / layout::FEATURE_COLUMNS;
    let (loss_to, loss_from) = (
        layout::loss_column(k_to),
        layout::loss_column(members.len()),
    );
    for component in Component::ALL {
        let r_to = ObservationRow::new(dst, component).index();
        let r_from = ObservationRow::new(src, component).index();
        for c in 0..layout::POSE_COLUMNS {
            to[(r_to, c)] = from[(r_from, c)];
        }
        for (q, &cand) in members.iter().enumerate() {
            for e in 0..layout::FEATURE_COLUMNS {
                to[(r_to, layout::feature_column(cand) + e)] =
                    from[(r_from, layout::feature_column(q) + e)];
            }
        }
        to[(r_to, loss_to)] = from[(r_from, loss_from)];
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
    let mut jacobian = DMatrix::zeros(layout::rows(k), beam_columns(k));
    let check = |p: &BeamPrediction, m: usize| {
        if p.z.len() != m
            || p.power_usable.len() != m
            || p.jacobian.nrows() != layout::rows(m)
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
