//! Features known beforehand: a saved map's features put into the state with the
//! covariance they were saved with, and taken out again when the vehicle leaves them
//! behind (localisation in a saved map keeps only the features near the vehicle).
//!
//! A known feature enters independent of everything in the state (no cross-covariance):
//! its uncertainty is the map's, not this run's. Taking it out drops its row and column
//! (its correlation with the pose is forgotten: putting it back later counts the map's
//! information on it again, the approximation every map-swapping localiser makes).

use nalgebra::{DMatrix, Matrix2, Matrix4};

use super::Ekf;
use crate::error::FilterError;
use crate::observation::BeamObservationModel;
use crate::predict::ProcessModel;
use crate::state::{FeatureId, FEATURE_DIM};

impl<M: ProcessModel, O: BeamObservationModel> Ekf<M, O> {
    /// Puts a known feature into the state at `xy` (m, the filter's frame) with position
    /// covariance `xy_cov`, material logits `uv` with covariance `uv_cov`, seen last at
    /// `time_s`. Both covariances must be symmetric positive definite and every value finite
    /// (typed errors otherwise, state untouched); at most
    /// [`FilterSettings::max_features`](crate::FilterSettings::max_features). O(n^2).
    pub fn insert_known_feature(
        &mut self,
        xy: [f64; 2],
        xy_cov: &Matrix2<f64>,
        uv: [f64; 2],
        uv_cov: &Matrix2<f64>,
        time_s: f64,
    ) -> Result<FeatureId, FilterError> {
        for m in [xy_cov, uv_cov] {
            if !m.iter().all(|v| v.is_finite()) {
                return Err(FilterError::NonFiniteInput("known feature covariance"));
            }
            let sym = 0.5 * (m + m.transpose());
            if sym.cholesky().is_none() {
                return Err(FilterError::CovarianceNotPositiveDefinite);
            }
        }
        let mut block = Matrix4::zeros();
        block
            .fixed_view_mut::<2, 2>(0, 0)
            .copy_from(&(0.5 * (xy_cov + xy_cov.transpose())));
        block
            .fixed_view_mut::<2, 2>(2, 2)
            .copy_from(&(0.5 * (uv_cov + uv_cov.transpose())));
        let cross = DMatrix::zeros(FEATURE_DIM, self.state.dim());
        let id = self.state.augment(
            [xy[0], xy[1], uv[0], uv[1]],
            &cross,
            &block,
            time_s,
            self.settings.max_features,
        )?;
        Ok(id)
    }

    /// Takes feature `id` out of the state (not counted as retired). O(n^2).
    pub fn remove_feature(&mut self, id: FeatureId) -> Result<(), FilterError> {
        self.state.remove(id)
    }

    /// Numbers the features mapped from now on from `first` at least (a run extending a
    /// saved map numbers its features past the map's, so that ids stay unique in the
    /// merged map). Never numbers backwards.
    pub fn number_features_from(&mut self, first: u64) {
        self.state.number_features_from(first);
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Matrix3;
    use radar_model::geometry::{range_bearing, Pose2};
    use radar_model::motion::MotionModel;

    use crate::observation::{BeamObservation, RangeBearingModel, Target};
    use crate::predict::OdometrySample;
    use crate::settings::FilterSettings;
    use crate::Ekf;

    fn filter(pose_var: f64, add: bool) -> Ekf<MotionModel, RangeBearingModel> {
        let settings = FilterSettings {
            use_power: false,
            add_features: add,
            ..FilterSettings::default()
        };
        Ekf::new(
            settings,
            Pose2::new(0.0, 0.0, 0.0),
            Matrix3::from_diagonal(&nalgebra::Vector3::new(pose_var, pose_var, 1e-4)),
            0.0,
            MotionModel::Paper { step_s: 0.05 },
            RangeBearingModel,
        )
        .unwrap()
    }

    #[test]
    fn features_are_numbered_from_where_they_are_told_and_never_backwards() {
        let mut ekf = filter(1.0, false);
        let i = nalgebra::Matrix2::identity();
        ekf.number_features_from(1000);
        let a = ekf.insert_known_feature([5.0, 0.0], &i, [0.0, 0.0], &i, 0.0);
        ekf.number_features_from(10);
        let b = ekf.insert_known_feature([9.0, 0.0], &i, [0.0, 0.0], &i, 0.0);
        assert_eq!((a.unwrap().0, b.unwrap().0), (1000, 1001));
    }

    #[test]
    fn a_known_feature_seen_again_corrects_the_pose_and_nothing_new_is_mapped() {
        let mut ekf = filter(1.0, false);
        let post = [20.0, 5.0];
        let tight = nalgebra::Matrix2::identity() * 1e-4;
        let id = ekf
            .insert_known_feature(
                post,
                &tight,
                [0.0, 0.0],
                &nalgebra::Matrix2::identity(),
                0.0,
            )
            .unwrap();
        assert_eq!(ekf.feature_count(), 1);
        ekf.apply_odometry(OdometrySample {
            timestamp_s: 0.0,
            speed_mps: 0.0,
            steer_rad: 0.0,
        })
        .unwrap();
        // The true pose is (0.5, 0, 0): the post seen from there, and a stranger at 30 m.
        let truth = Pose2::new(0.5, 0.0, 0.0);
        let rb = range_bearing(&truth, post);
        let stranger = range_bearing(&truth, [-30.0, 1.0]);
        let before = ekf.pose_covariance()[(0, 0)];
        for k in 1..=5 {
            let t = 0.25 * f64::from(k);
            for (r, b) in [
                (rb.range_m, rb.bearing_rad),
                (stranger.range_m, stranger.bearing_rad),
            ] {
                ekf.process_beam(&BeamObservation {
                    timestamp_s: t,
                    bearing_rad: b,
                    targets: vec![Target {
                        range_m: r,
                        bearing_rad: b,
                        power_db: -40.0,
                    }],
                })
                .unwrap();
            }
        }
        assert_eq!(ekf.feature_count(), 1, "the stranger is not mapped");
        assert!(ekf.stats().dropped_targets >= 5);
        let after = ekf.pose_covariance()[(0, 0)];
        assert!(after < before, "x variance {before} -> {after}");
        // Along the line of sight (mostly x) the pose moved towards the truth.
        assert!(ekf.pose().x > 0.2, "{:?}", ekf.pose());
        ekf.remove_feature(id).unwrap();
        assert_eq!(ekf.feature_count(), 0);
        assert!(ekf.remove_feature(id).is_err());
    }

    #[test]
    fn a_known_feature_with_a_bad_covariance_is_refused_and_the_state_untouched() {
        let mut ekf = filter(1.0, false);
        let i = nalgebra::Matrix2::identity();
        let not_pd = nalgebra::Matrix2::new(1.0, 2.0, 2.0, 1.0);
        assert!(ekf
            .insert_known_feature([1.0, 1.0], &not_pd, [0.0, 0.0], &i, 0.0)
            .is_err());
        assert!(ekf
            .insert_known_feature([1.0, 1.0], &i, [0.0, 0.0], &(i * f64::NAN), 0.0)
            .is_err());
        assert!(ekf
            .insert_known_feature([f64::NAN, 1.0], &i, [0.0, 0.0], &i, 0.0)
            .is_err());
        assert_eq!(ekf.feature_count(), 0);
        assert_eq!(ekf.state().dim(), filter(1.0, true).state().dim());
    }
}
