//! One rotation's estimate against the truth: the record every run produces (a leaf the
//! filter-alone runs and the daemon runs share).

use radar_model::geometry::{wrap_angle, Pose2};
use slam_filter::CovarianceHealth;

/// The estimate against the truth at the end of one rotation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotationRecord {
    /// Time (s since the run's start).
    pub time_s: f64,
    /// True pose.
    pub truth: Pose2,
    /// Estimated pose.
    pub estimate: Pose2,
    /// Pose NEES (3 dof); `None` if the pose covariance was not positive definite.
    pub nees: Option<f64>,
    /// Features in the state.
    pub features: usize,
    /// Standard deviations of the estimate `[x m, y m, theta rad]`.
    pub sigma: [f64; 3],
    /// Wall time of detection, grouping and filtering for this rotation (s).
    pub work_s: f64,
    /// The covariance's health, when asked for at this rotation.
    pub health: Option<CovarianceHealth>,
}

impl RotationRecord {
    /// Position error (m).
    pub fn position_error_m(&self) -> f64 {
        (self.estimate.x - self.truth.x).hypot(self.estimate.y - self.truth.y)
    }

    /// Heading error (rad, wrapped).
    pub fn heading_error_rad(&self) -> f64 {
        wrap_angle(self.estimate.theta - self.truth.theta)
    }
}
