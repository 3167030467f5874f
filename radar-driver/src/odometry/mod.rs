//! Odometry: the vehicle's speed and steering, read from the stream format of
//! `docs/contracts.md` over TCP ([`TcpOdometry`]) or from a file ([`FileOdometry`]), behind
//! the [`OdometrySource`] seam so the daemon and tests can substitute their own.
//!
//! The seam is synchronous: the filter runs on its own thread without async. The line
//! format's shared checks ([`split_line`], [`decimal`]), the line files' reader
//! ([`LineReader`]) and the TCP line-stream client ([`LineStreamClient`], generic over a
//! [`LineParser`]) serve slam-node's gyro stream as well.

mod file;
mod format;
mod line_stream;
mod lines;
mod tcp;

pub use file::FileOdometry;
pub use format::{
    decimal, parse_line, split_line, Fields, Line, LineError, LineSplitter, OdometryRecord,
    RecordParser, MAX_LINE_BYTES, MAX_TIMESTAMP_DECIMALS, ODOMETRY_HEADER,
};
pub use line_stream::{
    BadLine, LineItem, LineParser, LineStreamClient, LineStreamSettings, LineStreamStats,
    LineStreamStatsSnapshot,
};
pub use lines::{open_regular, LineReader};
pub use tcp::{OdometryStats, OdometryStatsSnapshot, TcpOdometry, TcpOdometrySettings};

use std::path::PathBuf;
use std::time::Duration;

/// The result of asking a source for its next record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OdometryPoll {
    /// A record.
    Record(OdometryRecord),
    /// Nothing yet (a live source within the timeout).
    Pending,
    /// The source has no more records (end of file, or the source was shut down).
    Ended,
}

/// Polls a channel of records as a source does: `Pending` when nothing arrives within
/// `timeout` (at once when it is zero), `Ended` once every sender is gone. For sources that
/// decode on another thread and hand records over a channel (a recording's reader, a
/// middleware subscription).
pub fn poll_channel(
    rx: &crossbeam_channel::Receiver<OdometryRecord>,
    timeout: Duration,
) -> OdometryPoll {
    use crossbeam_channel::RecvTimeoutError;
    match recv_within(rx, timeout) {
        Ok(r) => OdometryPoll::Record(r),
        Err(RecvTimeoutError::Timeout) => OdometryPoll::Pending,
        Err(RecvTimeoutError::Disconnected) => OdometryPoll::Ended,
    }
}

/// The next item of `rx` within `timeout`; with a zero timeout, without waiting at all.
/// (crossbeam's `recv_timeout` spins, then yields the thread four times before it looks at
/// its deadline: on a loaded machine each yield hands the core away for a scheduler slice,
/// and a pipeline that polls once an azimuth spent 11.5 ms an azimuth there.)
fn recv_within<T>(
    rx: &crossbeam_channel::Receiver<T>,
    timeout: Duration,
) -> Result<T, crossbeam_channel::RecvTimeoutError> {
    use crossbeam_channel::{RecvTimeoutError, TryRecvError};
    if timeout.is_zero() {
        return rx.try_recv().map_err(|e| match e {
            TryRecvError::Empty => RecvTimeoutError::Timeout,
            TryRecvError::Disconnected => RecvTimeoutError::Disconnected,
        });
    }
    rx.recv_timeout(timeout)
}

/// Why a source could not give a record.
#[derive(Debug, thiserror::Error)]
pub enum OdometryError {
    /// One line was bad; the source carries on with the next one.
    #[error("odometry line {line} is malformed")]
    Line {
        /// 1-based line number within the file or connection.
        line: u64,
        /// What was wrong.
        #[source]
        source: LineError,
    },
    /// The odometry file cannot be opened.
    #[error("cannot open odometry file {path}")]
    Open {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Reading the file failed; the source has ended.
    #[error("reading odometry failed")]
    Read(#[source] std::io::Error),
    /// The configured source is not one this crate opens (`zenoh`: slam-node subscribes to
    /// it on its own Zenoh session).
    #[error("odometry source \"{0}\" is opened by slam-node, not by radar-driver")]
    OpenedElsewhere(&'static str),
}

impl OdometryError {
    /// True when the source can carry on after this error (it cost one line only).
    pub fn is_recoverable(&self) -> bool {
        matches!(self, OdometryError::Line { .. })
    }
}

/// A source of odometry records in time order.
pub trait OdometrySource: Send {
    /// The next record, waiting at most `timeout` for a live source (a file answers at once).
    /// A recoverable error costs one line: call again for the next.
    fn poll_next(&mut self, timeout: Duration) -> Result<OdometryPoll, OdometryError>;
}

#[cfg(feature = "config")]
/// Opens the source the `[odometry]` section names: a [`TcpOdometry`] (spawned on
/// `runtime`, stopped by `shutdown`), a [`FileOdometry`], or `None` for `source = "none"`;
/// `source = "zenoh"` is [`OdometryError::OpenedElsewhere`] (slam-node opens it).
pub fn open_configured(
    settings: &config::OdometrySettings,
    runtime: &tokio::runtime::Handle,
    shutdown: crate::shutdown::Shutdown,
) -> Result<Option<Box<dyn OdometrySource>>, OdometryError> {
    Ok(match &settings.source {
        config::odometry::OdometrySource::Tcp { address } => Some(Box::new(TcpOdometry::spawn(
            runtime,
            TcpOdometrySettings::new(*address),
            shutdown,
        ))),
        config::odometry::OdometrySource::File { path } => {
            Some(Box::new(FileOdometry::open(path)?))
        }
        config::odometry::OdometrySource::Zenoh { .. } => {
            return Err(OdometryError::OpenedElsewhere("zenoh"))
        }
        config::odometry::OdometrySource::None => None,
    })
}
