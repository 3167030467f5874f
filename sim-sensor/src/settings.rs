//! Programmatic settings of a simulator instance ([`SimOptions`]), and their construction
//! from config's validated `[sim]` section.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use crate::error::SimError;
use crate::faults::{FaultScope, FaultSettings};
#[cfg(feature = "config")]
use crate::radar::{DataWidth, RadarPreset};
#[cfg(feature = "config")]
use crate::scene::shipped;
use crate::scene::Scene;

/// How fast azimuths go out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Pacing {
    /// At the radar's own rate: azimuth `k` leaves when the wall clock reaches its timestamp.
    #[default]
    Realtime,
    /// As fast as the client reads (TCP back-pressure paces the server).
    AsFastAsPossible,
}

#[cfg(feature = "config")]
impl From<config::sim::Pacing> for Pacing {
    fn from(p: config::sim::Pacing) -> Self {
        match p {
            config::sim::Pacing::Realtime => Pacing::Realtime,
            config::sim::Pacing::AsFastAsPossible => Pacing::AsFastAsPossible,
        }
    }
}

/// What the server streams.
#[derive(Debug, Clone)]
pub enum SourceSpec {
    /// Spectra rendered from a scene.
    Scene(Box<Scene>),
    /// A directory of Oxford polar PNG scans (or a data set folder with a `radar/` of
    /// them), served in time order: as `PolarScans` with the Oxford layout.
    OxfordPng(PathBuf),
    /// A recorded data set's polar scans in its own layout (`None`: detected from the
    /// folder's contents, see [`crate::replay::ReplayFormat::detect`]).
    PolarScans {
        /// The data set's folder.
        dir: PathBuf,
        /// Its layout.
        format: Option<crate::replay::ReplayFormat>,
    },
    /// A raw Colossus byte stream recorded from a radar (or by the driver): its first
    /// configuration is announced and its FFT frames re-served.
    RawStream(PathBuf),
}

/// Most clients a simulator serves at once (as `[sim] max_clients`).
pub const MAX_CLIENTS: usize = 64;

/// Odometry noise: each record is `v + bias_speed + N(0, sigma_speed^2)`,
/// `steer + bias_steer + N(0, sigma_steer^2)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryNoise {
    /// Records per second.
    pub rate_hz: f64,
    /// Speed noise standard deviation, m/s.
    pub sigma_speed_mps: f64,
    /// Steering noise standard deviation, rad.
    pub sigma_steer_rad: f64,
    /// Constant speed bias, m/s.
    pub bias_speed_mps: f64,
    /// Constant steering bias, rad.
    pub bias_steer_rad: f64,
}

impl Default for OdometryNoise {
    fn default() -> Self {
        Self {
            rate_hz: 20.0,
            sigma_speed_mps: 0.1,
            sigma_steer_rad: 0.01,
            bias_speed_mps: 0.0,
            bias_steer_rad: 0.0,
        }
    }
}

/// A fixed start for the simulator's clock (2024-01-01T00:00:00Z, Unix ns): for runs that
/// must repeat to the last bit (tests, the embedded simulator as fast as possible).
pub const FIXED_START_UNIX_NS: u64 = 1_704_067_200_000_000_000;

/// Everything one simulator instance needs.
#[derive(Debug, Clone)]
pub struct SimOptions {
    /// Radar port (6317 by default; `127.0.0.1:0` in tests).
    pub bind: SocketAddr,
    /// Odometry port; `None` serves no odometry. Only scenes have odometry.
    pub odometry_bind: Option<SocketAddr>,
    /// Address of the gyro port ([`crate::gyro`]); `None` to not serve a gyro. Scenes only.
    pub gyro_bind: Option<SocketAddr>,
    /// Clients served at once (3 like a real radar); more are refused and closed.
    pub max_clients: usize,
    /// Real time or as fast as the client reads.
    pub pacing: Pacing,
    /// Keep-alive interval (1 s like a real radar).
    pub keepalive_interval: Duration,
    /// A client whose socket takes no data for this long is dropped, freeing its slot
    /// (default 5 s; `[sim] write_timeout_ms`). Counted while the simulator runs: a
    /// deadline noticed 250 ms or more late (the process was stopped) gives the client 1 s
    /// more.
    pub write_timeout: Duration,
    /// A client that has not asked for data this long after connecting is dropped, freeing
    /// its slot (default 60 s; `[sim] idle_timeout_ms`).
    pub idle_timeout: Duration,
    /// What to stream.
    pub source: SourceSpec,
    /// Faults to inject.
    pub faults: FaultSettings,
    /// Which connections get the faults.
    pub fault_scope: FaultScope,
    /// Odometry rate and noise.
    pub odometry: OdometryNoise,
    /// The gyro's rate, bias and noise.
    pub gyro: crate::gyro::GyroNoise,
    /// Write the ground truth here (scenes only).
    pub ground_truth_path: Option<PathBuf>,
    /// Write one ground-truth pose every this many azimuths (1 = every azimuth).
    pub ground_truth_every_n_azimuths: u32,
    /// Unix time of azimuth 0, nanoseconds; overrides the scene; `None` = the scene's, or
    /// the moment the server starts.
    pub start_time_ns: Option<u64>,
    /// Overrides the scene's seed.
    pub seed: Option<u64>,
    /// The scene ends after this many azimuths (streams stop, keep-alives go on).
    pub stop_after_azimuths: Option<u64>,
    /// Replays start again from the first frame when they reach the end.
    pub replay_loop: bool,
    /// Whom a client's contour (50) and sector blanking (51) apply to, and for how long.
    pub shaping_scope: ShapingScope,
}

/// Whom a client's contour (message 50) and sector blanking (51) apply to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ShapingScope {
    /// The radar's settings: they shape every client's azimuths and outlive the connection
    /// that sent them, as Navtech's `colossus_protocol_test` expects of a radar (it sets a
    /// contour on one connection and checks the azimuths on the next).
    #[default]
    Radar,
    /// The sending connection's own: only its azimuths, until it disconnects.
    Connection,
}

impl SimOptions {
    /// Defaults of a real radar for a scene: port 6317 and odometry on 6318 on 127.0.0.1,
    /// 3 clients, real time, keep-alive every second, no faults.
    pub fn new(source: SourceSpec) -> Self {
        Self {
            bind: SocketAddr::from(([127, 0, 0, 1], 6317)),
            odometry_bind: Some(SocketAddr::from(([127, 0, 0, 1], 6318))),
            gyro_bind: Some(SocketAddr::from(([127, 0, 0, 1], 6319))),
            max_clients: 3,
            pacing: Pacing::Realtime,
            keepalive_interval: Duration::from_secs(1),
            write_timeout: Duration::from_secs(5),
            idle_timeout: Duration::from_secs(60),
            source,
            faults: FaultSettings::default(),
            fault_scope: FaultScope::EveryConnection,
            odometry: OdometryNoise::default(),
            gyro: crate::gyro::GyroNoise::default(),
            ground_truth_path: None,
            ground_truth_every_n_azimuths: 1,
            start_time_ns: None,
            seed: None,
            stop_after_azimuths: None,
            replay_loop: false,
            shaping_scope: ShapingScope::Radar,
        }
    }

    /// For tests: both ports on `127.0.0.1:0`, as fast as the client reads, and a fixed
    /// start time ([`FIXED_START_UNIX_NS`]) so timestamps are reproducible.
    pub fn for_tests(scene: Scene) -> Self {
        Self {
            start_time_ns: Some(FIXED_START_UNIX_NS),
            ..Self::for_tests_from(SourceSpec::Scene(Box::new(scene)))
        }
    }

    /// For tests, any source: every port on `127.0.0.1:0` (never the radar's fixed ports)
    /// and as fast as the client reads.
    pub fn for_tests_from(source: SourceSpec) -> Self {
        let any = SocketAddr::from(([127, 0, 0, 1], 0));
        Self {
            bind: any,
            odometry_bind: Some(any),
            gyro_bind: Some(any),
            pacing: Pacing::AsFastAsPossible,
            ..Self::new(source)
        }
    }

    /// Builds options from config's validated `[sim]` section (reading the scene file when
    /// the section names one). With the `config` feature (on by default).
    #[cfg(feature = "config")]
    pub fn from_config(sim: &config::SimSettings) -> Result<Self, SimError> {
        let scene = match &sim.scene {
            config::sim::SceneRef::Shipped(name) => shipped::load(name)?,
            config::sim::SceneRef::File(path) => Scene::load(path)?,
        };
        let preset = match sim.radar_preset {
            config::sim::RadarPreset::Paper200 => RadarPreset::Paper200,
            config::sim::RadarPreset::Cts350x400 => RadarPreset::Cts350x400,
        };
        let width = match sim.data_width {
            config::sim::DataWidth::Bits8 => DataWidth::Bits8,
            config::sim::DataWidth::Bits16 => DataWidth::Bits16,
        };
        // The config's preset and width apply only when they differ from the defaults, so a
        // scene file's own radar section is not silently replaced by an unset config.
        let scene =
            if preset != scene.preset && sim.radar_preset != config::sim::RadarPreset::Paper200 {
                scene.with_preset(preset)
            } else {
                scene
            };
        let scene = if width == DataWidth::Bits16 {
            scene.with_data_width(width)
        } else {
            scene
        };
        let mut options = Self::new(SourceSpec::Scene(Box::new(scene)));
        options.bind = sim.bind;
        options.odometry_bind = Some(sim.odometry_bind);
        options.max_clients = sim.max_clients.get();
        options.pacing = sim.pacing.into();
        options.keepalive_interval = sim.keepalive_interval;
        options.write_timeout = sim.write_timeout;
        options.idle_timeout = sim.idle_timeout;
        options.faults = FaultSettings::from(&sim.faults);
        options.seed = Some(sim.seed);
        options.odometry = OdometryNoise {
            rate_hz: sim.odometry_rate_hz.get(),
            sigma_speed_mps: sim.sigma_speed_mps.get(),
            sigma_steer_rad: sim.sigma_steer_rad.get(),
            bias_speed_mps: sim.bias_speed_mps.get(),
            bias_steer_rad: sim.bias_steer_rad.get(),
        };
        options.gyro_bind = Some(sim.gyro.bind);
        options.gyro = crate::gyro::GyroNoise {
            rate_hz: sim.gyro.rate_hz.get(),
            noise_density_rad_s_per_sqrt_hz: sim.gyro.noise_density_rad_s_per_sqrt_hz.get(),
            bias_rad_s: sim.gyro.bias_rad_s.get(),
        };
        options.ground_truth_path.clone_from(&sim.ground_truth_path);
        Ok(options)
    }

    /// Checks the values a caller could have set by hand.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |field: &str, reason: &str| {
            Err(SimError::Setting {
                field: field.into(),
                reason: reason.into(),
            })
        };
        if !(1..=MAX_CLIENTS).contains(&self.max_clients) {
            return bad("max_clients", "must be in [1, 64]");
        }
        if self.write_timeout.is_zero() || self.idle_timeout.is_zero() {
            return bad("write_timeout / idle_timeout", "must be > 0");
        }
        if self.keepalive_interval.is_zero() {
            return bad("keepalive_interval", "must be > 0");
        }
        let o = &self.odometry;
        if !(o.rate_hz.is_finite() && o.rate_hz > 0.0 && o.rate_hz <= 1000.0) {
            return bad("odometry.rate_hz", "must be in (0, 1000]");
        }
        for (name, v) in [
            ("odometry.sigma_speed_mps", o.sigma_speed_mps),
            ("odometry.sigma_steer_rad", o.sigma_steer_rad),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, "must be finite and >= 0");
            }
        }
        if !(o.bias_speed_mps.is_finite() && o.bias_steer_rad.is_finite()) {
            return bad("odometry.bias", "must be finite");
        }
        let g = &self.gyro;
        if !(g.rate_hz.is_finite() && g.rate_hz > 0.0 && g.rate_hz <= 1000.0) {
            return bad("gyro.rate_hz", "must be in (0, 1000]");
        }
        if !(g.noise_density_rad_s_per_sqrt_hz.is_finite()
            && g.noise_density_rad_s_per_sqrt_hz >= 0.0
            && g.bias_rad_s.is_finite())
        {
            return bad("gyro", "noise density must be finite and >= 0, bias finite");
        }
        if self.ground_truth_every_n_azimuths == 0 {
            return bad("ground_truth_every_n_azimuths", "must be >= 1");
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(feature = "config")]
    #[test]
    fn a_config_sim_section_maps_onto_the_options() {
        let text = r#"
            [sim]
            bind = "127.0.0.1:0"
            odometry_bind = "127.0.0.1:0"
            max_clients = 2
            pacing = "as-fast-as-possible"
            keepalive_interval_ms = 250
            write_timeout_ms = 1500
            idle_timeout_ms = 20000
            scene = "long-loop"
            data_width = 16
            seed = 42
            odometry_rate_hz = 50.0
            sigma_speed_mps = 0.2
            bias_steer_rad = 0.01
            [sim.faults]
            drop_after_messages = 100
            no_keepalive = true
        "#;
        let config = config::Config::from_toml_str(text).expect("valid config");
        let options = SimOptions::from_config(&config.sim).expect("options");
        options.validate().expect("valid options");
        assert_eq!(options.max_clients, 2);
        assert_eq!(options.pacing, Pacing::AsFastAsPossible);
        assert_eq!(options.keepalive_interval, Duration::from_millis(250));
        assert_eq!(options.write_timeout, Duration::from_millis(1500));
        assert_eq!(options.idle_timeout, Duration::from_secs(20));
        assert_eq!(options.seed, Some(42));
        assert_eq!(options.odometry.rate_hz, 50.0);
        assert_eq!(options.odometry.sigma_speed_mps, 0.2);
        assert_eq!(options.odometry.bias_steer_rad, 0.01);
        assert_eq!(
            options.faults.drop_after_messages.map(|n| n.get()),
            Some(100)
        );
        assert!(options.faults.no_keepalive);
        let SourceSpec::Scene(scene) = &options.source else {
            panic!("a scene source");
        };
        assert_eq!(scene.name, "long-loop");
        // The scene's own CTS350-X radar is kept (config's preset is the default), and the
        // config's 16-bit width applies.
        assert_eq!(scene.preset, RadarPreset::Cts350x400);
        assert_eq!(scene.radar.data_width, DataWidth::Bits16);
    }

    #[cfg(feature = "config")]
    #[test]
    fn the_plain_timeouts_are_the_sim_section_defaults() {
        let scene = crate::scene::shipped::load("penetration-wood").expect("scene");
        // `for_tests` is `new` on 127.0.0.1:0, as fast as possible: the timeouts are `new`'s.
        let plain = SimOptions::for_tests(scene);
        let section = config::sim::SimSettings::default();
        assert_eq!(plain.write_timeout, section.write_timeout);
        assert_eq!(plain.idle_timeout, section.idle_timeout);
    }

    #[test]
    fn hand_made_options_with_impossible_values_are_rejected() {
        let scene = crate::scene::shipped::load("penetration-wood").expect("scene");
        let mut options = SimOptions::for_tests(scene);
        options.max_clients = 0;
        assert!(options.validate().is_err());
        options.max_clients = 3;
        options.odometry.rate_hz = f64::NAN;
        assert!(options.validate().is_err());
        options.odometry.rate_hz = 20.0;
        options.keepalive_interval = Duration::ZERO;
        assert!(options.validate().is_err());
    }
}
