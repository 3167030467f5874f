//! `radar-driver`: connect to a Navtech radar (or the simulator), print its configuration and
//! live rates, optionally record the raw byte stream.
//!
//! Thin by design: parse arguments, build validated settings, set up logging, run the
//! library's driver, map errors to an exit code.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Parser;
use radar_driver::{Driver, DriverSettings, MetricsSnapshot};

/// Connect to a Navtech radar (Colossus protocol, TCP port 6317) or the simulator, print its
/// configuration and live rates.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// Radar address (ip:port). Overrides the configuration file. Default 127.0.0.1:6317.
    #[arg(long, short)]
    address: Option<SocketAddr>,
    /// A configuration file; its `[radar]` section is used.
    #[arg(long, short)]
    config: Option<PathBuf>,
    /// Record the raw Colossus byte stream to this file (see the `record` module for the
    /// format: the stream exactly as received, replayable by the simulator).
    #[arg(long)]
    record: Option<PathBuf>,
    /// Request non-contoured data (message 140) instead of 21.
    #[arg(long)]
    non_contoured: bool,
    /// Stop after this many seconds (default: run until Ctrl-C).
    #[arg(long)]
    duration_s: Option<f64>,
    /// Seconds between rate lines.
    #[arg(long, default_value_t = 1.0)]
    interval_s: f64,
    /// Watchdog period in milliseconds (nothing received for this long: reconnect).
    #[arg(long)]
    watchdog_ms: Option<u64>,
}

fn settings(args: &Args) -> anyhow::Result<DriverSettings> {
    let radar = match &args.config {
        Some(path) => {
            config::Config::load(path)
                .with_context(|| format!("loading {}", path.display()))?
                .radar
        }
        None => config::RadarSettings::default(),
    };
    let mut s = DriverSettings::from_config(&radar);
    if let Some(a) = args.address {
        s.address = a;
    }
    if args.record.is_some() {
        s.record_path.clone_from(&args.record);
    }
    if args.non_contoured {
        s.non_contoured = true;
    }
    if let Some(ms) = args.watchdog_ms {
        s.watchdog_timeout = Duration::from_millis(ms);
    }
    s.validate().map_err(anyhow::Error::msg)?;
    if !(args.interval_s.is_finite() && args.interval_s > 0.0) {
        anyhow::bail!("--interval-s must be > 0");
    }
    if let Some(d) = args.duration_s {
        if !(d.is_finite() && d > 0.0) {
            anyhow::bail!("--duration-s must be > 0");
        }
    }
    Ok(s)
}

fn print_configuration(c: &protocol::Configuration) {
    println!("radar configuration:");
    println!("  azimuth samples     {}", c.azimuth_samples);
    println!("  encoder size        {}", c.encoder_size);
    println!("  range in bins       {}", c.range_in_bins);
    println!("  bin size            {} (x 0.1 mm)", c.bin_size);
    println!("  rotation speed      {} mHz", c.rotation_speed_millihertz);
    println!("  packet rate         {} azimuths/s", c.packet_rate);
    println!("  range gain          {}", c.range_gain);
    println!("  range offset        {} m", c.range_offset_m);
    match c.geometry() {
        Ok(g) => {
            println!("  data width          {} bits", g.data_width.bits());
            println!("  max range           {:.2} m", g.max_range_m());
            if let Some(r) = g.range_resolution_m {
                println!("  range resolution    {r} m (protobuf)");
            }
        }
        Err(e) => println!("  (unusable geometry: {e})"),
    }
    println!("  protobuf            {:?}", c.data);
}

fn rate_line(prev: &MetricsSnapshot, now: &MetricsSnapshot, dt_s: f64, consumed: u64) -> String {
    let per_s = |a: u64, b: u64| (b.saturating_sub(a)) as f64 / dt_s;
    format!(
        "{:8.1} az/s {:6.2} rot/s {:7.3} MB/s | consumed {} | drops az {} rot {} | skipped {} sweep gaps {} | decode errors {} | reconnects {} | latency median {:.1} us p99 {:.1} us",
        per_s(prev.fft_frames, now.fft_frames),
        per_s(prev.rotations_sent, now.rotations_sent),
        per_s(prev.bytes, now.bytes) / 1e6,
        consumed,
        now.azimuth_drops,
        now.rotation_drops,
        now.skipped_azimuths,
        now.sweep_gaps,
        now.decode_errors.total(),
        now.reconnects,
        now.latency.median_ns as f64 / 1e3,
        now.latency.p99_ns as f64 / 1e3,
    )
}

async fn run(args: Args) -> anyhow::Result<()> {
    let settings = settings(&args)?;
    println!("connecting to {}", settings.address);
    let (driver, receivers) = Driver::new(settings);
    let handle = driver.spawn();

    // Consumers: count what arrives, as a filter would take it.
    let consumed = Arc::new(AtomicU64::new(0));
    let mut consumers = Vec::new();
    if let Some(rx) = receivers.azimuths {
        let c = Arc::clone(&consumed);
        consumers.push(std::thread::spawn(move || {
            for _ in rx {
                c.fetch_add(1, Ordering::Relaxed);
            }
        }));
    }
    if let Some(rx) = receivers.rotations {
        consumers.push(std::thread::spawn(move || for _ in rx {}));
    }

    let mut configuration = handle.configuration();
    let started = Instant::now();
    let mut ticker = tokio::time::interval(Duration::from_secs_f64(args.interval_s));
    ticker.tick().await;
    let mut prev = handle.metrics();
    let mut prev_t = Instant::now();
    let deadline = args.duration_s.map(Duration::from_secs_f64);
    loop {
        tokio::select! {
            _ = tokio::signal::ctrl_c() => break,
            changed = configuration.changed() => {
                if changed.is_err() {
                    break;
                }
                if let Some(c) = configuration.borrow_and_update().clone() {
                    print_configuration(&c);
                }
            }
            _ = ticker.tick() => {
                let now = handle.metrics();
                let dt = prev_t.elapsed().as_secs_f64();
                println!("{}", rate_line(&prev, &now, dt, consumed.load(Ordering::Relaxed)));
                prev = now;
                prev_t = Instant::now();
                if deadline.is_some_and(|d| started.elapsed() >= d) {
                    break;
                }
            }
        }
    }
    let exit = handle.stop().await?;
    for c in consumers {
        let _ = c.join();
    }
    let m = &exit.metrics;
    println!(
        "done: {} frames, {} bytes, {} azimuths ({} dropped), {} rotations ({} dropped), {} reconnects, decode errors {:?}, latency median {} ns p99 {} ns",
        m.frames, m.bytes, m.azimuths_sent, m.azimuth_drops, m.rotations_sent, m.rotation_drops, m.reconnects, m.decode_errors, m.latency.median_ns, m.latency.p99_ns
    );
    if let Some(r) = exit.recording {
        println!(
            "recorded {} bytes to {} ({} chunks dropped){}",
            r.bytes_written,
            r.path.display(),
            r.chunks_dropped,
            r.error.map(|e| format!("; error: {e}")).unwrap_or_default()
        );
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    let args = Args::parse();
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("radar-driver: cannot start the runtime: {e}");
            return std::process::ExitCode::from(2);
        }
    };
    match runtime.block_on(run(args)) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("radar-driver: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
