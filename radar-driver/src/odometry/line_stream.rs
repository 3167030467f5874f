//! A line-format stream over TCP (the odometry's, slam-node's gyro), generic over the
//! format's parser: a tokio task keeps the connection (reconnecting with backoff; an idle
//! link judged by [`crate::liveness`]) and hands records, and one error per bad line, to the
//! synchronous side through a bounded channel whose newest items are dropped when the reader
//! is behind. Does network IO on the caller's runtime.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crossbeam_channel::{bounded, Receiver, RecvTimeoutError, Sender, TrySendError};
use tokio::io::AsyncReadExt;
use tokio::runtime::Handle;
use tokio::task::JoinHandle;

use super::{LineError, LineSplitter};
use crate::backoff::{Backoff, BackoffPolicy};
use crate::liveness::{bytes_waiting, resume_grace};
use crate::shutdown::Shutdown;
use crate::socket::{connect, SocketOptions};

/// One line format: its records, its line errors and its header rule.
pub trait LineParser: Send + 'static {
    /// What a line holds.
    type Record: Send + 'static;
    /// What is wrong with a line; the splitter's over-long lines become one.
    type Error: From<LineError> + Send + 'static;
    /// The stream's name in log lines (`odometry`, `gyro`).
    const NAME: &'static str;
    /// `Ok(Some(record))` for a record, `Ok(None)` for a header or blank line.
    fn parse(&mut self, line: &[u8]) -> Result<Option<Self::Record>, Self::Error>;
    /// Expects a header again (a new connection).
    fn reset(&mut self);
}

/// A line the parser refused.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BadLine<E> {
    /// 1-based line number within the connection.
    pub line: u64,
    /// What was wrong.
    pub error: E,
}

/// Where and how to read a line stream.
#[derive(Debug, Clone, PartialEq)]
pub struct LineStreamSettings {
    /// The server.
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

impl LineStreamSettings {
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

/// Counters of a line stream's task.
#[derive(Debug, Default)]
pub struct LineStreamStats {
    records: AtomicU64,
    line_errors: AtomicU64,
    drops: AtomicU64,
    connections: AtomicU64,
    connect_failures: AtomicU64,
}

/// A copy of [`LineStreamStats`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LineStreamStatsSnapshot {
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

impl LineStreamStats {
    /// A copy of the counters.
    pub fn snapshot(&self) -> LineStreamStatsSnapshot {
        let g = |a: &AtomicU64| a.load(Ordering::Relaxed);
        LineStreamStatsSnapshot {
            records: g(&self.records),
            line_errors: g(&self.line_errors),
            drops: g(&self.drops),
            connections: g(&self.connections),
            connect_failures: g(&self.connect_failures),
        }
    }
}

/// What the task hands over: a record or a bad line.
pub type LineItem<P> = Result<<P as LineParser>::Record, BadLine<<P as LineParser>::Error>>;

/// The reading end of a line stream over TCP.
#[derive(Debug)]
pub struct LineStreamClient<P: LineParser> {
    rx: Receiver<LineItem<P>>,
    stats: Arc<LineStreamStats>,
    task: JoinHandle<()>,
}

impl<P: LineParser> LineStreamClient<P> {
    /// Starts the connection task on `runtime`, parsing with `parser`; it runs until
    /// `shutdown` fires or this value is dropped.
    pub fn spawn(
        runtime: &Handle,
        settings: LineStreamSettings,
        parser: P,
        shutdown: Shutdown,
    ) -> Self {
        let (tx, rx) = bounded(settings.capacity.max(1));
        let stats = Arc::new(LineStreamStats::default());
        let task = runtime.spawn(run(settings, parser, tx, Arc::clone(&stats), shutdown));
        Self { rx, stats, task }
    }

    /// The next record or bad line within `timeout` (at once when it is zero); `Timeout`
    /// when none came, `Disconnected` once the task has ended.
    pub fn recv(&self, timeout: Duration) -> Result<LineItem<P>, RecvTimeoutError> {
        super::recv_within(&self.rx, timeout)
    }

    /// The task's counters.
    pub fn stats(&self) -> LineStreamStatsSnapshot {
        self.stats.snapshot()
    }
}

impl<P: LineParser> Drop for LineStreamClient<P> {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// Offers an item; false when the reader is gone. A full channel drops the item.
fn offer<T>(tx: &Sender<T>, item: T, stats: &LineStreamStats) -> bool {
    match tx.try_send(item) {
        Ok(()) => true,
        Err(TrySendError::Full(_)) => {
            stats.drops.fetch_add(1, Ordering::Relaxed);
            true
        }
        Err(TrySendError::Disconnected(_)) => false,
    }
}

async fn run<P: LineParser>(
    settings: LineStreamSettings,
    mut parser: P,
    tx: Sender<LineItem<P>>,
    stats: Arc<LineStreamStats>,
    mut shutdown: Shutdown,
) {
    let name = P::NAME;
    let mut backoff = Backoff::new(settings.backoff);
    let mut splitter = LineSplitter::new();
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
                tracing::warn!(address = %settings.address, attempt = backoff.attempt(), ?delay, error = %e, "{name} connection failed; retrying");
                tokio::select! {
                    () = tokio::time::sleep(delay) => continue,
                    () = shutdown.triggered() => return,
                }
            }
        };
        stats.connections.fetch_add(1, Ordering::Relaxed);
        tracing::info!(address = %settings.address, "{name} connected");
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
                let item = match line.map_err(P::Error::from).and_then(|l| parser.parse(&l)) {
                    Ok(Some(record)) => {
                        stats.records.fetch_add(1, Ordering::Relaxed);
                        Ok(record)
                    }
                    Ok(None) => continue,
                    Err(error) => {
                        stats.line_errors.fetch_add(1, Ordering::Relaxed);
                        Err(BadLine {
                            line: line_no,
                            error,
                        })
                    }
                };
                if !offer(&tx, item, &stats) {
                    return; // The reader is gone.
                }
            }
        };
        let delay = backoff.next_delay();
        tracing::warn!(address = %settings.address, reason = %end, ?delay, "{name} link lost; reconnecting");
        tokio::select! {
            () = tokio::time::sleep(delay) => {}
            () = shutdown.triggered() => return,
        }
    }
}
