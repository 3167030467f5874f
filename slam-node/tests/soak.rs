//! The soak (issue 17): the whole daemon, against a fake radar and a fake odometry bridge on
//! 127.0.0.1:0, fed good input interleaved with bursts of what a real radar, a real vehicle
//! and a long day send: far-future stamps, a stuck encoder, garbage bytes, a trickling
//! link, a dropped connection, an odometry gap, absurd odometry, noisy spectra. The daemon
//! must never die, its memory must stay bounded, and mapping must resume within a few
//! seconds of good input after each burst.
//!
//! `a_minute_of_mixed_hostile_input_*` runs for `SLAM_SOAK_S` seconds (default 60: one
//! cycle of every burst, in CI). The longer soak is the same test for `SLAM_SOAK_LONG_S`
//! seconds (default 3600), ignored by default:
//!
//! ```sh
//! cargo test --release -p slam-node --test soak -- --ignored --nocapture
//! ```
//!
//! After an odometry gap the filter used to bridge with a pose uncertainty of 12 m and 69
//! degrees and associate beam by beam inside those gates: in this map of four reflectors
//! the parked vehicle was relocalised 19 m off after the first gap and 48-296 m off after
//! later ones. It now relocalises against the map (several features jointly) before it
//! uses a beam again (slam-filter `relocalise_after_gap`), and the gap is checked like
//! every other burst.
//!
//! The garbage phase left about 100 features mapped just after it (retired within about
//! 7 s): the inverted bytes that land in the bins are one-bin spikes that the TPP
//! detector's smoothing over rotations carried into the next rotation, which confirmed them.
//! The detector now resets a bin's smoothing when a scan drops 45 dB below it, which leaves
//! the smaller spikes: 29-40 features at most in `tests/garbage_frames.rs`' replay of the
//! phase (was 113-116); in this soak (release, 2026-11-29, the machine shared) 28 features
//! 0.7 s after the garbage phase, against 3-8 after the other bursts.

mod support;

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use bytes::BytesMut;
use protocol::{BinWidth, FftData, FrameDecoder, Message, Timestamp};
use rand::{Rng, SeedableRng};
use sim_sensor::radar::RadarPreset;
use slam_node::daemon::{run_daemon, DaemonOptions};
use support::{add_point, empty_scene, SimRadar, REFLECTORS};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

/// Unix time of the stream's start (2023-11-14), nanoseconds.
const T0_NS: u64 = 1_700_000_000_000_000_000;
/// 2100-01-01 in Unix seconds.
const YEAR_2100_S: u32 = 4_102_444_800;
/// The daemon's byte budget for radar data in this test, MiB.
const BUDGET_MIB: usize = 16;
/// The filter's feature limit in this test: its state (4 numbers a feature) and covariance
/// are bounded by it, (4 x 200 + 4)^2 x 8 bytes = 5 MB; the shipped 1000 allows 128 MB,
/// which a noise burst's phantoms do fill.
const MAX_FEATURES: usize = 200;

/// What the fake radar and the fake odometry bridge are doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
enum Phase {
    Good = 0,
    /// A few azimuths stamped in 2100 among good ones.
    FarFutureStamps,
    /// Valid frames whose encoder never moves.
    StuckEncoder,
    /// Random bytes and corrupted frames between good frames.
    Garbage,
    /// One byte every 100 ms and no frame (the watchdog must drop the link).
    Trickle,
    /// The radar closes each connection as soon as data is asked for.
    Disconnect,
    /// Every bin random: detections everywhere.
    Noise,
    /// The odometry bridge sends nothing (longer than the filter's 5 s gap limit).
    OdometryGap,
    /// Odometry at 1e199 m/s, 1000 rad of steer, stamped 2100.
    AbsurdOdometry,
}

impl Phase {
    fn from_u8(v: u8) -> Phase {
        [
            Phase::Good,
            Phase::FarFutureStamps,
            Phase::StuckEncoder,
            Phase::Garbage,
            Phase::Trickle,
            Phase::Disconnect,
            Phase::Noise,
            Phase::OdometryGap,
            Phase::AbsurdOdometry,
        ]
        .get(usize::from(v))
        .copied()
        .unwrap_or(Phase::Good)
    }
}

/// One cycle: each burst of bad input (seconds), each followed by good input (seconds).
const CYCLE: [(Phase, f64, f64); 8] = [
    (Phase::FarFutureStamps, 0.5, 4.0),
    (Phase::StuckEncoder, 2.0, 4.0),
    (Phase::Noise, 0.5, 5.0),
    (Phase::Garbage, 1.5, 4.0),
    (Phase::Trickle, 3.0, 5.0),
    (Phase::Disconnect, 0.5, 4.0),
    (Phase::OdometryGap, 6.0, 5.0),
    (Phase::AbsurdOdometry, 1.0, 4.0),
];
/// Good input before the first burst, seconds.
const WARM_UP_S: f64 = 5.0;

/// Shared between the test, the fake radar and the fake odometry bridge.
struct World {
    phase: AtomicU8,
    started: Instant,
    /// Azimuths per second.
    rate: f64,
    stop: AtomicBool,
}

impl World {
    fn phase(&self) -> Phase {
        Phase::from_u8(self.phase.load(Ordering::Relaxed))
    }

    /// The stream's clock: real time since the start, as a real radar's.
    fn elapsed_s(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }
}

fn frame(message: &Message) -> Vec<u8> {
    let mut b = BytesMut::new();
    message.encode(&mut b).expect("encodable");
    b.to_vec()
}

fn timestamp(ns: u64) -> Timestamp {
    Timestamp::new(
        u32::try_from(ns / 1_000_000_000).expect("before 2106"),
        u32::try_from(ns % 1_000_000_000).expect("nanoseconds"),
    )
    .expect("timestamp")
}

/// Serves one connection: the configuration, then (once data is asked for) azimuths at the
/// radar's rate on the stream's clock, spoilt as the phase says. Returns when the link
/// ends or the phase closes it.
async fn serve_radar(
    stream: TcpStream,
    radar: &mut SimRadar,
    configuration: &protocol::Configuration,
    world: &World,
    rng: &mut rand_chacha::ChaCha8Rng,
) {
    let _ = stream.set_nodelay(true);
    let (mut rd, mut wr) = stream.into_split();
    let asked = Arc::new(AtomicBool::new(false));
    let reader = {
        let asked = Arc::clone(&asked);
        tokio::spawn(async move {
            let mut buf = BytesMut::new();
            let mut decoder = FrameDecoder::new();
            loop {
                match rd.read_buf(&mut buf).await {
                    Ok(0) | Err(_) => return,
                    Ok(_) => {}
                }
                while let Ok(Some(m)) = decoder.decode(&mut buf) {
                    if matches!(m, Message::StartFftData | Message::StartNonContourFftData) {
                        asked.store(true, Ordering::Relaxed);
                    }
                }
            }
        })
    };
    let config = frame(&Message::Configuration(Box::new(configuration.clone())));
    if wr.write_all(&config).await.is_err() {
        return;
    }
    let mut next = (world.elapsed_s() * world.rate) as u64;
    let mut tick = tokio::time::interval(Duration::from_millis(10));
    let mut future_sent = 0u32;
    while !world.stop.load(Ordering::Relaxed) && !reader.is_finished() {
        tick.tick().await;
        if !asked.load(Ordering::Relaxed) {
            continue;
        }
        let phase = world.phase();
        let due = (world.elapsed_s() * world.rate) as u64;
        let mut out = Vec::new();
        match phase {
            Phase::Trickle => {
                // A byte now and then, never a whole frame; the azimuths of the silence are
                // lost, as a real radar's are.
                if rng.gen_bool(0.1) {
                    out.push(0x5a);
                }
                next = due;
            }
            // Every connection during the phase is closed (the driver reconnects).
            Phase::Disconnect => break,
            _ => {
                if phase != Phase::FarFutureStamps {
                    future_sent = 0;
                }
                while next < due {
                    let az = radar.azimuth(next);
                    let mut stamp = timestamp(radar.unix_ns(next));
                    let mut encoder = az.encoder;
                    let mut bins = az.bins.clone();
                    match phase {
                        Phase::FarFutureStamps if future_sent < 3 && next.is_multiple_of(50) => {
                            future_sent += 1;
                            stamp = Timestamp::new(YEAR_2100_S, 0).expect("2100");
                        }
                        Phase::StuckEncoder => encoder = 1000,
                        Phase::Noise => {
                            let noisy: Vec<u8> = (0..bins.len()).map(|_| rng.gen()).collect();
                            bins = noisy.into();
                        }
                        _ => {}
                    }
                    let sweep = (next % 65_536) as u16;
                    let mut bytes = frame(&Message::FftData(FftData::new(
                        BinWidth::Eight,
                        sweep,
                        encoder,
                        stamp,
                        bins,
                    )));
                    if phase == Phase::Garbage {
                        if rng.gen_bool(0.3) {
                            let junk: Vec<u8> =
                                (0..rng.gen_range(1..400)).map(|_| rng.gen()).collect();
                            out.extend_from_slice(&junk);
                        }
                        if rng.gen_bool(0.2) {
                            let at = rng.gen_range(0..bytes.len());
                            bytes[at] ^= 0xff;
                        }
                    }
                    out.extend_from_slice(&bytes);
                    next += 1;
                }
            }
        }
        if !out.is_empty() && wr.write_all(&out).await.is_err() {
            break;
        }
    }
    reader.abort();
}

/// The fake radar: accepts connection after connection on 127.0.0.1:0.
async fn fake_radar(listener: TcpListener, world: Arc<World>, t0_ns: u64) {
    let mut scene = empty_scene("soak", RadarPreset::Paper200, 5);
    for (x, y) in REFLECTORS {
        add_point(&mut scene, x, y, 0.5, 0.3);
    }
    let configuration = scene.radar.configuration();
    let mut radar = SimRadar::new(&scene, None, 3600.0, t0_ns);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    while !world.stop.load(Ordering::Relaxed) {
        let accepted = tokio::time::timeout(Duration::from_millis(200), listener.accept()).await;
        if let Ok(Ok((stream, _))) = accepted {
            serve_radar(stream, &mut radar, &configuration, &world, &mut rng).await;
        }
    }
}

/// The fake odometry bridge: a parked vehicle at 20 Hz on the stream's clock, a little
/// ahead of the radar, spoilt as the phase says.
async fn fake_odometry(listener: TcpListener, world: Arc<World>, t0_s: f64) {
    while !world.stop.load(Ordering::Relaxed) {
        let Ok(Ok((mut stream, _))) =
            tokio::time::timeout(Duration::from_millis(200), listener.accept()).await
        else {
            continue;
        };
        if stream
            .write_all(b"# odometry v1 timestamp_s speed_mps steer_rad\n")
            .await
            .is_err()
        {
            continue;
        }
        let mut k = ((world.elapsed_s() / 0.05) as u64).saturating_sub(1);
        let mut tick = tokio::time::interval(Duration::from_millis(10));
        while !world.stop.load(Ordering::Relaxed) {
            tick.tick().await;
            let phase = world.phase();
            let mut out = String::new();
            while (k as f64) * 0.05 <= world.elapsed_s() + 0.1 {
                let t = t0_s + k as f64 * 0.05;
                match phase {
                    Phase::OdometryGap => {}
                    Phase::AbsurdOdometry => out.push_str(&match k % 3 {
                        0 => format!("{t:.9} 1e199 0\n"),
                        1 => format!("{t:.9} 0 1000\n"),
                        _ => format!("{YEAR_2100_S}.000000000 0 0\n"),
                    }),
                    _ => out.push_str(&format!("{t:.9} 0 0\n")),
                }
                k += 1;
            }
            if !out.is_empty() && stream.write_all(out.as_bytes()).await.is_err() {
                break;
            }
        }
    }
}

/// Resident memory of this process (Linux), bytes.
fn rss_bytes() -> Option<usize> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: usize = statm.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * 4096)
}

/// What the pipeline reported after one rotation.
#[derive(Debug, Clone, Copy)]
struct Progress {
    wall_s: f64,
    stream_s: f64,
    beams: u64,
    features: usize,
    x: f64,
    y: f64,
}

fn config_text(radar: SocketAddr, odometry: SocketAddr, out: &std::path::Path) -> String {
    format!(
        r#"
[radar]
address = "{radar}"
watchdog_timeout_ms = 1500
reconnect_initial_backoff_ms = 50
reconnect_max_backoff_ms = 200
max_held_mib = {BUDGET_MIB}

[odometry]
source = "tcp"
address = "{odometry}"

[model]
compensation = "40db"

[filter]
max_features = {MAX_FEATURES}

[output]
directory = "{}"
pictures = false
progress = false
"#,
        out.display()
    )
}

/// A burst and when it ended, wall seconds since the start.
#[derive(Debug, Clone, Copy)]
struct Burst {
    phase: Phase,
    started_s: f64,
    ended_s: f64,
    next_burst_s: f64,
}

async fn soak(duration_s: f64) {
    let dir = tempfile::tempdir().expect("temporary folder");
    let radar_listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let odometry_listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let text = config_text(
        radar_listener.local_addr().expect("address"),
        odometry_listener.local_addr().expect("address"),
        dir.path(),
    );
    let config = config::Config::from_toml_str(&text).expect("valid configuration");
    let world = Arc::new(World {
        phase: AtomicU8::new(Phase::Good as u8),
        started: Instant::now(),
        rate: RadarPreset::Paper200.params().packet_rate_f64(),
        stop: AtomicBool::new(false),
    });
    let radar_task = tokio::spawn(fake_radar(radar_listener, Arc::clone(&world), T0_NS));
    let odometry_task = tokio::spawn(fake_odometry(
        odometry_listener,
        Arc::clone(&world),
        T0_NS as f64 * 1e-9,
    ));
    let progress: Arc<Mutex<Vec<Progress>>> = Arc::default();
    let callback = {
        let progress = Arc::clone(&progress);
        let world = Arc::clone(&world);
        Box::new(
            move |s: &slam_node::pipeline::PipelineSummary,
                  ekf: &slam_node::pipeline::DaemonEkf| {
                let pose = ekf.pose();
                progress.lock().expect("progress").push(Progress {
                    wall_s: world.elapsed_s(),
                    stream_s: s.last_time_s.map_or(0.0, |t| t - T0_NS as f64 * 1e-9),
                    beams: s.beams,
                    features: ekf.feature_count(),
                    x: pose.x,
                    y: pose.y,
                });
            },
        ) as slam_node::pipeline::run::ProgressFn
    };
    let stop = Arc::new(AtomicBool::new(false));
    let opts = DaemonOptions {
        config,
        simulator: None,
        mcap: None,
        max_stream_s: None,
        out_dir: dir.path().to_path_buf(),
        figures: false,
        progress_every_rotations: 0,
        stop: Arc::clone(&stop),
        keep_configured_compensation: false,
        spectrum_bearings_deg: Vec::new(),
        detector: Some(slam_node::detect::DetectorSettings::default()),
        written: None,
    };
    let daemon = tokio::spawn(run_daemon(opts, Some(callback)));
    // Resident memory, sampled every 10 ms from after the warm-up.
    let rss_peak = Arc::new(AtomicUsize::new(0));
    let rss_stop = Arc::new(AtomicBool::new(false));
    let mut rss_baseline = None;
    // The schedule: warm up, then cycles of bursts, each followed by good input.
    let mut bursts = Vec::new();
    let sleep_until = |t: f64| {
        let wait = (t - world.elapsed_s()).max(0.0);
        tokio::time::sleep(Duration::from_secs_f64(wait))
    };
    let mut t = WARM_UP_S;
    sleep_until(t).await;
    if let Some(rss) = rss_bytes() {
        rss_baseline = Some(rss);
        rss_peak.store(rss, Ordering::Relaxed);
        let (peak, stop_rss) = (Arc::clone(&rss_peak), Arc::clone(&rss_stop));
        std::thread::spawn(move || {
            while !stop_rss.load(Ordering::Relaxed) {
                peak.fetch_max(rss_bytes().unwrap_or(0), Ordering::Relaxed);
                std::thread::sleep(Duration::from_millis(10));
            }
        });
    }
    'cycles: loop {
        for (phase, bad_s, good_s) in CYCLE {
            if t + bad_s + 3.0 > duration_s {
                break 'cycles;
            }
            assert!(!daemon.is_finished(), "the daemon ended during the soak");
            world.phase.store(phase as u8, Ordering::Relaxed);
            t += bad_s;
            sleep_until(t).await;
            world.phase.store(Phase::Good as u8, Ordering::Relaxed);
            let ended_s = t;
            t = (t + good_s).min(duration_s);
            bursts.push(Burst {
                phase,
                started_s: ended_s - bad_s,
                ended_s,
                next_burst_s: t,
            });
            sleep_until(t).await;
        }
    }
    sleep_until(duration_s).await;
    assert!(!daemon.is_finished(), "the daemon ended during the soak");
    stop.store(true, Ordering::Relaxed);
    let report = tokio::time::timeout(Duration::from_secs(30), daemon)
        .await
        .expect("the daemon stops within 30 s of the stop request")
        .expect("the daemon task did not panic")
        .expect("the daemon ran to the end without an error");
    world.stop.store(true, Ordering::Relaxed);
    rss_stop.store(true, Ordering::Relaxed);
    let _ = tokio::join!(radar_task, odometry_task);

    // Never died.
    assert!(
        report.driver_failure.is_none(),
        "{:?}",
        report.driver_failure
    );
    let summary = &report.run.summary;
    let driver = report.driver.clone().expect("driver metrics");
    println!("{}", slam_node::daemon::report::summary_text(&report));
    println!(
        "driver: {} reconnects, {} watchdog trips, {} decode errors; held at most {} bytes of {}, {} azimuths dropped by the budget",
        driver.reconnects,
        driver.watchdog_timeouts,
        driver.decode_errors.total(),
        driver.held_bytes_peak,
        driver.max_held_bytes,
        driver.budget_drops
    );
    // Every kind of bad input was met (the link was dropped and came back, frames were
    // refused, stamps and odometry were refused).
    if bursts.len() >= CYCLE.len() {
        assert!(driver.reconnects >= 2, "trickle and disconnect reconnect");
        assert!(
            driver.watchdog_timeouts >= 1,
            "the trickle trips the watchdog"
        );
        assert!(driver.decode_errors.total() > 0, "garbage is refused");
        assert!(summary.clock_outliers > 0, "far-future stamps are refused");
        assert!(summary.odometry_refused > 0, "absurd odometry is refused");
    }
    // Mapping resumes after each burst: a rotation of azimuths stamped after the burst's
    // end has beams taken by the filter, the map holds the reflectors and the parked
    // vehicle's pose stays put.
    let progress = progress.lock().expect("progress").clone();
    let mut worst = 0.0f64;
    for b in &bursts {
        let after: Vec<&Progress> = progress
            .iter()
            .filter(|p| p.wall_s >= b.ended_s && p.wall_s <= b.next_burst_s)
            .collect();
        let resumed = after.windows(2).find(|w| {
            w[1].beams > w[0].beams && w[1].stream_s >= b.ended_s + 0.5 && w[1].features >= 3
        });
        let Some(w) = resumed else {
            panic!(
                "mapping did not resume within {:.1} s after {:?}: {:#?}",
                b.next_burst_s - b.ended_s,
                b.phase,
                after
            );
        };
        let latency = w[1].wall_s - b.ended_s;
        worst = worst.max(latency);
        println!(
            "{:?} ended at {:.1} s: mapping again {latency:.1} s later ({} features, pose ({:.2}, {:.2}))",
            b.phase, b.ended_s, w[1].features, w[1].x, w[1].y
        );
        // The burst did not move the parked vehicle's estimate (after an odometry gap the
        // filter relocalises against the map before it uses a beam again).
        let before = progress
            .iter()
            .rev()
            .find(|p| p.wall_s <= b.started_s)
            .copied()
            .unwrap_or(*w[1]);
        let moved = (w[1].x - before.x).hypot(w[1].y - before.y);
        assert!(
            moved < 1.0,
            "the parked vehicle's estimate moved {moved} m over {:?}: ({}, {}) to ({}, {})",
            b.phase,
            before.x,
            before.y,
            w[1].x,
            w[1].y
        );
        assert!(latency < 5.0, "{:?}: {latency} s", b.phase);
    }
    // Memory bounded: the driver's own accounting, and the process.
    assert!(driver.held_bytes_peak <= BUDGET_MIB << 20);
    if let Some(base) = rss_baseline {
        let growth = rss_peak.load(Ordering::Relaxed).saturating_sub(base);
        println!(
            "resident memory after the warm-up {:.1} MiB, grew by at most {:.1} MiB",
            base as f64 / 1048576.0,
            growth as f64 / 1048576.0
        );
        assert!(
            growth < 48 << 20,
            "resident memory grew by {growth} bytes over the soak"
        );
    }
    println!(
        "{} bursts over {duration_s} s; mapping resumed within {worst:.1} s of good input after each",
        bursts.len()
    );
}

fn seconds_from_env(name: &str, default: f64) -> f64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s >= 20.0)
        .unwrap_or(default)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "a minute of wall clock (SLAM_SOAK_S): run by hand, README.md 'Tests'"]
async fn a_minute_of_mixed_hostile_input_never_kills_the_daemon_nor_grows_its_memory_and_mapping_resumes_after_each_burst(
) {
    soak(seconds_from_env("SLAM_SOAK_S", 60.0)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "an hour by default (SLAM_SOAK_LONG_S): run by hand"]
async fn the_long_soak_of_mixed_hostile_input() {
    soak(seconds_from_env("SLAM_SOAK_LONG_S", 3600.0)).await;
}
