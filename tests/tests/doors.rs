//! Every door gives the same answer: the Oxford scans in `../shared` with the same odometry
//! samples through `slam-node --replay-dir` (the simulator in this process, odometry from
//! memory), through the simulator's replay over TCP into a vehicle configuration of two keys
//! (the radar's address, an odometry file), and through an MCAP recording of that run, give
//! the same trajectory. Each door chooses the radar's profile from what the radar announces;
//! the replay's map frame is the ground truth's, the others' the first odometry sample's, so
//! the poses are compared relative to each run's first.
//!
//! Skipped with a message when the scans are absent.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use e2e_tests::{oxford_dir, test_options as options};
use radar_model::geometry::{wrap_angle, Pose2};
use sim_sensor::settings::Pacing;
use sim_sensor::{SimOptions, SimServer, SourceSpec};
use slam_node::daemon::replay::OdometryErrors;
use slam_node::daemon::{run_daemon, run_mcap_replay, EmbeddedSim, RecordedReplay, Simulator};

/// A TUM trajectory's poses (x, y, heading), in time order.
fn read_tum(path: &Path) -> Vec<(f64, Pose2)> {
    let text = std::fs::read_to_string(path).expect("the trajectory");
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let f: Vec<f64> = l
                .split_whitespace()
                .map(|v| v.parse().expect("a number"))
                .collect();
            let theta = 2.0 * f[6].atan2(f[7]);
            (f[0], Pose2::new(f[1], f[2], wrap_angle(theta)))
        })
        .collect()
}

/// Each pose relative to the first (in the first's frame).
fn relative(poses: &[(f64, Pose2)]) -> Vec<(f64, Pose2)> {
    let Some(&(_, first)) = poses.first() else {
        return Vec::new();
    };
    poses.iter().map(|&(t, p)| (t, first.between(&p))).collect()
}

/// The largest difference in position (m) and heading (rad) between two runs' poses
/// relative to their first, matched by time.
fn largest_difference(a: &[(f64, Pose2)], b: &[(f64, Pose2)]) -> (f64, f64) {
    assert_eq!(a.len(), b.len(), "the same poses");
    let (ra, rb) = (relative(a), relative(b));
    let mut worst = (0.0f64, 0.0f64);
    for ((ta, pa), (tb, pb)) in ra.iter().zip(&rb) {
        assert!((ta - tb).abs() < 1e-6, "the same times: {ta} {tb}");
        worst.0 = worst.0.max((pa.x - pb.x).hypot(pa.y - pb.y));
        worst.1 = worst.1.max(wrap_angle(pa.theta - pb.theta).abs());
    }
    worst
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_replay_the_vehicle_configuration_and_its_mcap_recording_agree() {
    let Some(dir) = oxford_dir() else {
        return;
    };
    let work = tempfile::tempdir().expect("a folder");
    let odometry = work.path().join("odometry.txt");

    // Door 1: --replay-dir, no configuration file, odometry 5 % fast and +0.02 rad/s.
    let out_replay = work.path().join("replay");
    let mut sim = SimOptions::for_tests(sim_sensor::scene::shipped::load("outdoor-field").unwrap());
    sim.pacing = Pacing::AsFastAsPossible;
    let mut opts = options(config::Config::default(), None, &out_replay);
    // As the command line without a file: slam-node's measured default detector.
    opts.detector = Some(slam_node::detect::DetectorSettings::default());
    opts.simulator = Some(Simulator {
        sim: EmbeddedSim::new(sim),
        recorded: Some(RecordedReplay {
            dir: dir.clone(),
            format: None,
            errors: OdometryErrors {
                speed_scale: 1.05,
                yaw_rate_bias_rps: 0.02,
                ..OdometryErrors::default()
            },
            radar_odometry: true,
            write_odometry: Some(odometry.clone()),
            radar_only: false,
            gyro_from_truth: None,
        }),
    });
    let replay = run_daemon(opts, None).await.expect("the replay runs");
    assert_eq!(replay.run.summary.rotations, 8);

    // Door 2: the simulator's replay over TCP, a vehicle configuration of two keys and the
    // odometry file, recorded as MCAP.
    let server = SimOptions {
        odometry_bind: None,
        gyro_bind: None,
        ..SimOptions::for_tests_from(SourceSpec::PolarScans {
            dir: dir.clone(),
            format: None,
        })
    };
    let handle = SimServer::spawn(server).await.expect("the simulator");
    let text = format!(
        "[radar]\naddress = \"{}\"\n[odometry]\nsource = \"file\"\npath = \"{}\"\nmotion_model = \"bicycle\"\nwheelbase_m = 2.7\n",
        handle.local_addr(),
        odometry.display()
    );
    let mut config = config::Config::from_toml_str(&text).expect("the vehicle configuration");
    config.output.mcap = Some(PathBuf::from("run.mcap"));
    let out_vehicle = work.path().join("vehicle");
    let opts = options(config.clone(), Some(&text), &out_vehicle);
    // A live radar never ends: stop once its eight rotations have come (the last completes
    // when the run finishes).
    let stop = Arc::clone(&opts.stop);
    let seen = Arc::new(AtomicBool::new(false));
    let seen_in = Arc::clone(&seen);
    let progress: slam_node::pipeline::run::ProgressFn = Box::new(move |s, _| {
        if s.rotations >= 7 {
            seen_in.store(true, Ordering::Relaxed);
        }
    });
    let run = tokio::spawn(run_daemon(opts, Some(progress)));
    let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
    while !seen.load(Ordering::Relaxed) && tokio::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    tokio::time::sleep(Duration::from_secs(1)).await;
    stop.store(true, Ordering::Relaxed);
    let vehicle = run.await.expect("joined").expect("the vehicle door runs");
    handle.shutdown().await.expect("the simulator stops");
    assert_eq!(vehicle.run.summary.rotations, 8);

    // Door 3: the MCAP recording of door 2.
    let out_mcap = work.path().join("mcap");

    config.output.mcap = None;
    let opts = options(config, Some(&text), &out_mcap);
    let recording = out_vehicle.join("run.mcap");
    let mcap = tokio::task::spawn_blocking(move || run_mcap_replay(opts, recording, None, None))
        .await
        .expect("joined")
        .expect("the MCAP replay runs");
    assert_eq!(mcap.run.summary.rotations, 8);

    let a = read_tum(&out_replay.join("trajectory.tum"));
    let b = read_tum(&out_vehicle.join("trajectory.tum"));
    let c = read_tum(&out_mcap.join("trajectory.tum"));
    assert_eq!(a.len(), 8, "a pose a rotation");
    // The TUM files hold micrometres and nano-radians of quaternion: equal to their digits
    // (two files' rounding, carried through the pose relative to the first).
    let (ab_m, ab_rad) = largest_difference(&a, &b);
    let (bc_m, bc_rad) = largest_difference(&b, &c);
    println!("replay vs vehicle: {ab_m:.2e} m, {ab_rad:.2e} rad; vehicle vs MCAP: {bc_m:.2e} m, {bc_rad:.2e} rad");
    assert!(ab_m < 3e-6 && ab_rad < 1e-7, "{ab_m} m {ab_rad} rad");
    assert!(bc_m < 3e-6 && bc_rad < 1e-7, "{bc_m} m {bc_rad} rad");
}
