//! `sim-sensor`: a simulated Navtech radar on the Colossus protocol, with odometry, replay
//! and fault injection. Thin: parses arguments, builds [`SimOptions`], runs the library until
//! Ctrl-C or SIGTERM, maps errors to an exit code.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Parser, ValueEnum};
use sim_sensor::radar::{DataWidth, RadarPreset};
use sim_sensor::render::SceneRenderer;
use sim_sensor::scene::{shipped, Scene};
use sim_sensor::{Pacing, ShapingScope, SimOptions, SimServer, SourceSpec};

#[derive(Debug, Clone, Copy, ValueEnum)]
enum PacingArg {
    /// At the radar's rotation rate.
    Realtime,
    /// As fast as the client reads.
    Fast,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum ShapingScopeArg {
    /// The radar's: every client's azimuths, outliving the connection that sent them.
    Radar,
    /// The sending connection's own, until it closes.
    Connection,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum PresetArg {
    /// The paper's unit: 200 azimuths, 0.25 m bins to 200 m.
    #[value(name = "paper-200")]
    Paper200,
    /// CTS350-X-like: 400 azimuths, 3768 bins of 0.0438 m, 4 Hz.
    #[value(name = "cts350x-400")]
    Cts350x400,
}

/// A simulated Navtech radar serving synthetic spectra (or recordings) over the real
/// Colossus protocol.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// A config file whose `[sim]` section sets the defaults (command-line flags win).
    #[arg(long)]
    config: Option<PathBuf>,
    /// A shipped scene name or a scene file (TOML). Default: outdoor-field.
    #[arg(long)]
    scene: Option<String>,
    /// Replace the scene's radar with a preset.
    #[arg(long, value_enum)]
    preset: Option<PresetArg>,
    /// Bits per bin on the wire (8: message 30, 16: message 31).
    #[arg(long)]
    data_width: Option<u32>,
    /// Pacing.
    #[arg(long, value_enum)]
    pacing: Option<PacingArg>,
    /// Radar port address.
    #[arg(long)]
    bind: Option<SocketAddr>,
    /// Odometry port address.
    #[arg(long)]
    odometry_bind: Option<SocketAddr>,
    /// Serve no odometry.
    #[arg(long)]
    no_odometry: bool,
    /// Gyro port address (the yaw rate, `[sim.gyro]`; default 127.0.0.1:6319).
    #[arg(long)]
    gyro_bind: Option<SocketAddr>,
    /// Serve no gyro.
    #[arg(long)]
    no_gyro: bool,
    /// Replay a recorded data set's polar PNG scans instead of a scene (Oxford, Boreas or
    /// RADIATE layout; a folder of Oxford scans alone works too).
    #[arg(long, conflicts_with_all = ["scene", "replay_raw"])]
    replay_dir: Option<PathBuf>,
    /// With --replay-dir: the layout, oxford, boreas or radiate (default: detected from the
    /// folder's contents; a folder without a data set's marker file is read as Oxford scans).
    #[arg(long, requires = "replay_dir", value_name = "oxford|boreas|radiate")]
    replay_format: Option<sim_sensor::replay::ReplayFormat>,
    /// Replay a raw Colossus byte stream (e.g. from `radar-driver --record`).
    #[arg(long, conflicts_with = "scene")]
    replay_raw: Option<PathBuf>,
    /// Start a replay again when it ends.
    #[arg(long = "loop")]
    replay_loop: bool,
    /// Write the ground truth (JSON Lines) to this file.
    #[arg(long)]
    ground_truth: Option<PathBuf>,
    /// Random seed (overrides the scene's).
    #[arg(long)]
    seed: Option<u64>,
    /// Clients served at once, 1 to 64 (as `[sim] max_clients`).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=64))]
    max_clients: Option<u16>,
    /// End the scene after this many azimuths.
    #[arg(long)]
    stop_after_azimuths: Option<u64>,
    /// Whom a client's contour (50) and sector blanking (51) apply to (default: radar).
    #[arg(long, value_enum)]
    shaping_scope: Option<ShapingScopeArg>,
    /// List the shipped scenes and exit.
    #[arg(long)]
    list_scenes: bool,
    /// Render this many azimuths of the scene on one core, print the rate, and exit.
    #[arg(long, value_name = "AZIMUTHS")]
    measure_render: Option<u64>,
}

fn load_scene(name: &str) -> Result<Scene> {
    Ok(match shipped::text(name) {
        Some(_) => shipped::load(name)?,
        None => {
            Scene::load(&PathBuf::from(name)).with_context(|| format!("loading scene {name}"))?
        }
    })
}

fn build_options(args: &Args) -> Result<SimOptions> {
    let mut options = match &args.config {
        Some(path) => {
            let config = config::Config::load(path)
                .with_context(|| format!("loading {}", path.display()))?;
            SimOptions::from_config(&config.sim)?
        }
        None => SimOptions::new(SourceSpec::Scene(Box::new(shipped::load(
            config::sim::DEFAULT_SCENE,
        )?))),
    };
    if let Some(name) = &args.scene {
        options.source = SourceSpec::Scene(Box::new(load_scene(name)?));
    }
    if let SourceSpec::Scene(scene) = &mut options.source {
        if let Some(preset) = args.preset {
            let preset = match preset {
                PresetArg::Paper200 => RadarPreset::Paper200,
                PresetArg::Cts350x400 => RadarPreset::Cts350x400,
            };
            **scene = (**scene).clone().with_preset(preset);
        }
        if let Some(bits) = args.data_width {
            let Some(width) = DataWidth::from_bits(bits) else {
                bail!("--data-width must be 8 or 16, got {bits}");
            };
            **scene = (**scene).clone().with_data_width(width);
        }
    }
    if let Some(dir) = &args.replay_dir {
        let format = args
            .replay_format
            .or_else(|| sim_sensor::replay::ReplayFormat::detect(dir).ok());
        options.source = match format {
            Some(format) => SourceSpec::PolarScans {
                dir: dir.clone(),
                format: Some(format),
            },
            None => SourceSpec::OxfordPng(dir.clone()),
        };
    }
    if let Some(path) = &args.replay_raw {
        options.source = SourceSpec::RawStream(path.clone());
    }
    if let Some(p) = args.pacing {
        options.pacing = match p {
            PacingArg::Realtime => Pacing::Realtime,
            PacingArg::Fast => Pacing::AsFastAsPossible,
        };
    }
    if let Some(bind) = args.bind {
        options.bind = bind;
    }
    if let Some(bind) = args.odometry_bind {
        options.odometry_bind = Some(bind);
    }
    if args.no_odometry {
        options.odometry_bind = None;
    }
    if let Some(bind) = args.gyro_bind {
        options.gyro_bind = Some(bind);
    }
    if args.no_gyro {
        options.gyro_bind = None;
    }
    if args.ground_truth.is_some() {
        options.ground_truth_path.clone_from(&args.ground_truth);
    }
    if args.seed.is_some() {
        options.seed = args.seed;
    }
    if let Some(n) = args.max_clients {
        options.max_clients = usize::from(n);
    }
    options.stop_after_azimuths = args.stop_after_azimuths.or(options.stop_after_azimuths);
    options.replay_loop |= args.replay_loop;
    if let Some(scope) = args.shaping_scope {
        options.shaping_scope = match scope {
            ShapingScopeArg::Radar => ShapingScope::Radar,
            ShapingScopeArg::Connection => ShapingScope::Connection,
        };
    }
    Ok(options)
}

/// Renders `n` azimuths on this thread and prints the rate against the real radar's.
fn measure_render(options: &SimOptions, n: u64) -> Result<()> {
    let SourceSpec::Scene(scene) = &options.source else {
        bail!("--measure-render needs a scene");
    };
    let renderer = std::sync::Arc::new(SceneRenderer::new(scene, options.seed, 3600.0)?);
    let mut cursor = renderer.cursor();
    let mut frame = bytes::BytesMut::with_capacity(16 * 1024);
    let start = Instant::now();
    for k in 0..n {
        frame.clear();
        cursor.render(
            k,
            (k % 65_536) as u16,
            protocol::Timestamp::EPOCH,
            &mut frame,
        )?;
    }
    let seconds = start.elapsed().as_secs_f64();
    let rate = n as f64 / seconds;
    let real = scene.radar.packet_rate_f64();
    println!(
        "scene {}: {} azimuths x {} bins in {seconds:.3} s = {rate:.0} azimuths/s on one core, {:.1} x the radar's {real:.0}/s",
        scene.name,
        n,
        scene.radar.range_bins,
        rate / real
    );
    Ok(())
}

/// Ctrl-C, or SIGTERM on Unix.
async fn shutdown_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        if let Ok(mut term) = signal(SignalKind::terminate()) {
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
            }
            return;
        }
    }
    let _ = tokio::signal::ctrl_c().await;
}

#[tokio::main]
async fn main() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        // Colour only on a terminal: a log written to a file or a pipe stays plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stdout()))
        .init();
    let args = Args::parse();
    if args.list_scenes {
        for name in shipped::NAMES {
            let scene = shipped::load(name)?;
            println!(
                "{name:22} {:4} features  {}",
                scene.features.len(),
                scene.description
            );
        }
        return Ok(());
    }
    let options = build_options(&args)?;
    if let Some(n) = args.measure_render {
        return measure_render(&options, n);
    }
    let handle = SimServer::spawn(options).await?;
    tracing::info!(radar = %handle.local_addr(), odometry = ?handle.odometry_addr(), "sim-sensor running; Ctrl-C or SIGTERM stops it");
    let token = handle.shutdown_token();
    tokio::spawn(async move {
        shutdown_signal().await;
        tracing::info!("signal received: shutting down");
        token.cancel();
    });
    handle.wait().await?;
    Ok(())
}
