//! Errors, layered: [`protocol::DecodeError`] (one bad frame) -> [`SessionError`] (one
//! connection) -> [`DriverError`] (the driver as a whole).
//!
//! A decode error costs one frame and is counted, not returned, unless the stream stays
//! garbled; a session error costs a reconnect; only a [`DriverError`] ends the driver.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

/// Why one connection ended.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// Creating the socket or setting an option failed.
    #[error("socket setup failed: {0}")]
    SocketOption(#[source] std::io::Error),
    /// The radar refused or the network failed while connecting.
    #[error("connecting to {addr} failed: {source}")]
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
    #[error("reading from the radar failed: {0}")]
    Read(#[source] std::io::Error),
    /// Writing a command to the radar failed (or timed out).
    #[error("sending message {message_id} to the radar failed: {source}")]
    Write {
        /// The Colossus message id being sent.
        message_id: u8,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The radar closed the connection.
    #[error("the radar closed the connection")]
    Closed,
    /// Nothing at all was received for the watchdog period.
    #[error("nothing received for {0:?}: link presumed dead")]
    Watchdog(Duration),
    /// The radar's configuration does not describe a usable geometry.
    #[error("the radar's configuration is unusable: {0}")]
    BadConfiguration(#[from] protocol::GeometryError),
    /// The stream stayed garbled: this many decode errors in a row without one good frame.
    #[error("{count} decode errors in a row without a good frame; last: {last}")]
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

/// Why the driver stopped.
#[derive(Debug, thiserror::Error)]
pub enum DriverError {
    /// The configured number of reconnection attempts failed in a row.
    #[error("gave up after {attempts} failed connection attempts; last: {last}")]
    GaveUp {
        /// Failed attempts in a row.
        attempts: u32,
        /// The last failure.
        #[source]
        last: SessionError,
    },
    /// The recording file could not be created.
    #[error("cannot create the recording {path}: {source}")]
    Record {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Settings that cannot work (for example a zero watchdog period).
    #[error("invalid driver settings: {0}")]
    Settings(String),
    /// The driver task panicked or was aborted.
    #[error("the driver task ended abnormally: {0}")]
    Task(#[from] tokio::task::JoinError),
}
