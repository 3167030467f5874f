//! The filter's errors. Every failure the caller can see is a variant here; none panics.

use thiserror::Error;

use super::id::FeatureId;
use super::settings::SettingsError;

/// Why a filter operation was refused or failed. When an operation returns an error the
/// state is unchanged unless the variant says otherwise.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FilterError {
    /// The settings did not validate.
    #[error("invalid filter settings: {0}")]
    Settings(#[from] SettingsError),
    /// An observation (range, bearing or power) was NaN or infinite; nothing was applied.
    #[error("non-finite observation: {what} = {value}")]
    NonFiniteObservation {
        /// Which quantity.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// An odometry sample was NaN or infinite.
    #[error("non-finite odometry: {what} = {value}")]
    NonFiniteOdometry {
        /// Which quantity.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// A target too close to the radar to place a feature (no bearing information).
    #[error("target at {range_m} m is nearer than the minimum range {min_range_m} m")]
    TargetTooClose {
        /// Its range.
        range_m: f64,
        /// The settings' minimum range.
        min_range_m: f64,
    },
    /// A beam carried more targets than the settings allow; nothing was applied.
    #[error("beam has {count} targets, more than the limit {limit}")]
    TooManyTargets {
        /// Targets in the beam.
        count: usize,
        /// The settings' limit.
        limit: usize,
    },
    /// A range was negative.
    #[error("negative range {0} m")]
    NegativeRange(f64),
    /// Asked to predict to a time before the state's time.
    #[error("cannot predict backwards from {state_s} s to {requested_s} s")]
    TimeWentBackwards {
        /// The state's time.
        state_s: f64,
        /// The requested time.
        requested_s: f64,
    },
    /// Asked to predict across a gap longer than the settings allow.
    #[error("prediction gap {gap_s} s exceeds the limit {limit_s} s")]
    GapTooLong {
        /// The gap.
        gap_s: f64,
        /// The limit.
        limit_s: f64,
    },
    /// No odometry has been received, so there is nothing to predict with.
    #[error("no odometry received yet: refusing to predict the vehicle's motion")]
    NoOdometry,
    /// The innovation covariance S was not positive definite (Cholesky failed).
    #[error("innovation covariance is not positive definite ({dim}x{dim})")]
    InnovationNotPositiveDefinite {
        /// Dimension of S.
        dim: usize,
    },
    /// The update would have produced a non-positive or non-finite variance; not applied.
    #[error("update refused: variance of state element {index} would become {value}")]
    CovarianceLostDefiniteness {
        /// State index.
        index: usize,
        /// Variance it would have had.
        value: f64,
    },
    /// A pose or feature covariance block was not positive definite when computing NEES.
    #[error("covariance block is not positive definite")]
    CovarianceNotPositiveDefinite,
    /// A matrix or vector handed to the filter had the wrong shape.
    #[error("shape mismatch: {0}")]
    Shape(&'static str),
    /// A value handed to the filter (initial state, Jacobian) was not finite.
    #[error("non-finite value in {0}")]
    NonFiniteInput(&'static str),
    /// No feature with this id is in the state.
    #[error("unknown feature {0:?}")]
    UnknownFeature(FeatureId),
    /// The state already holds the maximum number of features.
    #[error("the state already holds the maximum of {0} features")]
    TooManyFeatures(usize),
    /// The observation or motion model failed for this beam.
    #[error("the radar model failed")]
    Model(#[from] radar_model::ModelError),
}
