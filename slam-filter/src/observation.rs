//! What the filter observes and the seam to the observation model.
//!
//! A beam's observation is every target detected down it: `(R, beta, P)` per target
//! (eq. 14). The model predicts, for the features the filter believes are in the beam
//! (sorted by range), `h_i = [R_i, beta_i, P_i]` (eq. 3, 4, 13) and the dense Jacobian of
//! all of them with respect to the beam-local columns `[pose(3), (x, y, u, v) per beam
//! feature, L]`. The filter maps those columns onto state indices and discards the power
//! rows when power is switched off or the model says a power is not usable (targets closer
//! than the range resolution).

use nalgebra::{DMatrix, Matrix3};
use radar_model::geometry::{range_bearing_with_jacobian, Pose2};
use radar_model::layout::{self, Component, ObservationRow};

use super::error::FilterError;
use super::state::{feature_index, FeatureParams, FEATURE_DIM, LOSS_INDEX, POSE_DIM};

/// One target detected down a beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// Range (m).
    pub range_m: f64,
    /// Bearing (rad, clockwise from forward: eq. 4's convention).
    pub bearing_rad: f64,
    /// Uncompensated received power (dB): the receiver's compensation already removed.
    pub power_db: f64,
}

impl Target {
    /// Rejects NaN, infinities and negative ranges.
    pub fn check(&self) -> Result<(), FilterError> {
        for (what, value) in [
            ("range_m", self.range_m),
            ("bearing_rad", self.bearing_rad),
            ("power_db", self.power_db),
        ] {
            if !value.is_finite() {
                return Err(FilterError::NonFiniteObservation { what, value });
            }
        }
        if self.range_m < 0.0 {
            return Err(FilterError::NegativeRange(self.range_m));
        }
        Ok(())
    }
}

/// Every target detected down one beam at one time.
#[derive(Debug, Clone, PartialEq)]
pub struct BeamObservation {
    /// The azimuth's timestamp (s).
    pub timestamp_s: f64,
    /// The beam's bearing (rad, eq. 4's convention: a Navtech azimuth angle).
    pub bearing_rad: f64,
    /// The targets, in any order.
    pub targets: Vec<Target>,
}

impl BeamObservation {
    /// Rejects any non-finite value before the filter looks at anything else.
    pub fn check(&self) -> Result<(), FilterError> {
        for (what, value) in [
            ("timestamp_s", self.timestamp_s),
            ("beam bearing_rad", self.bearing_rad),
        ] {
            if !value.is_finite() {
                return Err(FilterError::NonFiniteObservation { what, value });
            }
        }
        self.targets.iter().try_for_each(Target::check)
    }
}

/// The model's prediction for the features in one beam (sorted by range).
#[derive(Debug, Clone, PartialEq)]
pub struct BeamPrediction {
    /// `[R_i, beta_i, P_i]` per feature, in the order given.
    pub z: Vec<[f64; 3]>,
    /// `3k x (3 + 4k + 1)`, laid out as [`radar_model::layout`] says: feature i's
    /// `(R, beta, P)` rows; columns `[x, y, theta, (x, y, u, v) per feature in order, L]`.
    pub jacobian: DMatrix<f64>,
    /// Whether each feature's power prediction can be used (false when not resolvable
    /// from its neighbour, or when the model has no power).
    pub power_usable: Vec<bool>,
}

/// Predicts what a beam sees. Implemented for radar-model's multi-target physics by
/// [`super::radar::RadarBeamModel`], and by [`RangeBearingModel`] for plain SLAM.
pub trait BeamObservationModel {
    /// Predicts the observations of `features` (sorted by increasing range) from `pose`,
    /// with radar loss `loss_db`.
    fn predict_beam(
        &self,
        pose: &Pose2,
        features: &[FeatureParams],
        loss_db: f64,
    ) -> Result<BeamPrediction, FilterError>;
}

/// Ordinary range-bearing SLAM (eq. 3, 4): no power, so power rows are zero and unusable.
#[derive(Debug, Clone, Copy, Default)]
pub struct RangeBearingModel;

impl BeamObservationModel for RangeBearingModel {
    fn predict_beam(
        &self,
        pose: &Pose2,
        features: &[FeatureParams],
        _loss_db: f64,
    ) -> Result<BeamPrediction, FilterError> {
        let k = features.len();
        let mut jacobian = DMatrix::zeros(layout::rows(k), layout::columns(k));
        let mut z = Vec::with_capacity(k);
        for (i, f) in features.iter().enumerate() {
            let (rb, jac) =
                range_bearing_with_jacobian(pose, [f.x_m, f.y_m]).map_err(FilterError::Model)?;
            z.push([rb.range_m, rb.bearing_rad, 0.0]);
            jac.write_rows(
                &mut jacobian,
                ObservationRow::new(i, Component::Range).index(),
                layout::feature_column(i),
            );
        }
        Ok(BeamPrediction {
            z,
            jacobian,
            power_usable: vec![false; k],
        })
    }
}

/// Number of beam-local Jacobian columns for `k` features.
pub const fn beam_columns(k: usize) -> usize {
    layout::columns(k)
}

/// The Jacobian row indices of `rows`, in order.
pub fn row_indices(rows: &[ObservationRow]) -> Vec<usize> {
    rows.iter().map(|r| r.index()).collect()
}

/// The columns of `h` with at least one nonzero entry, or `None` when every column has one.
///
/// A beam's Jacobian spans the pose, L and every candidate feature in the beam, but a row
/// touches only the pose, L, its own feature and (for power) the features in front of it:
/// the products with the other columns are exact zeros, so they can be left out of
/// `H P H^T` and `P H^T` without changing the result.
pub fn nonzero_columns(h: &DMatrix<f64>) -> Option<Vec<usize>> {
    let cols: Vec<usize> = (0..h.ncols())
        .filter(|&j| h.column(j).iter().any(|v| *v != 0.0))
        .collect();
    (cols.len() < h.ncols()).then_some(cols)
}

/// State indices of the beam-local columns, given the features' slots in beam order.
pub fn state_columns(slots: &[usize]) -> Vec<usize> {
    let mut cols = Vec::with_capacity(beam_columns(slots.len()));
    cols.extend(0..layout::POSE_COLUMNS);
    for &s in slots {
        let i = feature_index(s);
        cols.extend(i..i + FEATURE_DIM);
    }
    cols.push(LOSS_INDEX);
    cols
}

/// The observation noise of one feature's rows: diagonal, `rows` 2 or 3.
pub fn noise_block(range_std_m: f64, bearing_std_rad: f64, power_std_db: f64) -> Matrix3<f64> {
    Matrix3::from_diagonal(&nalgebra::Vector3::new(
        range_std_m * range_std_m,
        bearing_std_rad * bearing_std_rad,
        power_std_db * power_std_db,
    ))
}

// The state stores a feature's block in the order the beam layout uses.
const _: () = assert!(FEATURE_DIM == layout::FEATURE_COLUMNS && POSE_DIM == layout::POSE_COLUMNS);
