//! A simulated world for the evaluation: one of sim-sensor's scenes with its true
//! trajectory, its features (positions and materials), the simulator's own physics
//! (`sim_sensor::render::physics`) and its noisy odometry, on a fixed clock.
//!
//! Nothing here talks to a socket: spectra come from the simulator's renderer directly,
//! exactly as its server renders them, so a run is reproducible from the scene and a seed.

use std::sync::Arc;

use radar_model::compensation::Compensation;
use radar_model::geometry::{wrap_angle, Pose2};
use radar_model::material::Material;
use radar_model::motion::MotionModel;
use radar_model::noise::NoiseModel;
use radar_model::power::PowerModel;
use radar_model::spectrum::SpectrumGeometry;
use sim_sensor::odometry::OdometryGenerator;
use sim_sensor::render::{azimuth_in_rotation, offset_ns, physics, RenderCursor, SceneRenderer};
use sim_sensor::scene::Scene;
use sim_sensor::trajectory::{motion_model, Trajectory};
use sim_sensor::OdometryNoise;
use slam_filter::OdometrySample;

use crate::error::EvalError;

/// Unix time (s) of every simulated run's azimuth 0.
pub const EPOCH_S: f64 = 1_700_000_000.0;

/// A feature of the world as the evaluation knows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueFeature {
    /// The scene's feature id.
    pub id: u32,
    /// World position (m).
    pub xy: [f64; 2],
    /// Material as radar-model holds it.
    pub material: Material,
    /// Reflected share.
    pub rho: f64,
    /// Absorbed share.
    pub alpha: f64,
}

/// A scene made ready to run: truth, physics, renderer, odometry.
#[derive(Debug)]
pub struct World {
    /// The scene.
    pub scene: Scene,
    /// The simulator's renderer (shared by cursors).
    pub renderer: Arc<SceneRenderer>,
    /// Every feature with its true material.
    pub features: Vec<TrueFeature>,
    /// The simulator's power model (spreading form, constants, range resolution).
    pub power: PowerModel,
    /// The simulator's receiver compensation.
    pub compensation: Compensation,
    /// The simulator's noise models.
    pub noise: NoiseModel,
    /// The simulator's spectrum geometry.
    pub geometry: SpectrumGeometry,
    /// The vehicle's process model.
    pub motion: MotionModel,
    odometry: OdometryGenerator,
}

impl World {
    /// Prepares `scene` for `horizon_s` seconds; `seed` drives every random draw (spectra,
    /// bearing errors, odometry noise).
    pub fn new(
        scene: Scene,
        seed: u64,
        horizon_s: f64,
        odometry: OdometryNoise,
    ) -> Result<Self, EvalError> {
        let renderer = Arc::new(SceneRenderer::new(&scene, Some(seed), horizon_s + 2.0)?);
        let (power, compensation, noise, geometry) = physics(&scene);
        let features = scene
            .features
            .iter()
            .map(|f| {
                Ok(TrueFeature {
                    id: f.id,
                    xy: [f.x_m, f.y_m],
                    material: Material::from_rho_alpha(f.rho, f.alpha)?,
                    rho: f.rho,
                    alpha: f.alpha,
                })
            })
            .collect::<Result<Vec<_>, radar_model::ModelError>>()?;
        let motion = motion_model(scene.motion);
        Ok(Self {
            odometry: OdometryGenerator::new(odometry, seed ^ 0x00D0_3E7E, 0),
            renderer,
            features,
            power,
            compensation,
            noise,
            geometry,
            motion,
            scene,
        })
    }

    /// Azimuths per rotation.
    pub fn azimuths(&self) -> u64 {
        u64::from(self.scene.radar.azimuths.max(1))
    }

    /// Seconds per rotation.
    pub fn rotation_s(&self) -> f64 {
        1.0 / self.scene.radar.rotation_hz()
    }

    /// Azimuths in `seconds` of running (whole rotations, at least one).
    pub fn azimuths_in(&self, seconds: f64) -> u64 {
        let rotations = (seconds / self.rotation_s()).floor().max(1.0);
        // A finite, non-negative count far below u64::MAX for any sane duration.
        (rotations as u64).saturating_mul(self.azimuths())
    }

    /// Unix time (s) of azimuth `index` counted from the start.
    pub fn azimuth_time_s(&self, index: u64) -> f64 {
        EPOCH_S + offset_ns(&self.scene.radar, index) as f64 * 1e-9
    }

    /// Nanoseconds from the start to azimuth `index`.
    pub fn azimuth_offset_ns(&self, index: u64) -> u64 {
        offset_ns(&self.scene.radar, index)
    }

    /// The wire timestamp of azimuth `index` (whole seconds from the 1.7e9 s epoch).
    pub fn azimuth_timestamp(&self, index: u64) -> Result<protocol::Timestamp, EvalError> {
        let offset = self.azimuth_offset_ns(index);
        protocol::Timestamp::new(
            u32::try_from(1_700_000_000 + offset / 1_000_000_000).unwrap_or(u32::MAX),
            u32::try_from(offset % 1_000_000_000).unwrap_or(0),
        )
        .map_err(|e| EvalError::Setting(format!("timestamp: {e}")))
    }

    /// Bearing of azimuth `index` (rad, clockwise from forward, wrapped): its encoder angle.
    pub fn bearing_rad(&self, index: u64) -> f64 {
        let r = &self.scene.radar;
        wrap_angle(r.angle_of_encoder(r.encoder_of(azimuth_in_rotation(r, index))))
    }

    /// A fresh render cursor (its own trajectory cursor and buffers).
    pub fn cursor(&self) -> RenderCursor {
        self.renderer.cursor()
    }

    /// The true trajectory.
    pub fn trajectory(&self) -> &Trajectory {
        self.renderer.trajectory()
    }

    /// The true start pose.
    pub fn start_pose(&self) -> Pose2 {
        let s = self.scene.start;
        Pose2::new(s[0], s[1], wrap_angle(s[2]))
    }

    /// Odometry record `j` as the filter takes it (time, noisy speed and steering).
    pub fn odometry(&self, j: u64) -> OdometrySample {
        let offset = self.odometry.offset_ns(j);
        let controls = self.trajectory().controls_at(offset);
        let record = self.odometry.record(j, controls);
        OdometrySample {
            timestamp_s: EPOCH_S + offset as f64 * 1e-9,
            speed_mps: record.speed_mps,
            steer_rad: record.steer_rad,
        }
    }

    /// Time (s) of odometry record `j`.
    pub fn odometry_time_s(&self, j: u64) -> f64 {
        EPOCH_S + self.odometry.offset_ns(j) as f64 * 1e-9
    }

    /// The feature with scene id `id`.
    pub fn feature(&self, id: u32) -> Option<&TrueFeature> {
        self.features.iter().find(|f| f.id == id)
    }
}
