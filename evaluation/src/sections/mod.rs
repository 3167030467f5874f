//! The report's sections, one module each. Every section runs its measurements, draws its
//! figures into the report folder and returns Markdown that quotes the numbers.

pub mod accuracy;
pub mod association;
pub mod association_sweep;
pub mod consistency;
pub mod oxford;
pub mod realistic_city;
pub mod spectra;
pub mod stability;
pub mod sweep;

use sim_sensor::scene::Scene;
use sim_sensor::OdometryNoise;
use slam_filter::FilterSettings;
use slam_node::detect::DetectorSettings;

use crate::error::EvalError;
use crate::run::{matched_filter, Mode, RunSpec};
use crate::world::World;

/// A run of `scene` with the settings the daemon ships with (`config::Config::default()`
/// converted by the daemon: detector, compensation, grouping, filter), the filter's input
/// noise matched to the simulator's odometry, every azimuth, every bin, one beam per
/// azimuth. In `Targets` mode the observation noise is the simulator's exact noise instead.
pub fn shipped_spec(
    scene: Scene,
    seed: u64,
    seconds: f64,
    mode: Mode,
) -> Result<RunSpec, EvalError> {
    let odometry = OdometryNoise::default();
    let world = World::new(scene.clone(), seed, 1.0, odometry)?;
    let shipped = crate::daemon::shipped_settings()?;
    let filter = match mode {
        Mode::Targets => matched_filter(&world, &odometry, true),
        _ => FilterSettings {
            speed_std_mps: odometry.sigma_speed_mps.max(1e-3),
            steer_std_rad: odometry.sigma_steer_rad.max(1e-5),
            input_noise_correlation_s: 1.0 / odometry.rate_hz,
            ..shipped.filter.clone()
        },
    };
    Ok(RunSpec {
        filter,
        filter_power: match mode {
            Mode::Targets => world.power,
            _ => shipped.power,
        },
        scene,
        seed,
        seconds,
        mode,
        azimuth_stride: 1,
        beam_batch: 1,
        odometry,
        initial_sigma: [1e-3, 1e-3, 1e-4],
        health_every_rotations: None,
    })
}

/// The daemon's pipeline as shipped.
pub fn shipped_daemon() -> Result<Mode, EvalError> {
    Ok(Mode::Daemon(Box::new(crate::daemon::shipped_settings()?)))
}

/// The shipped detector, for procedures that detect one scan on its own (it must not need
/// previous scans: TPP does, so CFAR with the shipped threshold and window is used then).
pub fn single_scan_detector() -> Result<DetectorSettings, EvalError> {
    let mut d = crate::daemon::shipped_settings()?.detector;
    if d.kind == slam_node::detect::DetectorKind::Tpp {
        d.kind = slam_node::detect::DetectorKind::OsCfar;
    }
    Ok(d)
}
