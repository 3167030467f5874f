//! Hostile replay folders (issue 38, items 2, 5 and 6): scans and ground-truth files that are
//! FIFOs or symlinks to `/dev/zero`, a valid scan padded past its byte limit, and ground
//! truth spanning centuries. Each is refused by name, at once: nothing blocks, nothing reads
//! without end, nothing is allocated from the file's size or the truth's span.
//!
//! A FIFO's read runs on a thread the test waits for at most [`BLOCKED_AFTER`]: a reader
//! that blocks fails the test (and is released by opening the FIFO's other end) rather than
//! hanging it.

#![cfg(unix)]

use std::path::Path;
use std::time::{Duration, Instant};

use sim_sensor::replay::boreas::{boreas_poses, read_radar_poses};
use sim_sensor::replay::files::{
    not_a_regular_file, FileKind, MAX_GPS_RECORD_BYTES, MAX_SCAN_BYTES, MAX_TRUTH_BYTES,
};
use sim_sensor::replay::png::read_polar_png;
use sim_sensor::replay::radiate::{radiate_poses, read_gps_fix, read_gps_index, read_radiate_png};
use sim_sensor::replay::scans::ScanFile;
use sim_sensor::replay::synthetic::write_gray_png;
use sim_sensor::replay::truth::{chain_pose_times, read_oxford_odometry, TruthError, MAX_SPAN_US};
use sim_sensor::replay::{ReplayFormat, ScanRecording, ScanSet};
use sim_sensor::ReplayError;

/// How long a read may take before it counts as blocked.
const BLOCKED_AFTER: Duration = Duration::from_secs(3);

const ODOMETRY_HEADER: &str = "source_timestamp,destination_timestamp,x,y,z,roll,pitch,yaw,source_radar_timestamp,destination_radar_timestamp\n";

/// A scan 10 ms after `us`: 2 azimuths of 4 bins, named by its time.
fn write_scan(path: &Path, us: i64) {
    let mut data = Vec::new();
    for row in 0..2i64 {
        data.extend_from_slice(&(us + row * 625).to_le_bytes());
        data.extend_from_slice(&(row as u16 * 2800).to_le_bytes());
        data.push(255);
        data.extend_from_slice(&[1, 2, 3, 4]);
    }
    write_gray_png(path, 15, 2, &data).unwrap();
}

/// An Oxford folder: valid scans at `scans` (µs) in `radar/` and a `radar_odometry.csv`
/// linking each to the next, 2 m ahead, the poses 125 ms after the scans' names.
fn oxford(scans: &[i64]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("radar")).unwrap();
    let mut csv = String::from(ODOMETRY_HEADER);
    for &us in scans {
        write_scan(&dir.path().join("radar").join(format!("{us}.png")), us);
    }
    for w in scans.windows(2) {
        csv.push_str(&format!(
            "{},{},2.0,0,0,0,0,0,{},{}\n",
            w[1] + 125_000,
            w[0] + 125_000,
            w[1],
            w[0]
        ));
    }
    std::fs::write(dir.path().join("radar_odometry.csv"), csv).unwrap();
    dir
}

/// Makes a FIFO at `path` (replacing what is there); `false`, with a message, when
/// `mkfifo` is not available.
fn mkfifo(path: &Path) -> bool {
    let _ = std::fs::remove_file(path);
    match std::process::Command::new("mkfifo").arg(path).status() {
        Ok(s) if s.success() => true,
        outcome => {
            println!("SKIPPED: mkfifo {} failed: {outcome:?}", path.display());
            false
        }
    }
}

/// Replaces `path` by a symlink to `/dev/zero`.
fn dev_zero(path: &Path) {
    let _ = std::fs::remove_file(path);
    std::os::unix::fs::symlink("/dev/zero", path).unwrap();
}

/// Runs `read` on a thread and returns its result, failing the test when it takes longer
/// than [`BLOCKED_AFTER`] (a reader blocked on the FIFO `fifo` is then released by opening
/// the FIFO for writing, on a thread of its own).
fn without_blocking<T: Send + 'static>(
    fifo: &Path,
    read: impl FnOnce() -> T + Send + 'static,
) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(read());
    });
    match rx.recv_timeout(BLOCKED_AFTER) {
        Ok(value) => value,
        Err(_) => {
            let other_end = fifo.to_path_buf();
            std::thread::spawn(move || {
                drop(std::fs::OpenOptions::new().write(true).open(other_end))
            });
            panic!(
                "reading a replay folder blocked on the FIFO {}",
                fifo.display()
            );
        }
    }
}

/// `err` is a scan-side refusal of a non-regular file of `kind`, `what` it is, naming `path`.
fn assert_not_regular(err: &ReplayError, kind: FileKind, what: &str, path: &Path) {
    let refused = not_a_regular_file(err).unwrap_or_else(|| panic!("not a refusal: {err}"));
    assert_eq!((refused.kind, refused.what), (kind, what), "{err}");
    assert!(
        err.to_string().contains(&path.display().to_string())
            && err.to_string().contains("not a regular file"),
        "{err}"
    );
}

/// `err` is a ground-truth refusal of a non-regular file, `what` it is, naming `path`.
fn assert_truth_not_regular(err: &TruthError, what: &str, path: &Path) {
    assert!(
        matches!(err, TruthError::NotRegularFile { path: p, what: w } if p == path && *w == what),
        "{err}"
    );
    assert!(
        err.to_string().contains(&path.display().to_string()),
        "{err}"
    );
}

#[test]
fn a_scan_that_is_a_fifo_is_refused_by_name_instead_of_blocking_start_up() {
    let dir = oxford(&[1_000_000, 1_250_000]);
    let first = dir.path().join("radar/1000000.png");
    if !mkfifo(&first) {
        return;
    }
    let folder = dir.path().to_path_buf();
    let err = without_blocking(&first, move || {
        ScanRecording::open(&folder, None).expect_err("a FIFO for a scan")
    });
    assert_not_regular(&err, FileKind::Scan, "a FIFO", &first);
    // RADIATE's scans are read by the same reader.
    let scan = ScanFile {
        path: first.clone(),
        time_us: 1_000_000,
        period_us: 250_000,
    };
    let err = without_blocking(&first, move || {
        read_radiate_png(&scan).expect_err("a FIFO for a RADIATE scan")
    });
    assert_not_regular(&err, FileKind::Scan, "a FIFO", &first);
}

#[test]
fn ground_truth_and_index_files_that_are_fifos_are_refused_by_name_instead_of_blocking() {
    let dir = oxford(&[1_000_000, 1_250_000]);
    let csv = dir.path().join("radar_odometry.csv");
    if !mkfifo(&csv) {
        return;
    }
    let path = csv.clone();
    let err = without_blocking(&csv, move || read_oxford_odometry(&path).unwrap_err());
    assert_truth_not_regular(&err, "a FIFO", &csv);

    for (name, read) in [
        (
            "radar_poses.csv",
            (|p: &Path| read_radar_poses(p).map(drop)) as fn(&Path) -> Result<(), TruthError>,
        ),
        ("GPS_IMU_Twist.txt", |p: &Path| read_gps_index(p).map(drop)),
        ("000001.txt", |p: &Path| read_gps_fix(p, 0).map(drop)),
    ] {
        let fifo = dir.path().join(name);
        assert!(mkfifo(&fifo));
        let path = fifo.clone();
        let err = without_blocking(&fifo, move || read(&path).unwrap_err());
        assert_truth_not_regular(&err, "a FIFO", &fifo);
    }

    // RADIATE's scan index, with the layout named (detection does not take a FIFO for a
    // marker file).
    let index = dir.path().join("Navtech_Polar.txt");
    assert!(mkfifo(&index));
    let folder = dir.path().to_path_buf();
    let err = without_blocking(&index, move || {
        ScanSet::open(&folder, Some(ReplayFormat::Radiate)).unwrap_err()
    });
    assert_not_regular(&err, FileKind::ScanIndex, "a FIFO", &index);
}

#[test]
fn a_scan_that_is_a_symlink_to_dev_zero_is_refused_by_name_unread() {
    let dir = oxford(&[1_000_000, 1_250_000]);
    let first = dir.path().join("radar/1000000.png");
    dev_zero(&first);
    let started = Instant::now();
    let err = read_polar_png(&first).unwrap_err();
    assert_not_regular(&err, FileKind::Scan, "a character device", &first);
    let err = ScanRecording::open(dir.path(), None).unwrap_err();
    assert_not_regular(&err, FileKind::Scan, "a character device", &first);
    let err = read_radiate_png(&ScanFile {
        path: first.clone(),
        time_us: 1_000_000,
        period_us: 250_000,
    })
    .unwrap_err();
    assert_not_regular(&err, FileKind::Scan, "a character device", &first);
    assert!(started.elapsed() < Duration::from_millis(500));
}

#[test]
fn ground_truth_and_index_files_that_are_symlinks_to_dev_zero_are_refused_by_name_unread() {
    let dir = oxford(&[1_000_000, 1_250_000]);
    let started = Instant::now();
    let csv = dir.path().join("radar_odometry.csv");
    dev_zero(&csv);
    let err = read_oxford_odometry(&csv).unwrap_err();
    assert_truth_not_regular(&err, "a character device", &csv);
    let poses = dir.path().join("radar_poses.csv");
    dev_zero(&poses);
    let err = read_radar_poses(&poses).unwrap_err();
    assert_truth_not_regular(&err, "a character device", &poses);
    let gps = dir.path().join("GPS_IMU_Twist.txt");
    dev_zero(&gps);
    let err = read_gps_index(&gps).unwrap_err();
    assert_truth_not_regular(&err, "a character device", &gps);
    let fix = dir.path().join("000001.txt");
    dev_zero(&fix);
    let err = read_gps_fix(&fix, 0).unwrap_err();
    assert_truth_not_regular(&err, "a character device", &fix);
    let index = dir.path().join("Navtech_Polar.txt");
    dev_zero(&index);
    let err = ScanSet::open(dir.path(), Some(ReplayFormat::Radiate)).unwrap_err();
    assert_not_regular(&err, FileKind::ScanIndex, "a character device", &index);
    assert!(started.elapsed() < Duration::from_millis(500));
}

#[test]
fn a_valid_scan_padded_past_its_byte_limit_is_refused_by_its_size_unread() {
    let dir = oxford(&[1_000_000, 1_250_000]);
    let first = dir.path().join("radar/1000000.png");
    read_polar_png(&first).expect("the scan decodes before it is padded");
    // Sparse: zeros after the PNG's end, which a decoder never reaches (the 3 GiB
    // take the same path as one byte past the limit).
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(&first)
        .unwrap();
    file.set_len(MAX_SCAN_BYTES + 1).unwrap();
    drop(file);
    let started = Instant::now();
    let err = read_polar_png(&first).unwrap_err();
    assert!(
        matches!(&err, ReplayError::TooLarge { path, bytes, limit }
            if path == &first && *bytes == MAX_SCAN_BYTES + 1 && *limit == MAX_SCAN_BYTES),
        "{err}"
    );
    let err = ScanRecording::open(dir.path(), None).unwrap_err();
    assert!(
        matches!(&err, ReplayError::TooLarge { path, .. } if path == &first),
        "{err}"
    );
    assert!(started.elapsed() < Duration::from_millis(500));

    // A GPS record padded past its limit (well within the ground-truth tables').
    let fix = dir.path().join("000001.txt");
    let mut text = String::from("55.9,-3.3,60.0\n");
    for _ in 0..15 {
        text.push_str("0.0,0.0,0.0\n");
    }
    text.push_str("1.0,2.0,0.0\n0.0,0.0,0.1\n");
    std::fs::write(&fix, &text).unwrap();
    read_gps_fix(&fix, 0).expect("the record reads before it is padded");
    let file = std::fs::OpenOptions::new().write(true).open(&fix).unwrap();
    file.set_len(MAX_GPS_RECORD_BYTES + 1).unwrap();
    drop(file);
    let err = read_gps_fix(&fix, 0).unwrap_err();
    assert!(
        matches!(&err, TruthError::TooLarge { limit, .. } if *limit == MAX_GPS_RECORD_BYTES),
        "{err}"
    );
    // And a ground-truth table past its own.
    let csv = dir.path().join("radar_odometry.csv");
    let file = std::fs::OpenOptions::new().write(true).open(&csv).unwrap();
    file.set_len(MAX_TRUTH_BYTES + 1).unwrap();
    drop(file);
    let err = read_oxford_odometry(&csv).unwrap_err();
    assert!(
        matches!(&err, TruthError::TooLarge { limit, .. } if *limit == MAX_TRUTH_BYTES),
        "{err}"
    );
}

#[test]
fn ground_truth_spanning_more_than_a_day_is_refused_naming_the_file_and_row() {
    const FAR: i64 = 9_000_000_000_000_000_000;
    // Oxford, one scan named 9000000000000000000.png: its row is named.
    let dir = oxford(&[1_000_000, 1_250_000, FAR]);
    let scans = ScanSet::open(dir.path(), None).unwrap();
    let csv = dir.path().join("radar_odometry.csv");
    let rows = read_oxford_odometry(&csv).unwrap();
    let err = chain_pose_times(&csv, &rows, &scans.times_us()).unwrap_err();
    assert!(
        matches!(&err, TruthError::TooLong { row: Some(3), last_us, .. } if *last_us == FAR + 125_000),
        "{err}"
    );
    let text = err.to_string();
    assert!(
        text.contains("radar_odometry.csv") && text.contains("row 3") && text.contains("a day"),
        "{text}"
    );
    // Oxford, one row whose pose time is far off its scans'.
    std::fs::write(
        &csv,
        format!("{ODOMETRY_HEADER}{FAR},1125000,2.0,0,0,0,0,0,1250000,1000000\n"),
    )
    .unwrap();
    let rows = read_oxford_odometry(&csv).unwrap();
    let err = chain_pose_times(&csv, &rows, &[1_000_000, 1_250_000]).unwrap_err();
    assert!(
        matches!(err, TruthError::TooLong { row: Some(2), .. }),
        "{err}"
    );
    // A day exactly is a recording.
    std::fs::write(
        &csv,
        format!(
            "{ODOMETRY_HEADER}{},1125000,2.0,0,0,0,0,0,1250000,1000000\n",
            1_125_000 + MAX_SPAN_US
        ),
    )
    .unwrap();
    let rows = read_oxford_odometry(&csv).unwrap();
    chain_pose_times(&csv, &rows, &[1_000_000, 1_250_000]).expect("a day");

    // Boreas: a scan and its row at 9000000000000000000 us.
    let poses = dir.path().join("radar_poses.csv");
    std::fs::write(
        &poses,
        format!("GPSTime\n1000000,0,0,0,0,0,0,0,0,0,0,0,0\n{FAR},0,0,0,0,0,0,0,0,0,0,0,0\n"),
    )
    .unwrap();
    let rows = read_radar_poses(&poses).unwrap();
    let err = boreas_poses(&poses, &rows, &[1_000_000, FAR]).unwrap_err();
    assert!(
        matches!(&err, TruthError::TooLong { path, last_us, .. } if path == &poses && *last_us == FAR),
        "{err}"
    );
    // RADIATE: refused before any GPS file is read (there are none here).
    let err = radiate_poses(dir.path(), &[1_000_000, FAR]).unwrap_err();
    assert!(
        matches!(&err, TruthError::TooLong { path, .. } if path.ends_with("GPS_IMU_Twist.txt")),
        "{err}"
    );
}
