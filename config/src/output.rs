//! `[output]`: where the daemon writes its trajectory, map and diagnostics, and what it shows
//! while running.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::live::{RawZenoh, ZenohSettings};
use crate::values::ValueError;

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
    /// Record the run as an MCAP file (ROS 2 messages, CDR), relative to `directory`,
    /// ending in `.mcap`. Default: none.
    pub mcap: Option<PathBuf>,
    /// `[output.zenoh]`: live ROS 2 topics over Zenoh. Default off.
    pub zenoh: RawZenoh,
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
            mcap: None,
            zenoh: RawZenoh::default(),
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
    /// MCAP recording file name, if the run is recorded.
    pub mcap: Option<PathBuf>,
    /// Live topics over Zenoh.
    pub zenoh: ZenohSettings,
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
            mcap: c.check_opt("output.mcap", self.mcap.as_deref(), mcap_file),
            zenoh: self.zenoh.check(c, "output.zenoh"),
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
            mcap: s.mcap.clone(),
            zenoh: RawZenoh::from(&s.zenoh),
        }
    }
}
