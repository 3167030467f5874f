//! Odometry over TCP: a tokio task keeps the connection (reconnecting with backoff) and hands
//! records to the synchronous [`OdometrySource`] side through a bounded channel.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crossbeam_channel::{bounded, Receiver, RecvTimeoutError, Sender, TrySendError};
use tokio::io::AsyncReadExt;
use tokio::runtime::Handle;
use tokio::task::JoinHandle;

use super::{LineSplitter, OdometryError, OdometryPoll, OdometrySource, RecordParser};
use crate::backoff::{Backoff, BackoffPolicy};
use crate::liveness::{bytes_waiting, resume_grace};
use crate::shutdown::Shutdown;
use crate::socket::{connect, SocketOptions};

/// Where and how to read the odometry stream.
#[derive(Debug, Clone, PartialEq)]
pub struct TcpOdometrySettings {
    /// The odometry server.
    pub address: SocketAddr,
    /// Socket options and connect timeout.
    pub socket: SocketOptions,
    /// Reconnection delays.
    pub backoff: BackoffPolicy,
    /// Nothing received for this long is a dead link: reconnect (unless records are waiting
    /// in the socket, or the deadline was noticed late: see [`crate::liveness`]).
    pub idle_timeout: Duration,
    /// Records (and line errors) buffered for the reader; beyond it the newest is dropped.
    pub capacity: usize,
}

impl TcpOdometrySettings {
    /// Defaults for `address`: 3 s connect timeout, 7 s idle timeout, 1024 records buffered.
    pub fn new(address: SocketAddr) -> Self {
        Self {
            address,
            socket: SocketOptions {
                recv_buffer_bytes: None,
                ..SocketOptions::default()
            },
            backoff: BackoffPolicy::default(),
            idle_timeout: Duration::from_secs(7),
            capacity: 1024,
        }
    }
}

/// Counters of the TCP odometry task.
#[derive(Debug, Default)]
pub struct OdometryStats {
    records: AtomicU64,
    line_errors: AtomicU64,
    drops: AtomicU64,
    connections: AtomicU64,
    connect_failures: AtomicU64,
}

/// A copy of [`OdometryStats`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct OdometryStatsSnapshot {
    /// Records parsed.
    pub records: u64,
    /// Lines rejected.
    pub line_errors: u64,
    /// Records or errors dropped because the reader was behind.
    pub drops: u64,
    /// Connections established.
    pub connections: u64,
    /// Connection attempts that failed.
    pub connect_failures: u64,
}

impl OdometryStats {
    /// A copy of the counters.
    pub fn snapshot(&self) -> OdometryStatsSnapshot {
        let g = |a: &AtomicU64| a.load(Ordering::Relaxed);
        OdometryStatsSnapshot {
            records: g(&self.records),
            line_errors: g(&self.line_errors),
            drops: g(&self.drops),
            connections: g(&self.connections),
            connect_failures: g(&self.connect_failures),
        }
    }
}

type Item = Result<super::OdometryRecord, OdometryError>;

/// The reading end of a TCP odometry stream.
#[derive(Debug)]
pub struct TcpOdometry {
    rx: Receiver<Item>,
    stats: Arc<OdometryStats>,
    task: JoinHandle<()>,
}

impl TcpOdometry {
    /// Starts the connection task on `runtime`; it runs until `shutdown` fires or this value
    /// is dropped.
    pub fn spawn(runtime: &Handle, settings: TcpOdometrySettings, shutdown: Shutdown) -> Self {
        let (tx, rx) = bounded(settings.capacity.max(1));
        let stats = Arc::new(OdometryStats::default());
        let task = runtime.spawn(run(settings, tx, Arc::clone(&stats), shutdown));
        Self { rx, stats, task }
    }

    /// The task's counters.
    pub fn stats(&self) -> OdometryStatsSnapshot {
        self.stats.snapshot()
    }
}

impl Drop for TcpOdometry {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl OdometrySource for TcpOdometry {
    fn poll_next(&mut self, timeout: Duration) -> Result<OdometryPoll, OdometryError> {
        match super::recv_within(&self.rx, timeout) {
            Ok(Ok(record)) => Ok(OdometryPoll::Record(record)),
            Ok(Err(e)) => Err(e),
            Err(RecvTimeoutError::Timeout) => Ok(OdometryPoll::Pending),
            Err(RecvTimeoutError::Disconnected) => Ok(OdometryPoll::Ended),
        }
    }
}

fn offer(tx: &Sender<Item>, item: Item, stats: &OdometryStats) -> bool {
    match tx.try_send(item) {
        Ok(()) => true,
        Err(TrySendError::Full(_)) => {
            stats.drops.fetch_add(1, Ordering::Relaxed);
            true
        }
        Err(TrySendError::Disconnected(_)) => false,
    }
}

async fn run(
    settings: TcpOdometrySettings,
    tx: Sender<Item>,
    stats: Arc<OdometryStats>,
    mut shutdown: Shutdown,
) {
    let mut backoff = Backoff::new(settings.backoff);
    let mut splitter = LineSplitter::new();
    let mut parser = RecordParser::new();
    loop {
        let connected = tokio::select! {
            c = connect(settings.address, &settings.socket) => c,
            () = shutdown.triggered() => return,
        };
        let mut stream = match connected {
            Ok(s) => s,
            Err(e) => {
                stats.connect_failures.fetch_add(1, Ordering::Relaxed);
                let delay = backoff.next_delay();
                tracing::warn!(address = %settings.address, attempt = backoff.attempt(), ?delay, error = %e, "odometry connection failed; retrying");
                tokio::select! {
                    () = tokio::time::sleep(delay) => continue,
                    () = shutdown.triggered() => return,
                }
            }
        };
        stats.connections.fetch_add(1, Ordering::Relaxed);
        tracing::info!(address = %settings.address, "odometry connected");
        backoff.reset();
        splitter.reset();
        parser.reset();
        let mut line_no = 0u64;
        let mut buf = vec![0u8; 4096];
        let idle = settings.idle_timeout;
        let mut idle_deadline = tokio::time::Instant::now() + idle;
        let end = loop {
            let read = tokio::select! {
                r = tokio::time::timeout_at(idle_deadline, stream.read(&mut buf)) => r,
                () = shutdown.triggered() => return,
            };
            // An expired idle deadline is judged by what can be read (crate::liveness):
            // records already in the socket are read; a deadline noticed late (this process
            // was not running) gives the server a moment more.
            let read = match read {
                Err(_) if bytes_waiting(&stream) => Ok(stream.read(&mut buf).await),
                Err(elapsed) => match resume_grace(idle_deadline, idle) {
                    Some(grace) => {
                        idle_deadline = tokio::time::Instant::now() + grace;
                        continue;
                    }
                    None => Err(elapsed),
                },
                ok => ok,
            };
            let n = match read {
                Ok(Ok(0)) => break "closed by the server".to_owned(),
                Ok(Ok(n)) => {
                    idle_deadline = tokio::time::Instant::now() + idle;
                    n
                }
                Ok(Err(e)) => break format!("read failed: {e}"),
                Err(_) => break format!("nothing received for {idle:?}"),
            };
            splitter.push(buf.get(..n).unwrap_or_default());
            while let Some(line) = splitter.next_line() {
                line_no += 1;
                let item = match line.and_then(|l| parser.parse(&l)) {
                    Ok(Some(record)) => {
                        stats.records.fetch_add(1, Ordering::Relaxed);
                        Ok(record)
                    }
                    Ok(None) => continue,
                    Err(source) => {
                        stats.line_errors.fetch_add(1, Ordering::Relaxed);
                        Err(OdometryError::Line {
                            line: line_no,
                            source,
                        })
                    }
                };
                if !offer(&tx, item, &stats) {
                    return; // The reader is gone.
                }
            }
        };
        let delay = backoff.next_delay();
        tracing::warn!(address = %settings.address, reason = %end, ?delay, "odometry link lost; reconnecting");
        tokio::select! {
            () = tokio::time::sleep(delay) => {}
            () = shutdown.triggered() => return,
        }
    }
}
