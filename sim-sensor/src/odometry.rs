//! The vehicle's odometry, served on its own TCP port in the format of
//! `docs/contracts.md`: ASCII, one record a line, a header line
//! `# odometry v1 timestamp_s speed_mps steer_rad`, then `<timestamp_s> <speed_mps>
//! <steer_rad>` with the timestamp in Unix seconds (9 decimals, exact from integer
//! nanoseconds).
//!
//! Record `j` is stamped `start + j / rate` and carries the controls in force then, plus
//! the configured bias and Gaussian noise (drawn from the scene's seed and `j`, so every
//! client reads identical records). In real time a record leaves when the wall clock reaches
//! its stamp; as fast as possible, records are released up to [`FAST_LEAD_NS`] ahead of the
//! radar's frontier, so odometry is always available for the azimuths being served but never
//! races unboundedly ahead of them. A new client starts, in real time, at the record in
//! force at the world's current time; as fast as possible, [`REPLAY_ON_CONNECT_S`] before the
//! first record no client has been written yet (the first client at the scene's first
//! record, whenever it connects): there the radar's frontier is not the consumer's time (it
//! runs ahead by whatever the sockets and the client's queues hold), so a client that
//! reconnects carries on where its stream stopped, and one that connects after the radar
//! started still reads the records from the start. (Starting at the frontier made both
//! depend on the machine's timing: the odometry was cut short after a reconnect, or began
//! late.) A record written to a link counts as written, not as delivered: TCP does not say
//! what the peer read before it closed, so a reconnecting client is sent again the last
//! [`REPLAY_ON_CONNECT_S`] of records, as a real bridge replays its last records; the
//! daemon's odometry gate drops the ones it took (same time, speed and steer).
//!
//! Slots. Clients say nothing on this port, so one that is connected and idle cannot be told
//! from one that reads while little flows. When all [`MAX_ODOMETRY_CLIENTS`] slots are taken,
//! a new client is served and the longest-connected one is closed (logged): a bridge whose
//! link died silently reconnects and must be served, and the half-open sockets it leaves
//! behind must not fill the port (before, eight idle clients locked every later one out). A
//! client that stops reading is dropped once a write has waited [`SimOptions`]'
//! `write_timeout`, as on the radar port. A client that closes its sending side
//! (`shutdown(SHUT_WR)`) keeps receiving records (before, it was closed after the header);
//! one that has gone entirely looks the same until a write to it fails, and while the radar
//! stands still (as fast as possible, nothing is written) its slot is taken back when a new
//! client needs it.
//!
//! [`SimOptions`]: crate::SimOptions

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream};
use tokio::task::JoinSet;
use tokio_util::sync::CancellationToken;

use crate::error::SimError;
use crate::server::world::World;
use crate::settings::{OdometryNoise, Pacing};
use crate::trajectory::Trajectory;

/// The header line (without its newline).
pub const HEADER: &str = "# odometry v1 timestamp_s speed_mps steer_rad";
/// How far odometry may run ahead of the radar when pacing is as fast as possible.
pub const FAST_LEAD_NS: u64 = 500_000_000;
/// As fast as possible, a connecting client is sent again the records written this long
/// (s) before the first record not yet written to any client: what a closed link may have
/// held unread. Within the daemon's replay window (5 s), where repeats are dropped.
pub const REPLAY_ON_CONNECT_S: f64 = 4.0;
/// Most odometry clients served at once.
pub const MAX_ODOMETRY_CLIENTS: usize = 8;
/// Random stream reserved for odometry noise.
const ODOMETRY_STREAM: u64 = 1 << 62;
/// Polling period while waiting for the radar's frontier to advance.
const FRONTIER_POLL: Duration = Duration::from_millis(2);

/// One odometry record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryRecord {
    /// Unix time, nanoseconds.
    pub unix_ns: u64,
    /// Measured speed, m/s.
    pub speed_mps: f64,
    /// Measured steering, rad.
    pub steer_rad: f64,
}

impl OdometryRecord {
    /// Appends the record's line (with its newline) to `out`.
    pub fn write_line(&self, out: &mut String) {
        let _ = writeln!(
            out,
            "{}.{:09} {:.6} {:.6}",
            self.unix_ns / 1_000_000_000,
            self.unix_ns % 1_000_000_000,
            self.speed_mps,
            self.steer_rad
        );
    }
}

/// What a line port serves: its header and the line of record `j` (the odometry's, the
/// gyro's, [`crate::gyro`]); the port's pacing, slots and replay are the same for both.
pub trait LineStream: Clone + Send + Sync + 'static {
    /// The port's name in the log.
    const WHAT: &'static str;
    /// The header line, without its newline.
    fn header(&self) -> &'static str;
    /// Time between records, nanoseconds.
    fn period_ns(&self) -> u64;
    /// Records in [`REPLAY_ON_CONNECT_S`].
    fn replay_records(&self) -> u64;
    /// Scene time of record `j`, nanoseconds after the start.
    fn offset_ns(&self, j: u64) -> u64 {
        j.saturating_mul(self.period_ns())
    }
    /// Appends record `j`'s line (with its newline), at scene time `t_ns` on `trajectory`.
    fn write_line(&self, j: u64, trajectory: &Trajectory, t_ns: u64, out: &mut String);
}

impl LineStream for OdometryGenerator {
    const WHAT: &'static str = "odometry";

    fn header(&self) -> &'static str {
        HEADER
    }

    fn period_ns(&self) -> u64 {
        self.period_ns
    }

    fn replay_records(&self) -> u64 {
        OdometryGenerator::replay_records(self)
    }

    fn write_line(&self, j: u64, trajectory: &Trajectory, t_ns: u64, out: &mut String) {
        self.record(j, trajectory.controls_at(t_ns)).write_line(out);
    }
}

/// Generates the records of one scene.
#[derive(Debug, Clone)]
pub struct OdometryGenerator {
    noise: OdometryNoise,
    seed: u64,
    period_ns: u64,
    start_unix_ns: u64,
}

impl OdometryGenerator {
    /// A generator for a scene starting at `start_unix_ns`.
    pub fn new(noise: OdometryNoise, seed: u64, start_unix_ns: u64) -> Self {
        let period_ns = (1e9 / noise.rate_hz).round().max(1.0) as u64;
        Self {
            noise,
            seed,
            period_ns,
            start_unix_ns,
        }
    }

    /// Time between records, nanoseconds.
    pub fn period_ns(&self) -> u64 {
        self.period_ns
    }

    /// Records in [`REPLAY_ON_CONNECT_S`].
    pub fn replay_records(&self) -> u64 {
        (REPLAY_ON_CONNECT_S * 1e9 / self.period_ns as f64).ceil() as u64
    }

    /// Scene time of record `j`, nanoseconds after the start.
    pub fn offset_ns(&self, j: u64) -> u64 {
        j.saturating_mul(self.period_ns)
    }

    /// Record `j`, given the true controls `(speed, steer)` in force at its time.
    pub fn record(&self, j: u64, controls: (f64, f64)) -> OdometryRecord {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ j.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        rng.set_stream(ODOMETRY_STREAM);
        let n_speed: f64 = StandardNormal.sample(&mut rng);
        let n_steer: f64 = StandardNormal.sample(&mut rng);
        OdometryRecord {
            unix_ns: self.start_unix_ns.saturating_add(self.offset_ns(j)),
            speed_mps: controls.0
                + self.noise.bias_speed_mps
                + n_speed * self.noise.sigma_speed_mps,
            steer_rad: controls.1
                + self.noise.bias_steer_rad
                + n_steer * self.noise.sigma_steer_rad,
        }
    }
}

/// A line port: the odometry's ([`OdometryGenerator`]) or the gyro's.
#[derive(Debug)]
pub(crate) struct OdometryServer<G = OdometryGenerator> {
    listener: TcpListener,
    world: Arc<World>,
    generator: G,
    /// The first record not yet written to any client (as fast as possible a client starts
    /// [`REPLAY_ON_CONNECT_S`] before it).
    unsent: Arc<AtomicU64>,
    /// A write that waits this long drops the client.
    write_timeout: Duration,
}

impl OdometryServer {
    pub(crate) async fn bind(
        addr: SocketAddr,
        world: Arc<World>,
        noise: OdometryNoise,
        write_timeout: Duration,
    ) -> Result<Self, SimError> {
        let seed = world.scene().map_or(0, |s| s.seed());
        let generator = OdometryGenerator::new(noise, seed, world.start_unix_ns);
        OdometryServer::bind_with(addr, world, generator, write_timeout).await
    }
}

impl<G: LineStream + std::fmt::Debug> OdometryServer<G> {
    /// A port serving `generator`'s lines.
    pub(crate) async fn bind_with(
        addr: SocketAddr,
        world: Arc<World>,
        generator: G,
        write_timeout: Duration,
    ) -> Result<Self, SimError> {
        let listener = TcpListener::bind(addr)
            .await
            .map_err(|source| SimError::Bind {
                what: G::WHAT,
                addr,
                source,
            })?;
        Ok(Self {
            listener,
            world,
            generator,
            unsent: Arc::new(AtomicU64::new(0)),
            write_timeout,
        })
    }

    pub(crate) fn local_addr(&self) -> SocketAddr {
        self.listener
            .local_addr()
            .unwrap_or_else(|_| SocketAddr::from(([127, 0, 0, 1], 0)))
    }

    pub(crate) async fn run(self, cancel: CancellationToken) -> Result<(), SimError> {
        let mut clients = JoinSet::new();
        // The clients being served, oldest first: (number, peer, its stop).
        let mut served: VecDeque<(u64, SocketAddr, CancellationToken)> = VecDeque::new();
        let mut connections: u64 = 0;
        loop {
            tokio::select! {
                () = cancel.cancelled() => break,
                Some(ended) = clients.join_next(), if !clients.is_empty() => {
                    if let Ok(number) = ended {
                        served.retain(|(n, _, _)| *n != number);
                    }
                }
                accepted = self.listener.accept() => {
                    let Ok((socket, peer)) = accepted else {
                        tokio::time::sleep(Duration::from_millis(20)).await;
                        continue;
                    };
                    if served.len() >= MAX_ODOMETRY_CLIENTS {
                        if let Some((_, oldest, stop)) = served.pop_front() {
                            tracing::warn!(%peer, closed = %oldest, max = MAX_ODOMETRY_CLIENTS, port = G::WHAT, "port full: closing its longest-connected client to serve a new one");
                            stop.cancel();
                        }
                    }
                    connections += 1;
                    let number = connections;
                    tracing::info!(%peer, port = G::WHAT, "client connected");
                    let stop = cancel.child_token();
                    served.push_back((number, peer, stop.clone()));
                    let (world, generator) = (Arc::clone(&self.world), self.generator.clone());
                    let unsent = Arc::clone(&self.unsent);
                    let write_timeout = self.write_timeout;
                    clients.spawn(async move {
                        let link = Link { world, generator, unsent, write_timeout, stop };
                        if let Err(error) = link.serve(socket).await {
                            tracing::info!(%peer, %error, port = G::WHAT, "client gone");
                        }
                        number
                    });
                }
            }
        }
        clients.shutdown().await;
        Ok(())
    }
}

/// One client's link.
struct Link<G> {
    world: Arc<World>,
    generator: G,
    unsent: Arc<AtomicU64>,
    write_timeout: Duration,
    stop: CancellationToken,
}

impl<G: LineStream> Link<G> {
    async fn serve(self, socket: TcpStream) -> std::io::Result<()> {
        serve_odometry(
            socket,
            self.world,
            self.generator,
            self.unsent,
            self.write_timeout,
            self.stop,
        )
        .await
    }
}

/// Writes `bytes`, giving up when `cancel` is cancelled (`Ok(false)`) or when the write has
/// waited `limit` (a client that does not read).
async fn write_bounded(
    socket: &mut TcpStream,
    bytes: &[u8],
    limit: Duration,
    cancel: &CancellationToken,
) -> std::io::Result<bool> {
    tokio::select! {
        () = cancel.cancelled() => Ok(false),
        written = tokio::time::timeout(limit, socket.write_all(bytes)) => match written {
            Ok(result) => result.map(|()| true),
            Err(_) => Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!("the client read nothing for {} ms: dropped, its slot freed", limit.as_millis()),
            )),
        },
    }
}

async fn serve_odometry<G: LineStream>(
    mut socket: TcpStream,
    world: Arc<World>,
    generator: G,
    unsent: Arc<AtomicU64>,
    write_timeout: Duration,
    cancel: CancellationToken,
) -> std::io::Result<()> {
    let Some(scene) = world.scene().cloned() else {
        return Ok(());
    };
    let trajectory = scene.trajectory();
    let mut line = String::with_capacity(256);
    line.push_str(generator.header());
    line.push('\n');
    if !write_bounded(&mut socket, line.as_bytes(), write_timeout, &cancel).await? {
        return Ok(());
    }
    // Whether the client's sending side is still open (its end shows that it has gone).
    let mut sending = true;
    let mut j = match world.pacing {
        Pacing::Realtime => world.current_offset_ns() / generator.period_ns(),
        Pacing::AsFastAsPossible => unsent
            .load(Ordering::Acquire)
            .saturating_sub(generator.replay_records()),
    };
    let end_ns = world.stop_after.map(|n| scene.offset_ns(n));
    loop {
        let t_ns = generator.offset_ns(j);
        if end_ns.is_some_and(|end| t_ns > end) {
            // The scene has ended: hold the connection open until shutdown.
            cancel.cancelled().await;
            return Ok(());
        }
        // Wait until record j may leave.
        loop {
            let release_ns = match world.pacing {
                Pacing::Realtime => world.current_offset_ns(),
                Pacing::AsFastAsPossible => world.current_offset_ns().saturating_add(FAST_LEAD_NS),
            };
            if t_ns <= release_ns {
                break;
            }
            let wait = match world.pacing {
                Pacing::Realtime => Duration::from_nanos(t_ns - release_ns),
                Pacing::AsFastAsPossible => FRONTIER_POLL,
            };
            tokio::select! {
                () = cancel.cancelled() => return Ok(()),
                () = tokio::time::sleep(wait) => {}
                // A client says nothing on this port: its socket turns readable when it
                // leaves. Noticed here, not at the next write, which may be long in coming
                // while the radar stands still, so a gone client gives its slot back.
                readable = socket.readable(), if sending => {
                    readable?;
                    match socket.try_read(&mut [0u8; 256]) {
                        // Gone, or only its sending side closed (the two look the same
                        // until a write fails on a closed link): served until then, or
                        // until a new client needs its slot.
                        Ok(0) => sending = false,
                        Ok(_) => {} // ignored
                        Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                        Err(e) => return Err(e),
                    }
                }
            }
        }
        line.clear();
        generator.write_line(j, trajectory, t_ns, &mut line);
        if !write_bounded(&mut socket, line.as_bytes(), write_timeout, &cancel).await? {
            return Ok(());
        }
        j += 1;
        unsent.fetch_max(j, Ordering::AcqRel);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_record_line_has_nine_exact_decimals_and_single_spaces() {
        let r = OdometryRecord {
            unix_ns: 1_704_067_200_050_000_001,
            speed_mps: 1.5,
            steer_rad: -0.04,
        };
        let mut s = String::new();
        r.write_line(&mut s);
        assert_eq!(s, "1704067200.050000001 1.500000 -0.040000\n");
        assert!(s.len() <= 256);
    }

    #[test]
    fn records_are_reproducible_and_carry_the_configured_bias_and_noise() {
        let noise = OdometryNoise {
            rate_hz: 50.0,
            sigma_speed_mps: 0.2,
            sigma_steer_rad: 0.01,
            bias_speed_mps: 0.5,
            bias_steer_rad: -0.02,
        };
        let g = OdometryGenerator::new(noise, 9, 0);
        assert_eq!(g.record(17, (2.0, 0.1)), g.record(17, (2.0, 0.1)));
        assert_eq!(g.offset_ns(3), 60_000_000);
        let n = 20_000;
        let (mut sum_v, mut sum_v2, mut sum_a) = (0.0, 0.0, 0.0);
        for j in 0..n {
            let r = g.record(j, (2.0, 0.1));
            sum_v += r.speed_mps;
            sum_v2 += r.speed_mps * r.speed_mps;
            sum_a += r.steer_rad;
        }
        let nf = n as f64;
        let mean_v = sum_v / nf;
        let sd_v = (sum_v2 / nf - mean_v * mean_v).sqrt();
        // Mean 2.5 +/- 4 standard errors (0.2 / sqrt(20000) = 0.0014); sd within 3 %.
        assert!((mean_v - 2.5).abs() < 0.006, "{mean_v}");
        assert!((sd_v - 0.2).abs() < 0.006, "{sd_v}");
        assert!((sum_a / nf - 0.08).abs() < 0.0003, "{}", sum_a / nf);
    }
}
