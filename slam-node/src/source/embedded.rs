//! The simulator started in this process (the `sim` feature, on by default; a vehicle build
//! turns it off and links no simulator): the daemon's settings adjusted to the scene, ground
//! truth from the scene, the simulator's server and odometry on 127.0.0.1.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crossbeam_channel::Receiver;
use radar_driver::{
    Azimuth, Driver, DriverSettings, OdometrySource, Shutdown, TcpOdometry, TcpOdometrySettings,
};
use radar_model::compensation::Compensation;
use radar_model::power::RadarConstants;
use sim_sensor::{SimHandle, SimOptions, SimServer};
use tracing::info;

use super::{sink, Inputs, Running, SourceEnd, SourceError, Stopping};
use crate::output::figures::TruthOverlay;
use crate::pipeline::{Pipeline, SceneTruth, SettingsRecipe, SourceFacts, TruthOracle};

/// The embedded simulator's ground-truth file inside the output folder (`sim-sensor`'s
/// format), written when `[output] ground_truth` is true.
pub const GROUND_TRUTH_JSONL: &str = "ground-truth.jsonl";

/// Where the embedded simulator's clock starts when neither the options nor the scene say
/// (the simulator's fixed start): runs as fast as possible are then reproducible.
pub const EMBEDDED_START_UNIX_NS: u64 = sim_sensor::settings::FIXED_START_UNIX_NS;

/// The simulator to start in this process.
#[derive(Debug, Clone)]
pub struct EmbeddedSim {
    /// The simulator's options (bind 127.0.0.1:0 for tests and the default run).
    pub options: SimOptions,
    /// Nothing received on the odometry link for this long is a dead link: the client
    /// reconnects (default 7 s, as against a vehicle; tests shorten it).
    pub odometry_idle_timeout: Duration,
}

impl EmbeddedSim {
    /// The simulator with `options`, the odometry client's defaults.
    pub fn new(options: SimOptions) -> Self {
        let defaults = TcpOdometrySettings::new(std::net::SocketAddr::from(([127, 0, 0, 1], 0)));
        Self {
            options,
            odometry_idle_timeout: defaults.idle_timeout,
        }
    }
}

/// What the simulator's `scene` tells the daemon exactly: its motion model, its receiver's
/// compensation (unless `keep_compensation`), its beam, its range-Doppler coupling, its peak
/// width (one bin), its start pose.
pub fn embedded_facts(scene: &sim_sensor::scene::Scene, keep_compensation: bool) -> SourceFacts {
    // The simulator's receiver compensation is known exactly: use it, as a calibrated gain
    // curve would be used on a real unit.
    let slope = scene.receiver.compensation_db_per_decade;
    if keep_compensation {
        info!(
            scene_db_per_decade = slope,
            "keeping the configured receiver compensation, not the scene's"
        );
    }
    SourceFacts {
        motion: Some(sim_sensor::trajectory::motion_model(scene.motion)),
        compensation: (!keep_compensation)
            .then(|| Compensation::calibrated(slope, &RadarConstants::default())),
        beam_width_rad: Some(scene.radar.beam_width_rad),
        // The simulated radar's range-Doppler coupling is known exactly too (0 for the
        // paper's unit, a CTS350-X's 0.049 s): detections are corrected with it.
        doppler_range_coupling_s: Some(scene.radar.doppler_range_coupling_s),
        // The simulator draws each peak one bin wide (FWHM).
        peak_fwhm_m: Some(f64::from(scene.radar.range_gain) * scene.radar.bin_size_m()),
        initial_pose: Some((scene.start, [0.0; 3])),
        ..SourceFacts::default()
    }
}

/// What the simulated radar announces, in the profiles' terms.
pub fn scene_announced(scene: &sim_sensor::scene::Scene) -> radar_model::profile::Announced {
    let r = &scene.radar;
    radar_model::profile::Announced {
        azimuths: r.azimuths,
        encoder_size: r.encoder_size,
        range_bins: r.range_bins,
        bin_size_m: f64::from(r.range_gain) * r.bin_size_m(),
        rotation_hz: f64::from(r.rotation_mhz) / 1000.0,
    }
}

/// The daemon's settings against the simulator's `scene`: its radar's profile (the
/// simulator declares its unit unless `[radar] model` names one) and the scene's facts.
pub fn embedded_settings(
    recipe: &SettingsRecipe,
    scene: &sim_sensor::scene::Scene,
    keep_compensation: bool,
) -> Result<crate::pipeline::Derived, SourceError> {
    let choice = radar_model::profile::simulated(
        recipe.config.radar.model.as_deref(),
        &scene_announced(scene),
        scene.realism.is_some(),
    )
    .map_err(crate::pipeline::settings::SettingsError::from)?;
    Ok(recipe.derive(choice, embedded_facts(scene, keep_compensation))?)
}

/// A driver for the embedded simulator: as fast as possible, a blocking hand-off lets TCP
/// back-pressure pace the simulator to the pipeline; in real time, the driver's own
/// channel and drop policy, as against a radar.
pub(super) fn connect(
    driver_settings: DriverSettings,
    fast: bool,
) -> Result<(Receiver<Azimuth>, Driver), SourceError> {
    if fast {
        let capacity = driver_settings.handoff.azimuth_capacity.unwrap_or(4096);
        let (sink, rx) = sink::BlockingSink::new(capacity);
        Ok((rx, Driver::with_sink(driver_settings, Box::new(sink))))
    } else {
        let (driver, receivers) = Driver::new(driver_settings);
        let rx = receivers.azimuths.ok_or(SourceError::NoAzimuthChannel)?;
        Ok((rx, driver))
    }
}

/// The simulator's server, stopped when the run ends.
pub(super) struct SimRunning(pub SimHandle);

impl Running for SimRunning {
    fn stop(self: Box<Self>) -> Stopping {
        Box::pin(async move {
            let scans_skipped = self.0.stats().scans_skipped;
            let first_scan_skipped = self.0.first_scan_skipped();
            if let Err(e) = self.0.shutdown().await {
                tracing::warn!(error = %e, "simulator shutdown");
            }
            SourceEnd {
                scans_skipped,
                first_scan_skipped,
                mcap: None,
            }
        })
    }
}

/// How often a build in progress looks at the stop request.
const STOP_POLL: Duration = Duration::from_millis(20);

/// Waits for `work` (a task doing a build: the scene's truth, the simulator's renderer),
/// unless `stop` is set first: then the build is abandoned (aborted at its next await, or
/// left to finish unobserved on its thread) and the daemon gives up with
/// [`SourceError::Stopped`]. A large scene's build (a day's trajectory, 200,000 features)
/// takes seconds; Ctrl-C must not wait for it.
async fn unless_stopped<T: Send + 'static>(
    stop: &AtomicBool,
    mut work: tokio::task::JoinHandle<T>,
) -> Result<T, SourceError> {
    let mut poll = tokio::time::interval(STOP_POLL);
    loop {
        tokio::select! {
            joined = &mut work => return joined.map_err(|_| SourceError::BuildPanicked),
            _ = poll.tick() => {
                if stop.load(Ordering::Relaxed) {
                    work.abort();
                    info!("stop requested while building the scene: abandoned");
                    return Err(SourceError::Stopped);
                }
            }
        }
    }
}

/// Starts the simulator and connects a driver and an odometry client to it; the pipeline is
/// built (everything that can fail is checked) before the simulator starts. A stop request
/// (`stop`, Ctrl-C) during the builds ends it at once with [`SourceError::Stopped`].
/// `odometry` (Zenoh's, opened by the daemon) replaces the simulator's odometry port.
#[allow(clippy::too_many_arguments)]
pub async fn start(
    sim: EmbeddedSim,
    recipe: &SettingsRecipe,
    mut driver_settings: DriverSettings,
    out_dir: &Path,
    max_stream_s: Option<f64>,
    keep_configured_compensation: bool,
    odo_shutdown: Shutdown,
    stop: &Arc<AtomicBool>,
    odometry: Option<Box<dyn OdometrySource>>,
) -> Result<Inputs, SourceError> {
    let mut options = sim.options;
    // A copy of the truth for other tools (`[output] ground_truth`): the run scores itself
    // against the scene's truth in memory (the oracle below), with or without it.
    options.ground_truth_path = recipe
        .config
        .output
        .ground_truth
        .then(|| out_dir.join(GROUND_TRUTH_JSONL));
    let sim_sensor::settings::SourceSpec::Scene(scene) = options.source.clone() else {
        return Err(SourceError::NotAScene);
    };
    // The clock's start: the options' (the wall clock's now in real time), else the
    // scene's, else a fixed one, so that a run as fast as possible is reproducible.
    let start_ns = *options
        .start_time_ns
        .get_or_insert(scene.start_time_ns.unwrap_or(EMBEDDED_START_UNIX_NS));
    let settings = embedded_settings(recipe, &scene, keep_configured_compensation)?.settings;
    let motion = settings.motion;
    // Radar only (`[odometry] source = "none"`): the simulator's odometry port is not read.
    let radar_only = settings.radar_drives;
    let start_s = start_ns as f64 * 1e-9;
    let horizon = max_stream_s.unwrap_or(600.0) + 30.0;
    let fast = options.pacing == sim_sensor::settings::Pacing::AsFastAsPossible;
    let mut build_settings = settings.clone();
    // Paced by the pipeline, the global layer's solutions are waited for at each switch, as
    // if the layer kept up with the simulated time as it keeps up with a radar's.
    if let Some(o) = build_settings.submaps.as_mut() {
        o.wait_for_joins = fast;
    }
    let scene_name = scene.name.clone();
    let (truth_overlay, pipeline) = unless_stopped(
        stop,
        tokio::task::spawn_blocking(move || -> Result<_, SourceError> {
            let oracle = SceneTruth::new(&scene, start_s, horizon)?;
            let mut truth_overlay = TruthOverlay {
                features: oracle.features().iter().map(|f| (f.x_m, f.y_m)).collect(),
                trajectory: (0..(horizon.min(3600.0) * 4.0) as usize)
                    .filter_map(|k| oracle.pose_at(start_s + k as f64 * 0.25))
                    .map(|p| (p.x, p.y))
                    .collect(),
            };
            if let Some(limit) = max_stream_s {
                let keep = (limit * 4.0).ceil() as usize + 1;
                truth_overlay.trajectory.truncate(keep);
            }
            let pipeline = Pipeline::new(build_settings, Some(start_s), Some(Box::new(oracle)))?;
            Ok((truth_overlay, pipeline))
        }),
    )
    .await??;
    let handle = unless_stopped(stop, tokio::spawn(SimServer::spawn(options))).await??;
    info!(radar = %handle.local_addr(), odometry = ?handle.odometry_addr(), scene = %scene_name, "embedded simulator started");
    driver_settings.address = handle.local_addr();
    let idle_timeout = sim.odometry_idle_timeout;
    let gyro_shutdown = odo_shutdown.clone();
    let simulated: Option<Box<dyn OdometrySource>> =
        handle.odometry_addr().filter(|_| !radar_only).map(|a| {
            let mut odometry = TcpOdometrySettings::new(a);
            odometry.idle_timeout = idle_timeout;
            Box::new(TcpOdometry::spawn(
                &tokio::runtime::Handle::current(),
                odometry,
                odo_shutdown,
            )) as Box<dyn OdometrySource>
        });
    // A TCP gyro reads the simulator's gyro port (as the odometry reads its odometry port).
    let gyro = match (&recipe.config.gyro.source, handle.gyro_addr()) {
        (config::gyro::GyroSource::Tcp { .. }, Some(a)) => {
            let mut settings = super::gyro::tcp_gyro_settings(a);
            settings.idle_timeout = idle_timeout;
            Some(Box::new(super::gyro::TcpGyro::spawn(
                &tokio::runtime::Handle::current(),
                settings,
                gyro_shutdown,
            )) as Box<dyn super::gyro::GyroSource>)
        }
        _ => super::gyro::open_configured(
            &recipe.config.gyro,
            &tokio::runtime::Handle::current(),
            gyro_shutdown,
        )?,
    };
    let (azimuths, driver) = connect(driver_settings, fast)?;
    Ok(Inputs {
        azimuths,
        driver: Some(driver),
        gyro,
        odometry: odometry.or(simulated),
        pipeline: pipeline.into(),
        motion,
        name: Some(scene_name),
        truth_overlay,
        end_after_silence: None,
        played_out: None,
        replay: None,
        running: Box::new(SimRunning(handle)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The simulated radar's range-Doppler coupling replaces the configured one: a
    /// CTS350-X scene's 0.049 s whatever the configuration says, the paper's unit's 0.
    #[test]
    fn the_daemon_corrects_the_range_doppler_coupling_the_simulated_radar_renders() {
        let mut config = config::Config::default();
        config.model.doppler_range_coupling_s = config::values::FiniteF64::new(0.02).unwrap();
        let recipe = SettingsRecipe::from_config(config);
        let cts = sim_sensor::scene::shipped::load("long-loop").expect("shipped scene");
        let paper = sim_sensor::scene::shipped::load("outdoor-field").expect("shipped scene");
        assert_eq!(cts.radar.doppler_range_coupling_s, 0.049);
        let d = embedded_settings(&recipe, &cts, false).unwrap();
        assert_eq!(d.choice.profile.name, "sim-cts350x");
        assert_eq!(d.settings.doppler_range_coupling_s, 0.049);
        assert_eq!(d.settings.front_end().doppler_range_coupling_s, 0.049);
        let d = embedded_settings(&recipe, &paper, false).unwrap();
        assert_eq!(d.choice.profile.name, "paper-2006");
        assert_eq!(d.settings.doppler_range_coupling_s, 0.0);
    }
}
