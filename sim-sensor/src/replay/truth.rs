//! Ground truth that comes with recorded scans. Oxford Radar RobotCar: `radar_odometry.csv`
//! (each row: the pose of the scan at `source_radar_timestamp` in the frame of the scan at
//! `destination_radar_timestamp`; x forward, y right, yaw clockwise), chained into poses in
//! the first scan's frame (x forward, y left, heading counter-clockwise), one per scan. A
//! row's poses hold at its own times, `source_timestamp` and `destination_timestamp`, which
//! are the middle of each scan's rotation (about 126 ms after the scan's name, its first
//! azimuth), as the data set's SDK interpolates them: [`chain_pose_times`].
//! Boreas ([`super::boreas`]) and RADIATE ([`super::radiate`]) give absolute poses, which
//! [`relative_to_first`] puts in the same frame. No IO beyond reading the files named, each
//! through [`super::files`] (regular files only, at most [`MAX_TRUTH_BYTES`] each).
//!
//! The ground truth of one recording spans at most [`MAX_SPAN_US`] (a day): the odometry
//! made from it has a sample every 50 ms over its span, so a span of centuries (one row or
//! one scan named `9000000000000000000`) is refused by name ([`TruthError::TooLong`]) rather
//! than made into samples.

use std::path::{Path, PathBuf};

use radar_model::geometry::{wrap_angle, Pose2};

pub use super::files::MAX_TRUTH_BYTES;
use super::files::{read_bounded_text, FileKind};

/// Longest span of a recording's ground truth, first pose to last (µs): a day. The data
/// sets' sequences last minutes (Oxford, RADIATE) to an hour or so (Boreas).
pub const MAX_SPAN_US: i64 = 86_400 * 1_000_000;

/// Largest distance (m) between the poses of consecutive scans in an Oxford row: a scan is
/// a quarter of a second, 1 km is 4,000 m/s.
pub const MAX_STEP_M: f64 = 1_000.0;
/// Largest coordinate (m) of an absolute pose (Boreas' UTM easting and northing are below
/// 10^7).
pub const MAX_COORDINATE_M: f64 = 1e8;
/// Largest speed (m/s) in a ground-truth row.
pub const MAX_SPEED_MPS: f64 = 1_000.0;
/// Largest angle (rad) in a ground-truth row: two turns either way.
pub const MAX_ANGLE_RAD: f64 = 4.0 * std::f64::consts::PI;

/// `value` if its magnitude is at most `limit`; else why not, naming field `k` (0-based)
/// and what it is. Finite but absurd values (1e300) are refused here rather than printed.
pub(crate) fn plausible(value: f64, limit: f64, k: usize, what: &str) -> Result<f64, String> {
    if value.abs() <= limit {
        Ok(value)
    } else {
        Err(format!(
            "field {} ({what}) is {value:?}, beyond the {limit:?} a ground truth may hold",
            k + 1
        ))
    }
}

/// Why the ground truth could not be read.
#[derive(Debug, thiserror::Error)]
pub enum TruthError {
    /// The file could not be read.
    #[error("reading {path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The file is larger than its kind's limit ([`MAX_TRUTH_BYTES`], or
    /// [`super::files::MAX_GPS_RECORD_BYTES`] for one GPS record).
    #[error("{path}: {bytes} bytes is larger than the {limit} read")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size (at least this many when it grew while being read).
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// The path names something other than a regular file, after following symlinks (a
    /// FIFO, a device such as `/dev/zero`, a directory): refused before it is opened.
    #[error(
        "{path}: not a regular file but {what}; ground truth must be read from a regular file"
    )]
    NotRegularFile {
        /// The file.
        path: PathBuf,
        /// What it is: "a FIFO", "a character device", "a directory"...
        what: &'static str,
    },
    /// Poses spanning more than [`MAX_SPAN_US`].
    #[error("{path}{}: the ground truth would span from {first_us} us to {last_us} us, more than the {} s (a day) a recording may", row.map(|r| format!(", row {r}")).unwrap_or_default(), MAX_SPAN_US / 1_000_000)]
    TooLong {
        /// The file.
        path: PathBuf,
        /// The 1-based line number of the row that goes past the limit, where one does.
        row: Option<usize>,
        /// The first pose's time (µs).
        first_us: i64,
        /// The time past the limit (µs).
        last_us: i64,
    },
    /// A row that does not parse.
    #[error("{path}, row {row}: {reason}")]
    Row {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        row: usize,
        /// What is wrong.
        reason: String,
    },
    /// Rows whose times do not increase.
    #[error("{path}, row {row}: time {later_us} us comes after {earlier_us} us but is not later")]
    OutOfOrder {
        /// The file.
        path: PathBuf,
        /// 1-based line number of the later row.
        row: usize,
        /// The earlier row's time (µs).
        earlier_us: i64,
        /// The later row's time (µs).
        later_us: i64,
    },
    /// No pose for a scan.
    #[error("{path}: no pose for the scan at {scan_us} us: {reason}")]
    NoPose {
        /// The ground-truth file.
        path: PathBuf,
        /// The scan's time (µs).
        scan_us: i64,
        /// Why.
        reason: String,
    },
    /// No row links a scan to the one before it.
    #[error("{path}: no row gives scan {to_us} relative to scan {from_us}")]
    Missing {
        /// The file.
        path: PathBuf,
        /// The earlier scan (µs).
        from_us: i64,
        /// The later scan (µs).
        to_us: i64,
    },
}

/// One row: the later scan's pose in the earlier scan's frame, in our convention.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RelativePose {
    /// The later scan (µs since the epoch).
    pub source_us: i64,
    /// The earlier scan (µs since the epoch).
    pub destination_us: i64,
    /// The time at which the later scan's pose holds (`source_timestamp`, µs): the middle of
    /// its rotation.
    pub source_pose_us: i64,
    /// The time at which the earlier scan's pose holds (`destination_timestamp`, µs).
    pub destination_pose_us: i64,
    /// The row's 1-based line in its file.
    pub line: usize,
    /// The source's pose in the destination's frame (x forward, y left, CCW heading).
    pub pose: Pose2,
}

/// `a` followed by `b` (`b` expressed in `a`'s frame).
pub fn compose(a: &Pose2, b: &Pose2) -> Pose2 {
    let (s, c) = a.theta.sin_cos();
    Pose2::new(
        a.x + c * b.x - s * b.y,
        a.y + s * b.x + c * b.y,
        wrap_angle(a.theta + b.theta),
    )
}

/// `b` in the frame of `a` (both in the same world frame).
pub fn between(a: &Pose2, b: &Pose2) -> Pose2 {
    a.between(b)
}

/// World poses (x east, y north, heading counter-clockwise from east) put in the frame of
/// the first: x forward, y left, heading counter-clockwise, as the chained Oxford poses.
pub fn relative_to_first(world: &[Pose2]) -> Vec<Pose2> {
    let Some(first) = world.first().copied() else {
        return Vec::new();
    };
    world.iter().map(|p| between(&first, p)).collect()
}

/// Reads a ground-truth file of `kind` ([`FileKind::GroundTruth`] or
/// [`FileKind::GpsRecord`]): a regular file within the kind's limit ([`super::files`]).
pub(crate) fn read_text(path: &Path, kind: FileKind) -> Result<String, TruthError> {
    Ok(read_bounded_text(path, kind)?)
}

/// Whether `last_us` is within [`MAX_SPAN_US`] of `first_us`.
fn within_span(first_us: i64, last_us: i64) -> bool {
    (i128::from(last_us) - i128::from(first_us)).abs() <= i128::from(MAX_SPAN_US)
}

/// Refuses increasing times `times_us` (the poses' times) that span more than
/// [`MAX_SPAN_US`], naming `path`.
///
/// # Errors
/// [`TruthError::TooLong`] with the first time and the first one past the limit.
pub fn check_span(path: &Path, times_us: &[i64]) -> Result<(), TruthError> {
    let Some(&first_us) = times_us.first() else {
        return Ok(());
    };
    match times_us.iter().find(|&&t| !within_span(first_us, t)) {
        Some(&last_us) => Err(TruthError::TooLong {
            path: path.to_path_buf(),
            row: None,
            first_us,
            last_us,
        }),
        None => Ok(()),
    }
}

/// Parses `radar_odometry.csv` (header line first; ten comma-separated fields a row).
pub fn read_oxford_odometry(path: &Path) -> Result<Vec<RelativePose>, TruthError> {
    let text = read_text(path, FileKind::GroundTruth)?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        if line.trim().is_empty() {
            continue;
        }
        let bad = |reason: String| TruthError::Row {
            path: path.to_path_buf(),
            row: i + 1,
            reason,
        };
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 10 {
            return Err(bad(format!("{} fields, expected 10", f.len())));
        }
        let num = |k: usize| -> Result<f64, TruthError> {
            f.get(k)
                .and_then(|s| s.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(format!("field {} is not a finite number", k + 1)))
        };
        let int = |k: usize| -> Result<i64, TruthError> {
            f.get(k)
                .and_then(|s| s.parse::<i64>().ok())
                .ok_or_else(|| bad(format!("field {} is not an integer", k + 1)))
        };
        let within = |k: usize, limit: f64, what: &str| -> Result<f64, TruthError> {
            plausible(num(k)?, limit, k, what).map_err(&bad)
        };
        out.push(RelativePose {
            source_us: int(8)?,
            destination_us: int(9)?,
            source_pose_us: int(0)?,
            destination_pose_us: int(1)?,
            line: i + 1,
            pose: Pose2::new(
                within(2, MAX_STEP_M, "x, m")?,
                -within(3, MAX_STEP_M, "y, m")?,
                -within(7, MAX_ANGLE_RAD, "yaw, rad")?,
            ),
        });
    }
    Ok(out)
}

/// Poses of the scans at `scan_times_us` (in order) in the first scan's frame, chained from
/// the relative poses; every consecutive pair must have a row.
pub fn chain_poses(
    path: &Path,
    rows: &[RelativePose],
    scan_times_us: &[i64],
) -> Result<Vec<Pose2>, TruthError> {
    let index = LinkIndex::new(rows);
    let mut poses = Vec::with_capacity(scan_times_us.len());
    let mut last = Pose2::default();
    poses.push(last);
    for w in scan_times_us.windows(2) {
        let rel = index.link(path, w[0], w[1])?;
        last = compose(&last, &rel.pose);
        poses.push(last);
    }
    Ok(poses)
}

/// The rows by the scans they link, `(destination, source)`: found by binary search, not
/// by a search through every row for each pair of scans (600,000 rows and 2,000 scans took
/// 13 s of silent start-up).
struct LinkIndex<'a> {
    /// `(destination_us, source_us, row)`, sorted; among rows for the same pair the first in
    /// the file comes first (it is the one taken).
    keys: Vec<(i64, i64, usize)>,
    rows: &'a [RelativePose],
}

impl<'a> LinkIndex<'a> {
    fn new(rows: &'a [RelativePose]) -> Self {
        let mut keys: Vec<(i64, i64, usize)> = rows
            .iter()
            .enumerate()
            .map(|(k, r)| (r.destination_us, r.source_us, k))
            .collect();
        keys.sort_unstable();
        Self { keys, rows }
    }

    /// The first row giving scan `to_us` in the frame of scan `from_us`.
    fn link(&self, path: &Path, from_us: i64, to_us: i64) -> Result<&'a RelativePose, TruthError> {
        let at = self
            .keys
            .partition_point(|&(d, s, _)| (d, s) < (from_us, to_us));
        self.keys
            .get(at)
            .filter(|&&(d, s, _)| (d, s) == (from_us, to_us))
            .and_then(|&(_, _, k)| self.rows.get(k))
            .ok_or(TruthError::Missing {
                path: path.to_path_buf(),
                from_us,
                to_us,
            })
    }
}

/// The times (µs) at which the poses of [`chain_poses`] hold: each row's own
/// `destination_timestamp` for the first scan and `source_timestamp` for the others (the
/// middle of each rotation, where the data set's radar odometry places its poses). A time
/// that does not increase, or is more than [`MAX_SPAN_US`] after the first, is refused by
/// row.
pub fn chain_pose_times(
    path: &Path,
    rows: &[RelativePose],
    scan_times_us: &[i64],
) -> Result<Vec<i64>, TruthError> {
    let index = LinkIndex::new(rows);
    let mut times = Vec::with_capacity(scan_times_us.len());
    for (k, w) in scan_times_us.windows(2).enumerate() {
        let rel = index.link(path, w[0], w[1])?;
        if k == 0 {
            times.push(rel.destination_pose_us);
        }
        let earlier = times.last().copied().unwrap_or(i64::MIN);
        if rel.source_pose_us <= earlier || rel.destination_pose_us >= rel.source_pose_us {
            return Err(TruthError::OutOfOrder {
                path: path.to_path_buf(),
                row: rel.line,
                earlier_us: earlier.max(rel.destination_pose_us),
                later_us: rel.source_pose_us,
            });
        }
        if let Some(&first_us) = times.first() {
            if !within_span(first_us, rel.source_pose_us) {
                return Err(TruthError::TooLong {
                    path: path.to_path_buf(),
                    row: Some(rel.line),
                    first_us,
                    last_us: rel.source_pose_us,
                });
            }
        }
        times.push(rel.source_pose_us);
    }
    Ok(times)
}

impl From<super::files::FileError> for TruthError {
    fn from(e: super::files::FileError) -> Self {
        match e {
            super::files::FileError::Io { path, source } => TruthError::Io { path, source },
            super::files::FileError::NotRegular { path, refused } => TruthError::NotRegularFile {
                path,
                what: refused.what,
            },
            super::files::FileError::TooLarge {
                path, bytes, limit, ..
            } => TruthError::TooLarge { path, bytes, limit },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_chain_into_poses_and_a_missing_link_names_both_scans() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("radar_odometry.csv");
        std::fs::write(
            &path,
            "source_timestamp,destination_timestamp,x,y,z,roll,pitch,yaw,source_radar_timestamp,destination_radar_timestamp\n\
             250,150,2.0,0.0,0,0,0,-0.1,200,100\n\
             350,250,2.0,0.0,0,0,0,0.0,300,200\n",
        )
        .unwrap();
        let rows = read_oxford_odometry(&path).unwrap();
        let poses = chain_poses(&path, &rows, &[100, 200, 300]).unwrap();
        assert_eq!(poses.len(), 3);
        // A clockwise yaw in the data set is a left (counter-clockwise) turn... negated:
        // yaw -0.1 clockwise is +0.1 counter-clockwise.
        assert!((poses[1].theta - 0.1).abs() < 1e-12);
        assert!((poses[2].x - (2.0 + 2.0 * 0.1f64.cos())).abs() < 1e-12);
        // The poses hold at the rows' own times (the middle of each rotation).
        let times = chain_pose_times(&path, &rows, &[100, 200, 300]).unwrap();
        assert_eq!(times, vec![150, 250, 350]);
        let err = chain_poses(&path, &rows, &[100, 250]).unwrap_err();
        assert!(err.to_string().contains("250"), "{err}");
        std::fs::write(&path, "header\n1,2,3\n").unwrap();
        let err = read_oxford_odometry(&path).unwrap_err();
        assert!(err.to_string().contains("row 2"), "{err}");
    }

    #[test]
    fn finite_but_absurd_values_are_refused_naming_the_row_and_field() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("radar_odometry.csv");
        for (row, field) in [
            (
                "250,150,1e300,0.0,0,0,0,-0.1,200,100",
                "field 3 (x, m) is 1e300",
            ),
            (
                "250,150,2.0,-2000,0,0,0,-0.1,200,100",
                "field 4 (y, m) is -2000.0",
            ),
            (
                "250,150,2.0,0.0,0,0,0,1e10,200,100",
                "field 8 (yaw, rad) is 10000000000.0",
            ),
        ] {
            std::fs::write(&path, format!("header\n{row}\n")).unwrap();
            let err = read_oxford_odometry(&path).unwrap_err();
            assert!(
                matches!(err, TruthError::Row { row: 2, .. }) && err.to_string().contains(field),
                "{err}"
            );
        }
    }

    #[test]
    fn the_row_linking_each_pair_of_scans_is_found_among_many_and_the_first_of_duplicates_wins() {
        // 20,000 rows in shuffled order linking 20,000 scans 100 apart, and a second,
        // different row for the pair (100, 200) after the first.
        let n = 20_000i64;
        let row = |k: i64, x: f64| RelativePose {
            source_us: 100 * (k + 1),
            destination_us: 100 * k,
            source_pose_us: 100 * (k + 1) + 50,
            destination_pose_us: 100 * k + 50,
            line: 0,
            pose: Pose2::new(x, 0.0, 0.0),
        };
        let mut rows: Vec<RelativePose> = (0..n).map(|k| row((k * 7919) % n, 1.0)).collect();
        let first = rows.iter().position(|r| r.destination_us == 100).unwrap();
        rows.insert(first + 1, row(1, 5.0));
        let scans: Vec<i64> = (0..n).map(|k| 100 * k).collect();
        let path = Path::new("radar_odometry.csv");
        let poses = chain_poses(path, &rows, &scans).unwrap();
        assert_eq!(poses.len(), scans.len());
        assert!((poses[scans.len() - 1].x - (n - 1) as f64).abs() < 1e-6);
        let times = chain_pose_times(path, &rows, &scans).unwrap();
        assert_eq!(times[1], 150);
        let err = chain_poses(path, &rows, &[0, 150]).unwrap_err();
        assert!(
            matches!(
                err,
                TruthError::Missing {
                    from_us: 0,
                    to_us: 150,
                    ..
                }
            ),
            "{err}"
        );
    }
}
