//! The recorded data sets' folder layouts, and telling them apart by their contents.
//!
//! | layout | scans | scan times | ground truth |
//! |---|---|---|---|
//! | Oxford Radar RobotCar | `radar/<µs>.png` (or the folder itself), rows = azimuths with 11 metadata columns | file names; per-row timestamps in the image | `radar_odometry.csv`: relative motion scan to scan |
//! | Boreas | `radar/<µs>.png`, the same row layout (column 10 unused) | file names (the middle of the scan); per-row timestamps in the image | `applanix/radar_poses.csv`: absolute ENU poses, one row per scan |
//! | RADIATE | `Navtech_Polar/<frame:06>.png`, rows = 576 range bins, columns = 400 azimuths, no metadata | `Navtech_Polar.txt` (`Frame: N Time: s.ns`); per-azimuth times interpolated | `GPS_IMU_Twist.txt` + `GPS_IMU_Twist/<frame:06>.txt`: GPS fixes and INS velocities |

use std::path::Path;
use std::path::PathBuf;

use crate::error::ReplayError;

/// A recorded data set's layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ReplayFormat {
    /// Oxford Radar RobotCar.
    Oxford,
    /// Boreas (University of Toronto).
    Boreas,
    /// RADIATE (Heriot-Watt).
    Radiate,
}

impl ReplayFormat {
    /// Every layout, in the order detection reports them.
    pub const ALL: [ReplayFormat; 3] = [
        ReplayFormat::Oxford,
        ReplayFormat::Boreas,
        ReplayFormat::Radiate,
    ];

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ReplayFormat::Oxford => "oxford",
            ReplayFormat::Boreas => "boreas",
            ReplayFormat::Radiate => "radiate",
        }
    }

    /// What marks a folder as this layout (relative to the folder).
    pub fn marker(self) -> &'static str {
        match self {
            ReplayFormat::Oxford => "radar_odometry.csv",
            ReplayFormat::Boreas => "applanix/radar_poses.csv",
            ReplayFormat::Radiate => "Navtech_Polar.txt",
        }
    }

    /// Whether `dir` holds this layout's marker file.
    fn matches(self, dir: &Path) -> bool {
        dir.join(self.marker()).is_file()
    }

    /// The one layout whose marker `dir` holds (see [`ReplayFormat::marker`]).
    ///
    /// # Errors
    /// [`ReplayError::UnknownFormat`] when none matches, [`ReplayError::AmbiguousFormat`]
    /// when more than one does.
    pub fn detect(dir: &Path) -> Result<ReplayFormat, ReplayError> {
        let found: Vec<ReplayFormat> = Self::ALL.into_iter().filter(|f| f.matches(dir)).collect();
        match found.as_slice() {
            [one] => Ok(*one),
            [] => Err(ReplayError::UnknownFormat {
                dir: dir.to_path_buf(),
                looked_for: Self::ALL
                    .iter()
                    .map(|f| format!("{} for {}", f.marker(), f.name()))
                    .collect::<Vec<_>>()
                    .join(", "),
            }),
            many => Err(ReplayError::AmbiguousFormat {
                dir: dir.to_path_buf(),
                candidates: many
                    .iter()
                    .map(|f| format!("{} ({})", f.name(), f.marker()))
                    .collect::<Vec<_>>()
                    .join(" and "),
            }),
        }
    }
}

impl std::fmt::Display for ReplayFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for ReplayFormat {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| format!("{s:?} is not a layout: oxford, boreas or radiate"))
    }
}

/// Encoder counts per revolution (Navtech; Boreas: `azimuth = encoder * pi / 2800`).
pub const ENCODER_SIZE: u16 = 5600;

/// One scan file and its time.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScanFile {
    /// The PNG.
    pub path: PathBuf,
    /// The scan's time, µs since the epoch (Oxford, Boreas: the file name; RADIATE: its row
    /// of `Navtech_Polar.txt`).
    pub time_us: i64,
    /// How long its rotation took (µs): the interval to the next scan (Oxford, Boreas) or
    /// from the previous one (RADIATE, whose times mark a scan's arrival, its end) when that
    /// is within half and one and a half median intervals, the median interval otherwise.
    /// RADIATE's per-azimuth times are spread over it.
    pub period_us: i64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_layout_is_told_by_its_marker_and_two_markers_are_ambiguous() {
        let dir = tempfile::tempdir().unwrap();
        let err = ReplayFormat::detect(dir.path()).unwrap_err();
        assert!(
            matches!(err, ReplayError::UnknownFormat { .. })
                && err.to_string().contains("--replay-format"),
            "{err}"
        );
        std::fs::create_dir(dir.path().join("applanix")).unwrap();
        std::fs::write(dir.path().join("applanix/radar_poses.csv"), "").unwrap();
        assert_eq!(
            ReplayFormat::detect(dir.path()).unwrap(),
            ReplayFormat::Boreas
        );
        std::fs::write(dir.path().join("Navtech_Polar.txt"), "").unwrap();
        let err = ReplayFormat::detect(dir.path()).unwrap_err();
        assert!(
            err.to_string().contains("boreas") && err.to_string().contains("radiate"),
            "{err}"
        );
        std::fs::remove_dir_all(dir.path().join("applanix")).unwrap();
        assert_eq!(
            ReplayFormat::detect(dir.path()).unwrap(),
            ReplayFormat::Radiate
        );
        std::fs::remove_file(dir.path().join("Navtech_Polar.txt")).unwrap();
        std::fs::write(dir.path().join("radar_odometry.csv"), "").unwrap();
        assert_eq!(
            ReplayFormat::detect(dir.path()).unwrap(),
            ReplayFormat::Oxford
        );
    }

    #[test]
    fn names_parse_in_any_case_and_others_are_refused() {
        assert_eq!("Boreas".parse::<ReplayFormat>(), Ok(ReplayFormat::Boreas));
        assert_eq!("radiate".parse::<ReplayFormat>(), Ok(ReplayFormat::Radiate));
        assert!("kitti".parse::<ReplayFormat>().is_err());
    }
}
