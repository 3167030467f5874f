//! Per-rotation diagnostics (JSON Lines, one object a rotation) and per-beam spectrum
//! comparisons (predicted vs measured, for the paper's figures 8-10).

use serde::{Deserialize, Serialize};

/// What happened in one rotation. One JSON object per line in `diagnostics.jsonl`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RotationDiagnostics {
    /// Rotation counter since start.
    pub rotation: u64,
    /// Time of the rotation's last azimuth, Unix seconds.
    pub timestamp_s: f64,
    /// Azimuths processed.
    pub azimuths: u32,
    /// Azimuths the driver reported skipped.
    pub skipped_azimuths: u32,
    /// Targets found down all beams (before grouping).
    pub detections: u32,
    /// Observations after grouping across azimuths.
    pub observations: u32,
    /// Observations associated with a mapped feature.
    pub associated: u32,
    /// Features initialised this rotation.
    pub new_features: u32,
    /// Tentative targets (not in the state) seen this rotation.
    pub tentative: u32,
    /// Features retired this rotation.
    pub retired: u32,
    /// Observations rejected (outside every gate and not new, or failed updates).
    pub rejected: u32,
    /// Features in the state after the rotation.
    pub map_size: u32,
    /// Mean normalised innovation squared of the associated observations.
    pub mean_nis: Option<f64>,
    /// Share of predicted-minus-measured bins inside +-16.35 dB over the compared beams.
    pub spectrum_in_bound_fraction: Option<f64>,
    /// Mean of predicted minus measured over the compared bins, dB.
    pub spectrum_bias_db: Option<f64>,
    /// Wall time spent on detection, ms.
    pub detect_ms: f64,
    /// Wall time spent in the filter (predictions, association, updates), ms.
    pub filter_ms: f64,
    /// Wall time spent on spectrum prediction and comparison, ms.
    pub spectrum_ms: f64,
    /// Total wall time of the rotation's processing, ms.
    pub total_ms: f64,
    /// Associations to the wrong scene feature (only when ground truth is known).
    pub association_errors: Option<u32>,
    /// Pose error at the rotation's end, estimate minus truth, x (m), when truth is known.
    pub pose_error_x_m: Option<f64>,
    /// Pose error, y (m).
    pub pose_error_y_m: Option<f64>,
    /// Pose error, heading (rad, wrapped).
    pub pose_error_theta_rad: Option<f64>,
    /// The filter's own standard deviations of x (m), y (m) and heading (rad).
    pub pose_sigma_x_m: Option<f64>,
    /// See `pose_sigma_x_m`.
    pub pose_sigma_y_m: Option<f64>,
    /// See `pose_sigma_x_m`.
    pub pose_sigma_theta_rad: Option<f64>,
    /// Pose NEES (3 dof) against truth: 95% of rotations below 7.81 for a consistent filter.
    pub pose_nees: Option<f64>,
}

/// A predicted and a measured spectrum of one beam, for figures and offline checks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpectrumComparison {
    /// Rotation counter.
    pub rotation: u64,
    /// Beam bearing (the paper's beta), radians.
    pub bearing_rad: f64,
    /// Range of bin 0 and bin spacing, metres.
    pub first_bin_m: f64,
    /// Bin spacing, metres.
    pub bin_m: f64,
    /// Measured spectrum, dB, as the radar sent it.
    pub measured_db: Vec<f64>,
    /// Predicted spectrum from the predicted pose, dB.
    pub predicted_db: Vec<f64>,
    /// The +- bound used for the in-bound fraction, dB.
    pub bound_db: f64,
}
