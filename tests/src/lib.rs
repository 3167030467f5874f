//! End-to-end tests across crates over loopback live in `tests/`; this library holds their
//! shared helpers: running the whole daemon against the simulator started in-process.
//!
//! Does IO: sockets on 127.0.0.1:0 and output files in a temporary folder.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use sim_sensor::{FaultScope, FaultSettings, OdometryNoise, Pacing, SimOptions};
use slam_node::daemon::{run_daemon, DaemonError, DaemonOptions, DaemonReport, EmbeddedSim};
use slam_node::detect::DetectorSettings;

/// How one end-to-end run is set up.
#[derive(Debug, Clone)]
pub struct Run {
    /// Shipped scene name.
    pub scene: &'static str,
    /// Stream seconds to run.
    pub duration_s: f64,
    /// Use the received power in the observation (the paper's filter).
    pub use_power: bool,
    /// Faults for the simulator.
    pub faults: FaultSettings,
    /// Connections the faults apply to.
    pub fault_scope: FaultScope,
    /// Serve odometry.
    pub odometry: bool,
    /// Simulator seed (None: the scene's).
    pub seed: Option<u64>,
    /// First-estimates Jacobians in the filter (the shipped default: on).
    pub first_estimate_jacobians: bool,
    /// Repeat-look decorrelation in the filter (the shipped default: on).
    pub repeat_look_decorrelation: bool,
    /// Drive the scene's mirror image (`Scene::mirrored`: the vehicle turns the other way).
    pub mirror: bool,
    /// The odometry link's idle timeout (`None`: the daemon's default, 7 s).
    pub odometry_idle_timeout: Option<Duration>,
    /// The simulator's odometry noise (`None`: its default, 0.1 m/s and 0.01 rad at 20 Hz).
    pub odometry_noise: Option<OdometryNoise>,
    /// The scene's bearing noise, degrees (`None`: the scene's).
    pub bearing_sigma_deg: Option<f64>,
    /// A scene file to run instead of the shipped scene `scene`.
    pub scene_file: Option<PathBuf>,
    /// A configuration file instead of the defaults (its `[detector]` applies; the filter
    /// switches above still override it; no raw recording is written).
    pub config_file: Option<PathBuf>,
}

impl Run {
    /// The shipped defaults on `scene` for `duration_s`.
    pub fn new(scene: &'static str, duration_s: f64) -> Self {
        Self {
            scene,
            duration_s,
            use_power: true,
            faults: FaultSettings::default(),
            fault_scope: FaultScope::EveryConnection,
            odometry: true,
            seed: None,
            first_estimate_jacobians: true,
            repeat_look_decorrelation: true,
            mirror: false,
            odometry_idle_timeout: None,
            odometry_noise: None,
            bearing_sigma_deg: None,
            scene_file: None,
            config_file: None,
        }
    }
}

/// Runs the daemon against the embedded simulator (as fast as possible, 127.0.0.1:0),
/// outputs in `out`, within `limit` of wall time.
pub async fn run(run: &Run, out: &Path, limit: Duration) -> Result<DaemonReport, DaemonError> {
    // As the command line: the keys the file writes override the radar profile's values.
    let (mut config, written) = match &run.config_file {
        Some(path) => {
            let (mut c, written) = config::Config::load_with_written(path)
                .expect("the run's configuration file loads");
            c.radar.record_path = None;
            (c, written)
        }
        None => (config::Config::default(), Default::default()),
    };
    config.filter.use_power_in_observation = run.use_power;
    config.filter.first_estimate_jacobians = run.first_estimate_jacobians;
    config.filter.repeat_look_decorrelation = run.repeat_look_decorrelation;
    // A short hand-off queue (half a second of the paper's unit): the simulator is paced by
    // the pipeline through it, so a radar stall reaches the pipeline as silence at once
    // instead of hiding behind seconds of queued azimuths in a slow (debug) build.
    config.radar.azimuth_channel_capacity =
        config::values::Capacity::new(256, 1 << 20).expect("valid capacity");
    // Likewise a small socket receive buffer (the default 4 MiB holds ten seconds of it).
    config.radar.recv_buffer_bytes =
        config::values::Capacity::new(64 * 1024, 1 << 28).expect("valid size");
    let mut scene = match &run.scene_file {
        Some(path) => sim_sensor::scene::Scene::load(path),
        None => sim_sensor::scene::shipped::load(run.scene),
    }
    .map_err(|e| slam_node::source::SourceError::Sim(e.into()))?;
    if run.mirror {
        scene = scene
            .mirrored()
            .map_err(|e| slam_node::source::SourceError::Sim(e.into()))?;
    }
    if let Some(sigma) = run.bearing_sigma_deg {
        scene.noise.bearing_sigma_deg = sigma;
    }
    let mut options = SimOptions::for_tests(scene);
    options.pacing = Pacing::AsFastAsPossible;
    options.faults = run.faults.clone();
    options.fault_scope = run.fault_scope;
    if let Some(seed) = run.seed {
        options.seed = Some(seed);
    }
    if let Some(noise) = run.odometry_noise {
        options.odometry = noise;
    }
    if !run.odometry {
        options.odometry_bind = None;
    }
    let mut embedded = EmbeddedSim::new(options);
    if let Some(idle) = run.odometry_idle_timeout {
        embedded.odometry_idle_timeout = idle;
    }
    let stop = Arc::new(AtomicBool::new(false));
    let opts = DaemonOptions {
        config,
        simulator: Some(slam_node::daemon::Simulator {
            sim: embedded,
            recorded: None,
        }),
        mcap: None,
        max_stream_s: Some(run.duration_s),
        out_dir: out.to_path_buf(),
        figures: false,
        progress_every_rotations: 0,
        stop: Arc::clone(&stop),
        detector: run.config_file.is_none().then(DetectorSettings::default),
        written: Some(written),
        keep_configured_compensation: false,
        spectrum_bearings_deg: Vec::new(),
    };
    match tokio::time::timeout(limit, run_daemon(opts, None)).await {
        Ok(r) => r,
        Err(_) => {
            stop.store(true, std::sync::atomic::Ordering::Relaxed);
            panic!("the daemon did not finish within {limit:?}");
        }
    }
}

/// Prints the summary (visible with `--nocapture`).
pub fn print(report: &DaemonReport) {
    println!("{}", slam_node::daemon::report::summary_text(report));
}

/// The Oxford Radar RobotCar scans in `../shared`, or `None` with a SKIPPED line when they
/// are absent.
pub fn oxford_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/oxford-radar-robotcar");
    if dir.join("radar").is_dir() {
        Some(dir)
    } else {
        println!(
            "SKIPPED: the Oxford Radar RobotCar scans are not at {} (they live in ../shared beside the workspace)",
            dir.display()
        );
        None
    }
}

/// The daemon's options for a test: `config`, whose file wrote `written` (`None`: no keys),
/// outputs in `out`, no figures, no progress lines, no simulator yet.
pub fn test_options(config: config::Config, written: Option<&str>, out: &Path) -> DaemonOptions {
    DaemonOptions {
        config,
        simulator: None,
        mcap: None,
        max_stream_s: None,
        out_dir: out.to_path_buf(),
        figures: false,
        progress_every_rotations: 0,
        stop: Arc::new(AtomicBool::new(false)),
        keep_configured_compensation: false,
        spectrum_bearings_deg: Vec::new(),
        detector: None,
        written: Some(written.map(config::written_keys).unwrap_or_default()),
    }
}

/// `seconds` of `scene` on the embedded simulator (every port on 127.0.0.1:0, as fast as
/// the machine goes) through the shipped configuration `config/examples/<config>`, its
/// `scene =` line dropped so that the simulator takes `scene` directly; outputs in `out`.
pub async fn shipped_config_on_scene(
    config: &str,
    scene: sim_sensor::scene::Scene,
    seconds: f64,
    out: &Path,
) -> DaemonReport {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../config/examples")
        .join(config);
    let text: String = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .filter(|l| !l.starts_with("scene ="))
        .map(|l| format!("{l}\n"))
        .collect();
    let parsed = config::Config::from_toml_str(&text).expect("the shipped configuration");
    let mut sim = SimOptions::for_tests(scene);
    sim.pacing = Pacing::AsFastAsPossible;
    let mut opts = test_options(parsed, Some(&text), out);
    opts.max_stream_s = Some(seconds);
    opts.simulator = Some(slam_node::daemon::Simulator {
        sim: EmbeddedSim::new(sim),
        recorded: None,
    });
    run_daemon(opts, None).await.expect("the run")
}

/// `seconds` of [`lamp_post_road`] through the realistic city's wheel-odometry
/// configuration (`config/examples/realistic-city.toml`, its scene given directly), the
/// scene and the outputs in `out`.
pub async fn on_the_lamp_post_road(seconds: f64, out: &Path) -> DaemonReport {
    let scene_path = out.join("posts.toml");
    std::fs::write(&scene_path, lamp_post_road()).expect("the scene written");
    let scene = sim_sensor::scene::Scene::load(&scene_path).expect("the posts");
    shipped_config_on_scene("realistic-city.toml", scene, seconds, out).await
}

/// Lamp posts along both sides of a straight road, 6-10 m out, every 10 m; 10 m/s; the
/// CTS350-X-like unit, realistic rendering.
pub fn lamp_post_road() -> String {
    let mut text = String::from(
        "name = \"posts\"\nseed = 3\nloss_db = 0.0\n[radar]\npreset = \"cts350x-400\"\n\
         [realism]\n[motion]\nmodel = \"bicycle\"\nwheelbase_m = 2.7\n\
         [start]\nx_m = 0.0\ny_m = 0.0\ntheta_deg = 0.0\n\
         [[control]]\nt_s = 0.0\nspeed_mps = 10.0\nsteer_rad = 0.0\n",
    );
    for i in 0..40 {
        let x = -50.0 + 10.0 * f64::from(i);
        for y in [7.0 + f64::from(i % 3), -6.5 - f64::from(i % 4)] {
            text.push_str(&format!(
                "[[features]]\nkind = \"lamp-post\"\nx_m = {x}\ny_m = {y}\n"
            ));
        }
    }
    text
}
