//! The driver's settings: plain values ([`DriverSettings::new`] gives the documented
//! defaults), or, with the `config` feature, the `[radar]` section of the project's
//! configuration in one place ([`DriverSettings::from_config`]). The library proper does not
//! depend on the configuration crate.

use std::net::SocketAddr;
use std::num::NonZeroU32;
use std::path::PathBuf;
use std::time::Duration;

#[cfg(feature = "config")]
use config::radar::ReconnectAttempts;
#[cfg(feature = "config")]
use config::RadarSettings;

use crate::backoff::BackoffPolicy;
use crate::error::SettingsError;
use crate::handoff::HandoffSettings;
use crate::socket::SocketOptions;

/// Everything the driver needs to know.
#[derive(Debug, Clone, PartialEq)]
pub struct DriverSettings {
    /// The radar (or simulator).
    pub address: SocketAddr,
    /// Socket options and connect timeout.
    pub socket: SocketOptions,
    /// No whole frame decoded for this long is a dead link (Navtech's client: 7 s). Bytes
    /// that do not complete a frame do not count.
    pub watchdog_timeout: Duration,
    /// Reconnection delays.
    pub backoff: BackoffPolicy,
    /// Failed attempts in a row before giving up; `None`: never give up.
    pub max_attempts: Option<NonZeroU32>,
    /// Request non-contoured data (140) instead of contoured (21).
    pub non_contoured: bool,
    /// Channels and drop policy.
    pub handoff: HandoffSettings,
    /// Record the raw byte stream here.
    pub record_path: Option<PathBuf>,
    /// Decode errors in a row, without one good frame, after which the link is taken as
    /// garbled and reconnected.
    pub max_consecutive_decode_errors: u32,
    /// Bytes requested per socket read.
    pub read_chunk_bytes: usize,
    /// Time allowed for sending stop (22) at shutdown.
    pub stop_timeout: Duration,
    /// Log lines caused by the wire (a re-sent configuration, an undecodable one, a lost
    /// link, an oversized rotation) repeat at most once per this period each, with a count
    /// of those suppressed. Default 10 s.
    pub log_interval: Duration,
    /// The most bytes of radar data held at once: every azimuth alive (queued, in a
    /// rotation, or with a consumer), the channels' slots and the recording queue (see
    /// [`crate::budget`]). An azimuth that would exceed it is dropped and counted.
    /// Default 64 MiB.
    pub max_held_bytes: usize,
}

/// The default of [`DriverSettings::max_held_bytes`]: 64 MiB.
pub const DEFAULT_MAX_HELD_BYTES: usize = 64 << 20;

impl DriverSettings {
    /// Defaults for `address` (the `[radar]` section's defaults; a test keeps them equal):
    /// 3 s connect timeout, TCP_NODELAY, 4 MiB receive buffer, 7 s watchdog, reconnection
    /// from 100 ms to 5 s with 20 % jitter, forever, contoured data (21), 4096 azimuths and 8
    /// rotations in flight, newest dropped when full, at most 64 MiB of radar data held.
    pub fn new(address: SocketAddr) -> Self {
        Self {
            address,
            socket: SocketOptions {
                connect_timeout: Duration::from_millis(3000),
                tcp_nodelay: true,
                tcp_keepalive: None,
                recv_buffer_bytes: Some(4 << 20),
            },
            watchdog_timeout: Duration::from_millis(7000),
            backoff: BackoffPolicy {
                initial: Duration::from_millis(100),
                max: Duration::from_millis(5000),
                jitter: 0.2,
            },
            max_attempts: None,
            non_contoured: false,
            handoff: HandoffSettings {
                azimuth_capacity: Some(4096),
                rotation_capacity: Some(8),
                drop_policy: crate::handoff::DropPolicy::DropNewest,
            },
            record_path: None,
            max_consecutive_decode_errors: 64,
            read_chunk_bytes: 64 * 1024,
            stop_timeout: Duration::from_millis(500),
            log_interval: Duration::from_secs(10),
            max_held_bytes: DEFAULT_MAX_HELD_BYTES,
        }
    }

    /// The settings of the `[radar]` section.
    #[cfg(feature = "config")]
    pub fn from_config(radar: &RadarSettings) -> Self {
        Self {
            address: radar.address,
            socket: SocketOptions {
                connect_timeout: radar.connect_timeout,
                tcp_nodelay: radar.tcp_nodelay,
                tcp_keepalive: radar.tcp_keepalive,
                recv_buffer_bytes: Some(radar.recv_buffer_bytes.get()),
            },
            watchdog_timeout: radar.watchdog_timeout,
            backoff: BackoffPolicy {
                initial: radar.reconnect_backoff.initial(),
                max: radar.reconnect_backoff.max(),
                jitter: radar.reconnect_backoff.jitter.get(),
            },
            max_attempts: match radar.reconnect_max_attempts {
                ReconnectAttempts::Forever => None,
                ReconnectAttempts::AtMost(n) => Some(n),
            },
            non_contoured: radar.non_contoured,
            handoff: HandoffSettings {
                azimuth_capacity: Some(radar.azimuth_channel_capacity.get()),
                rotation_capacity: Some(radar.rotation_channel_capacity.get()),
                drop_policy: match radar.drop_policy {
                    config::radar::DropPolicy::DropNewest => crate::handoff::DropPolicy::DropNewest,
                    config::radar::DropPolicy::DropOldest => crate::handoff::DropPolicy::DropOldest,
                },
            },
            record_path: radar.record_path.clone(),
            max_consecutive_decode_errors: 64,
            read_chunk_bytes: 64 * 1024,
            stop_timeout: Duration::from_millis(500),
            log_interval: Duration::from_secs(10),
            max_held_bytes: radar.max_held_mib.get().saturating_mul(1 << 20),
        }
    }

    /// The id of the message that starts the FFT stream: 140 or 21.
    pub fn start_message(&self) -> protocol::Message {
        if self.non_contoured {
            protocol::Message::StartNonContourFftData
        } else {
            protocol::Message::StartFftData
        }
    }

    /// Checks what the types cannot.
    pub fn validate(&self) -> Result<(), SettingsError> {
        if self.watchdog_timeout.is_zero() {
            return Err(SettingsError::ZeroWatchdog);
        }
        if self.socket.connect_timeout.is_zero() {
            return Err(SettingsError::ZeroConnectTimeout);
        }
        if self.read_chunk_bytes == 0 {
            return Err(SettingsError::ZeroReadChunk);
        }
        if self.max_consecutive_decode_errors == 0 {
            return Err(SettingsError::ZeroMaxDecodeErrors);
        }
        let slot_bytes = self.handoff.slot_bytes();
        if slot_bytes >= self.max_held_bytes {
            return Err(SettingsError::BudgetBelowChannels {
                slot_bytes,
                max_held_bytes: self.max_held_bytes,
            });
        }
        if self.backoff.initial > self.backoff.max {
            return Err(SettingsError::BackoffInitialExceedsMax {
                initial: self.backoff.initial,
                max: self.backoff.max,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_budget_the_channels_slots_alone_would_fill_is_refused() {
        let mut s = DriverSettings::new(SocketAddr::from(([127, 0, 0, 1], 0)));
        assert_eq!(s.validate(), Ok(()));
        s.handoff.azimuth_capacity = Some(1 << 20);
        s.max_held_bytes = 1 << 20;
        assert!(matches!(
            s.validate(),
            Err(SettingsError::BudgetBelowChannels { .. })
        ));
    }

    #[cfg(feature = "config")]
    #[test]
    fn the_configuration_bounds_a_channel_slot_from_above() {
        let word = std::mem::size_of::<usize>();
        for slot in [
            std::mem::size_of::<crate::Azimuth>() + word,
            std::mem::size_of::<crate::Rotation>() + word,
        ] {
            assert!(slot <= config::radar::SLOT_BYTES_BOUND, "{slot}");
        }
    }

    #[cfg(feature = "config")]
    #[test]
    fn the_plain_defaults_are_the_configuration_defaults() {
        let from_config = DriverSettings::from_config(&RadarSettings::default());
        assert_eq!(DriverSettings::new(from_config.address), from_config);
    }
}
