//! `[radar]`: how the driver reaches the radar (or the simulator) and what it does when the
//! link is slow, silent or gone.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::values::{self, Capacity, Probability, ValueError};

/// Largest receive buffer accepted: 256 MiB.
pub const MAX_RECV_BUFFER_BYTES: usize = 256 << 20;
/// Largest channel capacity accepted (azimuths or rotations in flight).
pub const MAX_CHANNEL_CAPACITY: usize = 1 << 20;
/// Largest byte budget accepted for the radar data the driver holds, MiB.
pub const MAX_HELD_MIB: usize = 16_384;
/// Bytes counted per channel slot (azimuth or rotation) against `max_held_mib` when
/// checking that the channels fit: an upper bound of the driver's slot size, which the
/// driver's tests check.
pub const SLOT_BYTES_BOUND: usize = 128;

/// What the driver does when the consumer is slower than the radar and a channel is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DropPolicy {
    /// Keep what is queued; discard the item that does not fit (counted).
    DropNewest,
    /// Discard the oldest queued item to make room for the new one (counted).
    DropOldest,
}

/// `[radar]` as written in the file: every field optional, defaults documented per field.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawRadar {
    /// Radar address `ip:port`. Default `127.0.0.1:6317` (a real Navtech unit is
    /// `192.168.0.1:6317`).
    pub address: String,
    /// TCP connect timeout, ms > 0. Default 3000.
    pub connect_timeout_ms: i64,
    /// Set TCP_NODELAY. Default true.
    pub tcp_nodelay: bool,
    /// TCP keep-alive idle time in seconds, > 0; absent leaves the OS default. Default absent.
    pub tcp_keepalive_s: Option<f64>,
    /// Socket receive buffer, bytes in `[1, 256 MiB]`. Default 4 MiB.
    pub recv_buffer_bytes: i64,
    /// Nothing received for this long (ms > 0) means the link is dead. Default 7000, as
    /// Navtech's own client.
    pub watchdog_timeout_ms: i64,
    /// First reconnect delay, ms > 0. Default 100.
    pub reconnect_initial_backoff_ms: i64,
    /// Longest reconnect delay, ms >= the initial one. Default 5000.
    pub reconnect_max_backoff_ms: i64,
    /// Relative jitter on each delay, in `[0, 1]`. Default 0.2.
    pub reconnect_jitter: f64,
    /// Attempts before giving up; 0 means forever. Default 0.
    pub reconnect_max_attempts: i64,
    /// false: request contoured FFT data (message 21); true: non-contoured (message 140).
    /// Default false.
    pub non_contoured: bool,
    /// Azimuths in flight between the driver and the filter, `[1, 2^20]`. Default 4096.
    pub azimuth_channel_capacity: i64,
    /// Whole rotations in flight, `[1, 2^20]`. Default 8.
    pub rotation_channel_capacity: i64,
    /// `"drop-newest"` or `"drop-oldest"`. Default `"drop-newest"`.
    pub drop_policy: DropPolicy,
    /// The most radar data the driver holds at once, MiB in `[1, 16384]`: every azimuth
    /// alive (queued, in a rotation being assembled or queued, or with the consumer; its
    /// bins plus a fixed overhead of a few hundred bytes), the channels' slots (about 80
    /// bytes per slot of `azimuth_channel_capacity` and `rotation_channel_capacity`) and the
    /// recording queue. An azimuth that would exceed it is dropped, counted and logged
    /// (rate-limited); under drop-oldest the oldest queued items go first. The capacities'
    /// slots must fit well inside it. Default 64 (a CTS350-X sends about 6 MB/s).
    pub max_held_mib: i64,
    /// Record the raw byte stream to this file. Default absent (no recording).
    pub record_path: Option<PathBuf>,
    /// The radar's model, naming its profile (`paper-2006`, `cts350x`, `cts350x-radiate`,
    /// `cir204h`, `cir304h`, `sim-cts350x`: radar-model's `profile`; `slam-node --radar-profiles` prints
    /// them). Default absent: the profile is chosen
    /// from what the radar announces at connection (azimuths, encoder size, bins, bin
    /// size, rotation rate), the nearest with a WARN when none matches.
    pub model: Option<String>,
}

impl Default for RawRadar {
    fn default() -> Self {
        Self {
            address: "127.0.0.1:6317".into(),
            connect_timeout_ms: 3000,
            tcp_nodelay: true,
            tcp_keepalive_s: None,
            recv_buffer_bytes: 4 << 20,
            watchdog_timeout_ms: 7000,
            reconnect_initial_backoff_ms: 100,
            reconnect_max_backoff_ms: 5000,
            reconnect_jitter: 0.2,
            reconnect_max_attempts: 0,
            non_contoured: false,
            azimuth_channel_capacity: 4096,
            rotation_channel_capacity: 8,
            drop_policy: DropPolicy::DropNewest,
            max_held_mib: 64,
            record_path: None,
            model: None,
        }
    }
}

/// How many times to try reconnecting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ReconnectAttempts {
    /// Never give up (`reconnect_max_attempts = 0`).
    Forever,
    /// Give up after this many failed attempts.
    AtMost(std::num::NonZeroU32),
}

/// Reconnect delays: exponential from `initial` up to `max`, each scaled by a random factor
/// in `[1 - jitter, 1 + jitter]`. `initial <= max` always holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backoff {
    initial: Duration,
    max: Duration,
    /// Relative jitter.
    pub jitter: Probability,
}

impl Backoff {
    /// A backoff; `initial` must not exceed `max`.
    pub fn new(initial: Duration, max: Duration, jitter: Probability) -> Result<Self, ValueError> {
        if initial > max {
            return Err(ValueError::Rule(format!(
                "must be <= the maximum backoff ({} ms), got {} ms",
                max.as_millis(),
                initial.as_millis()
            )));
        }
        Ok(Self {
            initial,
            max,
            jitter,
        })
    }
    /// The first delay.
    pub fn initial(&self) -> Duration {
        self.initial
    }
    /// The longest delay.
    pub fn max(&self) -> Duration {
        self.max
    }
}

/// `[radar]`, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct RadarSettings {
    /// Where the radar listens.
    pub address: SocketAddr,
    /// TCP connect timeout.
    pub connect_timeout: Duration,
    /// Set TCP_NODELAY.
    pub tcp_nodelay: bool,
    /// TCP keep-alive idle time; `None` leaves the OS default.
    pub tcp_keepalive: Option<Duration>,
    /// Socket receive buffer size in bytes.
    pub recv_buffer_bytes: Capacity,
    /// Silence longer than this is a dead link.
    pub watchdog_timeout: Duration,
    /// Reconnect delays.
    pub reconnect_backoff: Backoff,
    /// Reconnect attempts.
    pub reconnect_max_attempts: ReconnectAttempts,
    /// Request non-contoured data (140) instead of contoured (21).
    pub non_contoured: bool,
    /// Azimuth channel capacity.
    pub azimuth_channel_capacity: Capacity,
    /// Rotation channel capacity.
    pub rotation_channel_capacity: Capacity,
    /// What to drop when a channel is full.
    pub drop_policy: DropPolicy,
    /// The byte budget of the radar data held, MiB.
    pub max_held_mib: Capacity,
    /// Raw stream recording file.
    pub record_path: Option<PathBuf>,
    /// The radar's model (its profile's name); `None`: chosen from what the radar announces.
    pub model: Option<String>,
}

impl RadarSettings {
    /// The Colossus message id that starts the FFT stream: 140 when non-contoured, else 21.
    pub fn start_fft_message_id(&self) -> u8 {
        if self.non_contoured {
            140
        } else {
            21
        }
    }
}

impl Default for RadarSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let settings = RawRadar::default().check(&mut c);
        debug_assert!(c.is_clean(), "the [radar] defaults must be valid");
        settings
    }
}

impl RawRadar {
    /// Validates this section alone; errors name `radar.<field>`.
    pub fn validate(&self) -> Result<RadarSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c);
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker) -> RadarSettings {
        let initial = c.check_ok(
            "radar.reconnect_initial_backoff_ms",
            values::duration_from_ms(self.reconnect_initial_backoff_ms),
        );
        let max = c.check_ok(
            "radar.reconnect_max_backoff_ms",
            values::duration_from_ms(self.reconnect_max_backoff_ms),
        );
        let jitter = c.check(
            "radar.reconnect_jitter",
            Probability::new(self.reconnect_jitter),
        );
        let reconnect_backoff = match (initial, max) {
            (Some(initial), Some(max)) => c
                .check_ok(
                    "radar.reconnect_initial_backoff_ms",
                    Backoff::new(initial, max, jitter),
                )
                .unwrap_or(Backoff {
                    initial: max,
                    max,
                    jitter,
                }),
            (initial, max) => {
                let d = initial.or(max).unwrap_or(Duration::from_secs(1));
                Backoff {
                    initial: d,
                    max: d,
                    jitter,
                }
            }
        };
        let attempts = c.check(
            "radar.reconnect_max_attempts",
            values::count(self.reconnect_max_attempts, u64::from(u32::MAX)),
        );
        let reconnect_max_attempts = u32::try_from(attempts)
            .ok()
            .and_then(std::num::NonZeroU32::new)
            .map_or(ReconnectAttempts::Forever, ReconnectAttempts::AtMost);
        let azimuth_channel_capacity = c.check_ok(
            "radar.azimuth_channel_capacity",
            Capacity::new(self.azimuth_channel_capacity, MAX_CHANNEL_CAPACITY),
        );
        let rotation_channel_capacity = c.check_ok(
            "radar.rotation_channel_capacity",
            Capacity::new(self.rotation_channel_capacity, MAX_CHANNEL_CAPACITY),
        );
        let max_held_mib = c.check_ok(
            "radar.max_held_mib",
            Capacity::new(self.max_held_mib, MAX_HELD_MIB),
        );
        // The channels' slots are part of the budget; they must leave most of it for data.
        if let (Some(az), Some(rot), Some(held)) = (
            azimuth_channel_capacity,
            rotation_channel_capacity,
            max_held_mib,
        ) {
            let slots = az.get().saturating_add(rot.get());
            let slot_bytes = slots.saturating_mul(SLOT_BYTES_BOUND);
            let budget = held.get().saturating_mul(1 << 20);
            if slot_bytes > budget / 2 {
                c.fail(
                    "radar.max_held_mib",
                    ValueError::Rule(format!(
                        "must be at least twice the channels' slots (radar.azimuth_channel_capacity + \
                         radar.rotation_channel_capacity = {slots} slots of up to {SLOT_BYTES_BOUND} \
                         bytes = {slot_bytes} bytes), got {budget} bytes"
                    )),
                );
            }
        }
        let settings = RadarSettings {
            address: c.check("radar.address", values::socket_addr(&self.address)),
            connect_timeout: c.check(
                "radar.connect_timeout_ms",
                values::duration_from_ms(self.connect_timeout_ms),
            ),
            tcp_nodelay: self.tcp_nodelay,
            tcp_keepalive: c.check_opt(
                "radar.tcp_keepalive_s",
                self.tcp_keepalive_s,
                values::duration_from_s,
            ),
            recv_buffer_bytes: c.check(
                "radar.recv_buffer_bytes",
                Capacity::new(self.recv_buffer_bytes, MAX_RECV_BUFFER_BYTES),
            ),
            watchdog_timeout: c.check(
                "radar.watchdog_timeout_ms",
                values::duration_from_ms(self.watchdog_timeout_ms),
            ),
            reconnect_backoff,
            reconnect_max_attempts,
            non_contoured: self.non_contoured,
            azimuth_channel_capacity: azimuth_channel_capacity.unwrap_or(Capacity::ONE),
            rotation_channel_capacity: rotation_channel_capacity.unwrap_or(Capacity::ONE),
            drop_policy: self.drop_policy,
            max_held_mib: max_held_mib.unwrap_or(Capacity::ONE),
            record_path: c.check_opt(
                "radar.record_path",
                self.record_path.as_deref(),
                values::non_empty_path,
            ),
            model: c.check_opt("radar.model", self.model.as_deref(), model_name),
        };
        settings
    }
}

impl From<&RadarSettings> for RawRadar {
    /// The settings written back out (durations in whole milliseconds, rounded up).
    fn from(s: &RadarSettings) -> Self {
        Self {
            address: s.address.to_string(),
            connect_timeout_ms: values::whole_ms(s.connect_timeout),
            tcp_nodelay: s.tcp_nodelay,
            tcp_keepalive_s: s.tcp_keepalive.map(|d| d.as_secs_f64()),
            recv_buffer_bytes: values::as_i64(s.recv_buffer_bytes.get()),
            watchdog_timeout_ms: values::whole_ms(s.watchdog_timeout),
            reconnect_initial_backoff_ms: values::whole_ms(s.reconnect_backoff.initial),
            reconnect_max_backoff_ms: values::whole_ms(s.reconnect_backoff.max),
            reconnect_jitter: s.reconnect_backoff.jitter.get(),
            reconnect_max_attempts: match s.reconnect_max_attempts {
                ReconnectAttempts::Forever => 0,
                ReconnectAttempts::AtMost(n) => i64::from(n.get()),
            },
            non_contoured: s.non_contoured,
            azimuth_channel_capacity: values::as_i64(s.azimuth_channel_capacity.get()),
            rotation_channel_capacity: values::as_i64(s.rotation_channel_capacity.get()),
            drop_policy: s.drop_policy,
            max_held_mib: values::as_i64(s.max_held_mib.get()),
            record_path: s.record_path.clone(),
            model: s.model.clone(),
        }
    }
}

/// Longest `[radar] model` name accepted.
const MAX_MODEL_NAME: usize = 64;

/// A radar model's name: letters, digits, `-` and `_`, 1 to 64 of them. Whether it names a
/// profile is checked by the daemon, which owns the profiles (radar-model's `profile`).
fn model_name(name: &str) -> Result<String, ValueError> {
    if name.is_empty() {
        return Err(ValueError::Empty);
    }
    if name.len() > MAX_MODEL_NAME
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
    {
        return Err(ValueError::Rule(format!(
            "must be a radar model's name (letters, digits, '-', '_', at most {MAX_MODEL_NAME}), got {name:?}"
        )));
    }
    Ok(name.to_owned())
}
