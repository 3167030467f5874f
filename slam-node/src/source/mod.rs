//! The daemon's inputs, one constructor per source: the vehicle's radar over TCP
//! ([`radar`]), the simulator in this process ([`embedded`]), recorded scans replayed by it
//! ([`recorded`]), a rosbag2 MCAP recording ([`mcap`]). Each gives the same value,
//! [`Inputs`]: the numbered azimuths (rotations numbered by the radar driver's numbering),
//! an odometry source, the pipeline or how to build it once the radar has said what it is
//! (its profile is chosen from its announcement; `crate::pipeline::derive`), optional truth,
//! and what must be stopped when the run ends. The daemon's wiring (`crate::daemon`) runs any
//! of them the same way; whether the simulator is built in is decided here only.

#[cfg(feature = "sim")]
pub mod embedded;
pub mod figures;
pub mod gyro;
pub mod mcap;
pub mod radar;
#[cfg(feature = "sim")]
pub mod recorded;
#[cfg(feature = "sim")]
pub mod replay;
pub mod sink;

use std::future::Future;
use std::path::PathBuf;
use std::pin::Pin;
use std::time::Duration;

use crossbeam_channel::Receiver;
use radar_driver::{Azimuth, Driver, OdometrySource};
use radar_model::motion::MotionModel;

use crate::output::figures::TruthOverlay;
use crate::pipeline::run::PipelineStart;

pub use figures::{OdometryErrors, ReplayFigures};

/// Why a source could not start.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// The settings could not be derived.
    #[error(transparent)]
    Settings(#[from] crate::pipeline::settings::SettingsError),
    /// The pipeline could not be built.
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
    /// The odometry source could not be opened.
    #[error("odometry")]
    Odometry(#[from] radar_driver::OdometryError),
    /// The gyro source could not be opened.
    #[error("gyro")]
    Gyro(#[from] gyro::GyroError),
    /// The embedded simulator must render a scene (replays carry no ground truth).
    #[error("the embedded simulator must run a scene, not a replay")]
    NotAScene,
    /// A stop (Ctrl-C) came while the scene was being built: nothing ran.
    #[error("stopped while building the scene, before the run began")]
    Stopped,
    /// The driver was built without an azimuth channel.
    #[error("the radar driver has no azimuth channel")]
    NoAzimuthChannel,
    /// A build on a blocking thread panicked.
    #[error("a build thread panicked")]
    BuildPanicked,
    /// An MCAP replay could not start.
    #[error("MCAP replay")]
    McapReplay(#[from] mcap::McapReplayError),
}

/// What a source gives the daemon.
#[allow(missing_debug_implementations)] // holds a `dyn OdometrySource`
pub struct Inputs {
    /// The azimuths, numbered with their rotations.
    pub azimuths: Receiver<Azimuth>,
    /// The radar driver to run, when the azimuths come over TCP.
    pub driver: Option<Driver>,
    /// The odometry.
    pub odometry: Option<Box<dyn OdometrySource>>,
    /// The gyro (radar only, `[gyro]` or `--gyro-from-truth`).
    pub gyro: Option<Box<dyn gyro::GyroSource>>,
    /// The pipeline, or how to build it on the first azimuth.
    pub pipeline: PipelineStart,
    /// The motion model the odometry means (for the recording and the live output).
    pub motion: MotionModel,
    /// The run's name in the summary (a scene, a recording); `None`: a live radar.
    pub name: Option<String>,
    /// The true trajectory and features for the figures, when known.
    pub truth_overlay: TruthOverlay,
    /// End the run after this long without an azimuth (a recording played out).
    pub end_after_silence: Option<Duration>,
    /// Whether the source has sent all it will (the recording's stream has ended).
    pub played_out: Option<crate::pipeline::run::PlayedOut>,
    /// A replay's figures (dead reckoning, the distance driven).
    pub replay: Option<ReplayFigures>,
    /// What must be stopped when the run ends.
    pub running: Box<dyn Running>,
}

/// What a source reports when it is stopped.
#[derive(Debug, Default)]
pub struct SourceEnd {
    /// Recorded scans the simulator skipped as damaged.
    pub scans_skipped: u64,
    /// Why the first of them was skipped (naming the file).
    pub first_scan_skipped: Option<String>,
    /// An MCAP replay's counts.
    pub mcap: Option<mcap::McapReplayCounts>,
}

/// A stop that may wait (the simulator's shutdown, the MCAP reader's thread).
pub type Stopping = Pin<Box<dyn Future<Output = SourceEnd> + Send>>;

/// A source's running parts (the embedded simulator, an MCAP reader thread), stopped once
/// the pipeline has finished.
pub trait Running: Send {
    /// Stops them and says what they counted.
    fn stop(self: Box<Self>) -> Stopping;
}

/// Nothing to stop (a radar over TCP: its driver is stopped by the daemon).
#[derive(Debug)]
pub struct NothingRunning;

impl Running for NothingRunning {
    fn stop(self: Box<Self>) -> Stopping {
        Box::pin(async { SourceEnd::default() })
    }
}

/// An MCAP recording to run on instead of a radar.
#[derive(Debug, Clone, PartialEq)]
pub struct McapSource {
    /// The file.
    pub path: PathBuf,
    /// The odometry topic; `None`: the daemon's own (`/odom/twist`).
    pub odometry_topic: Option<String>,
    /// The largest uncompressed size a chunk may claim, bytes; `None`: 64 MiB.
    pub max_chunk_bytes: Option<u64>,
}

/// The simulator in this process, with recorded scans to replay or its scene; a build
/// without the `sim` feature has none (the type is then uninhabited).
#[cfg(feature = "sim")]
#[derive(Debug)]
pub struct Simulator {
    /// The simulator.
    pub sim: embedded::EmbeddedSim,
    /// Recorded scans to replay (its scene is then ignored).
    pub recorded: Option<recorded::RecordedReplay>,
}

/// Without the `sim` feature there is no simulator to start.
#[cfg(not(feature = "sim"))]
#[derive(Debug)]
pub enum Simulator {}

/// Starts the simulator in this process: recorded scans replayed over TCP, or its scene;
/// `odometry` (Zenoh's, opened by the daemon) replaces the simulator's.
#[allow(clippy::too_many_arguments)]
#[cfg_attr(not(feature = "sim"), allow(unused_variables))]
pub async fn start_simulator(
    simulator: Simulator,
    recipe: &crate::pipeline::SettingsRecipe,
    driver_settings: radar_driver::DriverSettings,
    out_dir: &std::path::Path,
    max_stream_s: Option<f64>,
    keep_configured_compensation: bool,
    odo_shutdown: radar_driver::Shutdown,
    stop: &std::sync::Arc<std::sync::atomic::AtomicBool>,
    odometry: Option<Box<dyn OdometrySource>>,
) -> Result<Inputs, SourceError> {
    #[cfg(feature = "sim")]
    {
        let Simulator { sim, recorded } = simulator;
        match recorded {
            Some(recorded) => {
                let mut inputs =
                    recorded::start(sim.options, recorded, recipe, driver_settings).await?;
                if odometry.is_some() {
                    inputs.odometry = odometry;
                }
                Ok(inputs)
            }
            None => {
                embedded::start(
                    sim,
                    recipe,
                    driver_settings,
                    out_dir,
                    max_stream_s,
                    keep_configured_compensation,
                    odo_shutdown,
                    stop,
                    odometry,
                )
                .await
            }
        }
    }
    #[cfg(not(feature = "sim"))]
    match simulator {}
}
