//! The daemon: radar driver, odometry, pipeline thread and writer thread wired together,
//! against a real radar by address or against the simulator started in the same process.
//!
//! Threads: the tokio runtime runs the driver (and the embedded simulator and the odometry
//! client); the pipeline runs on its own thread fed by the driver's lock-free channel; the
//! writer runs on another, fed by a channel the pipeline never blocks on.

#[cfg(feature = "sim")]
pub mod embedded;
pub mod mcap_replay;
#[cfg(feature = "sim")]
pub mod replay;
pub mod report;
pub mod sink;
pub mod zenoh_odometry;

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use radar_driver::{shutdown_pair, Driver, DriverSettings, OdometrySource};
use tracing::warn;

use crate::output::figures::TruthOverlay;
use crate::output::writer::WriterSummary;
use crate::output::{OutputEvent, OutputFiles, OutputHandle, RecordingFile};
use crate::pipeline::run::PipelineStart;
use crate::pipeline::run::ProgressFn;
use crate::pipeline::{
    run_pipeline, Pipeline, PipelineInputs, PipelineSettings, RunControl, RunReport,
};

#[cfg(feature = "sim")]
pub use embedded::{EmbeddedSim, RecordedReplay};

/// Why the daemon could not run.
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    /// Settings could not be turned into the pipeline's.
    #[error(transparent)]
    Settings(#[from] crate::pipeline::settings::SettingsError),
    /// The pipeline could not start.
    #[error(transparent)]
    Pipeline(#[from] crate::pipeline::PipelineError),
    /// Recorded scans could not be replayed.
    #[cfg(feature = "sim")]
    #[error("replay")]
    Replay(#[from] replay::ReplayError),
    /// The embedded simulator failed.
    #[cfg(feature = "sim")]
    #[error("simulator")]
    Sim(#[from] sim_sensor::SimError),
    /// The driver failed.
    #[error("radar driver")]
    Driver(#[from] radar_driver::DriverError),
    /// The odometry source could not be opened.
    #[error("odometry")]
    Odometry(#[from] radar_driver::OdometryError),
    /// There is no odometry and the daemon will not invent motion.
    #[error("no odometry source configured ([odometry] source = \"none\"): slam-node needs the vehicle's odometry to predict its motion and will not fabricate it")]
    NoOdometry,
    /// The output writer failed.
    #[error("output")]
    Output(#[from] crate::output::WriterError),
    /// The pipeline thread panicked.
    #[error("the pipeline thread panicked")]
    PipelinePanicked,
    /// The embedded simulator must render a scene (replays carry no ground truth).
    #[cfg(feature = "sim")]
    #[error("the embedded simulator must run a scene, not a replay")]
    NotAScene,
    /// A stop (Ctrl-C) came while the scene was being built: nothing ran.
    #[error("stopped while building the scene, before the run began")]
    Stopped,
    /// The driver was built without an azimuth channel.
    #[error("the radar driver has no azimuth channel")]
    NoAzimuthChannel,
    /// An MCAP replay could not start.
    #[error("MCAP replay")]
    McapReplay(#[from] mcap_replay::McapReplayError),
    /// The Zenoh session or the odometry subscription could not start.
    #[error("Zenoh")]
    Zenoh(#[from] crate::output::LiveError),
}

/// Everything a daemon run needs.
#[derive(Debug)]
pub struct DaemonOptions {
    /// The validated configuration.
    pub config: config::Config,
    /// Start this simulator and connect to it instead of `[radar] address`.
    #[cfg(feature = "sim")]
    pub embedded: Option<EmbeddedSim>,
    /// With `embedded`: replay these recorded scans (its scene is ignored) with odometry
    /// from their ground truth.
    #[cfg(feature = "sim")]
    pub recorded: Option<RecordedReplay>,
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
    /// Detection settings replacing the configuration's `[detector]` but for the radar
    /// profile's front end (the no-argument run uses slam-node's measured default, see
    /// `detect`).
    pub detector: Option<crate::detect::DetectorSettings>,
    /// The keys the configuration file writes (`config::written_keys`): those override
    /// the radar profile's values, the others take them. `None`: the configuration was
    /// built in code and its values win everywhere.
    pub written: Option<std::collections::BTreeSet<String>>,
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
    /// Replays of recorded scans: dead reckoning and the distance driven.
    #[cfg(feature = "sim")]
    pub replay: Option<replay::ReplayFigures>,
    /// Why the radar driver failed, if it did (it gave up reconnecting, or its recording
    /// could not be written): the run's job failed even though a summary exists.
    pub driver_failure: Option<radar_driver::DriverError>,
    /// A replay of an MCAP file: what it read and refused.
    pub mcap_replay: Option<mcap_replay::McapReplayCounts>,
    /// Odometry from Zenoh: what the subscription received and lost.
    pub zenoh_odometry: Option<zenoh_odometry::ZenohOdometryCounts>,
}

/// The Zenoh session a run needs (publishing, or odometry from Zenoh), opened on a blocking
/// thread; `None` when it needs none. Without the `zenoh` feature, asking for one is
/// [`crate::output::LiveError::NotBuilt`].
async fn open_zenoh(
    config: &config::Config,
) -> Result<Option<crate::output::live::SharedNode>, DaemonError> {
    let wanted = config.output.zenoh.enabled
        || matches!(
            config.odometry.source,
            config::odometry::OdometrySource::Zenoh { .. }
        );
    if !wanted {
        return Ok(None);
    }
    #[cfg(feature = "zenoh")]
    {
        let settings = config.output.zenoh.clone();
        let node = tokio::task::spawn_blocking(move || {
            crate::output::zenoh_node::ZenohNode::open(&settings, crate::output::live::NODE_NAME)
        })
        .await
        .map_err(|_| DaemonError::PipelinePanicked)??;
        Ok(Some(Arc::new(node)))
    }
    #[cfg(not(feature = "zenoh"))]
    Err(crate::output::LiveError::NotBuilt.into())
}

/// An odometry source over Zenoh and its counters.
type ZenohOdometrySource = (Box<dyn OdometrySource>, zenoh_odometry::SharedStats);

/// The odometry subscription `[odometry] source = "zenoh"` asks for, on `node`, decoding under
/// `motion`; `None` for other sources.
#[cfg(feature = "zenoh")]
fn zenoh_odometry_source(
    config: &config::Config,
    node: Option<&crate::output::live::SharedNode>,
    motion: radar_model::motion::MotionModel,
) -> Result<Option<ZenohOdometrySource>, DaemonError> {
    let (config::odometry::OdometrySource::Zenoh { topic, message }, Some(node)) =
        (&config.odometry.source, node)
    else {
        return Ok(None);
    };
    let message = match message {
        config::odometry::OdometryMessageKind::Odometry => {
            crate::output::ros::OdometryMessage::Odometry
        }
        config::odometry::OdometryMessageKind::TwistStamped => {
            crate::output::ros::OdometryMessage::TwistStamped
        }
    };
    let source = zenoh_odometry::ZenohOdometry::subscribe(node, topic, message, motion)?;
    let stats = source.stats();
    Ok(Some((Box::new(source), stats)))
}

/// Without the `zenoh` feature there is no Zenoh odometry ([`open_zenoh`] refused it).
#[cfg(not(feature = "zenoh"))]
fn zenoh_odometry_source(
    _config: &config::Config,
    _node: Option<&crate::output::live::SharedNode>,
    _motion: radar_model::motion::MotionModel,
) -> Result<Option<ZenohOdometrySource>, DaemonError> {
    Ok(None)
}

/// The settings recipe of a run: its configuration, the keys its file writes, and what the
/// command line adds.
fn recipe(opts: &DaemonOptions) -> Result<crate::pipeline::SettingsRecipe, DaemonError> {
    let recipe = crate::pipeline::SettingsRecipe {
        config: opts.config.clone(),
        written: opts.written.clone(),
        facts: crate::pipeline::SourceFacts {
            detector: opts.detector,
            spectrum_bearings_rad: opts
                .spectrum_bearings_deg
                .iter()
                .map(|d| radar_model::geometry::wrap_angle(d.to_radians()))
                .collect(),
            ..crate::pipeline::SourceFacts::default()
        },
    };
    // An unknown `[radar] model` is refused before anything connects.
    recipe.named_model()?;
    Ok(recipe)
}

/// Runs the daemon to the end of the stream, the duration limit or a stop request.
pub async fn run_daemon(
    opts: DaemonOptions,
    progress: Option<ProgressFn>,
) -> Result<DaemonReport, DaemonError> {
    let recipe = recipe(&opts)?;
    // The motion model the odometry means: the configuration's (the simulator's scene may
    // say otherwise, below); the radar's profile does not change it.
    let configured_motion = PipelineSettings::from_config(&opts.config)?.motion;
    let node = open_zenoh(&opts.config).await?;
    // The simulator writes its ground truth there before the writer starts; a folder that
    // cannot be made is reported by the writer below.
    let _ = std::fs::create_dir_all(&opts.out_dir);
    let mut zenoh_stats = None;
    let (odo_trigger, odo_shutdown) = shutdown_pair();
    #[cfg(feature = "sim")]
    let mut sim_handle: Option<sim_sensor::SimHandle> = None;
    #[cfg_attr(not(feature = "sim"), allow(unused_mut))]
    let mut pipeline: Option<PipelineStart> = None;
    #[cfg(feature = "sim")]
    let mut replay_figures = None;
    #[cfg_attr(not(feature = "sim"), allow(unused_mut))]
    let mut scene_name = None;
    #[cfg_attr(not(feature = "sim"), allow(unused_mut))]
    let mut truth_overlay = TruthOverlay::default();
    #[cfg_attr(not(feature = "sim"), allow(unused_mut))]
    let mut motion = configured_motion;
    let mut driver_settings = DriverSettings::from_config(&opts.config.radar);
    // The pipeline takes azimuths and finds rotation ends itself: no rotation channel, so
    // the driver neither assembles rotations nor counts them as dropped.
    driver_settings.handoff.rotation_capacity = None;
    #[cfg(feature = "sim")]
    let embedded = opts.embedded;
    #[cfg(not(feature = "sim"))]
    let embedded: Option<std::convert::Infallible> = None;
    let (azimuths, driver, odometry): (_, _, Option<Box<dyn OdometrySource>>) = if let Some(sim) =
        embedded
    {
        #[cfg(feature = "sim")]
        {
            let started = match opts.recorded {
                Some(recorded) => {
                    embedded::start_replay(sim.options, recorded, &recipe, driver_settings).await?
                }
                None => {
                    embedded::start(
                        sim,
                        &recipe,
                        driver_settings,
                        &opts.out_dir,
                        opts.max_stream_s,
                        opts.keep_configured_compensation,
                        odo_shutdown.clone(),
                        &opts.stop,
                    )
                    .await?
                }
            };
            replay_figures = started.replay;
            motion = started.motion;
            truth_overlay = started.truth_overlay;
            scene_name = Some(started.scene_name);
            pipeline = Some(started.pipeline);
            sim_handle = Some(started.handle);
            // Odometry from Zenoh instead of the simulator's odometry port.
            let odometry = match zenoh_odometry_source(&opts.config, node.as_ref(), motion)? {
                Some((source, stats)) => {
                    zenoh_stats = Some(stats);
                    Some(source)
                }
                None => started.odometry,
            };
            (started.azimuths, started.driver, odometry)
        }
        #[cfg(not(feature = "sim"))]
        match sim {}
    } else {
        let odometry = match zenoh_odometry_source(&opts.config, node.as_ref(), motion)? {
            Some((source, stats)) => {
                zenoh_stats = Some(stats);
                Some(source)
            }
            None => radar_driver::odometry::open_configured(
                &opts.config.odometry,
                &tokio::runtime::Handle::current(),
                odo_shutdown.clone(),
            )?,
        };
        if odometry.is_none() {
            return Err(DaemonError::NoOdometry);
        }
        let (driver, receivers) = Driver::new(driver_settings);
        let rx = receivers.azimuths.ok_or(DaemonError::NoAzimuthChannel)?;
        (rx, driver, odometry)
    };
    let output = OutputHandle::spawn(output_files_for(
        &opts.config,
        opts.figures,
        &opts.out_dir,
        motion,
        node.clone(),
    ))?;
    // A radar over TCP: its profile is chosen from the geometry of its first azimuth.
    let pipeline = match pipeline {
        Some(p) => p,
        None => PipelineStart::OnFirstAzimuth(Box::new(move |geometry: &protocol::Geometry| {
            let derived = recipe.for_radar(geometry, crate::pipeline::SourceFacts::default())?;
            Pipeline::new(derived.settings, None, None)
        })),
    };
    let driver_handle = driver.spawn();
    #[cfg(feature = "sim")]
    let end_after_silence = replay_figures.is_some().then(|| Duration::from_secs(2));
    #[cfg(not(feature = "sim"))]
    let end_after_silence = None;
    let control = RunControl {
        end_after_silence,
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
    if let Some(why) = &run.start_failure {
        warn!(error = %why, "the pipeline did not start for this radar");
    }
    let mut driver_failure = None;
    let driver = match tokio::time::timeout(Duration::from_secs(5), driver_handle.stop()).await {
        Ok(Ok(exit)) => Some(exit.metrics),
        Ok(Err(e)) => {
            warn!(error = %e, "radar driver ended with an error");
            driver_failure = Some(e);
            None
        }
        Err(_) => {
            warn!("radar driver did not stop within 5 s");
            None
        }
    };
    odo_trigger.trigger();
    #[cfg(feature = "sim")]
    if let Some(h) = sim_handle {
        if let Some(figures) = replay_figures.as_mut() {
            figures.scans_skipped = h.stats().scans_skipped;
        }
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
    let zenoh_odometry = zenoh_stats.map(|s| s.snapshot());
    close_zenoh(node).await;
    Ok(DaemonReport {
        run,
        driver,
        writer,
        out_dir: opts.out_dir,
        scene: scene_name,
        #[cfg(feature = "sim")]
        replay: replay_figures,
        driver_failure,
        mcap_replay: None,
        zenoh_odometry,
    })
}

/// Runs the daemon on a rosbag2 MCAP file (Navtech's radar messages and an odometry topic,
/// see [`mcap_replay`]) as fast as the pipeline goes, to the end of the file, the duration
/// limit or a stop request. `odometry_topic` defaults to the daemon's own `/odom/twist`.
pub fn run_mcap_replay(
    opts: DaemonOptions,
    path: PathBuf,
    odometry_topic: Option<String>,
    progress: Option<ProgressFn>,
) -> Result<DaemonReport, DaemonError> {
    let recipe = recipe(&opts)?;
    let motion = PipelineSettings::from_config(&opts.config)?.motion;
    // The replay's odometry comes from the file: a session only to publish.
    #[cfg(feature = "zenoh")]
    let node = if opts.config.output.zenoh.enabled {
        Some(Arc::new(crate::output::zenoh_node::ZenohNode::open(
            &opts.config.output.zenoh,
            crate::output::live::NODE_NAME,
        )?))
    } else {
        None
    };
    #[cfg(not(feature = "zenoh"))]
    let node: Option<crate::output::live::SharedNode> = None;
    let output = OutputHandle::spawn(output_files(&opts, motion, node.clone()))?;
    let mut replay = mcap_replay::McapReplaySettings::new(path, motion);
    if let Some(topic) = odometry_topic {
        replay.odometry_topic = topic;
    }
    let (azimuths, odometry, reader) = mcap_replay::start(replay)?;
    // The recorded radar's profile is chosen from the geometry of its first azimuth, as a
    // live radar's is.
    let pipeline = PipelineStart::OnFirstAzimuth(Box::new(move |geometry: &protocol::Geometry| {
        let derived = recipe.for_radar(geometry, crate::pipeline::SourceFacts::default())?;
        Pipeline::new(derived.settings, None, None)
    }));
    let control = RunControl {
        end_after_silence: None,
        stop: Arc::clone(&opts.stop),
        max_stream_s: opts.max_stream_s,
        progress,
    };
    let inputs = PipelineInputs {
        azimuths,
        odometry: Some(Box::new(odometry)),
    };
    let run = run_pipeline(pipeline, inputs, &output, control);
    let counts = reader.finish();
    let writer = output.finish()?;
    #[cfg(feature = "zenoh")]
    if let Some(node) = node {
        node.close();
    }
    #[cfg(not(feature = "zenoh"))]
    let _ = node;
    Ok(DaemonReport {
        run,
        driver: None,
        writer,
        out_dir: opts.out_dir,
        scene: None,
        #[cfg(feature = "sim")]
        replay: None,
        driver_failure: None,
        mcap_replay: Some(counts),
        zenoh_odometry: None,
    })
}

/// Closes the run's Zenoh session, if it has one, on a blocking thread.
async fn close_zenoh(node: Option<crate::output::live::SharedNode>) {
    #[cfg(feature = "zenoh")]
    if let Some(node) = node {
        let _ = tokio::task::spawn_blocking(move || node.close()).await;
    }
    #[cfg(not(feature = "zenoh"))]
    let _ = node;
}

/// The output files a run writes: the configured names in the output folder, the MCAP
/// recording when one is asked for, and the live Zenoh topics when `[output.zenoh]` is on.
fn output_files(
    opts: &DaemonOptions,
    motion: radar_model::motion::MotionModel,
    node: Option<crate::output::live::SharedNode>,
) -> OutputFiles {
    output_files_for(&opts.config, opts.figures, &opts.out_dir, motion, node)
}

/// [`output_files`] from its parts.
fn output_files_for(
    config: &config::Config,
    figures: bool,
    out_dir: &std::path::Path,
    motion: radar_model::motion::MotionModel,
    node: Option<crate::output::live::SharedNode>,
) -> OutputFiles {
    let o = &config.output;
    OutputFiles {
        figures,
        trajectory: o.trajectory.clone(),
        map: o.map.clone(),
        diagnostics: o.diagnostics.clone(),
        recording: o.mcap.as_ref().map(|file| RecordingFile {
            path: out_dir.join(file),
            motion,
        }),
        live: o.zenoh.enabled.then(|| crate::output::LiveOutput {
            zenoh: o.zenoh.clone(),
            motion,
            node,
        }),
        ..OutputFiles::in_dir(out_dir.to_path_buf())
    }
}
