//! `[gyro]`: a yaw-rate-only input (a gyro) for radar-only driving, and `[sim.gyro]`: the
//! gyro the simulator serves from its truth.
//!
//! A gyro is the optional second input of radar-only driving (`[odometry] source = "none"`,
//! or `--radar-only` in replay): the prediction's turn over a rotation comes from the gyro's
//! yaw rate, integrated over the samples' timestamps, instead of the last rotation's turn
//! held; the speed still comes from the radar's registration. The filter estimates the
//! gyro's bias (its steering offset) from the registrations. With wheel odometry the gyro
//! is refused (`gyro.source` names the conflict): the wheel odometry's steering is the turn
//! input there, and two turn inputs in one process model would count the turn twice.
//!
//! Noise figures, defaults. A rate-grade MEMS gyro (the class of an automotive yaw-rate
//! sensor) has an angle random walk above 0.5 deg/sqrt(h) and a bias drift of 10 to
//! 1000 deg/h (A. Norouzpour-Shirazi, "Interface Circuits and Systems for Inertial
//! Sensors", IEEE Sensors 2013 tutorial, table "Rate grade / Tactical grade / Navigation
//! grade"). The defaults take 0.6 deg/sqrt(h) (0.01 deg/s/sqrt(Hz), 1.75e-4
//! rad/s/sqrt(Hz)) and, for the simulator, an uncalibrated turn-on bias of 0.005 rad/s
//! (0.29 deg/s, 1030 deg/h: the top of that range).

use std::net::SocketAddr;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::values::{self, FiniteF64, NonNegativeF64, PositiveF64, ValueError};

/// The gyro source, as written: `source = "none" | "tcp" | "file"`. No Zenoh topic: the
/// odometry's Zenoh path decodes twist messages into speed and steering, and a gyro topic
/// (`sensor_msgs/msg/Imu`) would need its own decoder and subscription; the TCP line format
/// is what a bridge writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum GyroSourceKind {
    /// No gyro.
    #[default]
    None,
    /// The gyro line stream (`docs/contracts.md`, "Gyro stream") over TCP, at `address`.
    Tcp,
    /// The same lines read from the file at `path`.
    File,
}

/// Default gyro address: the simulator's gyro port.
pub const DEFAULT_GYRO_ADDRESS: &str = "127.0.0.1:6319";
/// Default white-noise density of the gyro's rate, rad/s/sqrt(Hz) (0.01 deg/s/sqrt(Hz)).
pub const DEFAULT_NOISE_DENSITY: f64 = 1.75e-4;
/// Default prior standard deviation of the gyro's bias, rad/s (an uncalibrated MEMS part).
pub const DEFAULT_BIAS_STD_RAD_S: f64 = 0.01;
/// Default random walk of the gyro's bias, rad/s per sqrt(s).
pub const DEFAULT_BIAS_WALK: f64 = 1e-5;
/// Default largest believable yaw rate, rad/s (a car's is under 1.5).
pub const DEFAULT_MAX_YAW_RATE_RAD_S: f64 = 3.0;
/// Default rate of the simulator's gyro, Hz.
pub const DEFAULT_SIM_RATE_HZ: f64 = 100.0;
/// Default bias of the simulator's gyro, rad/s.
pub const DEFAULT_SIM_BIAS_RAD_S: f64 = 0.005;
/// Highest simulated gyro rate, Hz.
pub const MAX_SIM_RATE_HZ: f64 = 1000.0;

/// `[gyro]` as written in the file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawGyro {
    /// `"none"`, `"tcp"` or `"file"`. Default `"none"`.
    pub source: GyroSourceKind,
    /// With `source = "tcp"`: `ip:port`. Default `127.0.0.1:6319`.
    pub address: Option<String>,
    /// With `source = "file"`: the gyro file (required then).
    pub path: Option<PathBuf>,
    /// White-noise density of the measured yaw rate, rad/s/sqrt(Hz) >= 0: the heading's
    /// variance grows by its square per second. Default 1.75e-4.
    pub noise_density_rad_s_per_sqrt_hz: f64,
    /// Prior standard deviation of the gyro's bias, rad/s >= 0; the filter estimates the
    /// bias when > 0. Default 0.01.
    pub bias_std_rad_s: f64,
    /// How fast the bias may drift, rad/s per sqrt(s) >= 0 (a rate random walk; a MEMS
    /// part's is 10-100 deg/h/sqrt(h), 1e-6 to 1e-5). Default 1e-5.
    pub bias_walk_rad_s_per_sqrt_s: f64,
    /// A sample reporting a faster yaw rate (rad/s > 0, either way) is refused. Default 3.
    pub max_yaw_rate_rad_s: f64,
}

impl Default for RawGyro {
    fn default() -> Self {
        Self {
            source: GyroSourceKind::None,
            address: None,
            path: None,
            noise_density_rad_s_per_sqrt_hz: DEFAULT_NOISE_DENSITY,
            bias_std_rad_s: DEFAULT_BIAS_STD_RAD_S,
            bias_walk_rad_s_per_sqrt_s: DEFAULT_BIAS_WALK,
            max_yaw_rate_rad_s: DEFAULT_MAX_YAW_RATE_RAD_S,
        }
    }
}

/// Where the gyro comes from, validated.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum GyroSource {
    /// No gyro.
    None,
    /// A TCP stream.
    Tcp {
        /// Where it is served.
        address: SocketAddr,
    },
    /// A file of gyro lines.
    File {
        /// The file.
        path: PathBuf,
    },
}

/// `[gyro]`, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct GyroSettings {
    /// Source.
    pub source: GyroSource,
    /// Rate noise density, rad/s/sqrt(Hz).
    pub noise_density_rad_s_per_sqrt_hz: NonNegativeF64,
    /// Prior standard deviation of the bias, rad/s (0: not estimated).
    pub bias_std_rad_s: NonNegativeF64,
    /// Random walk of the bias, rad/s per sqrt(s).
    pub bias_walk_rad_s_per_sqrt_s: NonNegativeF64,
    /// Largest believable yaw rate, rad/s.
    pub max_yaw_rate_rad_s: PositiveF64,
}

impl Default for GyroSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let settings = RawGyro::default().check(&mut c);
        debug_assert!(c.is_clean(), "the [gyro] defaults must be valid");
        settings
    }
}

fn only_with_source(value: &str) -> ValueError {
    ValueError::Rule(format!(
        "is only used with gyro.source = \"{value}\"; remove it"
    ))
}

impl RawGyro {
    /// Validates this section alone; errors name `gyro.<field>`. (That a gyro needs
    /// `[odometry] source = "none"` is checked with the whole file.)
    pub fn validate(&self) -> Result<GyroSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c);
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker) -> GyroSettings {
        if self.source != GyroSourceKind::Tcp && self.address.is_some() {
            c.fail("gyro.address", only_with_source("tcp"));
        }
        if self.source != GyroSourceKind::File && self.path.is_some() {
            c.fail("gyro.path", only_with_source("file"));
        }
        let source = match self.source {
            GyroSourceKind::None => GyroSource::None,
            GyroSourceKind::Tcp => GyroSource::Tcp {
                address: c.check(
                    "gyro.address",
                    values::socket_addr(self.address.as_deref().unwrap_or(DEFAULT_GYRO_ADDRESS)),
                ),
            },
            GyroSourceKind::File => match &self.path {
                Some(path) => GyroSource::File {
                    path: c.check("gyro.path", values::non_empty_path(path)),
                },
                None => {
                    c.fail(
                        "gyro.path",
                        ValueError::Rule("is required with gyro.source = \"file\"".into()),
                    );
                    GyroSource::None
                }
            },
        };
        GyroSettings {
            source,
            noise_density_rad_s_per_sqrt_hz: c.check(
                "gyro.noise_density_rad_s_per_sqrt_hz",
                NonNegativeF64::new(self.noise_density_rad_s_per_sqrt_hz),
            ),
            bias_std_rad_s: c.check(
                "gyro.bias_std_rad_s",
                NonNegativeF64::new(self.bias_std_rad_s),
            ),
            bias_walk_rad_s_per_sqrt_s: c.check(
                "gyro.bias_walk_rad_s_per_sqrt_s",
                NonNegativeF64::new(self.bias_walk_rad_s_per_sqrt_s),
            ),
            max_yaw_rate_rad_s: c.check(
                "gyro.max_yaw_rate_rad_s",
                PositiveF64::new(self.max_yaw_rate_rad_s),
            ),
        }
    }
}

impl From<&GyroSettings> for RawGyro {
    /// The settings written back out.
    fn from(s: &GyroSettings) -> Self {
        let (source, address, path) = match &s.source {
            GyroSource::None => (GyroSourceKind::None, None, None),
            GyroSource::Tcp { address } => (GyroSourceKind::Tcp, Some(address.to_string()), None),
            GyroSource::File { path } => (GyroSourceKind::File, None, Some(path.clone())),
        };
        Self {
            source,
            address,
            path,
            noise_density_rad_s_per_sqrt_hz: s.noise_density_rad_s_per_sqrt_hz.get(),
            bias_std_rad_s: s.bias_std_rad_s.get(),
            bias_walk_rad_s_per_sqrt_s: s.bias_walk_rad_s_per_sqrt_s.get(),
            max_yaw_rate_rad_s: s.max_yaw_rate_rad_s.get(),
        }
    }
}

/// The whole file's rule: a gyro only with radar odometry driving.
pub(crate) fn check_with_odometry(
    gyro: &GyroSettings,
    odometry: &crate::OdometrySettings,
    c: &mut Checker,
) {
    if gyro.source != GyroSource::None && odometry.source != crate::odometry::OdometrySource::None {
        c.fail(
            "gyro.source",
            ValueError::Rule(
                "a gyro is only used when the radar drives the filter (odometry.source = \"none\"): with wheel odometry its steering is the turn input, and a second one would count the turn twice; remove [gyro] source or set odometry.source = \"none\"".into(),
            ),
        );
    }
}

/// `[sim.gyro]` as written: the gyro the simulator serves on its own port, from its truth.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawSimGyro {
    /// Gyro port address. Default `127.0.0.1:6319`.
    pub bind: String,
    /// Samples per second, `(0, 1000]`. Default 100.
    pub rate_hz: f64,
    /// White-noise density added to the true yaw rate, rad/s/sqrt(Hz) >= 0 (each sample's
    /// standard deviation is this times sqrt(rate_hz)). Default 1.75e-4.
    pub noise_density_rad_s_per_sqrt_hz: f64,
    /// Constant bias added to the true yaw rate, rad/s. Default 0.005.
    pub bias_rad_s: f64,
}

impl Default for RawSimGyro {
    fn default() -> Self {
        Self {
            bind: DEFAULT_GYRO_ADDRESS.into(),
            rate_hz: DEFAULT_SIM_RATE_HZ,
            noise_density_rad_s_per_sqrt_hz: DEFAULT_NOISE_DENSITY,
            bias_rad_s: DEFAULT_SIM_BIAS_RAD_S,
        }
    }
}

/// `[sim.gyro]`, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct SimGyroSettings {
    /// Gyro port address.
    pub bind: SocketAddr,
    /// Samples per second.
    pub rate_hz: PositiveF64,
    /// Noise density, rad/s/sqrt(Hz).
    pub noise_density_rad_s_per_sqrt_hz: NonNegativeF64,
    /// Constant bias, rad/s.
    pub bias_rad_s: FiniteF64,
}

impl Default for SimGyroSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let settings = RawSimGyro::default().check(&mut c);
        debug_assert!(c.is_clean(), "the [sim.gyro] defaults must be valid");
        settings
    }
}

impl RawSimGyro {
    pub(crate) fn check(&self, c: &mut Checker) -> SimGyroSettings {
        let rate = c.check("sim.gyro.rate_hz", PositiveF64::new(self.rate_hz));
        let rate_hz = if rate.get() > MAX_SIM_RATE_HZ {
            c.fail(
                "sim.gyro.rate_hz",
                ValueError::OutOfRange {
                    range: format!("(0, {MAX_SIM_RATE_HZ}]"),
                    got: rate.to_string(),
                },
            );
            PositiveF64::ONE
        } else {
            rate
        };
        SimGyroSettings {
            bind: c.check("sim.gyro.bind", values::socket_addr(&self.bind)),
            rate_hz,
            noise_density_rad_s_per_sqrt_hz: c.check(
                "sim.gyro.noise_density_rad_s_per_sqrt_hz",
                NonNegativeF64::new(self.noise_density_rad_s_per_sqrt_hz),
            ),
            bias_rad_s: c.check("sim.gyro.bias_rad_s", FiniteF64::new(self.bias_rad_s)),
        }
    }
}

impl From<&SimGyroSettings> for RawSimGyro {
    fn from(s: &SimGyroSettings) -> Self {
        Self {
            bind: s.bind.to_string(),
            rate_hz: s.rate_hz.get(),
            noise_density_rad_s_per_sqrt_hz: s.noise_density_rad_s_per_sqrt_hz.get(),
            bias_rad_s: s.bias_rad_s.get(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn errors(text: &str) -> Vec<String> {
        match crate::Config::from_toml_str(text) {
            Ok(_) => Vec::new(),
            Err(e) => vec![format!("{e:#}"), format!("{e:?}")],
        }
    }

    #[test]
    fn the_defaults_are_no_gyro_and_a_rate_grade_mems_part() {
        let c = crate::Config::default();
        assert_eq!(c.gyro.source, GyroSource::None);
        assert_eq!(c.gyro.noise_density_rad_s_per_sqrt_hz.get(), 1.75e-4);
        assert_eq!(c.sim.gyro.bias_rad_s.get(), 0.005);
        assert_eq!(c.sim.gyro.rate_hz.get(), 100.0);
    }

    #[test]
    fn a_tcp_gyro_with_radar_only_driving_is_accepted() {
        // Parsed only, never connected to: a documentation address (RFC 5737), not a local port.
        let c = crate::Config::from_toml_str(
            "[odometry]\nsource = \"none\"\n[gyro]\nsource = \"tcp\"\naddress = \"192.0.2.1:7000\"\n",
        )
        .unwrap();
        assert_eq!(
            c.gyro.source,
            GyroSource::Tcp {
                address: "192.0.2.1:7000".parse().unwrap()
            }
        );
        let c = crate::Config::from_toml_str(
            "[odometry]\nsource = \"none\"\n[gyro]\nsource = \"file\"\npath = \"g.txt\"\n",
        )
        .unwrap();
        assert_eq!(
            c.gyro.source,
            GyroSource::File {
                path: "g.txt".into()
            }
        );
    }

    #[test]
    fn a_gyro_with_wheel_odometry_is_refused_by_name() {
        let e = errors("[gyro]\nsource = \"tcp\"\n").join("\n");
        assert!(e.contains("gyro.source"), "{e}");
        assert!(
            e.contains("odometry.source = \\\"none\\\"")
                || e.contains("odometry.source = \"none\""),
            "{e}"
        );
    }

    #[test]
    fn bad_gyro_fields_are_named() {
        for (text, key) in [
            (
                "[odometry]\nsource = \"none\"\n[gyro]\nsource = \"file\"\n",
                "gyro.path",
            ),
            ("[gyro]\naddress = \"192.0.2.1:7000\"\n", "gyro.address"),
            ("[gyro]\npath = \"x\"\n", "gyro.path"),
            (
                "[gyro]\nnoise_density_rad_s_per_sqrt_hz = -1.0\n",
                "gyro.noise_density_rad_s_per_sqrt_hz",
            ),
            ("[gyro]\nbias_std_rad_s = nan\n", "gyro.bias_std_rad_s"),
            (
                "[gyro]\nmax_yaw_rate_rad_s = 0.0\n",
                "gyro.max_yaw_rate_rad_s",
            ),
            ("[gyro]\nsource = \"zenoh\"\n", "source"),
            ("[gyro]\nrate = 1.0\n", "rate"),
            ("[sim.gyro]\nrate_hz = 5000.0\n", "sim.gyro.rate_hz"),
            ("[sim.gyro]\nbind = \"nowhere\"\n", "sim.gyro.bind"),
            ("[sim.gyro]\nbias_rad_s = inf\n", "sim.gyro.bias_rad_s"),
        ] {
            let e = errors(text).join("\n");
            assert!(e.contains(key), "{text:?}: {e}");
        }
    }

    #[test]
    fn the_settings_survive_writing_back() {
        let c = crate::Config::from_toml_str(
            "[odometry]\nsource = \"none\"\n[gyro]\nsource = \"tcp\"\nbias_std_rad_s = 0.02\n[sim.gyro]\nrate_hz = 50.0\nbias_rad_s = -0.01\n",
        )
        .unwrap();
        let back = crate::Config::from_toml_str(&c.to_toml_string().unwrap()).unwrap();
        assert_eq!(back.gyro, c.gyro);
        assert_eq!(back.sim.gyro, c.sim.gyro);
    }
}
