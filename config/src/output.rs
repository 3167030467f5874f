//! `[output]`: where the daemon writes its trajectory, map and diagnostics, and what it shows
//! while running; `[output.foxglove]` (the live view over Foxglove's WebSocket protocol) and
//! `[output.view]` (a page served beside it). Only slam-node built with its `foxglove` feature
//! serves them; this crate only checks the settings.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::live::{RawZenoh, ZenohSettings};
use crate::values::{Capacity, ValueError};

/// `[output]` as written in the file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawOutput {
    /// Output directory. Default `"out"`.
    pub directory: PathBuf,
    /// Trajectory file (TUM format), relative to `directory`. Default `"trajectory.tum"`.
    pub trajectory: PathBuf,
    /// Map file, relative to `directory`. Default `"map.csv"`.
    pub map: PathBuf,
    /// Diagnostics file, relative to `directory`. Default `"diagnostics.csv"`.
    pub diagnostics: PathBuf,
    /// Draw pictures (SVG). Default true.
    pub pictures: bool,
    /// Show progress while running. Default true.
    pub progress: bool,
    /// Write `spectra.jsonl` (each spectrum the filter predicted beside the measured one:
    /// 0.11 MB a minute on the shipped field, more with a longer range). Default true;
    /// false on a vehicle that runs for days, whose disk it would otherwise fill.
    pub spectra: bool,
    /// Write `ground-truth.jsonl` when the simulator runs in the daemon (`--embedded-sim`):
    /// the simulated truth, a JSON line per azimuth (1.2 GB an hour on the realistic city,
    /// 0.33 GB on the shipped field). Default true; false for long simulated runs. The run
    /// is scored against the truth either way (the summary's pose error, `groundtruth.tum`):
    /// the daemon holds it in memory, this file is only a copy.
    pub ground_truth: bool,
    /// Record the run as an MCAP file (ROS 2 messages, CDR), relative to `directory`,
    /// ending in `.mcap`. Default: none.
    pub mcap: Option<PathBuf>,
    /// `[output.zenoh]`: live ROS 2 topics over Zenoh. Default off.
    pub zenoh: RawZenoh,
    /// `[output.foxglove]`: the live view over Foxglove's WebSocket protocol. Default off.
    pub foxglove: RawFoxglove,
    /// `[output.view]`: a web page showing the live view, served beside it. Default off.
    pub view: RawView,
}

impl Default for RawOutput {
    fn default() -> Self {
        Self {
            directory: "out".into(),
            trajectory: "trajectory.tum".into(),
            map: "map.csv".into(),
            diagnostics: "diagnostics.csv".into(),
            pictures: true,
            progress: true,
            spectra: true,
            ground_truth: true,
            mcap: None,
            zenoh: RawZenoh::default(),
            foxglove: RawFoxglove::default(),
            view: RawView::default(),
        }
    }
}

/// `[output]`, validated: the file names are relative, non-empty and inside `directory`.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct OutputSettings {
    /// Output directory.
    pub directory: PathBuf,
    /// Trajectory file name.
    pub trajectory: PathBuf,
    /// Map file name.
    pub map: PathBuf,
    /// Diagnostics file name.
    pub diagnostics: PathBuf,
    /// Draw pictures.
    pub pictures: bool,
    /// Show progress.
    pub progress: bool,
    /// Write `spectra.jsonl`.
    pub spectra: bool,
    /// Write the embedded simulator's `ground-truth.jsonl`.
    pub ground_truth: bool,
    /// MCAP recording file name, if the run is recorded.
    pub mcap: Option<PathBuf>,
    /// Live topics over Zenoh.
    pub zenoh: ZenohSettings,
    /// The live view over Foxglove's WebSocket protocol.
    pub foxglove: FoxgloveSettings,
    /// The page beside it.
    pub view: ViewSettings,
}

impl OutputSettings {
    /// `directory/trajectory`.
    pub fn trajectory_path(&self) -> PathBuf {
        self.directory.join(&self.trajectory)
    }
    /// `directory/map`.
    pub fn map_path(&self) -> PathBuf {
        self.directory.join(&self.map)
    }
    /// `directory/diagnostics`.
    pub fn diagnostics_path(&self) -> PathBuf {
        self.directory.join(&self.diagnostics)
    }
    /// `directory/mcap`, when the run is recorded.
    pub fn mcap_path(&self) -> Option<PathBuf> {
        self.mcap.as_ref().map(|m| self.directory.join(m))
    }
}

impl Default for OutputSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let settings = RawOutput::default().check(&mut c);
        debug_assert!(c.is_clean(), "the [output] defaults must be valid");
        settings
    }
}

/// A file name inside the output directory: not empty, not absolute, no `..`.
pub(crate) fn relative_file(path: &Path) -> Result<PathBuf, ValueError> {
    use std::path::Component;
    if path.as_os_str().is_empty() {
        return Err(ValueError::Empty);
    }
    let inside = path
        .components()
        .all(|part| matches!(part, Component::Normal(_) | Component::CurDir));
    if inside {
        Ok(path.to_path_buf())
    } else {
        Err(ValueError::Rule(format!(
            "must be a relative path inside output.directory, got {:?}",
            path.display().to_string()
        )))
    }
}

/// An MCAP file name inside the output directory, ending in `.mcap`.
fn mcap_file(path: &Path) -> Result<PathBuf, ValueError> {
    let path = relative_file(path)?;
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
    {
        Ok(path)
    } else {
        Err(ValueError::Rule(format!(
            "must end in .mcap, got {:?}",
            path.display().to_string()
        )))
    }
}

impl RawOutput {
    /// Validates this section alone; errors name `output.<field>`.
    pub fn validate(&self) -> Result<OutputSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c);
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker) -> OutputSettings {
        OutputSettings {
            directory: c.check(
                "output.directory",
                crate::values::non_empty_path(&self.directory),
            ),
            trajectory: c.check("output.trajectory", relative_file(&self.trajectory)),
            map: c.check("output.map", relative_file(&self.map)),
            diagnostics: c.check("output.diagnostics", relative_file(&self.diagnostics)),
            pictures: self.pictures,
            progress: self.progress,
            spectra: self.spectra,
            ground_truth: self.ground_truth,
            mcap: c.check_opt("output.mcap", self.mcap.as_deref(), mcap_file),
            zenoh: self.zenoh.check(c, "output.zenoh"),
            foxglove: self.foxglove.check(c, "output.foxglove"),
            view: ViewSettings {
                enabled: self.view.enabled,
            },
        }
    }
}

impl From<&OutputSettings> for RawOutput {
    /// The settings written back out.
    fn from(s: &OutputSettings) -> Self {
        Self {
            directory: s.directory.clone(),
            trajectory: s.trajectory.clone(),
            map: s.map.clone(),
            diagnostics: s.diagnostics.clone(),
            pictures: s.pictures,
            progress: s.progress,
            spectra: s.spectra,
            ground_truth: s.ground_truth,
            mcap: s.mcap.clone(),
            zenoh: RawZenoh::from(&s.zenoh),
            foxglove: RawFoxglove::from(&s.foxglove),
            view: RawView {
                enabled: s.view.enabled,
            },
        }
    }
}

/// The most events the Foxglove publisher's queue may hold.
pub const MAX_FOXGLOVE_QUEUE: usize = 65_536;
/// The most messages waiting for one Foxglove client.
pub const MAX_FOXGLOVE_BACKLOG: usize = 4096;
/// The most clients the Foxglove server takes at once.
pub const MAX_FOXGLOVE_CLIENTS: usize = 64;
/// The radar image's side, pixels: at least this...
pub const MIN_IMAGE_SIZE_PX: i64 = 16;
/// ...and at most this (a 2048 x 2048 8-bit image is 4 MiB a rotation).
pub const MAX_IMAGE_SIZE_PX: i64 = 2048;
/// The radar image's half-width, whole metres: at most this.
pub const MAX_IMAGE_RANGE_M: i64 = 10_000;
/// The longest wait for a subscriber, seconds.
pub const MAX_WAIT_FOR_SUBSCRIBER_S: i64 = 3600;

/// `[output.foxglove]` as written in the file.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawFoxglove {
    /// Serve the live view. Default false.
    pub enabled: bool,
    /// Address to listen on, `ip:port` (port 0: any free port, logged and reported).
    /// Default `"127.0.0.1:8765"` (Foxglove's usual port, this host only).
    pub bind: String,
    /// Events waiting for the publisher thread; more are dropped and counted. Default 4096
    /// (the radar's azimuths go through it: a CTS350-X sends 1600 a second).
    pub queue: i64,
    /// Messages waiting for one client before its oldest are dropped. Default 64.
    pub backlog: i64,
    /// Clients served at once; more are refused (HTTP 503) and counted. Default 8.
    pub max_clients: i64,
    /// The radar image's side, pixels, [16, 2048]. Default 512.
    pub image_size: i64,
    /// The radar image's half-width, whole metres (the radar at its centre), [1, 10000].
    /// Default 100.
    pub image_range_m: i64,
    /// Hold the start of the run until a client subscribes to `/slam/pose`, at most this
    /// many seconds, [0, 3600] (for demonstrations and tests of a fast simulated run; the
    /// radar's data waits meanwhile). Default 0: start at once.
    pub wait_for_subscriber_s: i64,
}

impl Default for RawFoxglove {
    fn default() -> Self {
        Self {
            enabled: false,
            bind: "127.0.0.1:8765".into(),
            queue: 4096,
            backlog: 64,
            max_clients: 8,
            image_size: 512,
            image_range_m: 100,
            wait_for_subscriber_s: 0,
        }
    }
}

/// `[output.foxglove]`, validated.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct FoxgloveSettings {
    /// Serve the live view.
    pub enabled: bool,
    /// Where to listen.
    pub bind: std::net::SocketAddr,
    /// Publisher queue, events.
    pub queue: Capacity,
    /// Per-client backlog, messages.
    pub backlog: Capacity,
    /// Clients at once.
    pub max_clients: Capacity,
    /// Radar image side, pixels.
    pub image_size: u32,
    /// Radar image half-width, metres.
    pub image_range_m: u32,
    /// Longest wait for a subscriber before the run starts, seconds (0: none).
    pub wait_for_subscriber_s: u32,
}

impl Default for FoxgloveSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let settings = RawFoxglove::default().check(&mut c, "output.foxglove");
        debug_assert!(c.is_clean(), "the [output.foxglove] defaults must be valid");
        settings
    }
}

/// An integer in `[min, max]`, as a `u32`.
fn bounded(value: i64, min: i64, max: i64) -> Result<u32, ValueError> {
    match u32::try_from(value) {
        Ok(v) if (min..=max).contains(&value) => Ok(v),
        _ => Err(ValueError::OutOfRange {
            range: format!("[{min}, {max}]"),
            got: value.to_string(),
        }),
    }
}

impl RawFoxglove {
    /// Validates this table alone; errors name `output.foxglove.<field>`.
    pub fn validate(&self) -> Result<FoxgloveSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c, "output.foxglove");
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker, table: &str) -> FoxgloveSettings {
        FoxgloveSettings {
            enabled: self.enabled,
            bind: c
                .check_ok(
                    &format!("{table}.bind"),
                    crate::values::socket_addr(&self.bind),
                )
                .unwrap_or_else(|| ([127, 0, 0, 1], 8765).into()),
            queue: c.check(
                &format!("{table}.queue"),
                Capacity::new(self.queue, MAX_FOXGLOVE_QUEUE),
            ),
            backlog: c.check(
                &format!("{table}.backlog"),
                Capacity::new(self.backlog, MAX_FOXGLOVE_BACKLOG),
            ),
            max_clients: c.check(
                &format!("{table}.max_clients"),
                Capacity::new(self.max_clients, MAX_FOXGLOVE_CLIENTS),
            ),
            image_size: c
                .check_ok(
                    &format!("{table}.image_size"),
                    bounded(self.image_size, MIN_IMAGE_SIZE_PX, MAX_IMAGE_SIZE_PX),
                )
                .unwrap_or(512),
            image_range_m: c
                .check_ok(
                    &format!("{table}.image_range_m"),
                    bounded(self.image_range_m, 1, MAX_IMAGE_RANGE_M),
                )
                .unwrap_or(100),
            wait_for_subscriber_s: c
                .check_ok(
                    &format!("{table}.wait_for_subscriber_s"),
                    bounded(self.wait_for_subscriber_s, 0, MAX_WAIT_FOR_SUBSCRIBER_S),
                )
                .unwrap_or(0),
        }
    }
}

impl From<&FoxgloveSettings> for RawFoxglove {
    /// The settings written back out.
    fn from(s: &FoxgloveSettings) -> Self {
        Self {
            enabled: s.enabled,
            bind: s.bind.to_string(),
            queue: crate::values::as_i64(s.queue.get()),
            backlog: crate::values::as_i64(s.backlog.get()),
            max_clients: crate::values::as_i64(s.max_clients.get()),
            image_size: i64::from(s.image_size),
            image_range_m: i64::from(s.image_range_m),
            wait_for_subscriber_s: i64::from(s.wait_for_subscriber_s),
        }
    }
}

/// `[output.view]` as written in the file.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawView {
    /// Serve a page drawing the live view (the radar image, the map, the pose) at
    /// `http://<[output.foxglove] bind>/`, from the same WebSocket; turns the Foxglove output
    /// on. Default false.
    pub enabled: bool,
}

/// `[output.view]`, validated.
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash)]
pub struct ViewSettings {
    /// Serve the page.
    pub enabled: bool,
}

#[cfg(test)]
mod foxglove_tests {
    use super::*;

    #[test]
    fn the_foxglove_defaults_are_off_on_loopback_at_8765() {
        let s = FoxgloveSettings::default();
        assert!(!s.enabled);
        assert_eq!(s.bind, "127.0.0.1:8765".parse().unwrap());
        assert_eq!((s.image_size, s.image_range_m), (512, 100));
        assert_eq!(RawFoxglove::from(&s), RawFoxglove::default());
    }

    #[test]
    fn port_zero_is_accepted() {
        let raw = RawFoxglove {
            bind: "127.0.0.1:0".into(),
            ..RawFoxglove::default()
        };
        assert_eq!(raw.validate().unwrap().bind.port(), 0);
    }

    #[test]
    fn bad_values_are_named() {
        for (raw, field, text) in [
            (
                RawFoxglove {
                    bind: "localhost:8765".into(),
                    ..RawFoxglove::default()
                },
                "output.foxglove.bind",
                "ip:port",
            ),
            (
                RawFoxglove {
                    image_size: 4096,
                    ..RawFoxglove::default()
                },
                "output.foxglove.image_size",
                "[16, 2048]",
            ),
            (
                RawFoxglove {
                    image_range_m: 0,
                    ..RawFoxglove::default()
                },
                "output.foxglove.image_range_m",
                "[1, 10000]",
            ),
            (
                RawFoxglove {
                    queue: 0,
                    ..RawFoxglove::default()
                },
                "output.foxglove.queue",
                "[1, 65536]",
            ),
            (
                RawFoxglove {
                    max_clients: 1000,
                    ..RawFoxglove::default()
                },
                "output.foxglove.max_clients",
                "[1, 64]",
            ),
        ] {
            let e = raw.validate().unwrap_err().to_string();
            assert!(e.contains(field) && e.contains(text), "{e}");
        }
    }

    #[test]
    fn the_tables_parse_from_toml() {
        let raw: RawOutput = toml::from_str(
            "[foxglove]\nenabled = true\nbind = \"0.0.0.0:9000\"\nimage_size = 256\n[view]\nenabled = true\n",
        )
        .unwrap();
        let s = raw.validate().unwrap();
        assert!(s.foxglove.enabled && s.view.enabled);
        assert_eq!(s.foxglove.bind.port(), 9000);
        assert_eq!(s.foxglove.image_size, 256);
        assert!(toml::from_str::<RawOutput>("[foxglove]\nport = 1\n").is_err());
    }
}
