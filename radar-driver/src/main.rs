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
    /// Stop after this many seconds, in (0, 31536000] (default: run until Ctrl-C).
    #[arg(long, value_parser = parse_duration_s)]
    duration_s: Option<Duration>,
    /// Seconds between rate lines, in (0, 3600].
    #[arg(long, default_value = "1", value_parser = parse_interval_s)]
    interval_s: Duration,
    /// Watchdog period in milliseconds, in [1, 3600000] (no whole frame for this long:
    /// reconnect).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=MAX_WATCHDOG_MS))]
    watchdog_ms: Option<u64>,
}

/// Longest `--duration-s`: a year.
const MAX_DURATION_S: f64 = 365.0 * 24.0 * 3600.0;
/// Longest `--interval-s`: an hour.
const MAX_INTERVAL_S: f64 = 3600.0;
/// Longest `--watchdog-ms`: an hour.
const MAX_WATCHDOG_MS: u64 = 3_600_000;

/// Seconds as a finite number in (0, `max`], as a `Duration`.
fn parse_seconds(text: &str, max: f64) -> Result<Duration, String> {
    let s: f64 = text
        .trim()
        .parse()
        .map_err(|e| format!("not a number of seconds: {e}"))?;
    if !(s.is_finite() && s > 0.0 && s <= max) {
        return Err(format!("must be a finite number of seconds in (0, {max}]"));
    }
    Duration::try_from_secs_f64(s).map_err(|e| e.to_string())
}

fn parse_duration_s(text: &str) -> Result<Duration, String> {
    parse_seconds(text, MAX_DURATION_S)
}

fn parse_interval_s(text: &str) -> Result<Duration, String> {
    parse_seconds(text, MAX_INTERVAL_S)
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
    // A radar that keeps changing its configuration must not print at the rate it sends it.
    let mut print_limit = radar_driver::RateLimiter::new(std::time::Duration::from_secs(10));
    let mut ticker = tokio::time::interval(args.interval_s);
    ticker.tick().await;
    let mut prev = handle.metrics();
    let mut prev_t = Instant::now();
    // The run ends at the deadline itself, not at the next rate line.
    let deadline = async {
        match args.duration_s {
            Some(d) => tokio::time::sleep(d).await,
            None => std::future::pending().await,
        }
    };
    tokio::pin!(deadline);
    // Created once: a stop request between two turns of the loop is not missed.
    let stop = radar_driver::stop_signal();
    tokio::pin!(stop);
    loop {
        tokio::select! {
            _ = &mut stop => break,
            () = &mut deadline => break,
            changed = configuration.changed() => {
                if changed.is_err() {
                    break;
                }
                if let Some(c) = configuration.borrow_and_update().clone() {
                    if let Some(unprinted) = print_limit.check(tokio::time::Instant::now()) {
                        if unprinted > 0 {
                            println!("({unprinted} configuration changes not printed)");
                        }
                        print_configuration(&c);
                    }
                }
            }
            _ = ticker.tick() => {
                let now = handle.metrics();
                let dt = prev_t.elapsed().as_secs_f64();
                println!("{}", rate_line(&prev, &now, dt, consumed.load(Ordering::Relaxed)));
                prev = now;
                prev_t = Instant::now();
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
        // Colour only on a terminal: a log written to a file or a pipe stays plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
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
            eprintln!("radar-driver: {}", radar_driver::ErrorChain(e.as_ref()));
            std::process::ExitCode::FAILURE
        }
    }
}
