//! The vehicle's true trajectory: the scene's control schedule integrated through
//! radar-model's process model (`motion`), queryable at any time so each azimuth is rendered
//! from the pose at its own timestamp.
//!
//! Integration runs on a fixed grid of [`STEP_NS`]; between grid points the pose is one
//! partial step of the same model. Checkpoints every [`CHECKPOINT_STEPS`] grid steps are
//! computed once, up to a horizon; a [`TrajectoryCursor`] walks forward from the nearest
//! checkpoint, so every caller sees bit-identical poses whatever time it starts from.

use radar_model::geometry::{wrap_angle, Pose2};
use radar_model::motion::{ControlInput, MotionModel};

use crate::error::SimError;
use crate::scene::{MotionSpec, Scene};
use crate::schedule::ControlSchedule;

pub use crate::schedule::STEP_NS;
/// Grid steps between stored checkpoints (1 s).
pub const CHECKPOINT_STEPS: u64 = 100;

/// The scene's motion spec as radar-model's process model.
pub fn motion_model(spec: MotionSpec) -> MotionModel {
    match spec {
        MotionSpec::Paper { step_s } => MotionModel::Paper { step_s },
        MotionSpec::Bicycle { wheelbase_m } => MotionModel::Bicycle { wheelbase_m },
    }
}

/// The integrated trajectory (shared, immutable after construction).
#[derive(Debug, Clone)]
pub struct Trajectory {
    model: MotionModel,
    schedule: ControlSchedule,
    checkpoints: Vec<Pose2>,
}

impl Trajectory {
    /// Integrates the scene's schedule from its start pose up to `horizon_s` seconds
    /// (checkpoints beyond it are not stored; cursors integrate past it on their own).
    ///
    /// # Errors
    /// The process model rejects an input (e.g. bicycle steering beyond 80 degrees).
    pub fn new(scene: &Scene, horizon_s: f64) -> Result<Trajectory, SimError> {
        let model = motion_model(scene.motion);
        let start = Pose2::new(scene.start[0], scene.start[1], wrap_angle(scene.start[2]));
        let horizon_s = if horizon_s.is_finite() {
            horizon_s.clamp(1.0, 86_400.0)
        } else {
            3600.0
        };
        let n_checkpoints = (horizon_s.ceil() as usize).saturating_add(1);
        let mut checkpoints = Vec::with_capacity(n_checkpoints);
        let mut pose = start;
        let mut step: u64 = 0;
        checkpoints.push(pose);
        while checkpoints.len() < n_checkpoints {
            pose = step_pose(&model, &scene.schedule, pose, step)?;
            step += 1;
            if step.is_multiple_of(CHECKPOINT_STEPS) {
                checkpoints.push(pose);
            }
        }
        Ok(Trajectory {
            model,
            schedule: scene.schedule.clone(),
            checkpoints,
        })
    }

    /// The process model in use.
    pub fn model(&self) -> MotionModel {
        self.model
    }

    /// The control schedule.
    pub fn schedule(&self) -> &ControlSchedule {
        &self.schedule
    }

    /// A cursor positioned at the start.
    pub fn cursor(&self) -> TrajectoryCursor {
        let pose = self.checkpoints.first().copied().unwrap_or_default();
        TrajectoryCursor {
            step: 0,
            pose,
            anchors: [(0, pose); 2],
        }
    }

    /// The pose `t_ns` nanoseconds after the start (convenience: a fresh cursor each call).
    pub fn pose_at(&self, t_ns: u64) -> Result<Pose2, SimError> {
        self.pose_with(&mut self.cursor(), t_ns)
    }

    /// The controls in force `t_ns` after the start (what odometry measures): those of the
    /// integration step containing `t_ns`.
    pub fn controls_at(&self, t_ns: u64) -> (f64, f64) {
        let step = t_ns / STEP_NS;
        self.schedule
            .controls_at((step as f64) * (STEP_NS as f64) * 1e-9)
    }

    /// The pose `t_ns` nanoseconds after the start, walking `cursor` forward from where it
    /// is (or from the nearest checkpoint when that is closer or the time is earlier).
    /// Past the horizon the cursor keeps its own checkpoints, the last two grid multiples
    /// of [`CHECKPOINT_STEPS`] it walked through, so that asking for a time up to one
    /// checkpoint interval earlier costs at most two intervals' steps instead of the whole
    /// way from the horizon (the poses are the same to the bit: the same steps from the
    /// same start).
    ///
    /// # Errors
    /// The process model rejects an input.
    pub fn pose_with(&self, cursor: &mut TrajectoryCursor, t_ns: u64) -> Result<Pose2, SimError> {
        let target_step = t_ns / STEP_NS;
        let checkpoint = target_step / CHECKPOINT_STEPS;
        let stored = self.checkpoints.len() as u64;
        let best_checkpoint = checkpoint.min(stored.saturating_sub(1));
        let checkpoint_step = best_checkpoint * CHECKPOINT_STEPS;
        // Restart from a checkpoint if we are behind it or past the target: the cursor's own
        // when it lies between the stored one and the target, else the stored one.
        if cursor.step > target_step || cursor.step < checkpoint_step {
            let own = cursor
                .anchors
                .iter()
                .find(|(step, _)| *step > checkpoint_step && *step <= target_step)
                .copied();
            if let Some((step, pose)) = own {
                cursor.pose = pose;
                cursor.step = step;
            } else {
                let index = usize::try_from(best_checkpoint).unwrap_or(usize::MAX);
                if let Some(pose) = self.checkpoints.get(index) {
                    cursor.pose = *pose;
                    cursor.step = checkpoint_step;
                }
            }
        }
        while cursor.step < target_step {
            cursor.pose = step_pose(&self.model, &self.schedule, cursor.pose, cursor.step)?;
            cursor.step += 1;
            if cursor.step.is_multiple_of(CHECKPOINT_STEPS) && cursor.step > cursor.anchors[0].0 {
                cursor.anchors = [(cursor.step, cursor.pose), cursor.anchors[0]];
            }
        }
        let remainder_ns = t_ns - target_step * STEP_NS;
        if remainder_ns == 0 {
            return Ok(cursor.pose);
        }
        let t_s = (target_step as f64) * (STEP_NS as f64) * 1e-9;
        let (speed_mps, steer_rad) = self.schedule.controls_at(t_s);
        self.model
            .predict(
                &cursor.pose,
                &ControlInput::new(speed_mps, steer_rad),
                remainder_ns as f64 * 1e-9,
            )
            .map_err(|e| SimError::Model(format!("pose at t = {t_s} s: {e}")))
    }
}

fn step_pose(
    model: &MotionModel,
    schedule: &ControlSchedule,
    pose: Pose2,
    step: u64,
) -> Result<Pose2, SimError> {
    let t_s = (step as f64) * (STEP_NS as f64) * 1e-9;
    let (speed_mps, steer_rad) = schedule.controls_at(t_s);
    model
        .predict(
            &pose,
            &ControlInput::new(speed_mps, steer_rad),
            STEP_NS as f64 * 1e-9,
        )
        .map_err(|e| SimError::Model(format!("integrating the trajectory at t = {t_s} s: {e}")))
}

/// A position on a [`Trajectory`] that [`Trajectory::pose_with`] walks forward in time;
/// asking for an earlier time jumps back to a checkpoint.
#[derive(Debug, Clone, Copy)]
pub struct TrajectoryCursor {
    step: u64,
    pose: Pose2,
    /// The last two grid multiples of [`CHECKPOINT_STEPS`] walked through, latest first,
    /// with the poses there: a step back into the previous checkpoint's interval (a
    /// rotation that straddles a checkpoint) restarts from the earlier one.
    anchors: [(u64, Pose2); 2],
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    fn circle_scene() -> Scene {
        Scene::from_toml_str(
            "circle",
            "[motion]\nmodel = \"bicycle\"\nwheelbase_m = 2.0\n\
             [[control]]\nt_s = 0.0\nspeed_mps = 5.0\nsteer_rad = 0.19739555984988078\n",
        )
        .expect("valid")
    }

    #[test]
    fn a_constant_steering_bicycle_drives_a_circle_of_the_expected_radius() {
        // tan(0.19739556) = 0.2, so the radius is 2.0 / 0.2 = 10 m; centre at (0, 10).
        let scene = circle_scene();
        let trajectory = Trajectory::new(&scene, 30.0).expect("integrates");
        let mut cursor = trajectory.cursor();
        for k in 0..200 {
            let pose = trajectory
                .pose_with(&mut cursor, k * 73_000_000)
                .expect("pose");
            let r = pose.x.hypot(pose.y - 10.0);
            assert!((r - 10.0).abs() < 1e-3, "step {k}: radius {r}");
        }
        // One lap takes 2 pi 10 / 5 = 12.566 s and brings the vehicle back to the start.
        let lap_ns = (2.0 * std::f64::consts::PI * 10.0 / 5.0 * 1e9) as u64;
        let pose = trajectory.pose_with(&mut cursor, lap_ns).expect("pose");
        assert!(pose.x.abs() < 1e-3 && pose.y.abs() < 1e-3, "{pose:?}");
    }

    #[test]
    fn poses_are_identical_whichever_time_a_cursor_starts_from() {
        let scene = circle_scene();
        let trajectory = Trajectory::new(&scene, 30.0).expect("integrates");
        let t_ns = 7_123_456_789;
        let direct = trajectory.pose_at(t_ns).expect("pose");
        let mut walking = trajectory.cursor();
        for k in 0..100 {
            trajectory
                .pose_with(&mut walking, k * 70_000_000)
                .expect("pose");
        }
        assert_eq!(
            trajectory.pose_with(&mut walking, t_ns).expect("pose"),
            direct
        );
        // And going back in time restarts cleanly.
        assert_eq!(
            trajectory.pose_with(&mut walking, 1_000).expect("pose"),
            trajectory.pose_at(1_000).expect("pose")
        );
    }

    #[test]
    fn a_paper_model_scene_drives_exactly_as_equation_2_iterates() {
        // step_s equal to the integration step, so each step is eq. 2 with dt = step_s:
        // x += v dt cos(theta + a), y += v dt sin(theta + a), theta += a.
        let scene = Scene::from_toml_str(
            "eq2",
            "[motion]\nmodel = \"paper\"\nstep_s = 0.01\n\
             [start]\nx_m = 1.0\ny_m = 2.0\ntheta_deg = 170.0\n\
             [[control]]\nt_s = 0.0\nspeed_mps = 2.0\nsteer_rad = 0.003\n",
        )
        .expect("valid");
        let trajectory = Trajectory::new(&scene, 10.0).expect("integrates");
        let (v, a, dt) = (2.0_f64, 0.003_f64, 0.01_f64);
        let (mut x, mut y, mut theta) = (1.0_f64, 2.0_f64, 170.0_f64.to_radians());
        let mut cursor = trajectory.cursor();
        for k in 1..=500u64 {
            x += v * dt * (theta + a).cos();
            y += v * dt * (theta + a).sin();
            theta = wrap_angle(theta + a);
            let pose = trajectory
                .pose_with(&mut cursor, k * STEP_NS)
                .expect("pose");
            assert!(
                (pose.x - x).abs() < 1e-9 && (pose.y - y).abs() < 1e-9,
                "step {k}: {pose:?} against ({x}, {y})"
            );
            assert!(wrap_angle(pose.theta - theta).abs() < 1e-9, "step {k}");
        }
        // 500 steps of 0.003 rad turned the heading across +/- pi (170 deg + 86 deg).
        assert!(theta < 0.0);
    }

    #[test]
    fn a_stationary_scene_stays_at_its_start_pose() {
        let scene = Scene::from_toml_str(
            "still",
            "[start]\nx_m = 3.0\ny_m = -2.0\ntheta_deg = 90.0\n",
        )
        .expect("valid");
        let trajectory = Trajectory::new(&scene, 5.0).expect("integrates");
        let pose = trajectory.pose_at(4_500_000_000).expect("pose");
        assert_eq!((pose.x, pose.y), (3.0, -2.0));
        assert!((pose.theta - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn times_past_the_horizon_are_integrated_on_demand() {
        let scene = circle_scene();
        let short = Trajectory::new(&scene, 2.0).expect("integrates");
        let long = Trajectory::new(&scene, 20.0).expect("integrates");
        let t_ns = 15_000_000_000;
        assert_eq!(
            short.pose_at(t_ns).expect("pose"),
            long.pose_at(t_ns).expect("pose")
        );
    }

    #[test]
    fn past_the_horizon_a_step_back_restarts_from_the_cursors_own_checkpoint() {
        // A rotation's render asks for its middle first, then its samples from the start:
        // past the horizon that used to walk from the horizon every time (quadratic in the
        // run's length). The poses stay those of a trajectory integrated far enough.
        let scene = circle_scene();
        let short = Trajectory::new(&scene, 2.0).expect("integrates");
        let long = Trajectory::new(&scene, 60.0).expect("integrates");
        let mut cursor = short.cursor();
        for k in 0..200u64 {
            let start = 10_000_000_000 + k * 250_000_000;
            for t_ns in [
                start + 125_000_000,
                start,
                start + 60_000_000,
                start + 249_000_000,
            ] {
                assert_eq!(
                    short.pose_with(&mut cursor, t_ns).expect("pose"),
                    long.pose_at(t_ns).expect("pose")
                );
            }
        }
        // A step back from 15.1 s to 15.05 s walks from the cursor's checkpoint at 15.0 s,
        // one back to 14.98 s from the one at 14.0 s, not from the horizon at 2 s: moved
        // 1 m sideways, the checkpoint's pose moves the answer too.
        for (back_ns, anchor, which) in [(15_050_000_000, 1500, 0), (14_980_000_000, 1400, 1)] {
            let mut cursor = short.cursor();
            short.pose_with(&mut cursor, 15_100_000_000).expect("pose");
            assert_eq!(cursor.anchors[which].0, anchor);
            cursor.anchors[which].1.x += 1.0;
            let moved = short.pose_with(&mut cursor, back_ns).expect("pose");
            let truth = long.pose_at(back_ns).expect("pose");
            assert!((moved.x - truth.x - 1.0).abs() < 1e-9 && (moved.y - truth.y).abs() < 1e-9);
        }
    }
}
