//! The daemon: radar driver, odometry, pipeline thread and writer thread wired together,
//! against a real radar by address or against the simulator started in the same process.
//!
//! Threads: the tokio runtime runs the driver (and the embedded simulator and the odometry
//! client); the pipeline runs on its own thread fed by the driver's lock-free channel; the
//! writer runs on another, fed by a channel the pipeline never blocks on.

mod localise_report;
pub mod report;
pub mod start;
pub mod zenoh_odometry;
pub mod zenoh_prior;

// The sources' modules under their earlier names.
#[cfg(feature = "sim")]
pub use crate::source::embedded;
pub use crate::source::mcap as mcap_replay;
#[cfg(feature = "sim")]
pub use crate::source::replay;
#[cfg(feature = "sim")]
pub use crate::source::{embedded::EmbeddedSim, recorded::RecordedReplay};
pub use crate::source::{McapSource, Simulator};

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use radar_driver::{shutdown_pair, DriverSettings, OdometrySource};
use tracing::warn;

use crate::output::writer::WriterSummary;
use crate::output::{OutputEvent, OutputFiles, OutputHandle, RecordingFile};
use crate::pipeline::run::ProgressFn;
use crate::pipeline::{run_pipeline, PipelineInputs, RunControl, RunReport};
use crate::source::{Inputs, ReplayFigures, SourceError};

/// Why the daemon could not run.
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    /// Settings could not be turned into the pipeline's.
    #[error(transparent)]
    Settings(#[from] crate::pipeline::settings::SettingsError),
    /// The pipeline could not start.
    #[error(transparent)]
    Pipeline(#[from] crate::pipeline::PipelineError),
    /// The source (the radar, the simulator, a recording) could not start.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// The driver failed.
    #[error("radar driver")]
    Driver(#[from] radar_driver::DriverError),
    /// The output writer failed.
    #[error("output")]
    Output(#[from] crate::output::WriterError),
    /// The pipeline thread panicked.
    #[error("the pipeline thread panicked")]
    PipelinePanicked,
    /// The Zenoh session or the odometry subscription could not start.
    #[error("Zenoh")]
    Zenoh(#[from] crate::output::LiveError),
    /// The map to localise in could not be read (the message names the file and why).
    #[error(transparent)]
    Map(Box<slam_map::LoadError>),
    /// `[map] mode = "localise"` or `"extend"` without a map.
    #[error("[map] mode = \"localise\" or \"extend\" needs a map to localise in: --map FILE (or [map] file)")]
    NoMap,
    /// A map given without `[map] mode = "localise"` or `"extend"`.
    #[error("map file {0}: a map is read only with [map] mode = \"localise\" or \"extend\"")]
    MapNotUsed(PathBuf),
    /// `[map] mode = "extend"` without submaps.
    #[error("map file {0}: [map] mode = \"extend\" maps in submaps joined to the map's graph: set [submaps] enabled = true")]
    ExtendNeedsSubmaps(PathBuf),
}

impl DaemonError {
    /// Whether a stop (Ctrl-C, SIGTERM) came before the run began: while the scene was being
    /// built, or (the binary) anywhere in the start ([`start::abandon_start`]).
    pub fn is_stopped_before_start(&self) -> bool {
        matches!(self, DaemonError::Source(SourceError::Stopped))
    }
}

/// Everything a daemon run needs.
#[derive(Debug)]
pub struct DaemonOptions {
    /// The validated configuration.
    pub config: config::Config,
    /// Start this simulator (its scene, or recorded scans) and connect to it instead of
    /// `[radar] address`.
    pub simulator: Option<Simulator>,
    /// Run on this MCAP recording instead of a radar.
    pub mcap: Option<McapSource>,
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
    pub replay: Option<ReplayFigures>,
    /// Why the radar driver failed, if it did (it gave up reconnecting, or its recording
    /// could not be written): the run's job failed even though a summary exists.
    pub driver_failure: Option<radar_driver::DriverError>,
    /// A replay of an MCAP file: what it read and refused.
    pub mcap_replay: Option<mcap_replay::McapReplayCounts>,
    /// Odometry from Zenoh: what the subscription received and lost.
    pub zenoh_odometry: Option<zenoh_odometry::ZenohOdometryCounts>,
    /// Prior poses from Zenoh (`[map] initial_pose_topic`): what the subscription received
    /// and refused.
    pub zenoh_prior: Option<zenoh_odometry::ZenohOdometryCounts>,
}

/// The Zenoh session a run needs (publishing, or odometry from Zenoh), opened on a blocking
/// thread; `None` when it needs none. Without the `zenoh` feature, asking for one is
/// [`crate::output::LiveError::NotBuilt`].
async fn open_zenoh(
    config: &config::Config,
) -> Result<Option<crate::output::live::SharedNode>, DaemonError> {
    let wanted = config.output.zenoh.enabled
        || config.map.initial_pose_topic.is_some()
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

/// The prior poses `[map] initial_pose_topic` asks for, subscribed to on `node`: the
/// pipeline's end of their channel and the counters; `None` without the key.
type PriorSubscription = (
    crossbeam_channel::Receiver<crate::pipeline::localise::PriorPose>,
    zenoh_odometry::SharedStats,
    Box<dyn std::any::Any + Send>,
);

#[cfg(feature = "zenoh")]
fn zenoh_priors(
    config: &config::Config,
    node: Option<&crate::output::live::SharedNode>,
) -> Result<Option<PriorSubscription>, DaemonError> {
    let (Some(topic), Some(node)) = (config.map.initial_pose_topic.as_deref(), node) else {
        return Ok(None);
    };
    let priors = zenoh_prior::subscribe(node, topic)?;
    let stats = priors.stats();
    Ok(Some((priors.rx.clone(), stats, Box::new(priors))))
}

/// Without the `zenoh` feature there are no priors from Zenoh ([`open_zenoh`] refused them).
#[cfg(not(feature = "zenoh"))]
fn zenoh_priors(
    _config: &config::Config,
    _node: Option<&crate::output::live::SharedNode>,
) -> Result<Option<PriorSubscription>, DaemonError> {
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
        localise: localise_settings(&opts.config)?,
    };
    // An unknown `[radar] model` is refused before anything connects.
    recipe.named_model()?;
    Ok(recipe)
}

/// The saved map to localise in (`[map] mode = "localise"`, `--map FILE`): read and checked
/// here, so that a missing, truncated, corrupt or future-version file refuses the run
/// before anything connects.
fn localise_settings(
    c: &config::Config,
) -> Result<Option<crate::pipeline::localise::LocaliseSettings>, DaemonError> {
    match (c.map.mode, &c.map.file) {
        (config::MapMode::Map, None) => Ok(None),
        (config::MapMode::Map, Some(p)) => Err(DaemonError::MapNotUsed(p.clone())),
        (config::MapMode::Localise | config::MapMode::Extend, None) => Err(DaemonError::NoMap),
        (config::MapMode::Extend, Some(p)) if !c.submaps.enabled => {
            Err(DaemonError::ExtendNeedsSubmaps(p.clone()))
        }
        (config::MapMode::Localise | config::MapMode::Extend, Some(p)) => {
            let map = slam_map::Map::load(p).map_err(|e| DaemonError::Map(Box::new(e)))?;
            Ok(Some(crate::pipeline::localise::LocaliseSettings::new(
                p.clone(),
                Arc::new(map),
                &c.map,
            )))
        }
    }
}

/// The daemon's inputs from the source `opts` asks for: an MCAP recording, the simulator in
/// this process (its scene or recorded scans), or the radar at `[radar] address`. Odometry
/// from Zenoh, when configured, replaces the simulator's and the configured source.
async fn open_source(
    opts: &mut DaemonOptions,
    recipe: crate::pipeline::SettingsRecipe,
    node: Option<&crate::output::live::SharedNode>,
    odo_shutdown: radar_driver::Shutdown,
) -> Result<(Inputs, Option<zenoh_odometry::SharedStats>), DaemonError> {
    if let Some(mcap) = &opts.mcap {
        return Ok((crate::source::mcap::open(recipe, mcap, &opts.stop)?, None));
    }
    let motion = crate::pipeline::settings::motion_model(&opts.config);
    let (zenoh, stats) = match zenoh_odometry_source(&opts.config, node, motion)? {
        Some((source, stats)) => (Some(source), Some(stats)),
        None => (None, None),
    };
    let mut driver_settings = DriverSettings::from_config(&opts.config.radar);
    // The pipeline takes azimuths and finds rotation ends itself: no rotation channel, so
    // the driver neither assembles rotations nor counts them as dropped.
    driver_settings.handoff.rotation_capacity = None;
    let inputs = match opts.simulator.take() {
        Some(simulator) => {
            crate::source::start_simulator(
                simulator,
                &recipe,
                driver_settings,
                &opts.out_dir,
                opts.max_stream_s,
                opts.keep_configured_compensation,
                odo_shutdown,
                &opts.stop,
                zenoh,
            )
            .await?
        }
        None => crate::source::radar::open(recipe, driver_settings, zenoh, odo_shutdown)?,
    };
    Ok((inputs, stats))
}

/// Runs the daemon to the end of the stream, the duration limit or a stop request, on
/// whichever source `opts` names.
pub async fn run_daemon(
    mut opts: DaemonOptions,
    progress: Option<ProgressFn>,
) -> Result<DaemonReport, DaemonError> {
    let recipe = recipe(&opts)?;
    let node = open_zenoh(&opts.config).await?;
    // The simulator writes its ground truth there before the writer starts; a folder that
    // cannot be made is reported by the writer below.
    let _ = std::fs::create_dir_all(&opts.out_dir);
    let (odo_trigger, odo_shutdown) = shutdown_pair();
    let (inputs, zenoh_stats) = open_source(&mut opts, recipe, node.as_ref(), odo_shutdown).await?;
    // Held until the run ends: dropping it undeclares the subscription.
    let (priors, prior_stats, prior_subscription) = match zenoh_priors(&opts.config, node.as_ref())?
    {
        Some((rx, stats, held)) => (Some(rx), Some(stats), Some(held)),
        None => (None, None, None),
    };
    let Inputs {
        azimuths,
        driver,
        odometry,
        gyro,
        pipeline,
        motion,
        name,
        truth_overlay,
        end_after_silence,
        played_out,
        mut replay,
        running,
    } = inputs;
    let output = OutputHandle::spawn(output_files(&opts, motion, node.clone()))?;
    // The run begins: from here a stop request drains it and its outputs are written; before,
    // the binary ended the process at once (`start`), and a request that came first wins.
    if !start::begin_run() {
        return Err(SourceError::Stopped.into());
    }
    let driver_handle = driver.map(radar_driver::Driver::spawn);
    let control = RunControl {
        end_after_silence,
        played_out,
        stop: Arc::clone(&opts.stop),
        max_stream_s: opts.max_stream_s,
        progress,
    };
    let inputs = PipelineInputs {
        azimuths,
        odometry,
        gyro,
        priors,
    };
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
    let mut driver_metrics = None;
    if let Some(handle) = driver_handle {
        match tokio::time::timeout(Duration::from_secs(5), handle.stop()).await {
            Ok(Ok(exit)) => driver_metrics = Some(exit.metrics),
            Ok(Err(e)) => {
                warn!(error = %e, "radar driver ended with an error");
                driver_failure = Some(e);
            }
            Err(_) => warn!("radar driver did not stop within 5 s"),
        }
    }
    odo_trigger.trigger();
    let end = running.stop().await;
    if let Some(figures) = replay.as_mut() {
        figures.scans_skipped = end.scans_skipped;
        figures.first_scan_skipped = end.first_scan_skipped;
    }
    if !truth_overlay.trajectory.is_empty() {
        output.send_blocking(OutputEvent::Truth(truth_overlay));
    }
    let writer = tokio::task::spawn_blocking(move || output.finish())
        .await
        .map_err(|_| DaemonError::PipelinePanicked)??;
    let zenoh_odometry = zenoh_stats.map(|s| s.snapshot());
    let zenoh_prior = prior_stats.map(|s| s.snapshot());
    drop(prior_subscription);
    close_zenoh(node).await;
    Ok(DaemonReport {
        run,
        driver: driver_metrics,
        writer,
        out_dir: opts.out_dir,
        scene: name,
        replay,
        driver_failure,
        mcap_replay: end.mcap,
        zenoh_odometry,
        zenoh_prior,
    })
}

/// Runs the daemon on a rosbag2 MCAP file (Navtech's radar messages and an odometry topic,
/// see [`mcap_replay`]) as fast as the pipeline goes, to the end of the file, the duration
/// limit or a stop request, on a runtime of its own. `odometry_topic` defaults to the
/// daemon's own `/odom/twist`.
pub fn run_mcap_replay(
    mut opts: DaemonOptions,
    path: PathBuf,
    odometry_topic: Option<String>,
    progress: Option<ProgressFn>,
) -> Result<DaemonReport, DaemonError> {
    opts.mcap = Some(McapSource {
        path,
        odometry_topic,
        max_chunk_bytes: None,
    });
    opts.simulator = None;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|_| DaemonError::PipelinePanicked)?;
    runtime.block_on(run_daemon(opts, progress))
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
/// recording when one is asked for, the live Zenoh topics when `[output.zenoh]` is on, and
/// the Foxglove live view when `[output.foxglove]` or `[output.view]` is.
fn output_files(
    opts: &DaemonOptions,
    motion: radar_model::motion::MotionModel,
    node: Option<crate::output::live::SharedNode>,
) -> OutputFiles {
    let o = &opts.config.output;
    OutputFiles {
        figures: opts.figures,
        spectra: o.spectra,
        trajectory: o.trajectory.clone(),
        map: o.map.clone(),
        diagnostics: o.diagnostics.clone(),
        saved_map: opts.config.map.path.clone(),
        recording: o.mcap.as_ref().map(|file| RecordingFile {
            path: opts.out_dir.join(file),
            motion,
        }),
        live: o.zenoh.enabled.then(|| crate::output::LiveOutput {
            zenoh: o.zenoh.clone(),
            motion,
            node,
        }),
        foxglove: (o.foxglove.enabled || o.view.enabled).then(|| crate::output::FoxgloveOutput {
            settings: o.foxglove.clone(),
            view: o.view.enabled,
        }),
        ..OutputFiles::in_dir(opts.out_dir.clone())
    }
}
