//! Async tokio client for a Navtech radar speaking the Colossus protocol (or the project's
//! simulator): it keeps the radar's stream flowing into the filter.
//!
//! **Does IO**: TCP sockets (radar and odometry), timers, an optional recording file, and a
//! writer thread for it. The wire format itself is the `protocol` crate's.
//!
//! - [`socket`]: socket options (TCP_NODELAY, keep-alive, receive buffer, connect timeout)
//!   set in one place from the `[radar]` settings.
//! - [`session`]: one connection: read the configuration (10), request data (21 or 140),
//!   decode, hand off; a keep-alive watchdog declares a silent link dead.
//! - [`liveness`]: how the watchdog and the odometry link's idle timeout judge a silence:
//!   by what the socket holds, and with a moment more after this process was not running.
//! - [`driver`]: reconnection with exponential backoff and jitter, forever by default;
//!   session state (counters, rotation assembly, geometry) survives reconnections; a
//!   cancellation handle stops it cleanly (stop FFT data, 22, before closing).
//! - [`assembly`]: azimuths into [`Rotation`]s, counting skipped azimuths and sweep-counter
//!   gaps.
//! - [`handoff`]: the [`Sink`] seam and bounded crossbeam channels with a counted drop policy.
//! - [`budget`]: the memory bound in bytes: every azimuth's bins are copied out of the read
//!   buffer into an allocation charged to one [`ByteBudget`] until its last copy is dropped.
//! - [`stream`]: the same hand-off as async streams ([`Driver::with_streams`]).
//! - [`metrics`]: lock-free counters and read-to-send latency (median, p99).
//! - [`record`]: raw byte-stream recording.
//! - [`odometry`]: the odometry stream client (TCP, file) behind [`OdometrySource`].
//! - [`clock`]: the [`Clock`] seam.
//!
//! ```no_run
//! // `radar`: the unit's address (a Navtech radar listens on TCP port 6317); in tests, a
//! // listener bound to 127.0.0.1:0 and its port read back.
//! # async fn demo(radar: std::net::SocketAddr) -> Result<(), radar_driver::DriverError> {
//! use radar_driver::{Driver, DriverSettings};
//! let (driver, receivers) = Driver::new(DriverSettings::new(radar));
//! let handle = driver.spawn();
//! let azimuths = receivers.azimuths.expect("azimuth channel configured");
//! std::thread::spawn(move || {
//!     for azimuth in azimuths {
//!         let _peak = azimuth.bins_db().fold(f64::MIN, f64::max);
//!     }
//! });
//! // ... later:
//! let exit = handle.stop().await?;
//! println!("{} azimuths, {} dropped", exit.metrics.azimuths_sent, exit.metrics.azimuth_drops);
//! # Ok(()) }
//! ```

pub mod assembly;
pub mod azimuth;
pub mod backoff;
pub mod budget;
pub mod clock;
pub mod driver;
pub mod error;
pub mod handoff;
pub mod liveness;
pub mod metrics;
pub mod odometry;
pub mod ratelimit;
pub mod record;
pub mod session;
pub mod settings;
pub mod shutdown;
pub mod socket;
pub mod stream;

pub use assembly::RotationAssembler;
pub use azimuth::{Azimuth, Rotation};
pub use budget::{ByteBudget, Charge, AZIMUTH_OVERHEAD_BYTES};
pub use clock::{Clock, SystemClock};
pub use driver::{ConfigurationWatch, Driver, DriverExit, DriverHandle};
pub use error::{DriverError, ErrorChain, SessionError, SettingsError};
pub use handoff::{ChannelSink, Delivery, DropPolicy, HandoffSettings, Receivers, Shed, Sink};
pub use metrics::{DecodeErrorCounts, DecodeErrorKind, LatencySummary, Metrics, MetricsSnapshot};
pub use odometry::{
    FileOdometry, OdometryError, OdometryPoll, OdometryRecord, OdometrySource, TcpOdometry,
    TcpOdometrySettings,
};
pub use protocol::{BinWidth, Geometry};
pub use ratelimit::RateLimiter;
pub use settings::{DriverSettings, DEFAULT_MAX_HELD_BYTES};
pub use shutdown::{shutdown_pair, stop_signal, Shutdown, ShutdownTrigger, StopSignal};
pub use stream::{AzimuthStream, RotationStream, StreamSink, Streams};
