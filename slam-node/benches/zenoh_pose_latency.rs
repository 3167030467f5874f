//! Live pose latency over Zenoh on loopback: from a rotation's last azimuth to the pose
//! message in a subscriber's hands.
//!
//! `cargo bench -p slam-node --features zenoh --bench zenoh_pose_latency` runs the daemon
//! binary (release) against its embedded simulator in real time, once per radar preset,
//! with `[output.zenoh]` connecting to a subscriber peer in this process listening on a
//! loopback port (multicast off, no router). For each pose received it takes the
//! subscriber's system clock at receipt minus the radar time of the rotation's last azimuth
//! (the `timestamp_s` of the rotation's row in `diagnostics.csv`, matched to the pose by
//! order; the simulator stamps its azimuths on the system clock, so the figure holds the
//! simulator's send, the radar link, the driver, the pipeline up to the rotation's close
//! (which needs the next rotation's first azimuth), the queue to the publisher thread, CDR
//! encoding and Zenoh over TCP). `SLAM_LATENCY_S` sets each run's stream seconds
//! (default 20). Each preset runs with the simulator's odometry at 20 Hz (shipped) and at
//! 200 Hz (the pipeline waits, bounded, for odometry to reach an azimuth's time before it
//! uses it). Last, `radar-zenoh` on the same kind of simulator gives the path without the
//! SLAM (B-scan receipt minus its last azimuth).

use std::path::Path;
use std::process::Command;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use ros_msgs::from_cdr;
use ros_msgs::nav::Odometry;
use zenoh::Wait;

/// A peer listening on a port the system chose on 127.0.0.1, and its bound locator.
fn subscriber_session() -> (zenoh::Session, String) {
    slam_node::output::zenoh_node::loopback_peer().expect("a loopback Zenoh peer")
}

/// The last-azimuth times of the rotations, in order, from `diagnostics.csv`.
fn rotation_times(path: &Path) -> Vec<f64> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let at = header.iter().position(|h| *h == "timestamp_s").unwrap();
    lines
        .filter_map(|l| l.split(',').nth(at)?.parse().ok())
        .collect()
}

/// Pose stamps in `trajectory.tum`, in order.
fn pose_times(path: &Path) -> Vec<f64> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .filter_map(|l| l.split_whitespace().next()?.parse().ok())
        .collect()
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    let at = ((sorted.len() as f64 - 1.0) * q).round().max(0.0) as usize;
    sorted.get(at).copied().unwrap_or(f64::NAN)
}

fn run(preset: &str, odometry_hz: f64, seconds: f64) {
    let (session, endpoint) = subscriber_session();
    let subscriber = session.declare_subscriber("slam/odometry").wait().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("latency.toml");
    std::fs::write(
        &config,
        format!(
            "[sim]\nradar_preset = \"{preset}\"\nodometry_rate_hz = {odometry_hz:?}\n\n[output]\npictures = false\nprogress = false\n\n\
             [output.zenoh]\nenabled = true\nconnect = [\"{endpoint}\"]\nlisten = []\n"
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let mut child = Command::new(env!("CARGO_BIN_EXE_slam-node"))
        .arg("--config")
        .arg(&config)
        .args(["--embedded-sim", "--no-figures", "--duration"])
        .arg(seconds.to_string())
        .arg("--out")
        .arg(&out)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // (stamp of the pose, system clock at receipt), seconds.
    let mut received: Vec<(f64, f64)> = Vec::new();
    loop {
        match subscriber.recv_timeout(Duration::from_millis(200)) {
            Ok(Some(sample)) => {
                let now = SystemTime::now()
                    .duration_since(UNIX_EPOCH)
                    .unwrap()
                    .as_secs_f64();
                let odometry: Odometry = from_cdr(&sample.payload().to_bytes()).unwrap();
                let stamp = f64::from(odometry.header.stamp.sec)
                    + f64::from(odometry.header.stamp.nanosec) * 1e-9;
                received.push((stamp, now));
            }
            _ => {
                if child.try_wait().unwrap().is_some() {
                    break;
                }
            }
        }
    }
    let output = child.wait_with_output().unwrap();
    assert!(output.status.success(), "the daemon failed");
    let summary = String::from_utf8_lossy(&output.stdout);
    let poses = pose_times(&out.join("trajectory.tum"));
    let rotations = rotation_times(&out.join("diagnostics.csv"));
    let mut from_last_azimuth = Vec::new();
    let mut from_stamp = Vec::new();
    for (stamp, now) in &received {
        from_stamp.push((now - stamp) * 1e3);
        let Some(i) = poses.iter().position(|t| (t - stamp).abs() < 2e-6) else {
            continue;
        };
        if let Some(last_azimuth) = rotations.get(i) {
            from_last_azimuth.push((now - last_azimuth) * 1e3);
        }
    }
    from_last_azimuth.sort_by(f64::total_cmp);
    from_stamp.sort_by(f64::total_cmp);
    println!(
        "{preset}, odometry at {odometry_hz} Hz: {} poses received of {} written ({} rotations)",
        received.len(),
        poses.len(),
        rotations.len()
    );
    for (name, v) in [
        ("from the rotation's last azimuth", &from_last_azimuth),
        ("from the pose's own stamp (the filter's time)", &from_stamp),
    ] {
        println!(
            "  {name}: p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms, min {:.2} ms (n = {})",
            quantile(v, 0.5),
            quantile(v, 0.99),
            v.last().copied().unwrap_or(f64::NAN),
            v.first().copied().unwrap_or(f64::NAN),
            v.len()
        );
    }
    for line in summary
        .lines()
        .filter(|l| l.contains("Zenoh:") || l.contains("per rotation") || l.contains("real-time"))
    {
        println!("  daemon: {}", line.trim());
    }
}

/// The same path without the SLAM: `radar-zenoh` against the simulator (paper unit, real
/// time, in this process), receipt of each B-scan minus its stamp (its last azimuth's time).
fn radar_only(seconds: f64) {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let sim = runtime.block_on(async {
        let scene = sim_sensor::scene::shipped::load("outdoor-field").unwrap();
        let mut options = sim_sensor::SimOptions::for_tests(scene);
        options.odometry_bind = None;
        options.pacing = sim_sensor::settings::Pacing::Realtime;
        options.start_time_ns = None;
        sim_sensor::SimServer::spawn(options).await.unwrap()
    });
    let (session, endpoint) = subscriber_session();
    let subscriber = session
        .declare_subscriber("radar_data/b_scan_msg")
        .wait()
        .unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_radar-zenoh"))
        .args([
            "--address",
            &sim.local_addr().to_string(),
            "--connect",
            &endpoint,
        ])
        .arg("--duration-s")
        .arg(seconds.to_string())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut latency = Vec::new();
    loop {
        match subscriber.recv_timeout(Duration::from_millis(200)) {
            Ok(Some(sample)) => {
                let now = SystemTime::now()
                    .duration_since(UNIX_EPOCH)
                    .unwrap()
                    .as_secs_f64();
                let scan: ros_msgs::navtech::RadarBScanMsg =
                    from_cdr(&sample.payload().to_bytes()).unwrap();
                let stamp = scan.b_scan_img.header.stamp;
                latency.push((now - f64::from(stamp.sec) - f64::from(stamp.nanosec) * 1e-9) * 1e3);
            }
            _ => {
                if child.try_wait().unwrap().is_some() {
                    break;
                }
            }
        }
    }
    runtime.block_on(sim.shutdown()).unwrap();
    latency.sort_by(f64::total_cmp);
    println!(
        "radar-zenoh (no SLAM), paper-200: B-scan receipt minus its last azimuth: p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms, min {:.2} ms (n = {})",
        quantile(&latency, 0.5),
        quantile(&latency, 0.99),
        latency.last().copied().unwrap_or(f64::NAN),
        latency.first().copied().unwrap_or(f64::NAN),
        latency.len()
    );
}

fn main() {
    // `cargo bench` passes `--bench`; any other argument filters nothing here.
    let seconds: f64 = std::env::var("SLAM_LATENCY_S")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20.0);
    // The shipped simulator's odometry comes at 20 Hz; 200 Hz shortens any wait for it.
    for (preset, odometry_hz) in [
        ("paper-200", 20.0),
        ("cts350x-400", 20.0),
        ("paper-200", 200.0),
        ("cts350x-400", 200.0),
    ] {
        run(preset, odometry_hz, seconds);
    }
    radar_only(seconds);
}
