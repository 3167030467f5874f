//! Every setting of the radar SLAM system, loaded from TOML and validated into types that
//! cannot hold invalid values.
//!
//! Two stages. [`RawConfig`] mirrors the file: serde structs, one per section, every field
//! with a documented default and `deny_unknown_fields`, so a misspelt key is an error that
//! names the key and its line. [`RawConfig::validate`] turns it into [`Config`], whose fields
//! are newtypes ([`PositiveF64`], [`Probability`], [`Capacity`], ...), parsed socket
//! addresses, [`std::time::Duration`]s and enums; every invalid field is reported with its
//! full dotted path (`filter.initial_sigma_loss_db must be > 0, got -1`).
//!
//! A binary calls [`Config::resolve`]: a file (or, without one, a shipped [`Preset`]), then
//! command-line [`Override`]s (`radar.address=10.0.0.2:6317`) applied to the raw settings and
//! so checked exactly like keys in a file, then validation.
//!
//! IO: [`Config::load`] and [`Config::resolve`] read one file (at most [`MAX_CONFIG_BYTES`]);
//! nothing else here does IO. The shipped example files are compiled in ([`examples`]), so
//! binaries run on shipped settings with no file on disk. `examples/sim.toml` writes out
//! every key with its default and is the reference for what each one means.
//!
//! Section by section: [`radar`] (the driver's link), [`odometry`], [`gyro`] (and
//! `[sim.gyro]`), [`sim`] and
//! [`faults`] (the simulator), [`model`] (radar model constants), [`detector`], [`filter`]
//! (the EKF), [`output`] (and [`live`], `[output.zenoh]`), [`submaps`], [`map`] (the saved map). Each module holds its `Raw*` struct (as written, documented
//! defaults) and its validated `*Settings`, and can be validated alone
//! (`RawRadar::validate`).
//!
//! ```
//! let config = config::Config::from_toml_str("[radar]\naddress = \"192.168.0.1:6317\"\n")?;
//! assert_eq!(config.radar.address.port(), 6317);
//! # Ok::<(), config::ConfigError>(())
//! ```

mod check;
pub mod detector;
mod error;
pub mod examples;
pub mod faults;
pub mod filter;
pub mod gyro;
pub mod live;
pub mod map;
pub mod model;
pub mod odometry;
pub mod output;
mod overrides;
mod parse;
pub mod radar;
pub mod sim;
pub mod submaps;
pub mod values;

use std::io::Read;
use std::path::Path;

use serde::{Deserialize, Serialize};

pub use detector::{DetectorSettings, RawDetector};
pub use error::{ConfigError, FieldError, FieldErrors, Location};
pub use faults::{FaultSettings, NoiseBurst, RawFaults};
pub use filter::{FilterSettings, RawFilter};
pub use gyro::{GyroSettings, RawGyro};
pub use map::{LocaliseWith, MapMode, MapSettings, RawMap};
pub use model::{ModelSettings, RawModel};
pub use odometry::{OdometrySettings, RawOdometry};
pub use output::{OutputSettings, RawOutput};
pub use overrides::Override;
pub use radar::{RadarSettings, RawRadar};
pub use sim::{RawSim, SimSettings};
pub use submaps::{RawSubmaps, SubmapSettings};
pub use values::{
    Capacity, FiniteF64, NonNegativeF64, OpenProbability, PositiveF64, Probability, ValueError,
};

use check::Checker;

/// The largest configuration file [`Config::load`] reads: 1 MiB.
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

/// The name used in errors for text given to [`Config::from_toml_str`].
pub const STRING_ORIGIN: &str = "<string>";

/// The whole file as written: one table per section, each optional.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawConfig {
    /// `[radar]`.
    pub radar: RawRadar,
    /// `[odometry]`.
    pub odometry: RawOdometry,
    /// `[gyro]`.
    pub gyro: RawGyro,
    /// `[sim]` (and `[sim.faults]`).
    pub sim: RawSim,
    /// `[model]`.
    pub model: RawModel,
    /// `[detector]`.
    pub detector: RawDetector,
    /// `[filter]`.
    pub filter: RawFilter,
    /// `[output]`.
    pub output: RawOutput,
    /// `[submaps]`.
    pub submaps: RawSubmaps,
    /// `[map]`.
    pub map: RawMap,
}

/// Every setting, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// The radar link (driver).
    pub radar: RadarSettings,
    /// Odometry source and motion model.
    pub odometry: OdometrySettings,
    /// The gyro of radar-only driving.
    pub gyro: GyroSettings,
    /// The simulator.
    pub sim: SimSettings,
    /// The radar model.
    pub model: ModelSettings,
    /// Detection.
    pub detector: DetectorSettings,
    /// The EKF.
    pub filter: FilterSettings,
    /// Outputs.
    pub output: OutputSettings,
    /// Local submaps and the global layer.
    pub submaps: SubmapSettings,
    /// The saved map.
    pub map: MapSettings,
}

/// The three ways the system is used, each with a shipped example file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Preset {
    /// On the vehicle against a real radar (`examples/vehicle.toml`).
    Vehicle,
    /// Against the simulator (`examples/sim.toml`).
    Sim,
    /// Integration tests over loopback (`examples/test.toml`).
    Test,
}

impl RawConfig {
    /// Validates every section, reporting every invalid field.
    pub fn validate(&self) -> Result<Config, FieldErrors> {
        let mut c = Checker::new();
        let config = self.check(&mut c);
        c.finish(config)
    }

    fn check(&self, c: &mut Checker) -> Config {
        let odometry = self.odometry.check(c);
        let gyro = self.gyro.check(c);
        gyro::check_with_odometry(&gyro, &odometry, c);
        Config {
            radar: self.radar.check(c),
            odometry,
            gyro,
            sim: self.sim.check(c),
            model: self.model.check(c),
            detector: self.detector.check(c),
            filter: self.filter.check(c),
            output: self.output.check(c),
            submaps: self.submaps.check(c),
            map: self.map.check(c),
        }
    }

    /// Parses TOML text without validating it; errors are named `<string>`.
    pub fn from_toml_str(text: &str) -> Result<Self, ConfigError> {
        parse::raw_from_str(text, STRING_ORIGIN)
    }

    /// Serialises back to TOML (for printing the effective settings).
    pub fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        toml::to_string(self)
    }
}

impl From<&Config> for RawConfig {
    /// The settings written back out: validating the result gives the same settings (see
    /// the section conversions for the few values TOML rounds: durations to whole
    /// milliseconds, seeds above `i64::MAX`).
    fn from(c: &Config) -> Self {
        Self {
            radar: RawRadar::from(&c.radar),
            odometry: RawOdometry::from(&c.odometry),
            gyro: RawGyro::from(&c.gyro),
            sim: RawSim::from(&c.sim),
            model: RawModel::from(&c.model),
            detector: RawDetector::from(&c.detector),
            filter: RawFilter::from(&c.filter),
            output: RawOutput::from(&c.output),
            submaps: RawSubmaps::from(&c.submaps),
            map: RawMap::from(&c.map),
        }
    }
}

impl Default for Config {
    /// Every section's documented defaults: the simulator on loopback, real-time pacing.
    fn default() -> Self {
        let mut c = Checker::new();
        let config = RawConfig::default().check(&mut c);
        debug_assert!(c.is_clean(), "the defaults must be valid");
        config
    }
}

impl Config {
    /// Parses and validates TOML text; errors are named `<string>`.
    pub fn from_toml_str(text: &str) -> Result<Self, ConfigError> {
        Self::from_toml_str_named(text, STRING_ORIGIN)
    }

    /// Parses and validates TOML text; `origin` names the text in errors.
    pub fn from_toml_str_named(text: &str, origin: &str) -> Result<Self, ConfigError> {
        parse::raw_from_str(text, origin)?
            .validate()
            .map_err(|errors| ConfigError::Invalid {
                origin: origin.to_owned(),
                errors,
            })
    }

    /// Reads, parses and validates a file of at most [`MAX_CONFIG_BYTES`].
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ConfigError> {
        Self::load_with_written(path).map(|(config, _)| config)
    }

    /// As [`Config::load`], with the keys the file writes ([`written_keys`]): a key the file
    /// writes overrides the radar profile's value, an absent one takes the profile's.
    pub fn load_with_written(
        path: impl AsRef<Path>,
    ) -> Result<(Self, std::collections::BTreeSet<String>), ConfigError> {
        let path = path.as_ref();
        let text = read_limited(path)?;
        let config = Self::from_toml_str_named(&text, &path.display().to_string())?;
        Ok((config, written_keys(&text)))
    }

    /// What a binary runs with: the file at `path` (or, without one, the shipped `preset`),
    /// then `overrides` in order, then validation. Errors name the file (or the shipped
    /// example) and the field.
    pub fn resolve(
        path: Option<&Path>,
        preset: Preset,
        overrides: &[Override],
    ) -> Result<Self, ConfigError> {
        let (mut raw, origin) = match path {
            Some(path) => (
                parse::raw_from_str(&read_limited(path)?, &path.display().to_string())?,
                path.display().to_string(),
            ),
            None => {
                let (text, name) = examples::text(preset);
                (parse::raw_from_str(text, name)?, name.to_owned())
            }
        };
        raw.apply_overrides(overrides)?;
        raw.validate()
            .map_err(|errors| ConfigError::Invalid { origin, errors })
    }

    /// The settings as a TOML file that loads back to the same settings: what a run writes
    /// next to its outputs so that it can be repeated.
    pub fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        RawConfig::from(self).to_toml_string()
    }

    /// The settings of a shipped example file, compiled in.
    ///
    /// The shipped files are validated by this crate's tests, so this fails only if a shipped
    /// file was broken, which those tests catch.
    pub fn preset(preset: Preset) -> Result<Self, ConfigError> {
        let (text, name) = examples::text(preset);
        Self::from_toml_str_named(text, name)
    }
}

/// The dotted keys a TOML text writes, tables flattened (`model.sigma_range_m`,
/// `filter.initial_pose.sigma_x_m`); an array counts as one key. Text that does not parse
/// writes no keys (the parser's own error is reported by [`Config::from_toml_str`]).
pub fn written_keys(text: &str) -> std::collections::BTreeSet<String> {
    fn walk(prefix: &str, table: &toml::Table, out: &mut std::collections::BTreeSet<String>) {
        for (key, value) in table {
            let path = if prefix.is_empty() {
                key.clone()
            } else {
                format!("{prefix}.{key}")
            };
            match value {
                toml::Value::Table(inner) => walk(&path, inner, out),
                _ => {
                    out.insert(path);
                }
            }
        }
    }
    let mut out = std::collections::BTreeSet::new();
    if let Ok(table) = text.parse::<toml::Table>() {
        walk("", &table, &mut out);
    }
    out
}

/// Reads a UTF-8 file of at most [`MAX_CONFIG_BYTES`], never allocating more.
fn read_limited(path: &Path) -> Result<String, ConfigError> {
    let io = |source| ConfigError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut text = String::new();
    file.take(MAX_CONFIG_BYTES + 1)
        .read_to_string(&mut text)
        .map_err(io)?;
    if u64::try_from(text.len()).map_or(true, |n| n > MAX_CONFIG_BYTES) {
        return Err(ConfigError::TooLarge {
            path: path.to_path_buf(),
            max_bytes: MAX_CONFIG_BYTES,
        });
    }
    Ok(text)
}
