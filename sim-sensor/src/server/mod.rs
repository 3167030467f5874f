//! The Colossus server: accepts up to `max_clients` connections (a real radar serves 3;
//! more are closed at once with a log line), serves each with a reader task and a paced
//! writer, and runs the odometry port and the ground-truth writer beside it.
//!
//! Start one with [`SimServer::spawn`]; the returned [`SimHandle`] gives the bound addresses,
//! the counters, and the way to stop it.

mod client;
pub mod shaping;
mod stream;
pub(crate) mod world;

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use protocol::Configuration;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;
use tokio::task::JoinSet;
use tokio_util::sync::CancellationToken;

use world::{configuration_of, Source, World};

use crate::error::{ClientError, SimError};
use crate::faults::FaultInjector;
use crate::render::SceneRenderer;
use crate::replay::raw::RawRecording;
use crate::replay::{ReplayFormat, ScanRecording};
use crate::settings::{SimOptions, SourceSpec};
use crate::{odometry, truth};

/// Counters of what the server did (all connections together).
#[derive(Debug, Default)]
pub struct SimStats {
    /// Connections served.
    pub connections_accepted: AtomicU64,
    /// Connections refused because `max_clients` were already connected.
    pub connections_refused: AtomicU64,
    /// Connections closed because the client sent garbage.
    pub garbage_closes: AtomicU64,
    /// Connections closed by a fault injection.
    pub fault_closes: AtomicU64,
    /// FFT messages written.
    pub azimuths_sent: AtomicU64,
    /// Azimuths left out by the skip fault.
    pub azimuths_skipped: AtomicU64,
    /// Bytes written to radar clients.
    pub bytes_sent: AtomicU64,
    /// Recorded scans skipped because they could not be read or had the wrong shape.
    pub scans_skipped: AtomicU64,
    /// Why the first skipped scan was skipped (its error, naming the file).
    pub first_scan_skipped: std::sync::Mutex<Option<String>>,
    /// Azimuth streams that played to their end (a recording played out, a scene's stop).
    pub streams_ended: AtomicU64,
}

/// A copy of [`SimStats`] at one moment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SimStatsSnapshot {
    /// See [`SimStats::connections_accepted`].
    pub connections_accepted: u64,
    /// See [`SimStats::connections_refused`].
    pub connections_refused: u64,
    /// See [`SimStats::garbage_closes`].
    pub garbage_closes: u64,
    /// See [`SimStats::fault_closes`].
    pub fault_closes: u64,
    /// See [`SimStats::azimuths_sent`].
    pub azimuths_sent: u64,
    /// See [`SimStats::azimuths_skipped`].
    pub azimuths_skipped: u64,
    /// See [`SimStats::bytes_sent`].
    pub bytes_sent: u64,
    /// See [`SimStats::scans_skipped`].
    pub scans_skipped: u64,
    /// See [`SimStats::streams_ended`].
    pub streams_ended: u64,
}

impl SimStats {
    /// Reads every counter.
    pub fn snapshot(&self) -> SimStatsSnapshot {
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
        SimStatsSnapshot {
            connections_accepted: get(&self.connections_accepted),
            connections_refused: get(&self.connections_refused),
            garbage_closes: get(&self.garbage_closes),
            fault_closes: get(&self.fault_closes),
            azimuths_sent: get(&self.azimuths_sent),
            azimuths_skipped: get(&self.azimuths_skipped),
            bytes_sent: get(&self.bytes_sent),
            scans_skipped: get(&self.scans_skipped),
            streams_ended: get(&self.streams_ended),
        }
    }
}

/// Starts simulators.
#[derive(Debug)]
pub struct SimServer;

/// A running simulator: its addresses, counters, and the way to stop it.
#[derive(Debug)]
pub struct SimHandle {
    local_addr: SocketAddr,
    odometry_addr: Option<SocketAddr>,
    gyro_addr: Option<SocketAddr>,
    configuration: Configuration,
    start_unix_ns: u64,
    stats: Arc<SimStats>,
    cancel: CancellationToken,
    tasks: JoinSet<Result<(), SimError>>,
}

impl SimServer {
    /// Prepares the source (renders nothing yet), binds the radar port (and the odometry
    /// port for scenes), opens the ground-truth file, and starts serving on the current
    /// tokio runtime.
    ///
    /// # Errors
    /// Invalid options, an unusable scene or recording, a port that cannot be bound, a
    /// ground-truth file that cannot be created.
    pub async fn spawn(options: SimOptions) -> Result<SimHandle, SimError> {
        options.validate()?;
        let (source, configuration, start_ns) = match &options.source {
            SourceSpec::Scene(scene) => {
                let horizon_s = options
                    .stop_after_azimuths
                    .map_or(3600.0, |n| n as f64 / scene.radar.packet_rate_f64() + 1.0);
                let renderer = SceneRenderer::new(scene, options.seed, horizon_s)?;
                let start = options.start_time_ns.or(scene.start_time_ns);
                let configuration = configuration_of(&scene.radar);
                (Source::Scene(Arc::new(renderer)), configuration, start)
            }
            SourceSpec::OxfordPng(dir) | SourceSpec::PolarScans { dir, .. } => {
                let format = match &options.source {
                    SourceSpec::PolarScans { format, .. } => *format,
                    _ => Some(ReplayFormat::Oxford),
                };
                let dir = dir.clone();
                let recording =
                    tokio::task::spawn_blocking(move || ScanRecording::open(&dir, format))
                        .await
                        .map_err(|e| SimError::Task(e.to_string()))??;
                let configuration = recording.configuration();
                (Source::Png(Arc::new(recording)), configuration, None)
            }
            SourceSpec::RawStream(path) => {
                let recording = RawRecording::open(path).await?;
                let configuration = recording.configuration.clone();
                (Source::Raw(Arc::new(recording)), configuration, None)
            }
        };
        let listener = TcpListener::bind(options.bind)
            .await
            .map_err(|source| SimError::Bind {
                what: "radar",
                addr: options.bind,
                source,
            })?;
        let local_addr = listener.local_addr().map_err(|source| SimError::Bind {
            what: "radar",
            addr: options.bind,
            source,
        })?;
        let world = Arc::new(World::new(
            source,
            configuration.clone(),
            options.pacing,
            start_ns,
            options.stop_after_azimuths,
            options.replay_loop,
            options.shaping_scope,
        ));
        let cancel = CancellationToken::new();
        let stats = Arc::new(SimStats::default());
        let mut tasks = JoinSet::new();

        let mut odometry_addr = None;
        if let (Some(bind), Some(_)) = (options.odometry_bind, world.scene()) {
            let odo = odometry::OdometryServer::bind(
                bind,
                Arc::clone(&world),
                options.odometry,
                options.write_timeout,
            )
            .await?;
            odometry_addr = Some(odo.local_addr());
            tasks.spawn(odo.run(cancel.clone()));
        }
        let mut gyro_addr = None;
        if let (Some(bind), Some(scene)) = (options.gyro_bind, world.scene()) {
            let generator =
                crate::gyro::GyroGenerator::new(options.gyro, scene.seed(), world.start_unix_ns);
            let gyro = odometry::OdometryServer::bind_with(
                bind,
                Arc::clone(&world),
                generator,
                options.write_timeout,
            )
            .await?;
            gyro_addr = Some(gyro.local_addr());
            tasks.spawn(gyro.run(cancel.clone()));
        }
        if let (Some(path), Some(_)) = (&options.ground_truth_path, world.scene()) {
            let writer = truth::TruthWriter::create(
                path,
                Arc::clone(&world),
                options.ground_truth_every_n_azimuths,
            )?;
            let token = cancel.clone();
            tasks.spawn(async move {
                tokio::task::spawn_blocking(move || writer.run(&token))
                    .await
                    .map_err(|e| SimError::Task(e.to_string()))?
            });
        }
        let start_unix_ns = world.start_unix_ns;
        tracing::info!(%local_addr, ?odometry_addr, "simulated radar listening");
        tasks.spawn(accept_loop(
            listener,
            world,
            options,
            Arc::clone(&stats),
            cancel.clone(),
        ));
        Ok(SimHandle {
            local_addr,
            odometry_addr,
            gyro_addr,
            configuration,
            start_unix_ns,
            stats,
            cancel,
            tasks,
        })
    }
}

impl SimHandle {
    /// The radar port's address.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The odometry port's address (scenes only).
    pub fn odometry_addr(&self) -> Option<SocketAddr> {
        self.odometry_addr
    }

    /// The gyro port's address (scenes only, when asked for).
    pub fn gyro_addr(&self) -> Option<SocketAddr> {
        self.gyro_addr
    }

    /// The configuration message every client receives first.
    pub fn configuration(&self) -> &Configuration {
        &self.configuration
    }

    /// Unix time of the scene's azimuth 0, nanoseconds (for replays: when the server started).
    /// Ground truth and odometry timestamps count from it.
    pub fn start_unix_ns(&self) -> u64 {
        self.start_unix_ns
    }

    /// The server's counters now.
    pub fn stats(&self) -> SimStatsSnapshot {
        self.stats.snapshot()
    }

    /// The server's counters, shared: read while the server runs, from another thread.
    pub fn shared_stats(&self) -> Arc<SimStats> {
        Arc::clone(&self.stats)
    }

    /// Why the first recorded scan the server skipped was skipped, if one was.
    pub fn first_scan_skipped(&self) -> Option<String> {
        self.stats
            .first_scan_skipped
            .lock()
            .ok()
            .and_then(|s| s.clone())
    }

    /// A token that stops the server when cancelled (e.g. from a Ctrl-C handler).
    pub fn shutdown_token(&self) -> CancellationToken {
        self.cancel.clone()
    }

    /// Stops accepting, closes every connection, flushes the ground truth, and waits for
    /// every task.
    ///
    /// # Errors
    /// The first error a server task ended with.
    pub async fn shutdown(self) -> Result<(), SimError> {
        self.cancel.cancel();
        self.wait().await
    }

    /// Waits until the server stops (its token was cancelled, or a task failed, which
    /// stops the rest).
    ///
    /// # Errors
    /// The first error a server task ended with.
    pub async fn wait(mut self) -> Result<(), SimError> {
        let mut first_error = None;
        while let Some(joined) = self.tasks.join_next().await {
            let result = joined
                .map_err(|e| SimError::Task(e.to_string()))
                .and_then(|r| r);
            if let Err(error) = result {
                self.cancel.cancel();
                first_error.get_or_insert(error);
            }
        }
        first_error.map_or(Ok(()), Err)
    }
}

async fn accept_loop(
    listener: TcpListener,
    world: Arc<World>,
    options: SimOptions,
    stats: Arc<SimStats>,
    cancel: CancellationToken,
) -> Result<(), SimError> {
    let slots = Arc::new(Semaphore::new(options.max_clients));
    let mut clients: JoinSet<()> = JoinSet::new();
    let mut connections: u64 = 0;
    loop {
        tokio::select! {
            () = cancel.cancelled() => break,
            Some(_) = clients.join_next(), if !clients.is_empty() => {}
            accepted = listener.accept() => {
                let (socket, peer) = match accepted {
                    Ok(pair) => pair,
                    Err(error) => {
                        tracing::warn!(%error, "accept failed");
                        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
                        continue;
                    }
                };
                let Ok(permit) = Arc::clone(&slots).try_acquire_owned() else {
                    stats.connections_refused.fetch_add(1, Ordering::Relaxed);
                    tracing::warn!(%peer, max = options.max_clients, "refusing a client: the radar already serves its maximum number of clients");
                    drop(socket);
                    continue;
                };
                connections += 1;
                stats.connections_accepted.fetch_add(1, Ordering::Relaxed);
                let _ = socket.set_nodelay(true);
                let active = options.faults.any() && options.fault_scope.applies_to(connections);
                let injector = FaultInjector::new(&options.faults, active);
                let (world, stats, cancel) = (Arc::clone(&world), Arc::clone(&stats), cancel.clone());
                let keepalive = options.keepalive_interval;
                let timeouts = client::Timeouts {
                    write: options.write_timeout,
                    idle: options.idle_timeout,
                };
                tracing::info!(%peer, connection = connections, faults = active, "client connected");
                clients.spawn(async move {
                    let result = client::serve(socket, peer, world, keepalive, timeouts, injector, Arc::clone(&stats), cancel).await;
                    match result {
                        Ok(()) => tracing::info!(%peer, "client session ended"),
                        Err(ClientError::Closed) => tracing::info!(%peer, "client disconnected"),
                        Err(error @ (ClientError::NotReading(_) | ClientError::Idle(_))) => {
                            tracing::info!(%peer, %error, "client dropped, its slot freed")
                        }
                        // A client that leaves in the middle of a write is a normal disconnect.
                        Err(ClientError::Io(error)) if client_went_away(&error) => {
                            tracing::info!(%peer, %error, "client disconnected")
                        }
                        Err(ClientError::Garbage(reason)) => {
                            stats.garbage_closes.fetch_add(1, Ordering::Relaxed);
                            tracing::warn!(%peer, %reason, "closing a client that sent garbage");
                        }
                        Err(ClientError::Fault(what)) => {
                            stats.fault_closes.fetch_add(1, Ordering::Relaxed);
                            tracing::info!(%peer, what, "connection closed by fault injection");
                        }
                        Err(error) => tracing::warn!(%peer, %error, "client session failed"),
                    }
                    drop(permit);
                });
            }
        }
    }
    clients.shutdown().await;
    Ok(())
}

/// Whether a socket error only means the client went away (closed, reset, or the write
/// found the pipe broken): a normal disconnect, not a failure of the session.
fn client_went_away(error: &std::io::Error) -> bool {
    use std::io::ErrorKind::{BrokenPipe, ConnectionAborted, ConnectionReset, UnexpectedEof};
    matches!(
        error.kind(),
        BrokenPipe | ConnectionReset | ConnectionAborted | UnexpectedEof
    )
}

#[cfg(test)]
mod disconnect_tests {
    use super::client_went_away;
    use std::io::{Error, ErrorKind};

    #[test]
    fn a_client_leaving_mid_write_is_a_disconnect_and_other_socket_errors_are_not() {
        for kind in [
            ErrorKind::BrokenPipe,
            ErrorKind::ConnectionReset,
            ErrorKind::ConnectionAborted,
        ] {
            assert!(client_went_away(&Error::from(kind)), "{kind:?}");
        }
        assert!(!client_went_away(&Error::from(ErrorKind::PermissionDenied)));
    }
}
