//! Errors, layered: [`protocol::DecodeError`] (one bad frame) -> [`SessionError`] (one
//! connection) -> [`DriverError`] (the driver as a whole).
//!
//! A decode error costs one frame and is counted, not returned, unless the stream stays
//! garbled; a session error costs a reconnect; only a [`DriverError`] ends the driver.
//!
//! Every variant that wraps a cause keeps it as its `source` and does not repeat it in its
//! own message; [`ErrorChain`] prints the whole chain on one line (as the driver's logs do).

use std::fmt;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

/// Why one connection ended.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// Creating the socket or setting an option failed.
    #[error("setting up the socket failed")]
    SocketOption(#[source] std::io::Error),
    /// The radar refused or the network failed while connecting.
    #[error("connecting to {addr} failed")]
    Connect {
        /// Where.
        addr: SocketAddr,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// No connection within the connect timeout.
    #[error("connecting to {addr} timed out after {timeout:?}")]
    ConnectTimeout {
        /// Where.
        addr: SocketAddr,
        /// The timeout.
        timeout: Duration,
    },
    /// Reading from the socket failed.
    #[error("reading from the radar failed")]
    Read(#[source] std::io::Error),
    /// A command to the radar could not be encoded.
    #[error("encoding message {message_id} for the radar failed")]
    Encode {
        /// The Colossus message id being sent.
        message_id: u8,
        /// Why.
        #[source]
        source: protocol::EncodeError,
    },
    /// Writing a command to the radar failed.
    #[error("sending message {message_id} to the radar failed")]
    Write {
        /// The Colossus message id being sent.
        message_id: u8,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Writing a command to the radar did not finish in time.
    #[error("sending message {message_id} to the radar timed out after {timeout:?}")]
    WriteTimeout {
        /// The Colossus message id being sent.
        message_id: u8,
        /// The time allowed.
        timeout: Duration,
    },
    /// The radar closed the connection.
    #[error("the radar closed the connection")]
    Closed,
    /// No whole frame was decoded for the watchdog period (bytes that never complete a
    /// frame do not count).
    #[error("no whole frame received for {0:?}: link presumed dead")]
    Watchdog(Duration),
    /// The radar's configuration does not describe a usable geometry: the driver refuses
    /// it, asks for no data on that connection, and reconnects.
    #[error("the radar's configuration is unusable")]
    BadConfiguration(#[from] protocol::GeometryError),
    /// The stream stayed garbled: this many decode errors in a row without one good frame.
    #[error("{count} decode errors in a row without a good frame")]
    Garbled {
        /// Consecutive errors.
        count: u32,
        /// The last one.
        #[source]
        last: protocol::DecodeError,
    },
}

impl SessionError {
    /// True when the connection was established before it failed (the radar was reached).
    pub fn after_connect(&self) -> bool {
        !matches!(
            self,
            SessionError::SocketOption(_)
                | SessionError::Connect { .. }
                | SessionError::ConnectTimeout { .. }
        )
    }
}

/// Settings that cannot work, found by [`crate::DriverSettings::validate`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SettingsError {
    /// A zero watchdog period.
    #[error("watchdog_timeout must be > 0")]
    ZeroWatchdog,
    /// A zero connect timeout.
    #[error("connect_timeout must be > 0")]
    ZeroConnectTimeout,
    /// Zero bytes per socket read.
    #[error("read_chunk_bytes must be > 0")]
    ZeroReadChunk,
    /// Zero decode errors allowed in a row.
    #[error("max_consecutive_decode_errors must be > 0")]
    ZeroMaxDecodeErrors,
    /// The channels' slot arrays alone would take the whole byte budget.
    #[error("the channels' slots take {slot_bytes} bytes, not below the byte budget max_held_bytes = {max_held_bytes}: raise the budget or lower the capacities")]
    BudgetBelowChannels {
        /// Bytes of the channels' slot arrays.
        slot_bytes: usize,
        /// The budget.
        max_held_bytes: usize,
    },
    /// The first reconnect delay exceeds the longest.
    #[error("reconnect initial backoff {initial:?} exceeds the maximum {max:?}")]
    BackoffInitialExceedsMax {
        /// First delay.
        initial: Duration,
        /// Longest delay.
        max: Duration,
    },
}

/// Why the driver stopped.
#[derive(Debug, thiserror::Error)]
pub enum DriverError {
    /// The configured number of reconnection attempts failed in a row.
    #[error("gave up after {attempts} failed connection attempts")]
    GaveUp {
        /// Failed attempts in a row.
        attempts: u32,
        /// The last failure.
        #[source]
        last: SessionError,
    },
    /// The recording file could not be created.
    #[error("cannot create the recording {path}")]
    Record {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Settings that cannot work (for example a zero watchdog period).
    #[error("invalid driver settings")]
    Settings(#[from] SettingsError),
    /// [`crate::DriverHandle::join`] found no task to wait for.
    #[error("the driver was already joined")]
    AlreadyJoined,
    /// The driver task panicked or was aborted.
    #[error("the driver task ended abnormally")]
    Task(#[from] tokio::task::JoinError),
}

/// Displays an error and each of its sources, separated by `": "`, on one line. A source
/// whose text is already in the line (an error type that repeats its cause in its own
/// message) is not written twice: `No such file or directory (os error 2)`, once.
#[derive(Debug, Clone, Copy)]
pub struct ErrorChain<'a>(pub &'a (dyn std::error::Error + 'static));

impl fmt::Display for ErrorChain<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut text = self.0.to_string();
        let mut next = self.0.source();
        while let Some(e) = next {
            let link = e.to_string();
            if !link.is_empty() && !text.contains(&link) {
                text.push_str(": ");
                text.push_str(&link);
            }
            next = e.source();
        }
        f.write_str(&text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wrapping_error_does_not_repeat_its_cause_and_the_chain_names_it_once() {
        let e = DriverError::GaveUp {
            attempts: 3,
            last: SessionError::Read(std::io::Error::other("boom")),
        };
        assert_eq!(e.to_string(), "gave up after 3 failed connection attempts");
        assert_eq!(
            ErrorChain(&e).to_string(),
            "gave up after 3 failed connection attempts: reading from the radar failed: boom"
        );
        let bad =
            SessionError::BadConfiguration(protocol::GeometryError::NonPositiveRangeGain(0.0));
        assert_eq!(
            ErrorChain(&bad).to_string(),
            "the radar's configuration is unusable: range gain 0 is not positive"
        );
    }
}
