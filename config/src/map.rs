//! `[map]`: the saved map (slam-map's `.slmap` file: submaps, their frames in the global
//! graph, features, loop closures, the radar profile), for a later run to localise in, and
//! what a run does with a map it is given (`mode`, slam-node's `--map FILE`).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::values::{NonNegativeF64, ValueError};

/// The shortest period between two saves during a run (s): a save writes the whole map.
pub const MIN_SAVE_EVERY_S: f64 = 1.0;

/// The default prior's standard deviations `[x m, y m, heading rad]`.
pub const DEFAULT_INITIAL_SIGMA: [f64; 3] = [1.0, 1.0, 0.03];

/// What the run does with a map (`[map] mode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum MapMode {
    /// Map from nothing (no map is read): the default.
    #[default]
    Map,
    /// Load the map given with `--map FILE` and track the vehicle in it without adding
    /// features; the published pose is in the map's frame.
    Localise,
    /// Load the map given with `--map FILE`, localise in it as `Localise` does, then map:
    /// new submaps in the map's frame, joined to the map's graph, loops closed to its
    /// submaps; the map saved (`save`, `path`) is the merged one. Needs `[submaps]`.
    Extend,
}

impl MapMode {
    /// Whether the run reads a map (`--map FILE`).
    pub fn reads_a_map(self) -> bool {
        matches!(self, MapMode::Localise | MapMode::Extend)
    }
}

/// What localisation registers the vehicle against (`[map] localise_with`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LocaliseWith {
    /// The map's radar scans (every wall and front the mapping drive saw in two rotations
    /// or more): the search describes and verifies the last stretch's scan, tracking
    /// registers each rotation's cloud. Needs radar odometry (`[scan_match] enabled`, or
    /// `[odometry] source = "none"`) and a map with scans (version 3); without either the
    /// run falls back to `Features` with a warning. The default.
    #[default]
    Scans,
    /// The map's point features, tracked as known landmarks in the filter.
    Features,
}

/// `[map]` as written in the file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawMap {
    /// Write the saved map at the end of the run. Default true.
    pub save: bool,
    /// The map file, relative to `output.directory`. Default `"map.slmap"`.
    pub path: PathBuf,
    /// Also write it every this many seconds of the run's clock, at least 1 (0: only at the
    /// end). Default 0.
    pub save_every_s: f64,
    /// `"map"` (map from nothing, the default), `"localise"` (track in the map given with
    /// `--map FILE`; nothing is saved) or `"extend"` (localise in it, then map on in its
    /// frame; the merged map is saved).
    pub mode: MapMode,
    /// Localising or extending: the map file to localise in (slam-node's `--map FILE` sets
    /// it; a relative path is taken from the working directory).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<PathBuf>,
    /// Localising: where the vehicle starts in the map's frame, `[x m, y m, heading rad]`.
    /// Without it the run looks for its place in the map (place recognition) and publishes
    /// no pose until it has a fix.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub initial_pose: Option<[f64; 3]>,
    /// The prior's standard deviations `[x m, y m, heading rad]`, each > 0. Default
    /// `[1.0, 1.0, 0.03]`.
    pub initial_sigma: [f64; 3],
    /// Localising or extending: a ROS 2 topic (absolute, `/initialpose` as RViz's "2D Pose
    /// Estimate" publishes it) of `geometry_msgs/msg/PoseWithCovarianceStamped` in the
    /// `map` frame, subscribed to over Zenoh (`[output.zenoh]`'s session; slam-node built
    /// with its `zenoh` feature). Each message starts (or restarts) tracking at its pose,
    /// carried from its stamp to the latest rotation along the vehicle's motion; its
    /// covariance's x, y and yaw block is the prior's (all zero: `initial_sigma`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub initial_pose_topic: Option<String>,
    /// Localising: `"scans"` (the map's radar scans, the default) or `"features"` (its
    /// point features), in localise and extend mode alike.
    pub localise_with: LocaliseWith,
}

impl Default for RawMap {
    fn default() -> Self {
        Self {
            save: true,
            path: "map.slmap".into(),
            save_every_s: 0.0,
            mode: MapMode::Map,
            file: None,
            initial_pose: None,
            initial_sigma: DEFAULT_INITIAL_SIGMA,
            initial_pose_topic: None,
            localise_with: LocaliseWith::Scans,
        }
    }
}

/// `[map]`, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct MapSettings {
    /// Write the saved map.
    pub save: bool,
    /// The file, inside the output directory.
    pub path: PathBuf,
    /// The period of saves during the run (s); `None`: only at the end.
    pub save_every_s: Option<f64>,
    /// What the run does with a map.
    pub mode: MapMode,
    /// The map file to localise in.
    pub file: Option<PathBuf>,
    /// Localising: the prior pose in the map's frame (heading wrapped to (-pi, pi]).
    pub initial_pose: Option<[f64; 3]>,
    /// Its standard deviations, each finite and > 0.
    pub initial_sigma: [f64; 3],
    /// Localising or extending: the ROS 2 topic priors arrive on (over Zenoh).
    pub initial_pose_topic: Option<String>,
    /// What localisation registers against.
    pub localise_with: LocaliseWith,
}

impl Default for MapSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let s = RawMap::default().check(&mut c);
        debug_assert!(c.is_clean(), "the [map] defaults must be valid");
        s
    }
}

fn period(s: f64) -> Result<Option<f64>, ValueError> {
    let s = NonNegativeF64::new(s)?.get();
    if s == 0.0 {
        Ok(None)
    } else if s < MIN_SAVE_EVERY_S {
        Err(ValueError::Rule(format!(
            "must be 0 (only at the end) or at least {MIN_SAVE_EVERY_S} s, got {s}"
        )))
    } else {
        Ok(Some(s))
    }
}

fn prior_pose(p: Option<[f64; 3]>) -> Result<Option<[f64; 3]>, ValueError> {
    let Some([x, y, t]) = p else {
        return Ok(None);
    };
    if !(x.is_finite() && y.is_finite() && t.is_finite()) {
        return Err(ValueError::Rule(format!(
            "must be three finite numbers [x m, y m, heading rad], got [{x}, {y}, {t}]"
        )));
    }
    let wrapped =
        (t + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    let wrapped = if wrapped <= -std::f64::consts::PI {
        std::f64::consts::PI
    } else {
        wrapped
    };
    Ok(Some([x, y, wrapped]))
}

fn map_file(p: Option<&PathBuf>) -> Result<Option<PathBuf>, ValueError> {
    match p {
        Some(p) if p.as_os_str().is_empty() => Err(ValueError::Rule("empty".into())),
        _ => Ok(p.cloned()),
    }
}

fn prior_sigma(s: [f64; 3]) -> Result<[f64; 3], ValueError> {
    if s.iter().all(|v| v.is_finite() && *v > 0.0) {
        Ok(s)
    } else {
        Err(ValueError::Rule(format!(
            "must be three finite numbers > 0 [x m, y m, heading rad], got [{}, {}, {}]",
            s[0], s[1], s[2]
        )))
    }
}

fn prior_topic(topic: Option<&str>, mode: MapMode) -> Result<Option<String>, ValueError> {
    let Some(topic) = topic else {
        return Ok(None);
    };
    if !mode.reads_a_map() {
        return Err(ValueError::Rule(format!(
            "priors on {topic:?} are only read when localising or extending (map.mode = \"localise\" or \"extend\")"
        )));
    }
    crate::odometry::ros_topic(topic).map(Some)
}

impl RawMap {
    /// Validates this section alone; errors name `map.<field>`.
    pub fn validate(&self) -> Result<MapSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c);
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker) -> MapSettings {
        MapSettings {
            save: self.save,
            path: c.check("map.path", crate::output::relative_file(&self.path)),
            save_every_s: c.check("map.save_every_s", period(self.save_every_s)),
            mode: self.mode,
            file: c.check("map.file", map_file(self.file.as_ref())),
            initial_pose: c.check("map.initial_pose", prior_pose(self.initial_pose)),
            initial_sigma: c.check("map.initial_sigma", prior_sigma(self.initial_sigma)),
            initial_pose_topic: c.check(
                "map.initial_pose_topic",
                prior_topic(self.initial_pose_topic.as_deref(), self.mode),
            ),
            localise_with: self.localise_with,
        }
    }
}

impl From<&MapSettings> for RawMap {
    fn from(s: &MapSettings) -> Self {
        Self {
            save: s.save,
            path: s.path.clone(),
            save_every_s: s.save_every_s.unwrap_or(0.0),
            mode: s.mode,
            file: s.file.clone(),
            initial_pose: s.initial_pose,
            initial_sigma: s.initial_sigma,
            initial_pose_topic: s.initial_pose_topic.clone(),
            localise_with: s.localise_with,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_map_settings_are_named() {
        let raw = RawMap {
            save: true,
            path: "../elsewhere.slmap".into(),
            save_every_s: 0.5,
            ..RawMap::default()
        };
        let errors = raw.validate().unwrap_err().to_string();
        for field in ["map.path", "map.save_every_s"] {
            assert!(errors.contains(field), "{field} missing from {errors}");
        }
        let raw = RawMap {
            save_every_s: f64::NAN,
            ..RawMap::default()
        };
        assert!(raw.validate().is_err());
    }

    #[test]
    fn defaults_round_trip() {
        let s = MapSettings::default();
        assert_eq!(RawMap::from(&s).validate().unwrap(), s);
        assert!(s.save);
        assert_eq!(s.save_every_s, None);
        let every = RawMap {
            save_every_s: 30.0,
            ..RawMap::default()
        }
        .validate()
        .unwrap();
        assert_eq!(every.save_every_s, Some(30.0));
        assert_eq!(RawMap::from(&every).validate().unwrap(), every);
    }

    #[test]
    fn extend_mode_is_read_from_its_name() {
        let raw: RawMap = toml::from_str("mode = \"extend\"").unwrap();
        let s = raw.validate().unwrap();
        assert_eq!(s.mode, MapMode::Extend);
        assert!(s.mode.reads_a_map() && MapMode::Localise.reads_a_map());
        assert!(!MapMode::Map.reads_a_map());
        assert_eq!(RawMap::from(&s).validate().unwrap(), s);
        assert!(toml::from_str::<RawMap>("mode = \"extnd\"").is_err());
    }

    #[test]
    fn localise_with_is_read_from_its_name_and_defaults_to_scans() {
        assert_eq!(MapSettings::default().localise_with, LocaliseWith::Scans);
        let raw: RawMap = toml::from_str("localise_with = \"features\"").unwrap();
        let s = raw.validate().unwrap();
        assert_eq!(s.localise_with, LocaliseWith::Features);
        assert_eq!(RawMap::from(&s).validate().unwrap(), s);
        let err = toml::from_str::<RawMap>("localise_with = \"lidar\"").unwrap_err();
        assert!(err.to_string().contains("scans"), "{err}");
    }

    #[test]
    fn a_prior_pose_is_checked_and_its_heading_wrapped() {
        let raw = RawMap {
            mode: MapMode::Localise,
            initial_pose: Some([1.0, 2.0, 7.0]),
            ..RawMap::default()
        };
        let s = raw.validate().unwrap();
        let [x, y, t] = s.initial_pose.unwrap();
        assert_eq!((x, y), (1.0, 2.0));
        assert!((t - (7.0 - std::f64::consts::TAU)).abs() < 1e-12);
        assert_eq!(RawMap::from(&s).validate().unwrap(), s);
        for (pose, sigma, field) in [
            (
                Some([f64::NAN, 0.0, 0.0]),
                DEFAULT_INITIAL_SIGMA,
                "map.initial_pose",
            ),
            (None, [1.0, 0.0, 0.1], "map.initial_sigma"),
            (None, [1.0, 1.0, f64::INFINITY], "map.initial_sigma"),
        ] {
            let raw = RawMap {
                initial_pose: pose,
                initial_sigma: sigma,
                ..RawMap::default()
            };
            let e = raw.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
    }

    #[test]
    fn a_prior_topic_is_a_ros_topic_read_only_when_localising() {
        let raw = RawMap {
            mode: MapMode::Localise,
            initial_pose_topic: Some("/initialpose".into()),
            ..RawMap::default()
        };
        let s = raw.validate().unwrap();
        assert_eq!(s.initial_pose_topic.as_deref(), Some("/initialpose"));
        assert_eq!(RawMap::from(&s).validate().unwrap(), s);
        for (mode, topic, words) in [
            (MapMode::Localise, "initialpose", "absolute ROS 2 topic"),
            (MapMode::Extend, "/initial pose", "absolute ROS 2 topic"),
            (MapMode::Map, "/initialpose", "only read when localising"),
        ] {
            let raw = RawMap {
                mode,
                initial_pose_topic: Some(topic.into()),
                ..RawMap::default()
            };
            let e = raw.validate().unwrap_err().to_string();
            assert!(
                e.contains("map.initial_pose_topic") && e.contains(words),
                "{e}"
            );
        }
    }
}
