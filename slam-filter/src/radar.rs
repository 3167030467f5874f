//! The seam to radar-model: its process model (eq. 2 or the bicycle) and its multi-target
//! beam observation (eq. 3, 4, 13, 14) behind the filter's traits.

use nalgebra::Matrix3;
use radar_model::geometry::Pose2;
use radar_model::material::Material;
use radar_model::motion::{ControlInput, MotionModel};
use radar_model::observation::{observe_beam, BeamFeature};
use radar_model::power::PowerModel;

use super::error::FilterError;
use super::observation::{BeamObservationModel, BeamPrediction};
use super::predict::{MotionStep, ProcessModel};
use super::state::FeatureParams;

impl ProcessModel for MotionModel {
    fn step(
        &self,
        pose: &Pose2,
        speed_mps: f64,
        steer_rad: f64,
        dt_s: f64,
    ) -> Result<MotionStep, FilterError> {
        let (next, jac) = self
            .predict_with_jacobian(pose, &ControlInput::new(speed_mps, steer_rad), dt_s)
            .map_err(FilterError::Model)?;
        let wrt_pose: Matrix3<f64> = jac.wrt_pose;
        Ok(MotionStep {
            pose: next,
            wrt_pose,
            wrt_input: jac.wrt_input,
        })
    }
}

/// radar-model's multi-target observation: range, bearing and power of every feature in a
/// beam, the power of each depending on the features in front of it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RadarBeamModel {
    /// Spreading form, radar constants and range resolution.
    pub power: PowerModel,
}

impl BeamObservationModel for RadarBeamModel {
    fn predict_beam(
        &self,
        pose: &Pose2,
        features: &[FeatureParams],
        loss_db: f64,
    ) -> Result<BeamPrediction, FilterError> {
        let beam: Vec<BeamFeature> = features
            .iter()
            .map(|f| BeamFeature {
                xy: [f.x_m, f.y_m],
                material: Material::new(f.u, f.v),
            })
            .collect();
        let obs = observe_beam(pose, &beam, loss_db, &self.power).map_err(FilterError::Model)?;
        Ok(BeamPrediction {
            z: obs.z.iter().map(|o| o.as_array()).collect(),
            power_usable: obs.unresolvable.iter().map(|u| !u).collect(),
            jacobian: obs.jacobian,
        })
    }
}
