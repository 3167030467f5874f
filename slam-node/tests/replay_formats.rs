//! Boreas and RADIATE folders through the real path: small synthetic folders laid out as the
//! real data sets are (no such data is on this machine) replayed by the daemon binary (the
//! simulator's replay over TCP, the radar driver, the daemon) to its summary; their ground
//! truth read into the replay's trajectory; the layout chosen, detected, or refused.

use std::path::Path;
use std::process::{Command, Output};

use sim_sensor::replay::synthetic::SyntheticDrive;
use sim_sensor::replay::ScanSet;
use slam_node::daemon::replay::{OdometryErrors, RecordedTruth};
use slam_node::pipeline::TruthOracle;

fn boreas() -> (tempfile::TempDir, SyntheticDrive) {
    let dir = tempfile::tempdir().unwrap();
    let drive = SyntheticDrive::new(400, 0.0596);
    drive.write_boreas(dir.path()).unwrap();
    (dir, drive)
}

fn radiate() -> (tempfile::TempDir, SyntheticDrive) {
    let dir = tempfile::tempdir().unwrap();
    let drive = SyntheticDrive::new(576, 0.173611);
    drive.write_radiate(dir.path()).unwrap();
    (dir, drive)
}

fn replay(dir: &Path, extra: &[&str]) -> (Output, String, String) {
    let out = tempfile::tempdir().unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_slam-node"))
        .args([
            "--replay-dir",
            dir.to_str().unwrap(),
            "--fast",
            "--no-figures",
        ])
        .args([
            "--out",
            out.path().to_str().unwrap(),
            "--progress-every",
            "0",
        ])
        .args(extra)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout).to_string();
    let stderr = String::from_utf8_lossy(&run.stderr).to_string();
    (run, stdout, stderr)
}

fn assert_summary(stdout: &str, stderr: &str, expected: &[&str]) {
    for e in expected {
        assert!(
            stdout.contains(e),
            "{e:?} missing from\n{stdout}\nstderr:\n{stderr}"
        );
    }
}

#[test]
fn synthetic_boreas_and_radiate_folders_replay_through_the_daemon_to_a_summary() {
    for (name, (dir, _drive)) in [("boreas", boreas()), ("radiate", radiate())] {
        let (run, stdout, stderr) = replay(dir.path(), &[]);
        assert!(run.status.success(), "{name}: {stdout}\n{stderr}");
        println!("{stdout}");
        assert_summary(
            &stdout,
            &stderr,
            &[
                &format!("recorded {name} scans in"),
                &format!("recorded drive ({name}, 6 scans, 0 skipped as damaged): 10.0 m"),
                "azimuths 2400 (0 malformed)",
                "against the ground truth: filter RMS",
                "dead reckoning with the same odometry RMS",
                "per 100 m driven",
                "real-time factor",
            ],
        );
    }
}

#[test]
fn a_damaged_scan_in_the_middle_of_a_replay_is_skipped_and_counted() {
    let (dir, _) = boreas();
    let files = ScanSet::open(dir.path(), None).unwrap().files;
    std::fs::write(&files[3].path, b"\x89PNG\r\n\x1a\n cut short").unwrap();
    let (run, stdout, stderr) = replay(dir.path(), &[]);
    assert!(run.status.success(), "{stdout}\n{stderr}");
    assert_summary(
        &stdout,
        &stderr,
        &[
            "(boreas, 6 scans, 1 skipped as damaged)",
            "azimuths 2000 (0 malformed)",
        ],
    );
    let name = files[3]
        .path
        .file_name()
        .unwrap()
        .to_string_lossy()
        .to_string();
    assert!(
        stderr.contains("skipping a damaged scan") && stderr.contains(&name),
        "{stderr}"
    );
}

#[test]
fn the_layout_is_detected_chosen_or_refused_by_name() {
    let (dir, _) = radiate();
    // An Oxford marker as well: ambiguous unless the layout is named.
    std::fs::write(dir.path().join("radar_odometry.csv"), "header\n").unwrap();
    let (run, stdout, stderr) = replay(dir.path(), &[]);
    assert_eq!(run.status.code(), Some(1), "{stdout}\n{stderr}");
    assert!(
        stderr.contains("ambiguous") && stderr.contains("oxford") && stderr.contains("radiate"),
        "{stderr}"
    );
    let (run, stdout, stderr) = replay(dir.path(), &["--replay-format", "radiate"]);
    assert!(run.status.success(), "{stdout}\n{stderr}");
    assert!(stdout.contains("recorded radiate scans"), "{stdout}");
    let empty = tempfile::tempdir().unwrap();
    let (run, _, stderr) = replay(empty.path(), &[]);
    assert_eq!(run.status.code(), Some(1));
    assert!(
        stderr.contains("not a recording of a known layout"),
        "{stderr}"
    );
    let (run, _, stderr) = replay(empty.path(), &["--replay-format", "kitti"]);
    assert_eq!(run.status.code(), Some(2));
    assert!(stderr.contains("--replay-format"), "{stderr}");
}

#[test]
fn boreas_and_radiate_ground_truth_drive_the_same_arc_and_dead_reckoning_follows_it() {
    let exact = OdometryErrors {
        sigma_speed_mps: 0.0,
        sigma_yaw_rate_rps: 0.0,
        ..OdometryErrors::default()
    };
    for (name, (dir, drive)) in [("boreas", boreas()), ("radiate", radiate())] {
        let truth = RecordedTruth::read(&ScanSet::open(dir.path(), None).unwrap()).unwrap();
        assert_eq!(truth.times_s().len(), 6, "{name}");
        // Five 0.25 s steps at 8 m/s on a 80 m radius: 10 m of chords.
        assert!(
            (truth.distance_m() - 10.0).abs() < 0.01,
            "{name}: {}",
            truth.distance_m()
        );
        let last = truth.poses().last().copied().unwrap();
        assert!((last.theta - 0.125).abs() < 2e-3, "{name}: {last:?}");
        let errors = truth.dead_reckoning_errors(&truth.odometry(&exact));
        assert!(
            errors.iter().all(|e| *e < 0.05),
            "{name}: dead reckoning with exact odometry {errors:?}"
        );
        let mid = truth.pose_at(truth.times_s()[2] + 0.125).unwrap();
        assert!(
            mid.x > 0.0 && (drive.speed_mps - 8.0).abs() < 1e-12,
            "{name}"
        );
    }
}

/// `--config` with `--replay-dir` replays the folder with the configuration's settings (it
/// used to dial the configuration's radar address and wait for ever): the shipped example
/// that estimates the odometry's scale and steering offset runs to a summary that reports
/// them, in bounded time.
#[test]
fn a_configuration_given_with_a_replay_folder_is_used_and_the_replay_still_runs() {
    let (dir, _drive) = boreas();
    let out = tempfile::tempdir().unwrap();
    let config =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../config/examples/replay-odometry-bias.toml");
    let mut child = Command::new(env!("CARGO_BIN_EXE_slam-node"))
        .arg("--config")
        .arg(&config)
        .arg("--replay-dir")
        .arg(dir.path())
        .args(["--fast", "--no-figures", "--progress-every", "0", "--out"])
        .arg(out.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if std::time::Instant::now() > deadline {
            child.kill().unwrap();
            panic!("slam-node --config --replay-dir did not finish within 60 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let run = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout).to_string();
    let stderr = String::from_utf8_lossy(&run.stderr).to_string();
    assert!(run.status.success(), "{stdout}\n{stderr}");
    assert_summary(
        &stdout,
        &stderr,
        &[
            "recorded drive (boreas",
            "odometry corrections estimated: speed x ",
        ],
    );
}

/// Rewrites every scan of a Boreas folder with `offset` added to each row's encoder value.
fn shift_encoders(dir: &Path, offset: u16) {
    for file in ScanSet::open(dir, None).unwrap().files {
        let scan = sim_sensor::replay::png::read_polar_png(&file.path).unwrap();
        let width = sim_sensor::replay::png::META_COLUMNS + scan.bins;
        let mut data = Vec::with_capacity(width * scan.rows.len());
        for row in &scan.rows {
            data.extend_from_slice(&row.timestamp_us.to_le_bytes());
            data.extend_from_slice(&row.encoder.wrapping_add(offset).to_le_bytes());
            data.push(0);
            data.extend_from_slice(&row.bins);
        }
        sim_sensor::replay::synthetic::write_gray_png(&file.path, width, scan.rows.len(), &data)
            .unwrap();
    }
}

/// Issue 38 item 9: every row past the encoder size. Before: every azimuth dropped by the
/// driver, the run waited 30 s for a first azimuth and exited 0 with nothing naming the
/// encoders. Now each scan is skipped as damaged with a WARN naming its encoder values
/// and the encoder size, the run ends once the recording has played out, and exits 1
/// saying so.
#[test]
fn a_recording_whose_encoder_values_are_all_past_the_encoder_size_ends_and_names_them() {
    let (dir, _) = boreas();
    shift_encoders(dir.path(), 5600);
    let out = tempfile::tempdir().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_slam-node"))
        .args([
            "--replay-dir",
            dir.path().to_str().unwrap(),
            "--fast",
            "--no-figures",
        ])
        .args([
            "--out",
            out.path().to_str().unwrap(),
            "--progress-every",
            "0",
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if start.elapsed() > std::time::Duration::from_secs(20) {
            child.kill().unwrap();
            break None;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    let run = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    let stderr = String::from_utf8_lossy(&run.stderr);
    let status = status.unwrap_or_else(|| panic!("the replay did not end in 20 s\n{stderr}"));
    assert!(start.elapsed().as_secs_f64() < 15.0, "{stderr}");
    assert_eq!(status.code(), Some(1), "{stdout}\n{stderr}");
    for expected in [
        "400 of 400 azimuths carry encoder values from 5600 to 11186",
        "at or past the encoder size 5600",
        "no azimuth of the recording reached the pipeline; 6 of its 6 scans skipped as damaged",
        "the recording has played out",
    ] {
        assert!(
            stderr.contains(expected),
            "{expected:?} missing from\n{stderr}"
        );
    }
}
