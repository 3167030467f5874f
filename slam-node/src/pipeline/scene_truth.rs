//! Ground truth from a simulator scene (the `sim` feature only): the scene's trajectory,
//! integrated exactly as the simulator does, and its features.

use radar_model::geometry::Pose2;

use super::truth::{TrueFeature, TruthOracle};

/// Truth from a simulator scene: its trajectory, integrated exactly as the simulator does,
/// from the simulator's start time.
#[derive(Debug)]
pub struct SceneTruth {
    trajectory: sim_sensor::trajectory::Trajectory,
    start_s: f64,
    features: Vec<TrueFeature>,
    loss_db: f64,
}

impl SceneTruth {
    /// Truth for `scene` started at Unix time `start_s`, valid for `horizon_s` seconds.
    pub fn new(
        scene: &sim_sensor::scene::Scene,
        start_s: f64,
        horizon_s: f64,
    ) -> Result<Self, sim_sensor::SimError> {
        Ok(Self {
            trajectory: sim_sensor::trajectory::Trajectory::new(scene, horizon_s)?,
            start_s,
            loss_db: scene.loss_db,
            features: scene
                .features
                .iter()
                .map(|f| TrueFeature {
                    id: f.id,
                    x_m: f.x_m,
                    y_m: f.y_m,
                    rho: f.rho,
                    alpha: f.alpha,
                })
                .collect(),
        })
    }
}

impl TruthOracle for SceneTruth {
    fn pose_at(&self, t_s: f64) -> Option<Pose2> {
        // Unix seconds in f64 carry about 0.2 us of rounding: a time a hair before the
        // start is the start.
        let dt = t_s - self.start_s;
        if !(-1e-3..1.0e7).contains(&dt) {
            return None;
        }
        let dt = dt.max(0.0);
        // dt is finite, non-negative and below 1e7 s: the nanosecond count fits a u64.
        self.trajectory.pose_at((dt * 1e9).round() as u64).ok()
    }

    fn features(&self) -> &[TrueFeature] {
        &self.features
    }

    fn loss_db(&self) -> Option<f64> {
        Some(self.loss_db)
    }
}
