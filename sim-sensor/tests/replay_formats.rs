//! The Boreas and RADIATE layouts, on small synthetic folders laid out as the real data sets
//! are (no such data is on this machine): geometry announced from the data, every row's
//! time, encoder and bins over loopback, the ground truth's poses, and bad input, each
//! refused by name at open, or, for a damaged scan in the middle, skipped at the cost of
//! that scan only.

mod common;

use std::path::Path;
use std::time::Duration;

use common::TestClient;
use protocol::Message;
use radar_model::geometry::Pose2;
use sim_sensor::replay::boreas::{boreas_poses, read_radar_poses};
use sim_sensor::replay::radiate::radiate_poses;
use sim_sensor::replay::synthetic::{write_gray_png, SyntheticDrive};
use sim_sensor::replay::truth::{between, TruthError};
use sim_sensor::replay::{ReplayFormat, ScanRecording, ScanSet};
use sim_sensor::scene::shipped;
use sim_sensor::{ReplayError, SimOptions, SimServer, SourceSpec};

/// Bins in the synthetic scans: few, so the tests stay fast.
const BINS: u16 = 300;

fn boreas() -> (tempfile::TempDir, SyntheticDrive) {
    let dir = tempfile::tempdir().unwrap();
    let drive = SyntheticDrive::new(BINS, 0.0596);
    drive.write_boreas(dir.path()).unwrap();
    (dir, drive)
}

fn radiate() -> (tempfile::TempDir, SyntheticDrive) {
    let dir = tempfile::tempdir().unwrap();
    let drive = SyntheticDrive::new(576, 0.173611);
    drive.write_radiate(dir.path()).unwrap();
    (dir, drive)
}

/// Serves `dir` and checks every azimuth of the scans `served` (indices into the drive)
/// against the drive, then that the stream ends; returns the server's skipped-scan count.
async fn serve_and_check(dir: &Path, drive: &SyntheticDrive, served: &[usize]) -> u64 {
    let mut options = SimOptions::for_tests(shipped::load("penetration-wood").unwrap());
    options.source = SourceSpec::PolarScans {
        dir: dir.to_path_buf(),
        format: None,
    };
    let handle = SimServer::spawn(options).await.expect("spawn");
    let mut client = TestClient::connect(handle.local_addr()).await;
    let _ = client.configuration().await;
    client.send(Message::StartFftData).await;
    for &k in served {
        for a in 0..drive.azimuths {
            let fft = client.next_fft().await;
            let us = i64::from(fft.timestamp.seconds()) * 1_000_000
                + i64::from(fft.timestamp.nanos()) / 1000;
            assert_eq!(us, drive.azimuth_time_us(k, a), "scan {k} azimuth {a} time");
            assert_eq!(fft.azimuth, a * 14, "scan {k} azimuth {a} encoder");
            assert_eq!(
                fft.bins.as_ref(),
                drive.azimuth_bins(k, a).as_slice(),
                "scan {k} azimuth {a} bins"
            );
        }
    }
    assert!(
        !matches!(
            client.next_within(Duration::from_millis(300)).await,
            Some(Message::FftData(_))
        ),
        "the replay ends after the last scan"
    );
    let skipped = handle.stats().scans_skipped;
    handle.shutdown().await.expect("shutdown");
    skipped
}

#[test]
fn a_boreas_folder_is_detected_and_announces_its_own_geometry() {
    let (dir, drive) = boreas();
    let rec = ScanRecording::open(dir.path(), None).unwrap();
    assert_eq!(rec.scans.format, ReplayFormat::Boreas);
    assert_eq!(rec.scans.files.len(), drive.scans);
    let g = rec.geometry;
    assert_eq!((g.azimuths, g.bins, g.rotation_mhz), (400, BINS, 4000));
    assert!((g.bin_size_m - 0.0596).abs() < 1e-12);
    let c = rec.configuration();
    assert_eq!(
        (c.bin_size, c.range_in_bins, c.encoder_size),
        (596, BINS, 5600)
    );
    assert_eq!(rec.scans.times_us()[1], drive.boreas_scan_time_us(1));
}

#[test]
fn a_radiate_folder_is_detected_and_announces_its_own_geometry() {
    let (dir, drive) = radiate();
    let rec = ScanRecording::open(dir.path(), None).unwrap();
    assert_eq!(rec.scans.format, ReplayFormat::Radiate);
    let g = rec.geometry;
    assert_eq!((g.azimuths, g.bins, g.rotation_mhz), (400, 576, 4000));
    assert_eq!(rec.configuration().bin_size, 1736);
    assert!((g.max_range_m() - 100.0).abs() < 0.01);
    // Column a: its angle a * 0.9 degrees (encoder 14 a), its time spread over the scan.
    let scan = rec.read(2).unwrap();
    assert_eq!(scan.rows[100].encoder, 1400);
    assert_eq!(scan.rows[100].timestamp_us, drive.azimuth_time_us(2, 100));
    assert_eq!(scan.rows[100].bins, drive.azimuth_bins(2, 100));
}

#[tokio::test]
async fn boreas_scans_replay_with_their_recorded_times_encoders_and_bins() {
    let (dir, drive) = boreas();
    let all: Vec<usize> = (0..drive.scans).collect();
    assert_eq!(serve_and_check(dir.path(), &drive, &all).await, 0);
}

#[tokio::test]
async fn radiate_scans_replay_transposed_with_interpolated_times() {
    let (dir, drive) = radiate();
    let all: Vec<usize> = (0..drive.scans).collect();
    assert_eq!(serve_and_check(dir.path(), &drive, &all).await, 0);
}

#[tokio::test]
async fn a_damaged_scan_in_the_middle_costs_that_scan_only() {
    let (dir, drive) = boreas();
    let files = ScanSet::open(dir.path(), None).unwrap().files;
    // Scan 2 does not decode; scan 4 has the wrong shape (fewer bins).
    std::fs::write(&files[2].path, b"\x89PNG\r\n\x1a\n not a png").unwrap();
    write_gray_png(&files[4].path, 11 + 10, 400, &[0u8; 21 * 400]).unwrap();
    let skipped = serve_and_check(dir.path(), &drive, &[0, 1, 3, 5]).await;
    assert_eq!(skipped, 2);

    let (dir, drive) = radiate();
    let files = ScanSet::open(dir.path(), None).unwrap().files;
    write_gray_png(&files[1].path, 399, 576, &vec![0u8; 399 * 576]).unwrap();
    let skipped = serve_and_check(dir.path(), &drive, &[0, 2, 3, 4, 5]).await;
    assert_eq!(skipped, 1);
}

fn close(a: &Pose2, b: &Pose2, m: f64, rad: f64) -> bool {
    (a.x - b.x).abs() < m && (a.y - b.y).abs() < m && (a.theta - b.theta).abs() < rad
}

#[test]
fn boreas_ground_truth_gives_each_scan_its_pose_in_the_first_scans_frame() {
    let (dir, drive) = boreas();
    let scans = ScanSet::open(dir.path(), None).unwrap();
    let csv = dir.path().join("applanix/radar_poses.csv");
    let poses = boreas_poses(&csv, &read_radar_poses(&csv).unwrap(), &scans.times_us()).unwrap();
    let first = drive.pose_at(drive.boreas_scan_time_us(0));
    for (k, p) in poses.iter().enumerate() {
        let want = between(&first, &drive.pose_at(drive.boreas_scan_time_us(k)));
        assert!(
            close(p, &want, 1e-5, 1e-9),
            "scan {k}: {p:?} against {want:?}"
        );
    }
    // Driving forward at 8 m/s: 2 m ahead per scan, turning left.
    assert!(poses[1].x > 1.9 && poses[1].y > 0.0 && poses[1].theta > 0.0);
}

#[test]
fn radiate_ground_truth_follows_the_gps_fixes_and_the_course_over_ground() {
    let (dir, drive) = radiate();
    let scans = ScanSet::open(dir.path(), None).unwrap();
    let poses = radiate_poses(dir.path(), &scans.times_us()).unwrap();
    let first = drive.pose_at(drive.radiate_scan_time_us(0));
    for (k, p) in poses.iter().enumerate() {
        let want = between(&first, &drive.pose_at(drive.radiate_scan_time_us(k)));
        // Linear interpolation between 20 Hz fixes on a 80 m radius arc.
        assert!(
            close(p, &want, 0.01, 1e-3),
            "scan {k}: {p:?} against {want:?}"
        );
    }
}

#[test]
fn a_folder_without_scans_or_with_a_scan_named_otherwise_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("radar")).unwrap();
    std::fs::create_dir_all(dir.path().join("applanix")).unwrap();
    std::fs::write(dir.path().join("applanix/radar_poses.csv"), "GPSTime\n").unwrap();
    let err = ScanSet::open(dir.path(), None).unwrap_err();
    assert!(matches!(err, ReplayError::Empty(_)), "{err}");
    assert!(err.to_string().contains("radar"), "{err}");
    // Two names for the same time: out of order, naming both files (issue 38: the
    // earlier one was not named).
    std::fs::write(dir.path().join("radar/1000000.png"), b"").unwrap();
    std::fs::write(dir.path().join("radar/01000000.png"), b"").unwrap();
    let err = ScanSet::open(dir.path(), None).unwrap_err();
    let text = err.to_string();
    assert!(
        matches!(err, ReplayError::OutOfOrder { row: None, .. })
            && text.contains("radar/1000000.png")
            && text.contains("radar/01000000.png"),
        "{err}"
    );
    std::fs::write(dir.path().join("radar/first.png"), b"").unwrap();
    let err = ScanSet::open(dir.path(), None).unwrap_err();
    assert!(err.to_string().contains("first.png"), "{err}");
    // A RADIATE index without rows.
    let radiate = tempfile::tempdir().unwrap();
    std::fs::write(radiate.path().join("Navtech_Polar.txt"), "\n").unwrap();
    let err = ScanSet::open(radiate.path(), None).unwrap_err();
    assert!(
        matches!(err, ReplayError::Empty(_)) && err.to_string().contains("Navtech_Polar"),
        "{err}"
    );
    let err = ScanSet::open(&dir.path().join("nothing"), Some(ReplayFormat::Radiate)).unwrap_err();
    assert!(err.to_string().contains("Navtech_Polar.txt"), "{err}");
}

#[test]
fn a_first_scan_of_the_wrong_shape_is_refused_naming_the_file() {
    let (dir, _) = boreas();
    let files = ScanSet::open(dir.path(), None).unwrap().files;
    // 11 columns: metadata and no bins.
    write_gray_png(&files[0].path, 11, 400, &[0u8; 11 * 400]).unwrap();
    let err = ScanRecording::open(dir.path(), None).unwrap_err();
    assert!(matches!(err, ReplayError::Layout { .. }), "{err}");
    assert!(
        err.to_string().contains(
            &files[0]
                .path
                .file_name()
                .unwrap()
                .to_string_lossy()
                .to_string()
        ),
        "{err}"
    );
}

#[test]
fn radiate_scan_index_rows_that_are_malformed_missing_or_out_of_order_are_named() {
    let (dir, _) = radiate();
    let index = dir.path().join("Navtech_Polar.txt");
    let good = std::fs::read_to_string(&index).unwrap();
    let lines: Vec<&str> = good.lines().collect();
    std::fs::write(
        &index,
        format!("{}\n{}\nFrame 3 at noon\n", lines[0], lines[1]),
    )
    .unwrap();
    let err = ScanSet::open(dir.path(), None).unwrap_err();
    assert!(
        matches!(err, ReplayError::IndexRow { row: 3, .. })
            && err.to_string().contains("Navtech_Polar.txt"),
        "{err}"
    );
    std::fs::write(&index, format!("{}\n{}\n", lines[1], lines[0])).unwrap();
    let err = ScanSet::open(dir.path(), None).unwrap_err();
    assert!(
        matches!(err, ReplayError::OutOfOrder { row: Some(2), .. }),
        "{err}"
    );
    assert!(err.to_string().contains("row 2"), "{err}");
    std::fs::write(
        &index,
        format!("{}\nFrame: 000099 Time: 1600000002.0\n", lines[0]),
    )
    .unwrap();
    let err = ScanSet::open(dir.path(), None).unwrap_err();
    assert!(
        err.to_string().contains("000099.png") && err.to_string().contains("row 2"),
        "{err}"
    );
}

#[test]
fn boreas_ground_truth_rows_missing_or_out_of_order_are_named() {
    let (dir, _) = boreas();
    let scans = ScanSet::open(dir.path(), None).unwrap();
    let csv = dir.path().join("applanix/radar_poses.csv");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    let gone = lines.remove(3); // scan 2's row
    std::fs::write(&csv, lines.join("\n")).unwrap();
    let err = boreas_poses(&csv, &read_radar_poses(&csv).unwrap(), &scans.times_us()).unwrap_err();
    assert!(matches!(err, TruthError::NoPose { .. }), "{err}");
    assert!(
        err.to_string().contains(&scans.times_us()[2].to_string())
            && err.to_string().contains("radar_poses.csv"),
        "{err}"
    );
    lines.insert(2, gone);
    std::fs::write(&csv, lines.join("\n")).unwrap();
    let err = read_radar_poses(&csv).unwrap_err();
    assert!(
        matches!(err, TruthError::OutOfOrder { row: 4, .. }),
        "{err}"
    );
}

#[test]
fn radiate_ground_truth_out_of_order_missing_or_too_short_is_named() {
    let (dir, _) = radiate();
    let times = ScanSet::open(dir.path(), None).unwrap().times_us();
    let index = dir.path().join("GPS_IMU_Twist.txt");
    let good = std::fs::read_to_string(&index).unwrap();
    let lines: Vec<&str> = good.lines().collect();
    // A time going back, as in radiate_sdk's own sample fog_6_0 at row 29.
    let mut back = lines.clone();
    back.swap(20, 24);
    std::fs::write(&index, back.join("\n")).unwrap();
    let err = radiate_poses(dir.path(), &times).unwrap_err();
    assert!(
        matches!(err, TruthError::OutOfOrder { row: 22, .. })
            && err.to_string().contains("GPS_IMU_Twist.txt"),
        "{err}"
    );
    // The fixes end before the last scan.
    std::fs::write(&index, lines[..40].join("\n")).unwrap();
    let err = radiate_poses(dir.path(), &times).unwrap_err();
    assert!(matches!(err, TruthError::NoPose { .. }), "{err}");
    // A fix file that is not there, and one cut short.
    std::fs::write(&index, good).unwrap();
    let fix = dir.path().join("GPS_IMU_Twist/000030.txt");
    std::fs::remove_file(&fix).unwrap();
    let err = radiate_poses(dir.path(), &times).unwrap_err();
    assert!(err.to_string().contains("000030.txt"), "{err}");
    std::fs::write(&fix, "55.9,-3.3,60\n").unwrap();
    let err = radiate_poses(dir.path(), &times).unwrap_err();
    assert!(
        err.to_string().contains("000030.txt") && err.to_string().contains("row 17"),
        "{err}"
    );
}
