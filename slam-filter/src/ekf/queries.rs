//! What a caller reads from the filter: settings, state, totals, the pose and the features
//! with their uncertainty, NEES against a truth, covariance health, the odometry corrections.
//! Nothing here changes the filter.

use nalgebra::Matrix3;
use radar_model::geometry::Pose2;
use radar_model::material::Material;

use super::{Ekf, FeatureEstimate, FilterStats};
use crate::error::FilterError;
use crate::health::{covariance_health, pose_nees, position_nees, CovarianceHealth};
use crate::observation::BeamObservationModel;
use crate::predict::ProcessModel;
use crate::settings::FilterSettings;
use crate::state::{FeatureId, SlamState, CLONE_INDEX};

impl<M: ProcessModel, O: BeamObservationModel> Ekf<M, O> {
    /// The settings in force.
    pub fn settings(&self) -> &FilterSettings {
        &self.settings
    }

    /// The whole state (mean, covariance, tracks). The u, v variances of features not seen
    /// lately lag their random walk until [`Self::settle_material_noise`].
    pub fn state(&self) -> &SlamState {
        &self.state
    }

    /// Running totals.
    pub fn stats(&self) -> &FilterStats {
        &self.stats
    }

    /// Estimated pose.
    pub fn pose(&self) -> Pose2 {
        self.state.pose()
    }

    /// Pose covariance.
    pub fn pose_covariance(&self) -> Matrix3<f64> {
        self.state.pose_covariance()
    }

    /// Number of features in the state.
    pub fn feature_count(&self) -> usize {
        self.state.feature_count()
    }

    /// Every feature's estimate, in slot order.
    pub fn features(&self) -> Vec<FeatureEstimate> {
        (0..self.state.feature_count())
            .filter_map(|s| self.feature_estimate_at(s))
            .collect()
    }

    fn feature_estimate_at(&self, slot: usize) -> Option<FeatureEstimate> {
        let p = self.state.params(slot)?;
        let track = self.state.tracks().get(slot)?;
        let shares = Material::new(p.u, p.v).shares();
        Some(FeatureEstimate {
            id: track.id,
            x_m: p.x_m,
            y_m: p.y_m,
            rho: shares.rho,
            alpha: shares.alpha,
            position_cov: self.state.position_covariance(slot)?,
            hits: track.hits,
        })
    }

    /// One feature's estimate.
    pub fn feature(&self, id: FeatureId) -> Option<FeatureEstimate> {
        self.feature_estimate_at(self.state.slot_of(id)?)
    }

    /// Pose NEES against the true pose.
    pub fn pose_nees(&self, truth: &Pose2) -> Result<f64, FilterError> {
        pose_nees(&self.pose(), &self.pose_covariance(), truth)
    }

    /// Feature position NEES against its true position.
    pub fn feature_nees(&self, id: FeatureId, truth_xy: [f64; 2]) -> Result<f64, FilterError> {
        let f = self.feature(id).ok_or(FilterError::UnknownFeature(id))?;
        position_nees([f.x_m, f.y_m], &f.position_cov, truth_xy)
    }

    /// Covariance health (`with_eigenvalues` adds an O(n^3) eigen-decomposition) of the
    /// estimated part of the state: the clone (a copy of the pose at the last mark, exactly
    /// collinear with it at the mark) and odometry corrections that are not estimated (zero
    /// mean, zero variance, coupled to nothing) are left out.
    pub fn covariance_health(&self, with_eigenvalues: bool) -> CovarianceHealth {
        use crate::state::{FEATURE_BASE, SPEED_SCALE_INDEX, STEER_BIAS_INDEX};
        let cov = self.state.covariance();
        let kept: Vec<usize> = (0..cov.nrows())
            .filter(|&i| !(CLONE_INDEX..FEATURE_BASE).contains(&i))
            .filter(|&i| {
                !([SPEED_SCALE_INDEX, STEER_BIAS_INDEX].contains(&i) && cov[(i, i)] == 0.0)
            })
            .collect();
        let estimated = cov.select_rows(&kept).select_columns(&kept);
        covariance_health(&estimated, with_eigenvalues)
    }

    /// The odometry corrections `[k, b]` (see [`FilterSettings::speed_scale_std`]) and
    /// their standard deviations; `None` when they are not estimated.
    pub fn odometry_bias(&self) -> Option<([f64; 2], [f64; 2])> {
        if !self.state.estimates_odometry_bias() {
            return None;
        }
        let c = self.state.odometry_bias_covariance();
        Some((
            self.state.odometry_bias(),
            [c[(0, 0)].max(0.0).sqrt(), c[(1, 1)].max(0.0).sqrt()],
        ))
    }
}
