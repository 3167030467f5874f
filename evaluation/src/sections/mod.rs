//! The report's sections, one module each. Every section runs its measurements, draws its
//! figures into the report folder and returns Markdown that quotes the numbers.

pub mod accuracy;
pub mod association;
pub mod consistency;
pub mod oxford;
pub mod spectra;
pub mod stability;
pub mod sweep;

use radar_model::power::PowerModel;
use sim_sensor::scene::Scene;
use sim_sensor::OdometryNoise;
use slam_node::detect::DetectorSettings;

use crate::error::EvalError;
use crate::run::{matched_filter, Mode, RunSpec};
use crate::world::World;

/// A run of `scene` with the settings the daemon ships with (detector and filter defaults,
/// input noise matched to the simulator's odometry), the filter's power model equal to the
/// world's, every azimuth, every bin, one beam per update.
pub fn shipped_spec(
    scene: Scene,
    seed: u64,
    seconds: f64,
    mode: Mode,
) -> Result<RunSpec, EvalError> {
    let odometry = OdometryNoise::default();
    let world = World::new(scene.clone(), seed, 1.0, odometry)?;
    let targets = matches!(mode, Mode::Targets);
    Ok(RunSpec {
        filter: matched_filter(&world, &odometry, targets),
        filter_power: world.power,
        scene,
        seed,
        seconds,
        mode,
        azimuth_stride: 1,
        bin_stride: 1,
        beam_batch: 1,
        odometry,
        initial_sigma: [1e-3, 1e-3, 1e-4],
        health_every_rotations: None,
    })
}

/// The detector the daemon ships with.
pub fn shipped_detector() -> DetectorSettings {
    DetectorSettings::default()
}

/// The filter's power model for a world (same as the simulator's).
pub fn world_power(world: &World) -> PowerModel {
    world.power
}
