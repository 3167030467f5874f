//! Odometry over TCP: the line stream of [`super::line_stream`] with the odometry's parser,
//! behind the synchronous [`OdometrySource`] seam.

use std::time::Duration;

use crossbeam_channel::RecvTimeoutError;
use tokio::runtime::Handle;

use super::line_stream::{
    LineStreamClient, LineStreamSettings, LineStreamStats, LineStreamStatsSnapshot,
};
use super::{OdometryError, OdometryPoll, OdometrySource, RecordParser};
use crate::shutdown::Shutdown;

/// Where and how to read the odometry stream (1024 records buffered by default).
pub type TcpOdometrySettings = LineStreamSettings;

/// Counters of the TCP odometry task.
pub type OdometryStats = LineStreamStats;

/// A copy of [`OdometryStats`].
pub type OdometryStatsSnapshot = LineStreamStatsSnapshot;

/// The reading end of a TCP odometry stream.
#[derive(Debug)]
pub struct TcpOdometry {
    client: LineStreamClient<RecordParser>,
}

impl TcpOdometry {
    /// Starts the connection task on `runtime`; it runs until `shutdown` fires or this value
    /// is dropped.
    pub fn spawn(runtime: &Handle, settings: TcpOdometrySettings, shutdown: Shutdown) -> Self {
        Self {
            client: LineStreamClient::spawn(runtime, settings, RecordParser::new(), shutdown),
        }
    }

    /// The task's counters.
    pub fn stats(&self) -> OdometryStatsSnapshot {
        self.client.stats()
    }
}

impl OdometrySource for TcpOdometry {
    fn poll_next(&mut self, timeout: Duration) -> Result<OdometryPoll, OdometryError> {
        match self.client.recv(timeout) {
            Ok(Ok(record)) => Ok(OdometryPoll::Record(record)),
            Ok(Err(bad)) => Err(OdometryError::Line {
                line: bad.line,
                source: bad.error,
            }),
            Err(RecvTimeoutError::Timeout) => Ok(OdometryPoll::Pending),
            Err(RecvTimeoutError::Disconnected) => Ok(OdometryPoll::Ended),
        }
    }
}
