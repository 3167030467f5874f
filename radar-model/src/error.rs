//! The crate's error type: every bad input (non-finite numbers, unsorted targets,
//! invalid tables or material shares, undersized buffers) is a variant here, never a panic.

use thiserror::Error;

/// Why a model function refused its input.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ModelError {
    /// An input that must be a finite number was NaN or infinite.
    #[error("{what} is not finite")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// A feature sits on the sensor (range below `MIN_JACOBIAN_RANGE_M`): bearing and its
    /// Jacobian are undefined there.
    #[error("feature at range {range_m} m is too close to the sensor for a bearing")]
    FeatureAtSensor {
        /// The offending range.
        range_m: f64,
    },
    /// Targets passed as one beam were not in non-decreasing range order.
    #[error("beam targets must be sorted by range (target {index} is nearer than the one before)")]
    TargetsNotSorted {
        /// Index of the first out-of-order target.
        index: usize,
    },
    /// Material shares given by a user are not shares: negative, above one, or summing past one.
    #[error("invalid material shares rho = {rho}, alpha = {alpha}: need rho, alpha >= 0 and rho + alpha <= 1")]
    InvalidMaterial {
        /// The reflected share as given.
        rho: f64,
        /// The absorbed share as given.
        alpha: f64,
    },
    /// A gain table is unusable (too short, unsorted, non-finite or mismatched lengths).
    #[error("invalid gain table: {reason}")]
    InvalidTable {
        /// What is wrong with it.
        reason: &'static str,
    },
    /// A setting is out of its valid domain.
    #[error("invalid setting {what}: {reason}")]
    InvalidSetting {
        /// Which setting.
        what: &'static str,
        /// Why.
        reason: &'static str,
    },
    /// A caller-provided buffer is shorter than needed.
    #[error("buffer too small: need {needed}, got {got}")]
    BufferTooSmall {
        /// Required length.
        needed: usize,
        /// Provided length.
        got: usize,
    },
}

/// Checks that `value` is finite, naming it in the error otherwise.
pub(crate) fn finite(value: f64, what: &'static str) -> Result<f64, ModelError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ModelError::NonFinite { what })
    }
}
