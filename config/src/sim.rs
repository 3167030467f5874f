//! `[sim]`: the simulated radar server: where it listens, how fast it goes, what it renders,
//! the odometry it serves; faults live in [`crate::faults`].

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::faults::{FaultSettings, RawFaults};
use crate::values::{self, Capacity, FiniteF64, NonNegativeF64, PositiveF64, ValueError};

/// Most clients a simulator may be configured to serve at once.
pub const MAX_SIM_CLIENTS: usize = 64;
/// Highest odometry rate accepted, Hz.
pub const MAX_ODOMETRY_RATE_HZ: f64 = 1000.0;
/// The scene shipped with the simulator and used when none is named.
pub const DEFAULT_SCENE: &str = "outdoor-field";

/// How fast the simulator sends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Pacing {
    /// At the radar's own rotation rate.
    Realtime,
    /// As fast as the client reads.
    AsFastAsPossible,
}

/// Which radar the simulator pretends to be.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RadarPreset {
    /// The paper's unit: 200 azimuths per rotation, 0.25 m bins, out to 200 m.
    #[serde(rename = "paper-200")]
    Paper200,
    /// A current Navtech CTS350-X: 400 azimuths, 0.0438 m bins, 4 Hz.
    #[serde(rename = "cts350x-400")]
    Cts350x400,
}

/// Bits per FFT bin on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DataWidth {
    /// 8-bit bins, message 30.
    Bits8,
    /// 16-bit bins, message 31.
    Bits16,
}

impl DataWidth {
    /// Bits per bin.
    pub fn bits(self) -> u8 {
        match self {
            DataWidth::Bits8 => 8,
            DataWidth::Bits16 => 16,
        }
    }
    fn from_bits(bits: i64) -> Result<Self, ValueError> {
        match bits {
            8 => Ok(DataWidth::Bits8),
            16 => Ok(DataWidth::Bits16),
            other => Err(ValueError::Rule(format!("must be 8 or 16, got {other}"))),
        }
    }
}

/// The scene to render.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum SceneRef {
    /// A scene shipped with the simulator, by name (letters, digits, `-`, `_`).
    Shipped(String),
    /// A scene file.
    File(PathBuf),
}

impl SceneRef {
    /// A bare name (letters, digits, `-`, `_`) is a shipped scene; anything else (it contains
    /// `/`, `.` or other characters) is a file path. Write `./name` for a file in the current
    /// directory whose name looks like a scene name.
    pub fn parse(text: &str) -> Result<Self, ValueError> {
        if text.is_empty() {
            return Err(ValueError::Empty);
        }
        let is_name = text
            .chars()
            .all(|ch| ch.is_ascii_alphanumeric() || ch == '-' || ch == '_');
        Ok(if is_name {
            SceneRef::Shipped(text.to_owned())
        } else {
            SceneRef::File(PathBuf::from(text))
        })
    }
}

/// Longest `write_timeout_ms`: an hour.
pub const MAX_WRITE_TIMEOUT: Duration = Duration::from_secs(3600);
/// Longest `idle_timeout_ms`: a day.
pub const MAX_IDLE_TIMEOUT: Duration = Duration::from_secs(86_400);

/// A duration of `ms` milliseconds in `(0, max]`.
fn bounded_ms(ms: i64, max: Duration) -> Result<Duration, ValueError> {
    let d = values::duration_from_ms(ms)?;
    if d > max {
        return Err(ValueError::OutOfRange {
            range: format!("[1, {}] ms", values::whole_ms(max)),
            got: ms.to_string(),
        });
    }
    Ok(d)
}

/// `[sim]` as written in the file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawSim {
    /// Radar port address. Default `127.0.0.1:6317`; tests use `127.0.0.1:0`.
    pub bind: String,
    /// Odometry port address. Default `127.0.0.1:6318`.
    pub odometry_bind: String,
    /// Clients served at once, `[1, 64]`. Default 3.
    pub max_clients: i64,
    /// `"realtime"` or `"as-fast-as-possible"`. Default `"realtime"`.
    pub pacing: Pacing,
    /// Keep-alive interval, ms > 0. Default 1000.
    pub keepalive_interval_ms: i64,
    /// A client whose socket takes no data for this long (it stopped reading) is dropped
    /// and its slot freed, ms in `(0, 1 hour]`. Default 5000.
    pub write_timeout_ms: i64,
    /// A client that has not asked for data (start 21 or 140) for this long is dropped and
    /// its slot freed, ms in `(0, 1 day]`. Default 60000.
    pub idle_timeout_ms: i64,
    /// A shipped scene name or a scene file path. Default `"outdoor-field"`.
    pub scene: String,
    /// `"paper-200"` or `"cts350x-400"`. Default `"paper-200"`.
    pub radar_preset: RadarPreset,
    /// Bits per bin, 8 or 16. Default 8.
    pub data_width: i64,
    /// Random seed, >= 0. Default 1.
    pub seed: i64,
    /// Odometry records per second, `(0, 1000]`. Default 20.
    pub odometry_rate_hz: f64,
    /// Speed noise added to odometry, m/s >= 0. Default 0.1.
    pub sigma_speed_mps: f64,
    /// Steering noise added to odometry, rad >= 0. Default 0.01.
    pub sigma_steer_rad: f64,
    /// Constant speed bias, m/s. Default 0.
    pub bias_speed_mps: f64,
    /// Constant steering bias, rad. Default 0.
    pub bias_steer_rad: f64,
    /// Write ground truth to this file. Default absent.
    pub ground_truth_path: Option<PathBuf>,
    /// `[sim.faults]`: fault injection for tests. Default: no faults.
    pub faults: RawFaults,
    /// `[sim.gyro]`: the gyro served from the truth (`crate::gyro`).
    pub gyro: crate::gyro::RawSimGyro,
}

impl Default for RawSim {
    fn default() -> Self {
        Self {
            bind: "127.0.0.1:6317".into(),
            odometry_bind: "127.0.0.1:6318".into(),
            max_clients: 3,
            pacing: Pacing::Realtime,
            keepalive_interval_ms: 1000,
            write_timeout_ms: 5000,
            idle_timeout_ms: 60_000,
            scene: DEFAULT_SCENE.into(),
            radar_preset: RadarPreset::Paper200,
            data_width: 8,
            seed: 1,
            odometry_rate_hz: 20.0,
            sigma_speed_mps: 0.1,
            sigma_steer_rad: 0.01,
            bias_speed_mps: 0.0,
            bias_steer_rad: 0.0,
            ground_truth_path: None,
            faults: RawFaults::default(),
            gyro: crate::gyro::RawSimGyro::default(),
        }
    }
}

/// `[sim]`, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct SimSettings {
    /// Radar port address.
    pub bind: SocketAddr,
    /// Odometry port address.
    pub odometry_bind: SocketAddr,
    /// Clients served at once.
    pub max_clients: Capacity,
    /// Pacing.
    pub pacing: Pacing,
    /// Keep-alive interval.
    pub keepalive_interval: Duration,
    /// A client whose socket takes no data this long is dropped.
    pub write_timeout: Duration,
    /// A client that asks for no data this long is dropped.
    pub idle_timeout: Duration,
    /// Scene.
    pub scene: SceneRef,
    /// Radar preset.
    pub radar_preset: RadarPreset,
    /// Bits per bin.
    pub data_width: DataWidth,
    /// Random seed.
    pub seed: u64,
    /// Odometry rate, Hz.
    pub odometry_rate_hz: PositiveF64,
    /// Odometry speed noise, m/s.
    pub sigma_speed_mps: NonNegativeF64,
    /// Odometry steering noise, rad.
    pub sigma_steer_rad: NonNegativeF64,
    /// Odometry speed bias, m/s.
    pub bias_speed_mps: FiniteF64,
    /// Odometry steering bias, rad.
    pub bias_steer_rad: FiniteF64,
    /// Ground-truth file.
    pub ground_truth_path: Option<PathBuf>,
    /// Faults.
    pub faults: FaultSettings,
    /// The simulated gyro.
    pub gyro: crate::gyro::SimGyroSettings,
}

impl Default for SimSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let settings = RawSim::default().check(&mut c);
        debug_assert!(c.is_clean(), "the [sim] defaults must be valid");
        settings
    }
}

impl RawSim {
    /// Validates this section alone; errors name `sim.<field>`.
    pub fn validate(&self) -> Result<SimSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c);
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker) -> SimSettings {
        let rate = c.check(
            "sim.odometry_rate_hz",
            PositiveF64::new(self.odometry_rate_hz),
        );
        let odometry_rate_hz = if rate.get() > MAX_ODOMETRY_RATE_HZ {
            c.fail(
                "sim.odometry_rate_hz",
                ValueError::OutOfRange {
                    range: format!("(0, {MAX_ODOMETRY_RATE_HZ}]"),
                    got: rate.to_string(),
                },
            );
            PositiveF64::ONE
        } else {
            rate
        };
        let scene = match SceneRef::parse(&self.scene) {
            Ok(scene) => scene,
            Err(problem) => {
                c.fail("sim.scene", problem);
                SceneRef::Shipped(DEFAULT_SCENE.into())
            }
        };
        let data_width = match DataWidth::from_bits(self.data_width) {
            Ok(w) => w,
            Err(problem) => {
                c.fail("sim.data_width", problem);
                DataWidth::Bits8
            }
        };
        SimSettings {
            bind: c.check("sim.bind", values::socket_addr(&self.bind)),
            odometry_bind: c.check(
                "sim.odometry_bind",
                values::socket_addr(&self.odometry_bind),
            ),
            max_clients: c.check(
                "sim.max_clients",
                Capacity::new(self.max_clients, MAX_SIM_CLIENTS),
            ),
            pacing: self.pacing,
            keepalive_interval: c.check(
                "sim.keepalive_interval_ms",
                values::duration_from_ms(self.keepalive_interval_ms),
            ),
            write_timeout: c.check(
                "sim.write_timeout_ms",
                bounded_ms(self.write_timeout_ms, MAX_WRITE_TIMEOUT),
            ),
            idle_timeout: c.check(
                "sim.idle_timeout_ms",
                bounded_ms(self.idle_timeout_ms, MAX_IDLE_TIMEOUT),
            ),
            scene,
            radar_preset: self.radar_preset,
            data_width,
            seed: c.check("sim.seed", values::count(self.seed, u64::MAX)),
            odometry_rate_hz,
            sigma_speed_mps: c.check(
                "sim.sigma_speed_mps",
                NonNegativeF64::new(self.sigma_speed_mps),
            ),
            sigma_steer_rad: c.check(
                "sim.sigma_steer_rad",
                NonNegativeF64::new(self.sigma_steer_rad),
            ),
            bias_speed_mps: c.check("sim.bias_speed_mps", FiniteF64::new(self.bias_speed_mps)),
            bias_steer_rad: c.check("sim.bias_steer_rad", FiniteF64::new(self.bias_steer_rad)),
            ground_truth_path: c.check_opt(
                "sim.ground_truth_path",
                self.ground_truth_path.as_deref(),
                values::non_empty_path,
            ),
            faults: self.faults.check(c),
            gyro: self.gyro.check(c),
        }
    }
}

impl SceneRef {
    /// The text that parses back to this scene: a file path that looks like a bare name is
    /// written `./name`. A path that is not UTF-8 is written lossily.
    pub fn to_text(&self) -> String {
        match self {
            SceneRef::Shipped(name) => name.clone(),
            SceneRef::File(path) => {
                let text = path.display().to_string();
                match SceneRef::parse(&text) {
                    Ok(SceneRef::File(_)) => text,
                    _ => format!("./{text}"),
                }
            }
        }
    }
}

impl From<&SimSettings> for RawSim {
    /// The settings written back out (a seed above `i64::MAX`, which TOML cannot hold, is
    /// written as `i64::MAX`).
    fn from(s: &SimSettings) -> Self {
        Self {
            bind: s.bind.to_string(),
            odometry_bind: s.odometry_bind.to_string(),
            max_clients: values::as_i64(s.max_clients.get()),
            pacing: s.pacing,
            keepalive_interval_ms: values::whole_ms(s.keepalive_interval),
            write_timeout_ms: values::whole_ms(s.write_timeout),
            idle_timeout_ms: values::whole_ms(s.idle_timeout),
            scene: s.scene.to_text(),
            radar_preset: s.radar_preset,
            data_width: i64::from(s.data_width.bits()),
            seed: values::as_i64(s.seed),
            odometry_rate_hz: s.odometry_rate_hz.get(),
            sigma_speed_mps: s.sigma_speed_mps.get(),
            sigma_steer_rad: s.sigma_steer_rad.get(),
            bias_speed_mps: s.bias_speed_mps.get(),
            bias_steer_rad: s.bias_steer_rad.get(),
            ground_truth_path: s.ground_truth_path.clone(),
            faults: RawFaults::from(&s.faults),
            gyro: crate::gyro::RawSimGyro::from(&s.gyro),
        }
    }
}
