//! Loop closure over every true revisit: the daemon run twice on a scene with ground truth,
//! as `slam-node --config FILE --embedded-sim --fast --duration S` runs it, once with
//! loop-closure candidates from the pose uncertainty only (`[submaps] place_recognition =
//! false`) and once with place descriptors as well; for each, the true revisits (pairs of
//! submap frames whose true origins are within 10 m after at least 300 m of driving), how
//! many revisiting submaps a correct closure joins to a true partner (recall), how many
//! closures agree with the truth (precision: within 1 m and 2 degrees), and the optimised
//! trajectory's error.
//!
//! Run: `cargo run --release -p evaluation --bin loop_closure -- [--config
//! config/examples/city-drive.toml] [--scene FILE] [--duration 440] [--steer-bias RAD]
//! [--speed-bias M/S]`. The biases are added to the simulator's odometry (`[sim]
//! bias_steer_rad`, `bias_speed_mps`) so that the pose prior is loose and wrong. Outputs go
//! to a temporary folder.

use std::path::PathBuf;

use anyhow::Context;
use clap::Parser;
use slam_node::daemon::{run_daemon, DaemonOptions};

/// Runs a scene with and without place descriptors and scores the loop closures.
#[derive(Debug, Parser)]
#[command(about)]
struct Args {
    /// The configuration (its `[sim]` scene is run in this process).
    #[arg(long, default_value = "config/examples/city-drive.toml")]
    config: PathBuf,
    /// A scene file replacing the configuration's `[sim] scene`.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Seconds of stream.
    #[arg(long, default_value_t = 440.0)]
    duration: f64,
    /// Steering bias added to the simulator's odometry (rad).
    #[arg(long, default_value_t = 0.0)]
    steer_bias: f64,
    /// Speed bias added to the simulator's odometry (m/s).
    #[arg(long, default_value_t = 0.0)]
    speed_bias: f64,
}

fn options(args: &Args, place: bool, out: &std::path::Path) -> anyhow::Result<DaemonOptions> {
    let (mut config, written) =
        config::Config::load_with_written(&args.config).context("loading the configuration")?;
    config.submaps.place_recognition = place;
    if let Some(scene) = &args.scene {
        config.sim.scene = config::sim::SceneRef::File(scene.clone());
    }
    config.sim.bias_steer_rad =
        config::values::FiniteF64::new(args.steer_bias).context("--steer-bias")?;
    config.sim.bias_speed_mps =
        config::values::FiniteF64::new(args.speed_bias).context("--speed-bias")?;
    let mut sim = sim_sensor::SimOptions::from_config(&config.sim).context("the simulator")?;
    sim.bind = std::net::SocketAddr::from(([127, 0, 0, 1], 0));
    sim.odometry_bind = Some(std::net::SocketAddr::from(([127, 0, 0, 1], 0)));
    // Wheel odometry drives these runs: no gyro port (it would take the fixed default).
    sim.gyro_bind = None;
    sim.pacing = sim_sensor::Pacing::AsFastAsPossible;
    sim.start_time_ns = Some(
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
            .unwrap_or(0),
    );
    Ok(evaluation::daemon::embedded_run_options(
        config,
        written,
        sim,
        args.duration,
        out,
    ))
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    anyhow::ensure!(
        args.duration.is_finite() && args.duration > 0.0 && args.duration <= 86_400.0,
        "--duration must be in (0, 86400] s"
    );
    if !args.config.is_file() {
        anyhow::bail!(
            "{}: no such configuration (run from the repository's root)",
            args.config.display()
        );
    }
    let runtime = tokio::runtime::Runtime::new()?;
    println!(
        "loop closure over the true revisits: {}{} for {} s, odometry steer bias {} rad, speed bias {} m/s",
        args.config.display(),
        args.scene
            .as_ref()
            .map_or(String::new(), |s| format!(" with the scene {}", s.display())),
        args.duration,
        args.steer_bias,
        args.speed_bias
    );
    println!("candidates           | revisits (pairs / submaps) | closed | recall | closures | true | precision | from places (cand. / closed) | global RMS / max m | online RMS m");
    for place in [false, true] {
        let out = tempfile::tempdir()?;
        let opts = options(&args, place, out.path())?;
        let report = runtime
            .block_on(run_daemon(opts, None))
            .context("running the daemon")?;
        let s = &report.run.summary;
        let Some(sm) = s.submaps.as_ref() else {
            anyhow::bail!("the configuration runs no submaps ([submaps] enabled = false)");
        };
        let Some(r) = sm.revisits else {
            anyhow::bail!("the run has no ground truth to score against");
        };
        let pct = |v: Option<f64>| v.map_or("n/a".to_string(), |v| format!("{:.0}%", 100.0 * v));
        let (g_rms, g_max) = sm
            .optimised
            .map_or((f64::NAN, f64::NAN), |o| (o.rms_m, o.max_m));
        let online = s.online.map_or(f64::NAN, |o| o.rms_m);
        println!(
            "{:<20} | {:>5} / {:<20} | {:>6} | {:>6} | {:>8} | {:>4} | {:>9} | {:>6} / {:<21} | {:>6.2} / {:<9.2} | {:.2}",
            if place { "uncertainty + places" } else { "uncertainty only" },
            r.pairs,
            r.revisiting,
            r.closed,
            pct(r.recall()),
            r.closures,
            r.correct,
            pct(r.precision()),
            sm.global.place_candidates,
            sm.global.place_loops,
            g_rms,
            g_max,
            online
        );
    }
    Ok(())
}
