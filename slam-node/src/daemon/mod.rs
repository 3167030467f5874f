//! The daemon: radar driver, odometry, pipeline thread and writer thread wired together,
//! against a real radar by address or against the simulator started in the same process.
//!
//! Threads: the tokio runtime runs the driver (and the embedded simulator and the odometry
//! client); the pipeline runs on its own thread fed by the driver's lock-free channel; the
//! writer runs on another, fed by a channel the pipeline never blocks on.

pub mod report;
pub mod sink;

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use radar_driver::{
    shutdown_pair, Driver, DriverSettings, OdometrySource, TcpOdometry, TcpOdometrySettings,
};
use radar_model::compensation::Compensation;
use radar_model::power::RadarConstants;
use sim_sensor::{SimOptions, SimServer};
use tracing::{info, warn};

use crate::output::figures::TruthOverlay;
use crate::output::writer::WriterSummary;
use crate::output::{OutputEvent, OutputFiles, OutputHandle};
use crate::pipeline::run::ProgressFn;
use crate::pipeline::{
    run_pipeline, Pipeline, PipelineInputs, PipelineSettings, RunControl, RunReport, SceneTruth,
    TruthOracle,
};

/// Why the daemon could not run.
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    /// Settings could not be turned into the pipeline's.
    #[error(transparent)]
    Settings(#[from] crate::pipeline::settings::SettingsError),
    /// The pipeline could not start.
    #[error(transparent)]
    Pipeline(#[from] crate::pipeline::PipelineError),
    /// The embedded simulator failed.
    #[error("simulator: {0}")]
    Sim(#[from] sim_sensor::SimError),
    /// The driver failed.
    #[error("radar driver: {0}")]
    Driver(#[from] radar_driver::DriverError),
    /// The odometry source could not be opened.
    #[error("odometry: {0}")]
    Odometry(#[from] radar_driver::OdometryError),
    /// There is no odometry and the daemon will not invent motion.
    #[error("no odometry source configured ([odometry] source = \"none\"): slam-node needs the vehicle's odometry to predict its motion and will not fabricate it")]
    NoOdometry,
    /// The output writer failed.
    #[error("output: {0}")]
    Output(#[from] crate::output::WriterError),
    /// The pipeline thread panicked.
    #[error("the pipeline thread panicked")]
    PipelinePanicked,
    /// The embedded simulator must render a scene (replays carry no ground truth).
    #[error("the embedded simulator must run a scene, not a replay")]
    NotAScene,
    /// The driver was built without an azimuth channel.
    #[error("the radar driver has no azimuth channel")]
    NoAzimuthChannel,
}

/// The simulator to start in this process.
#[derive(Debug, Clone)]
pub struct EmbeddedSim {
    /// The simulator's options (bind 127.0.0.1:0 for tests and the default run).
    pub options: SimOptions,
}

/// Everything a daemon run needs.
#[derive(Debug)]
pub struct DaemonOptions {
    /// The validated configuration.
    pub config: config::Config,
    /// Start this simulator and connect to it instead of `[radar] address`.
    pub embedded: Option<EmbeddedSim>,
    /// Stop after this much stream time.
    pub max_stream_s: Option<f64>,
    /// Output folder.
    pub out_dir: PathBuf,
    /// Draw figures at the end.
    pub figures: bool,
    /// Print a progress line every this many rotations (0 = never).
    pub progress_every_rotations: u64,
    /// Set to stop the run early (Ctrl-C).
    pub stop: Arc<AtomicBool>,
    /// With the embedded simulator, keep the configuration's `[model] compensation` instead
    /// of the scene's receiver (to see the paper's 60 dB/decade bias, figure 10).
    pub keep_configured_compensation: bool,
    /// Bearings (degrees, clockwise from forward) whose predicted and measured spectra are
    /// written and drawn every 25 rotations; empty: the beam with the most mapped features.
    pub spectrum_bearings_deg: Vec<f64>,
    /// Detection settings replacing the configuration's `[detector]` (the no-argument run
    /// uses slam-node's measured default, see `detect`).
    pub detector: Option<crate::detect::DetectorSettings>,
}

/// What a run produced.
#[derive(Debug)]
pub struct DaemonReport {
    /// The pipeline thread's report.
    pub run: RunReport,
    /// The driver's counters at the end.
    pub driver: Option<radar_driver::MetricsSnapshot>,
    /// The writer's summary.
    pub writer: WriterSummary,
    /// Where the outputs are.
    pub out_dir: PathBuf,
    /// Scene name when the simulator was embedded.
    pub scene: Option<String>,
}

fn embedded_settings(
    mut settings: PipelineSettings,
    scene: &sim_sensor::scene::Scene,
    keep_compensation: bool,
) -> PipelineSettings {
    // The simulator's odometry means what its scene's motion model says.
    let motion = sim_sensor::trajectory::motion_model(scene.motion);
    if motion != settings.motion {
        info!(?motion, configured = ?settings.motion, "using the scene's motion model for its odometry");
        settings.motion = motion;
    }
    // The simulator's receiver compensation is known exactly: use it, as a calibrated gain
    // curve would be used on a real unit.
    let slope = scene.receiver.compensation_db_per_decade;
    if keep_compensation {
        info!(
            scene_db_per_decade = slope,
            "keeping the configured receiver compensation, not the scene's"
        );
    } else {
        settings.compensation = Compensation::calibrated(slope, &RadarConstants::default());
    }
    settings.beam_width_rad = scene.radar.beam_width_rad;
    // The simulator draws each peak one bin wide (FWHM).
    settings.noise.range.resolution_fwhm_m =
        f64::from(scene.radar.range_gain) * scene.radar.bin_size_m();
    settings.filter.beam_half_width_rad = 0.5 * scene.radar.beam_width_rad;
    if settings.filter.repeat_look_range_m > 0.0 && settings.filter.repeat_look_bearing_rad > 0.0 {
        use crate::pipeline::settings::REPEAT_LOOK_CELL_FRACTION as F;
        settings.filter.repeat_look_range_m = F * settings.noise.range.resolution_fwhm_m;
        settings.filter.repeat_look_bearing_rad = F * scene.radar.beam_width_rad;
    }
    settings.initial_pose = scene.start;
    settings.initial_pose_std = [0.0; 3];
    settings
}

/// Runs the daemon to the end of the stream, the duration limit or a stop request.
pub async fn run_daemon(
    opts: DaemonOptions,
    progress: Option<ProgressFn>,
) -> Result<DaemonReport, DaemonError> {
    let mut settings = PipelineSettings::from_config(&opts.config)?;
    if let Some(d) = opts.detector {
        settings.detector = d;
    }
    settings.spectrum_bearings_rad = opts
        .spectrum_bearings_deg
        .iter()
        .map(|d| radar_model::geometry::wrap_angle(d.to_radians()))
        .collect();
    info!(kind = ?settings.detector.kind, domain = ?settings.detector.domain, "detector");
    let o = &opts.config.output;
    let output = OutputHandle::spawn(OutputFiles {
        figures: opts.figures,
        trajectory: o.trajectory.clone(),
        map: o.map.clone(),
        diagnostics: o.diagnostics.clone(),
        ..OutputFiles::in_dir(opts.out_dir.clone())
    })?;
    let (odo_trigger, odo_shutdown) = shutdown_pair();
    let mut sim_handle = None;
    let mut truth: Option<Box<dyn TruthOracle>> = None;
    let mut pipeline: Option<Pipeline> = None;
    let mut start_time_s = None;
    let mut scene_name = None;
    let mut truth_overlay = TruthOverlay::default();
    let mut driver_settings = DriverSettings::from_config(&opts.config.radar);
    // The pipeline takes azimuths and finds rotation ends itself: no rotation channel, so
    // the driver neither assembles rotations nor counts them as dropped.
    driver_settings.handoff.rotation_capacity = None;
    let (azimuths, driver, odometry): (_, _, Option<Box<dyn OdometrySource>>) = if let Some(sim) =
        opts.embedded
    {
        let mut options = sim.options;
        options.ground_truth_path = Some(opts.out_dir.join("ground-truth.jsonl"));
        let start_ns = *options
            .start_time_ns
            .get_or_insert(1_704_067_200_000_000_000);
        let sim_sensor::settings::SourceSpec::Scene(scene) = options.source.clone() else {
            return Err(DaemonError::NotAScene);
        };
        settings = embedded_settings(settings, &scene, opts.keep_configured_compensation);
        let start_s = start_ns as f64 * 1e-9;
        start_time_s = Some(start_s);
        let horizon = opts.max_stream_s.unwrap_or(600.0) + 30.0;
        let oracle = SceneTruth::new(&scene, start_s, horizon)?;
        truth_overlay.features = oracle.features().iter().map(|f| (f.x_m, f.y_m)).collect();
        truth_overlay.trajectory = (0..(horizon.min(3600.0) * 4.0) as usize)
            .filter_map(|k| oracle.pose_at(start_s + k as f64 * 0.25))
            .map(|p| (p.x, p.y))
            .collect();
        if let Some(limit) = opts.max_stream_s {
            let keep = (limit * 4.0).ceil() as usize + 1;
            truth_overlay.trajectory.truncate(keep);
        }
        truth = Some(Box::new(oracle));
        scene_name = Some(scene.name.clone());
        // Everything that can fail is checked before the simulator starts.
        pipeline = Some(Pipeline::new(settings.clone(), start_time_s, truth.take())?);
        let fast = options.pacing == sim_sensor::settings::Pacing::AsFastAsPossible;
        let handle = SimServer::spawn(options).await?;
        info!(radar = %handle.local_addr(), odometry = ?handle.odometry_addr(), scene = %scene.name, "embedded simulator started");
        driver_settings.address = handle.local_addr();
        let odometry_addr = handle.odometry_addr();
        sim_handle = Some(handle);
        let odometry: Option<Box<dyn OdometrySource>> = odometry_addr.map(|a| {
            Box::new(TcpOdometry::spawn(
                &tokio::runtime::Handle::current(),
                TcpOdometrySettings::new(a),
                odo_shutdown.clone(),
            )) as Box<dyn OdometrySource>
        });
        if fast {
            let capacity = driver_settings.handoff.azimuth_capacity.unwrap_or(4096);
            let (sink, rx) = sink::BlockingSink::new(capacity);
            (
                rx,
                Driver::with_sink(driver_settings, Box::new(sink)),
                odometry,
            )
        } else {
            let (driver, receivers) = Driver::new(driver_settings);
            let rx = receivers.azimuths.ok_or(DaemonError::NoAzimuthChannel)?;
            (rx, driver, odometry)
        }
    } else {
        let odometry = radar_driver::odometry::open_configured(
            &opts.config.odometry,
            &tokio::runtime::Handle::current(),
            odo_shutdown.clone(),
        )?;
        if odometry.is_none() {
            return Err(DaemonError::NoOdometry);
        }
        let (driver, receivers) = Driver::new(driver_settings);
        let rx = receivers.azimuths.ok_or(DaemonError::NoAzimuthChannel)?;
        (rx, driver, odometry)
    };
    let pipeline = match pipeline {
        Some(p) => p,
        None => Pipeline::new(settings, start_time_s, truth)?,
    };
    let driver_handle = driver.spawn();
    let control = RunControl {
        stop: Arc::clone(&opts.stop),
        max_stream_s: opts.max_stream_s,
        progress,
    };
    let inputs = PipelineInputs { azimuths, odometry };
    let thread = std::thread::Builder::new()
        .name("slam-pipeline".into())
        .spawn(move || {
            let report = run_pipeline(pipeline, inputs, &output, control);
            (report, output)
        })
        .map_err(|_| DaemonError::PipelinePanicked)?;
    let joined = tokio::task::spawn_blocking(move || thread.join())
        .await
        .map_err(|_| DaemonError::PipelinePanicked)?;
    let (run, output) = joined.map_err(|_| DaemonError::PipelinePanicked)?;
    let driver = match tokio::time::timeout(Duration::from_secs(5), driver_handle.stop()).await {
        Ok(Ok(exit)) => Some(exit.metrics),
        Ok(Err(e)) => {
            warn!(error = %e, "radar driver ended with an error");
            None
        }
        Err(_) => {
            warn!("radar driver did not stop within 5 s");
            None
        }
    };
    odo_trigger.trigger();
    if let Some(h) = sim_handle {
        if let Err(e) = h.shutdown().await {
            warn!(error = %e, "simulator shutdown");
        }
    }
    if !truth_overlay.trajectory.is_empty() {
        output.send_blocking(OutputEvent::Truth(truth_overlay));
    }
    let writer = tokio::task::spawn_blocking(move || output.finish())
        .await
        .map_err(|_| DaemonError::PipelinePanicked)??;
    Ok(DaemonReport {
        run,
        driver,
        writer,
        out_dir: opts.out_dir,
        scene: scene_name,
    })
}
