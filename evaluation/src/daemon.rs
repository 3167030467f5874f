//! The daemon's own pipeline (`slam_node::pipeline::Pipeline`), as it ships, fed with the
//! simulator's wire bytes: every rendered FFT frame is decoded by `protocol`'s decoder,
//! wrapped as radar-driver's `Azimuth`, and handed to `process_azimuth` with the odometry
//! up to its time. Settings come from `config::Config::default()` through the daemon's own
//! conversion (`PipelineSettings::from_config`).

use std::sync::Arc;
use std::time::Instant;

use bytes::BytesMut;
use protocol::{FrameDecoder, Geometry, Message};
use radar_driver::Azimuth;
use sim_sensor::scene::Scene;
use sim_sensor::OdometryNoise;
use slam_node::pipeline::{Pipeline, PipelineSettings, PipelineSummary, SceneTruth};

use crate::error::EvalError;
use crate::record::RotationRecord;
use crate::world::{World, EPOCH_S};

/// The settings the daemon ships with: the default configuration, converted by the daemon.
pub fn shipped_settings() -> Result<PipelineSettings, EvalError> {
    PipelineSettings::from_config(&config::Config::default())
        .map_err(|e| EvalError::Setting(format!("shipped configuration: {e}")))
}

/// The settings the evaluation runs the daemon's pipeline with on `scene`: the daemon's own
/// adjustment to a simulated scene (`embedded_facts`: motion model, the receiver's
/// compensation, beam, bins, start pose), then the two things the evaluation sets on
/// purpose: the filter's odometry noise matched to the simulator's odometry, and a small
/// initial pose uncertainty. A test (`tests/settings.rs`) holds them to the daemon's.
pub fn scene_settings(
    settings: PipelineSettings,
    scene: &Scene,
    world: &World,
    odometry: &OdometryNoise,
) -> PipelineSettings {
    let mut settings =
        settings.with_facts(&slam_node::daemon::embedded::embedded_facts(scene, false));
    settings.motion = world.motion;
    let start = world.start_pose();
    settings.initial_pose = [start.x, start.y, start.theta];
    settings.initial_pose_std = [1e-3, 1e-3, 1e-4];
    settings.filter.speed_std_mps = odometry.sigma_speed_mps.max(1e-3);
    settings.filter.steer_std_rad = odometry.sigma_steer_rad.max(1e-5);
    settings.filter.input_noise_correlation_s = 1.0 / odometry.rate_hz;
    settings
}

/// What a daemon run measured.
#[derive(Debug, Clone)]
pub struct DaemonOutcome {
    /// One record per rotation (pose at the filter's time against the truth then).
    pub rotations: Vec<RotationRecord>,
    /// The daemon's own summary (its pose and map scores included).
    pub summary: PipelineSummary,
    /// Wall time including rendering (s).
    pub wall_s: f64,
    /// The filter's final radar loss estimate (dB).
    pub loss_db: f64,
}

/// The geometry a simulated radar announces.
pub fn geometry_of(scene: &Scene) -> Result<Geometry, EvalError> {
    scene.radar.configuration().geometry().map_err(|e| {
        EvalError::Setting(format!(
            "the scene's radar announces no usable geometry: {e}"
        ))
    })
}

/// Runs the daemon's pipeline over `seconds` of `scene` with `settings`; the motion model
/// is the scene's (the configuration's is for the vehicle it describes).
pub fn run_daemon(
    scene: &Scene,
    seed: u64,
    seconds: f64,
    mut settings: PipelineSettings,
    odometry: OdometryNoise,
) -> Result<DaemonOutcome, EvalError> {
    let started = Instant::now();
    let world = World::new(scene.clone(), seed, seconds, odometry)?;
    settings = scene_settings(settings, scene, &world, &odometry);
    let truth = SceneTruth::new(scene, EPOCH_S, seconds + 2.0)?;
    let mut pipeline = Pipeline::new(settings, Some(EPOCH_S), Some(Box::new(truth)))
        .map_err(|e| EvalError::Setting(format!("pipeline: {e}")))?;
    let geometry = Arc::new(geometry_of(scene)?);
    let mut cursor = world.cursor();
    let mut frame = BytesMut::new();
    let mut decoder = FrameDecoder::new();
    let mut events = Vec::new();
    let mut numbering = radar_driver::RotationAssembler::new();
    numbering.set_counting_only(true);
    let mut next_odometry = 0u64;
    let mut rotations = Vec::new();
    let mut work_s = 0.0;
    let total = world.azimuths_in(seconds);
    let n = world.azimuths();
    for index in 0..total {
        let t = world.azimuth_time_s(index);
        while world.odometry_time_s(next_odometry) <= t {
            pipeline.push_odometry(world.odometry(next_odometry));
            next_odometry += 1;
        }
        let ts = world.azimuth_timestamp(index)?;
        frame.clear();
        let sweep = u16::try_from(index % 65_536).unwrap_or(0);
        cursor.render(index, sweep, ts, &mut frame)?;
        let message = decoder
            .decode(&mut frame)
            .map_err(|e| EvalError::Setting(format!("decoding the simulator's frame: {e}")))?;
        let Some(Message::FftData(fft)) = message else {
            return Err(EvalError::Setting(
                "the simulator's frame was not FFT data".into(),
            ));
        };
        // Rotations numbered by the driver's own numbering.
        let mut az = Azimuth::from_fft(fft, Arc::clone(&geometry));
        numbering.number(&mut az);
        let clock = Instant::now();
        events.clear();
        pipeline
            .process_azimuth(&az, &mut events)
            .map_err(|e| EvalError::Setting(format!("pipeline: {e}")))?;
        work_s += clock.elapsed().as_secs_f64();
        if (index + 1) % n == 0 {
            let ekf = pipeline.ekf();
            let time_s = ekf.state().time_s();
            let offset_ns = ((time_s - EPOCH_S).max(0.0) * 1e9).round();
            // A non-negative time within the run, far below u64::MAX.
            let truth = world.trajectory().pose_at(offset_ns as u64)?;
            let p = ekf.pose_covariance();
            rotations.push(RotationRecord {
                time_s: time_s - EPOCH_S,
                truth,
                estimate: ekf.pose(),
                nees: ekf.pose_nees(&truth).ok(),
                features: ekf.feature_count(),
                sigma: [
                    p[(0, 0)].max(0.0).sqrt(),
                    p[(1, 1)].max(0.0).sqrt(),
                    p[(2, 2)].max(0.0).sqrt(),
                ],
                work_s,
                health: None,
            });
            work_s = 0.0;
        }
    }
    events.clear();
    let summary = pipeline.finish(&mut events);
    Ok(DaemonOutcome {
        loss_db: pipeline.ekf().state().loss_db(),
        rotations,
        summary,
        wall_s: started.elapsed().as_secs_f64(),
    })
}

/// The whole daemon's options for a run of `config` (with the keys its file wrote,
/// `written`) against the simulator in this process with `sim`'s options, for `seconds` of
/// stream, its outputs in `out`: no figures, no progress lines, the configuration's own
/// detector (what `slam-node --config FILE --embedded-sim --duration S` runs).
pub fn embedded_run_options(
    config: config::Config,
    written: std::collections::BTreeSet<String>,
    sim: sim_sensor::SimOptions,
    seconds: f64,
    out: &std::path::Path,
) -> slam_node::daemon::DaemonOptions {
    slam_node::daemon::DaemonOptions {
        out_dir: out.to_path_buf(),
        figures: false,
        progress_every_rotations: 0,
        max_stream_s: Some(seconds),
        simulator: Some(slam_node::daemon::Simulator {
            sim: slam_node::daemon::EmbeddedSim::new(sim),
            recorded: None,
        }),
        mcap: None,
        keep_configured_compensation: false,
        spectrum_bearings_deg: Vec::new(),
        config,
        stop: Arc::new(std::sync::atomic::AtomicBool::new(false)),
        detector: None,
        written: Some(written),
    }
}
