//! `radar-zenoh`: a Navtech radar (or the simulator) published live over Zenoh as Navtech's
//! ROS 2 driver publishes it, without the SLAM: `RadarConfigurationMsg`, a `RadarBScanMsg`
//! per rotation and with `--fft` a `RadarFftDataMsg` per azimuth, CDR, keyed as
//! zenoh-bridge-ros2dds maps `/radar_data/...` topics. A rig records them with
//! `ros2 bag record` behind the bridge, or any Zenoh subscriber.
//!
//! Thin: arguments and settings, the radar driver on a tokio runtime, the publisher on
//! this thread reading the driver's bounded channel (the driver drops on its side, never
//! waits for us), a summary at the end.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Parser;
use crossbeam_channel::RecvTimeoutError;
use radar_driver::{Driver, DriverSettings};
use slam_node::output::live::RadarPublisher;

/// Publish a Navtech radar's data live over Zenoh as Navtech's ROS 2 messages.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// A configuration file: its `[radar]` and `[output.zenoh]` tables are used
    /// (`enabled` is ignored: publishing is what this program does).
    #[arg(long, short)]
    config: Option<PathBuf>,
    /// Radar address (ip:port), overriding the configuration. Default 127.0.0.1:6317.
    #[arg(long, short)]
    address: Option<SocketAddr>,
    /// Zenoh endpoint to connect to, `tcp/host:port` (repeatable), replacing the
    /// configuration's `connect` list.
    #[arg(long, value_parser = endpoint)]
    connect: Vec<String>,
    /// Zenoh endpoint to listen on, `tcp/host:port` (repeatable), replacing the
    /// configuration's `listen` list.
    #[arg(long, value_parser = endpoint)]
    listen: Vec<String>,
    /// Also publish each azimuth as `RadarFftDataMsg` on `radar_data/fft_data`.
    #[arg(long)]
    fft: bool,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long, value_parser = seconds)]
    duration_s: Option<f64>,
}

fn endpoint(text: &str) -> Result<String, String> {
    config::live::endpoint(text).map_err(|e| e.to_string())
}

fn seconds(text: &str) -> Result<f64, String> {
    let v: f64 = text
        .parse()
        .map_err(|_| format!("{text:?} is not a number of seconds"))?;
    if v.is_finite() && v > 0.0 && v <= 365.0 * 86_400.0 {
        Ok(v)
    } else {
        Err(format!("must be in (0, 31536000] s, got {text}"))
    }
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| {
                tracing_subscriber::EnvFilter::new("warn,slam_node=info,radar_driver=info")
            }),
        )
        .with_writer(std::io::stderr)
        // Colour only on a terminal: a log written to a file or a pipe stays plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("radar-zenoh: {}", radar_driver::ErrorChain(e.as_ref()));
            ExitCode::FAILURE
        }
    }
}

fn run(args: Args) -> anyhow::Result<()> {
    let config = match &args.config {
        Some(path) => {
            config::Config::load(path).with_context(|| format!("loading {}", path.display()))?
        }
        None => config::Config::default(),
    };
    let mut zenoh = config.output.zenoh.clone();
    if !args.connect.is_empty() {
        zenoh.connect.clone_from(&args.connect);
    }
    if !args.listen.is_empty() {
        zenoh.listen.clone_from(&args.listen);
    }
    let mut driver_settings = DriverSettings::from_config(&config.radar);
    if let Some(a) = args.address {
        driver_settings.address = a;
    }
    driver_settings.handoff.rotation_capacity = None;
    driver_settings
        .validate()
        .map_err(anyhow::Error::msg)
        .context("radar settings")?;

    // Zenoh first (it blocks while opening): a bad endpoint is reported before any radar IO.
    let mut publisher = RadarPublisher::open(&zenoh, args.fft).context("starting Zenoh")?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    let stop = Arc::new(AtomicBool::new(false));
    let ctrl_c = Arc::clone(&stop);
    runtime.spawn(async move {
        let why = radar_driver::stop_signal().await;
        eprintln!("radar-zenoh: stopping ({why})");
        ctrl_c.store(true, Ordering::Relaxed);
    });
    eprintln!(
        "radar-zenoh: connecting to the radar at {}",
        driver_settings.address
    );
    let (driver, receivers) = {
        let _guard = runtime.enter();
        Driver::new(driver_settings)
    };
    let azimuths = receivers
        .azimuths
        .context("the radar driver has no azimuth channel")?;
    let handle = {
        let _guard = runtime.enter();
        driver.spawn()
    };
    let started = Instant::now();
    let limit = args.duration_s.map(Duration::from_secs_f64);
    let mut azimuth_count = 0u64;
    while !stop.load(Ordering::Relaxed) && limit.is_none_or(|l| started.elapsed() < l) {
        match azimuths.recv_timeout(Duration::from_millis(100)) {
            Ok(az) => {
                publisher.on_azimuth(&az);
                azimuth_count += 1;
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
    }
    let exit = runtime
        .block_on(async { tokio::time::timeout(Duration::from_secs(5), handle.stop()).await });
    let summary = publisher.finish();
    println!(
        "radar-zenoh: {azimuth_count} azimuths read; published {} messages ({}), {} failed",
        summary.total(),
        summary
            .published
            .iter()
            .map(|(k, n)| format!("{k} {n}"))
            .collect::<Vec<_>>()
            .join(", "),
        summary.failed
    );
    match exit {
        Ok(Ok(exit)) => {
            let m = &exit.metrics;
            println!(
                "radar driver: {} azimuths ({} dropped), {} reconnects",
                m.azimuths_sent, m.azimuth_drops, m.reconnects
            );
            Ok(())
        }
        Ok(Err(e)) => Err(anyhow::Error::new(e).context("the radar driver failed")),
        Err(_) => anyhow::bail!("the radar driver did not stop within 5 s"),
    }
}
