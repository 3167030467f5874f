//! The `slam-node` binary's command line (not part of the library): its flags, and the
//! daemon's options they make.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use anyhow::Context;
use clap::Parser;
use slam_node::daemon::DaemonOptions;

/// Augmented-state EKF SLAM for a rotating mm-wave radar (Jose & Adams).
#[derive(Debug, Parser)]
#[command(version, about)]
pub struct Args {
    /// Configuration file; without it the embedded simulator runs with the shipped defaults.
    #[arg(long)]
    config: Option<PathBuf>,
    #[cfg(feature = "sim")]
    /// Start the simulator in this process even with --config (uses its [sim] section).
    #[arg(long)]
    embedded_sim: bool,
    #[cfg(feature = "sim")]
    /// Scene for the embedded simulator (a shipped name or a file).
    #[arg(long)]
    scene: Option<String>,
    #[cfg(feature = "sim")]
    /// Run the embedded simulator as fast as possible instead of in real time.
    #[arg(long)]
    fast: bool,
    /// Stop after this much stream time, seconds (default: 60 with the embedded simulator,
    /// unlimited against a radar).
    #[arg(long, value_parser = positive_seconds)]
    duration: Option<f64>,
    /// Output folder (default: [output] directory).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Localise in this saved map (slam-map's `.slmap`, written by an earlier run) instead
    /// of mapping from nothing: needs `[map] mode = "localise"` (track in it) or `"extend"`
    /// (localise, then map on and save the merged map); sets `[map] file`.
    #[arg(long, value_name = "FILE")]
    map: Option<PathBuf>,
    /// Do not draw SVG figures.
    #[arg(long)]
    no_figures: bool,
    /// Record the run as MCAP (ROS 2 messages in CDR: radar B-scans, odometry, pose, tf,
    /// map, detections), a file name inside the output folder or an absolute path
    /// (default: [output] mcap, none).
    #[arg(long, value_parser = mcap_path)]
    mcap: Option<PathBuf>,
    /// Publish pose, tf, map and detections live over Zenoh as ROS 2 messages, with the
    /// endpoints of [output.zenoh] (default: connect to tcp/127.0.0.1:7447); needs a build
    /// with `--features zenoh`.
    #[arg(long)]
    zenoh: bool,
    /// Serve the live view over Foxglove's WebSocket protocol at [output.foxglove] bind
    /// (default ws://127.0.0.1:8765): open it in the Foxglove app; needs the `foxglove`
    /// feature (in the default build).
    #[arg(long)]
    foxglove: bool,
    /// Serve the Foxglove live view at this address, ip:port (port 0: any free port, logged);
    /// implies --foxglove.
    #[arg(long, value_name = "IP:PORT", value_parser = socket_address)]
    foxglove_bind: Option<std::net::SocketAddr>,
    /// Hold the run's start until a Foxglove client subscribes to /slam/pose, at most this
    /// many seconds (for a fast simulated run); implies --foxglove.
    #[arg(long, value_name = "SECONDS")]
    foxglove_wait: Option<u32>,
    /// Serve a page drawing the live view (radar image, map, pose) at
    /// http://<[output.foxglove] bind>/; implies --foxglove.
    #[arg(long)]
    view: bool,
    /// Run on a rosbag2 MCAP file instead of a radar: Navtech's ROS 2 radar messages
    /// (RadarBScanMsg or RadarFftDataMsg, with RadarConfigurationMsg) and an odometry topic,
    /// as fast as possible (a recording made with --mcap replays to the same trajectory).
    #[arg(long, conflicts_with = "embedded_sim")]
    replay_mcap: Option<PathBuf>,
    /// With --replay-mcap: the odometry topic (geometry_msgs/TwistStamped or
    /// nav_msgs/Odometry; the yaw rate becomes the motion model's steering input).
    #[arg(long, requires = "replay_mcap", default_value = "/odom/twist")]
    mcap_odometry_topic: String,
    /// With --replay-mcap: the largest uncompressed size a chunk may claim, MiB (the daemon
    /// writes a rotation per chunk, rosbag2 768 KiB); a larger claim ends the replay there.
    #[arg(long, requires = "replay_mcap", default_value_t = 64, value_parser = clap::value_parser!(u64).range(1..=4096))]
    mcap_max_chunk_mib: u64,
    #[cfg(feature = "sim")]
    /// With the embedded simulator, model the receiver by [model] compensation (60 dB per
    /// decade by default, as the paper did) instead of the scene's (40): shows the paper's
    /// negative spectrum bias.
    #[arg(long)]
    configured_compensation: bool,
    /// Draw predicted vs measured spectra at this bearing, degrees clockwise from forward
    /// (repeatable); default: the beam with the most mapped features, every 25 rotations.
    #[arg(long = "spectrum-bearing")]
    spectrum_bearings: Vec<f64>,
    /// Replay a folder of recorded polar scans (Oxford Radar RobotCar: `radar/*.png` and
    /// `radar_odometry.csv`; Boreas: `radar/*.png` and `applanix/radar_poses.csv`; RADIATE:
    /// `Navtech_Polar/`, `Navtech_Polar.txt` and `GPS_IMU_Twist*`) through the simulator's
    /// server, the driver and the daemon, with odometry made from the ground truth (see the
    /// --odometry-* options).
    #[cfg(feature = "sim")]
    #[arg(long, conflicts_with = "scene")]
    replay_dir: Option<PathBuf>,
    /// With --replay-dir: the folder's layout, oxford, boreas or radiate (default: detected
    /// from its contents).
    #[cfg(feature = "sim")]
    #[arg(long, requires = "replay_dir", value_name = "oxford|boreas|radiate")]
    replay_format: Option<sim_sensor::replay::ReplayFormat>,
    /// With --replay-dir: the odometry reads this factor times the true speed.
    #[cfg(feature = "sim")]
    #[arg(long, default_value_t = 1.0, requires = "replay_dir")]
    odometry_speed_scale: f64,
    /// With --replay-dir: rad/s added to the true yaw rate.
    #[cfg(feature = "sim")]
    #[arg(long, default_value_t = 0.0, requires = "replay_dir")]
    odometry_yaw_rate_bias: f64,
    /// With --replay-dir: speed noise (m/s) and yaw-rate noise (rad/s) per 50 ms sample.
    #[cfg(feature = "sim")]
    #[arg(long, num_args = 2, value_names = ["SPEED", "YAW_RATE"], requires = "replay_dir")]
    odometry_noise: Option<Vec<f64>>,
    /// With --replay-dir: seed of the odometry noise.
    #[cfg(feature = "sim")]
    #[arg(long, default_value_t = 1, requires = "replay_dir")]
    odometry_seed: u64,
    /// With --replay-dir: no radar odometry (by default rotations are registered against
    /// each other and the filter estimates the odometry's speed scale and steering offset).
    #[cfg(feature = "sim")]
    #[arg(long, requires = "replay_dir")]
    no_radar_odometry: bool,
    /// With --replay-dir: no odometry at all: radar odometry drives the filter (as
    /// `[odometry] source = "none"` does), and a recording without ground truth runs
    /// unscored.
    #[cfg(feature = "sim")]
    #[arg(long, requires = "replay_dir", conflicts_with_all = ["no_radar_odometry", "write_odometry"])]
    radar_only: bool,
    /// With --replay-dir --radar-only: a gyro made from the ground truth's yaw rate, with
    /// `[sim.gyro]`'s bias, noise and rate (default 0.005 rad/s bias, 1.75e-4
    /// rad/s/sqrt(Hz), 100 Hz), as a vehicle's MEMS gyro would give it.
    #[cfg(feature = "sim")]
    #[arg(long, requires = "radar_only")]
    gyro_from_truth: bool,
    /// With --replay-dir: also write the odometry made from the ground truth to this file,
    /// in the odometry stream's format (docs/contracts.md), for `[odometry] source = "file"`
    /// (the same samples through another door).
    #[cfg(feature = "sim")]
    #[arg(long, requires = "replay_dir", value_name = "FILE")]
    write_odometry: Option<PathBuf>,
    /// Progress line every this many rotations (0 = none; default 10, or none when the
    /// configuration says `[output] progress = false`).
    #[arg(long)]
    progress_every: Option<u64>,
    /// Print the radar profiles (every value with its source) and exit.
    #[arg(long)]
    radar_profiles: bool,
}

impl Args {
    /// Whether the run only lists the radar profiles.
    pub fn lists_profiles(&self) -> bool {
        self.radar_profiles
    }

    /// What the run does, for its error messages.
    pub fn doing(&self) -> &'static str {
        if self.replay_mcap.is_some() {
            "replaying the MCAP file"
        } else {
            "running the daemon"
        }
    }
}

/// The daemon's options from the command line: the configuration file (and the keys it
/// writes, which override the radar profile's values), then the flags.
pub fn options(args: &Args) -> anyhow::Result<DaemonOptions> {
    // The keys the file writes override the radar profile's values; the others take them.
    let (mut config, written) = match &args.config {
        Some(path) => {
            config::Config::load_with_written(path).context("loading the configuration")?
        }
        None => (config::Config::default(), Default::default()),
    };
    if let Some(mcap) = &args.mcap {
        config.output.mcap = Some(mcap.clone());
    }
    if let Some(map) = &args.map {
        config.map.file = Some(map.clone());
    }
    if args.zenoh {
        config.output.zenoh.enabled = true;
    }
    if args.foxglove || args.foxglove_bind.is_some() || args.foxglove_wait.is_some() || args.view {
        config.output.foxglove.enabled = true;
    }
    if let Some(wait) = args.foxglove_wait {
        anyhow::ensure!(
            i64::from(wait) <= config::output::MAX_WAIT_FOR_SUBSCRIBER_S,
            "--foxglove-wait must be at most {} s",
            config::output::MAX_WAIT_FOR_SUBSCRIBER_S
        );
        config.output.foxglove.wait_for_subscriber_s = wait;
    }
    if let Some(bind) = args.foxglove_bind {
        config.output.foxglove.bind = bind;
    }
    if args.view {
        config.output.view.enabled = true;
    }
    // A folder of recorded scans is served by the simulator in this process, whatever the
    // configuration's radar address says (without this, --config with --replay-dir dialled
    // the configured radar and waited for ever).
    #[cfg(feature = "sim")]
    let embedded = (args.config.is_none() || args.embedded_sim || args.replay_dir.is_some())
        && args.replay_mcap.is_none();
    #[cfg(not(feature = "sim"))]
    let embedded = false;
    #[cfg(not(feature = "sim"))]
    if args.config.is_none() && args.replay_mcap.is_none() {
        anyhow::bail!(
            "this is a vehicle build, without the simulator: pass --config with the radar's and the odometry's addresses (see config/examples/vehicle.toml)"
        );
    }
    #[cfg(feature = "sim")]
    let simulator = if embedded {
        Some(slam_node::daemon::Simulator {
            sim: embedded_sim(args, &config)?,
            recorded: recorded(args, &config)?,
        })
    } else {
        None
    };
    #[cfg(not(feature = "sim"))]
    let simulator = None;
    let stop = Arc::new(AtomicBool::new(false));
    Ok(DaemonOptions {
        out_dir: args
            .out
            .clone()
            .unwrap_or_else(|| config.output.directory.clone()),
        figures: config.output.pictures && !args.no_figures,
        progress_every_rotations: args.progress_every.unwrap_or(if config.output.progress {
            10
        } else {
            0
        }),
        max_stream_s: args.duration.or(if embedded && !replaying(args) {
            Some(60.0)
        } else {
            None
        }),
        simulator,
        mcap: args
            .replay_mcap
            .clone()
            .map(|path| slam_node::daemon::McapSource {
                path,
                odometry_topic: Some(args.mcap_odometry_topic.clone()),
                max_chunk_bytes: Some(args.mcap_max_chunk_mib << 20),
            }),
        #[cfg(feature = "sim")]
        keep_configured_compensation: args.configured_compensation,
        #[cfg(not(feature = "sim"))]
        keep_configured_compensation: false,
        spectrum_bearings_deg: args.spectrum_bearings.clone(),
        config,
        stop,
        // Without a configuration file the detector is slam-node's measured default (TPP with
        // the settings scored in `detection_scoring`), not a mapping of `[detector]`.
        detector: args
            .config
            .is_none()
            .then(slam_node::detect::DetectorSettings::default),
        written: Some(written),
    })
}

/// The longest run `--duration` takes: a year of stream.
const MAX_DURATION_S: f64 = 365.0 * 86_400.0;

/// A duration in seconds: finite, positive, at most a year.
fn positive_seconds(text: &str) -> Result<f64, String> {
    let v: f64 = text
        .parse()
        .map_err(|_| format!("{text:?} is not a number of seconds"))?;
    if !(v.is_finite() && v > 0.0 && v <= MAX_DURATION_S) {
        return Err(format!("must be in (0, {MAX_DURATION_S}] s, got {text}"));
    }
    Ok(v)
}

/// An address to listen on, `ip:port`, as `[output.foxglove] bind` takes it.
fn socket_address(text: &str) -> Result<std::net::SocketAddr, String> {
    config::values::socket_addr(text).map_err(|e| e.to_string())
}

/// An MCAP file to record to: not empty, ending in `.mcap`.
fn mcap_path(text: &str) -> Result<PathBuf, String> {
    let path = PathBuf::from(text);
    let is_mcap = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"));
    if text.is_empty() || !is_mcap {
        return Err(format!("must be a file name ending in .mcap, got {text:?}"));
    }
    Ok(path)
}

/// The simulator to start in this process, from `[sim]` and the command line.
#[cfg(feature = "sim")]
fn embedded_sim(
    args: &Args,
    config: &config::Config,
) -> anyhow::Result<slam_node::daemon::EmbeddedSim> {
    let mut sim = config.sim.clone();
    if let Some(scene) = &args.scene {
        sim.scene = if scene.contains('/') || scene.contains('.') {
            config::sim::SceneRef::File(PathBuf::from(scene))
        } else {
            config::sim::SceneRef::Shipped(scene.clone())
        };
    }
    let mut options =
        sim_sensor::SimOptions::from_config(&sim).context("building the simulator")?;
    options.bind = std::net::SocketAddr::from(([127, 0, 0, 1], 0));
    options.odometry_bind = Some(std::net::SocketAddr::from(([127, 0, 0, 1], 0)));
    // The simulator's gyro is served when the run reads one (`[gyro] source = "tcp"`).
    options.gyro_bind = (config.gyro.source != config::gyro::GyroSource::None)
        .then(|| std::net::SocketAddr::from(([127, 0, 0, 1], 0)));
    if args.fast {
        // As fast as possible the clock starts at the scene's start time (or the embedded
        // simulator's fixed one), not at the wall clock's: the same command gives the same
        // run, to the last bit, on any day. In real time it starts now, for live consumers.
        options.pacing = sim_sensor::settings::Pacing::AsFastAsPossible;
    } else {
        let now_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
            .unwrap_or(0);
        options.start_time_ns = Some(now_ns);
    }
    Ok(slam_node::daemon::EmbeddedSim::new(options))
}

/// Whether the run replays recorded scans.
fn replaying(args: &Args) -> bool {
    #[cfg(feature = "sim")]
    {
        args.replay_dir.is_some()
    }
    #[cfg(not(feature = "sim"))]
    {
        let _ = args;
        false
    }
}

/// The recorded scans to replay, with the odometry's errors.
#[cfg(feature = "sim")]
pub(crate) fn recorded(
    args: &Args,
    config: &config::Config,
) -> anyhow::Result<Option<slam_node::daemon::RecordedReplay>> {
    use slam_node::daemon::replay::OdometryErrors;
    let Some(dir) = &args.replay_dir else {
        return Ok(None);
    };
    if !dir.is_dir() {
        anyhow::bail!(
            "--replay-dir {}: no such folder (the Oxford scans are at ../shared/data/oxford-radar-robotcar)",
            dir.display()
        );
    }
    let mut errors = OdometryErrors {
        seed: args.odometry_seed,
        speed_scale: args.odometry_speed_scale,
        yaw_rate_bias_rps: args.odometry_yaw_rate_bias,
        ..OdometryErrors::default()
    };
    if let Some(noise) = &args.odometry_noise {
        errors.sigma_speed_mps = noise.first().copied().unwrap_or(errors.sigma_speed_mps);
        errors.sigma_yaw_rate_rps = noise.get(1).copied().unwrap_or(errors.sigma_yaw_rate_rps);
    }
    let finite = [
        errors.speed_scale,
        errors.yaw_rate_bias_rps,
        errors.sigma_speed_mps,
        errors.sigma_yaw_rate_rps,
    ];
    if finite.iter().any(|v| !v.is_finite())
        || errors.speed_scale <= 0.0
        || errors.sigma_speed_mps < 0.0
        || errors.sigma_yaw_rate_rps < 0.0
    {
        anyhow::bail!("the --odometry-* values must be finite, the scale > 0 and the noise >= 0");
    }
    Ok(Some(slam_node::daemon::RecordedReplay {
        dir: dir.clone(),
        format: args.replay_format,
        errors,
        radar_odometry: !args.no_radar_odometry,
        radar_only: args.radar_only,
        gyro_from_truth: args.gyro_from_truth.then(|| sim_sensor::gyro::GyroNoise {
            rate_hz: config.sim.gyro.rate_hz.get(),
            noise_density_rad_s_per_sqrt_hz: config.sim.gyro.noise_density_rad_s_per_sqrt_hz.get(),
            bias_rad_s: config.sim.gyro.bias_rad_s.get(),
        }),
        write_odometry: match &args.write_odometry {
            // An existing FIFO or device would block or swallow the write: refused up front.
            Some(path) if path.exists() && !path.is_file() => anyhow::bail!(
                "--write-odometry {}: not a regular file; the odometry is written to a file",
                path.display()
            ),
            other => other.clone(),
        },
    }))
}
