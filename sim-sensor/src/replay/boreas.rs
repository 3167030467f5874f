//! Boreas' ground truth: `applanix/radar_poses.csv`, one row per radar scan, as pyboreas
//! reads it (`utils.get_transform`, `DATA_REFERENCE.md`):
//!
//! | field | content |
//! |---|---|
//! | 1 `GPSTime` | the scan's time in µs: its PNG's file name |
//! | 2-4 `easting, northing, altitude` | the radar's position in a fixed ENU frame (m) |
//! | 5-7 `vel_east, vel_north, vel_up` | its velocity (m/s) |
//! | 8-10 `roll, pitch, heading` | `C_enu_radar = roll(r) pitch(p) yaw(y)` (rad) |
//! | 11-13 `angvel_z, angvel_y, angvel_x` | its angular velocity in its own frame (rad/s) |
//!
//! The poses are absolute; [`boreas_poses`] turns them into the replay's trajectory (poses
//! in the first scan's frame, one per scan). The planar heading is the direction of the
//! radar's x axis (forward) in the ENU frame, taken from the whole rotation matrix, so it
//! does not depend on whether the radar's z axis points up or down.

use std::path::Path;

use radar_model::geometry::Pose2;

use super::files::FileKind;
use super::truth::{
    check_span, plausible, read_text, relative_to_first, TruthError, MAX_ANGLE_RAD,
    MAX_COORDINATE_M, MAX_SPEED_MPS,
};

/// Fields a row has at least.
pub const FIELDS: usize = 13;

/// One row: the scan's time and the radar's planar pose in the ENU frame (x east, y north,
/// heading counter-clockwise from east).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnuPose {
    /// µs since the epoch.
    pub time_us: i64,
    /// The pose.
    pub pose: Pose2,
    /// East and north velocity (m/s).
    pub velocity_en_mps: (f64, f64),
}

/// Speed above which a row's heading is compared with its direction of travel (m/s).
pub const HEADING_CHECK_SPEED_MPS: f64 = 2.0;

/// Of the rows faster than [`HEADING_CHECK_SPEED_MPS`], how many have a heading within 45
/// degrees of their direction of travel, and how many there are. A forward-driving car's
/// radar should agree in nearly all: when it does not, the heading convention read from
/// the file is not the one pyboreas documents.
pub fn heading_agreement(rows: &[EnuPose]) -> (usize, usize) {
    let moving: Vec<&EnuPose> = rows
        .iter()
        .filter(|r| r.velocity_en_mps.0.hypot(r.velocity_en_mps.1) > HEADING_CHECK_SPEED_MPS)
        .collect();
    let agree = moving
        .iter()
        .filter(|r| {
            let travel = r.velocity_en_mps.1.atan2(r.velocity_en_mps.0);
            radar_model::geometry::wrap_angle(r.pose.theta - travel).abs()
                < std::f64::consts::FRAC_PI_4
        })
        .count();
    (agree, moving.len())
}

/// Heading (counter-clockwise from east) of the x axis of `roll(r) pitch(p) yaw(y)` in
/// pyboreas' convention, or `None` when that axis is within 30 degrees of vertical.
pub fn x_axis_heading(roll: f64, pitch: f64, yaw: f64) -> Option<f64> {
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    // First column of roll(r) @ pitch(p) @ yaw(y), with yaw(y) = [[c, s, 0], [-s, c, 0],
    // [0, 0, 1]] and likewise for the others (pyboreas.utils.utils).
    let east = cp * cy;
    let north = -cr * sy + sr * sp * cy;
    (east.hypot(north) >= 0.5).then(|| north.atan2(east))
}

/// Parses `radar_poses.csv` (a header line first, as pyboreas skips one).
///
/// # Errors
/// A file that cannot be read; a row with fewer than 13 fields, a field that is not a finite
/// number, a time that is not an integer or does not increase; each names the row.
pub fn read_radar_poses(path: &Path) -> Result<Vec<EnuPose>, TruthError> {
    let text = read_text(path, FileKind::GroundTruth)?;
    let mut out: Vec<EnuPose> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let row = i + 1;
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if i == 0 && f.first().is_some_and(|s| s.parse::<i64>().is_err()) {
            continue; // the header
        }
        if line.trim().is_empty() {
            continue;
        }
        let bad = |reason: String| TruthError::Row {
            path: path.to_path_buf(),
            row,
            reason,
        };
        if f.len() < FIELDS {
            return Err(bad(format!("{} fields, expected {FIELDS}", f.len())));
        }
        let num = |k: usize| -> Result<f64, TruthError> {
            f.get(k)
                .and_then(|s| s.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(format!("field {} is not a finite number", k + 1)))
        };
        let time_us = f
            .first()
            .and_then(|s| s.parse::<i64>().ok())
            .ok_or_else(|| bad("field 1 (GPSTime) is not an integer of microseconds".into()))?;
        let within = |k: usize, limit: f64, what: &str| -> Result<f64, TruthError> {
            plausible(num(k)?, limit, k, what).map_err(&bad)
        };
        let heading = x_axis_heading(
            within(7, MAX_ANGLE_RAD, "roll, rad")?,
            within(8, MAX_ANGLE_RAD, "pitch, rad")?,
            within(9, MAX_ANGLE_RAD, "heading, rad")?,
        )
        .ok_or_else(|| bad("roll and pitch put the radar's x axis near vertical".into()))?;
        if let Some(prev) = out.last() {
            if time_us <= prev.time_us {
                return Err(TruthError::OutOfOrder {
                    path: path.to_path_buf(),
                    row,
                    earlier_us: prev.time_us,
                    later_us: time_us,
                });
            }
        }
        out.push(EnuPose {
            time_us,
            pose: Pose2::new(
                within(1, MAX_COORDINATE_M, "easting, m")?,
                within(2, MAX_COORDINATE_M, "northing, m")?,
                heading,
            ),
            velocity_en_mps: (
                within(4, MAX_SPEED_MPS, "east velocity, m/s")?,
                within(5, MAX_SPEED_MPS, "north velocity, m/s")?,
            ),
        });
    }
    Ok(out)
}

/// The poses of the scans at `scan_times_us` in the first scan's frame: each scan needs the
/// row with its exact time (rows for other times are ignored).
///
/// # Errors
/// [`TruthError::TooLong`] when the scans span more than
/// [`super::truth::MAX_SPAN_US`]; [`TruthError::NoPose`] naming the first scan without a row.
pub fn boreas_poses(
    path: &Path,
    rows: &[EnuPose],
    scan_times_us: &[i64],
) -> Result<Vec<Pose2>, TruthError> {
    check_span(path, scan_times_us)?;
    let mut world = Vec::with_capacity(scan_times_us.len());
    let (agree, moving) = heading_agreement(rows);
    if moving > 0 && 2 * agree < moving {
        tracing::warn!(
            file = %path.display(),
            agree,
            moving,
            "the heading disagrees with the direction of travel in most moving rows: the radar's x axis may not point forward as assumed; the ground truth's heading is suspect"
        );
    }
    for &t in scan_times_us {
        let k = rows
            .binary_search_by(|r| r.time_us.cmp(&t))
            .map_err(|_| TruthError::NoPose {
                path: path.to_path_buf(),
                scan_us: t,
                reason: "no row has that GPSTime (a row's GPSTime is its scan's file name)".into(),
            })?;
        if let Some(r) = rows.get(k) {
            world.push(r.pose);
        }
    }
    Ok(relative_to_first(&world))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI};

    #[test]
    fn the_heading_is_the_x_axis_direction_whether_z_points_up_or_down() {
        // z up: yaw(y) is the transpose of the active rotation, so x points at -y.
        let h = x_axis_heading(0.0, 0.0, 0.3).unwrap();
        assert!((h + 0.3).abs() < 1e-12, "{h}");
        // z down (roll pi): x points at +y.
        let h = x_axis_heading(PI, 0.0, 0.3).unwrap();
        assert!((h - 0.3).abs() < 1e-12, "{h}");
        assert!(x_axis_heading(0.0, FRAC_PI_2, 0.0).is_none());
    }

    #[test]
    fn rows_become_poses_in_the_first_scans_frame_and_bad_rows_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("radar_poses.csv");
        // Heading east then north-east, z down (roll pi): 10 m east, then 10 m north.
        std::fs::write(
            &path,
            "GPSTime,easting,northing,altitude,vel_east,vel_north,vel_up,roll,pitch,heading,angvel_z,angvel_y,angvel_x\n\
             1000000,100.0,50.0,0,10,0,0,3.141592653589793,0,0,0,0,0\n\
             1250000,110.0,50.0,0,7,7,0,3.141592653589793,0,0.7853981633974483,0,0,0\n\
             1500000,110.0,60.0,0,0,10,0,3.141592653589793,0,1.5707963267948966,0,0,0\n",
        )
        .unwrap();
        let rows = read_radar_poses(&path).unwrap();
        // Every row drives along its heading.
        assert_eq!(heading_agreement(&rows), (3, 3));
        let poses = boreas_poses(&path, &rows, &[1_000_000, 1_500_000]).unwrap();
        assert_eq!(poses.len(), 2);
        assert!((poses[1].x - 10.0).abs() < 1e-9 && (poses[1].y - 10.0).abs() < 1e-9);
        assert!((poses[1].theta - FRAC_PI_2).abs() < 1e-9);
        let err = boreas_poses(&path, &rows, &[1_000_000, 1_400_000]).unwrap_err();
        assert!(
            err.to_string().contains("radar_poses.csv") && err.to_string().contains("1400000"),
            "{err}"
        );
        std::fs::write(
            &path,
            "GPSTime\n2000,1,2,3,4,5,6,0,0,0,0,0,0\n1000,1,2,3,4,5,6,0,0,0,0,0,0\n",
        )
        .unwrap();
        let err = read_radar_poses(&path).unwrap_err();
        assert!(
            matches!(err, TruthError::OutOfOrder { row: 3, .. }),
            "{err}"
        );
        std::fs::write(&path, "GPSTime\n2000,1,2,3\n").unwrap();
        let err = read_radar_poses(&path).unwrap_err();
        assert!(err.to_string().contains("row 2"), "{err}");
        std::fs::write(&path, "GPSTime\n2000,1,2,3,4,5,6,0,0,nan,0,0,0\n").unwrap();
        let err = read_radar_poses(&path).unwrap_err();
        assert!(err.to_string().contains("field 10"), "{err}");
        // Finite but absurd: refused by field, not printed as a drive of 1e300 m.
        std::fs::write(&path, "GPSTime\n2000,1e300,2,3,4,5,6,0,0,0,0,0,0\n").unwrap();
        let err = read_radar_poses(&path).unwrap_err();
        assert!(
            err.to_string().contains("field 2 (easting, m) is 1e300"),
            "{err}"
        );
        std::fs::write(&path, "GPSTime\n2000,1,2,3,4,5e9,6,0,0,0,0,0,0\n").unwrap();
        let err = read_radar_poses(&path).unwrap_err();
        assert!(err.to_string().contains("field 6 (north velocity"), "{err}");
    }
}
