//! One client connection: a reader task that decodes the client's commands (anything
//! undecodable closes this client, never the server) and a writer loop that owns the socket's
//! write half: the configuration first, keep-alives, and the azimuth stream, paced and
//! subject to the connection's faults. Writes are awaited one frame at a time, so a slow
//! client slows its own stream (TCP back-pressure) and never grows the server's memory.

use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use bytes::BytesMut;
use protocol::{FrameDecoder, Message};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::net::TcpStream;
use tokio::sync::mpsc;
use tokio::time::MissedTickBehavior;
use tokio_util::sync::CancellationToken;

use super::shaping::ClientShaping;
use super::stream::AzimuthStream;
use super::world::World;
use super::SimStats;
use crate::error::ClientError;
use crate::faults::{After, FaultInjector, Send};

/// Largest amount of undecoded client bytes held; commands are tiny, so more is garbage.
pub const MAX_CLIENT_BUFFER: usize = 64 * 1024;

/// What the reader tells the writer.
#[derive(Debug)]
enum Command {
    Start { contoured: bool },
    Contour(protocol::ContourUpdate),
    Blanking(protocol::SectorBlanking),
    Stop,
    SendConfiguration,
    Closed,
    Garbage(String),
    Failed(std::io::Error),
}

/// How long a client may keep its slot without reading, or without asking for data.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Timeouts {
    pub write: Duration,
    pub idle: Duration,
}

/// Serves one connection until it ends; returns why it ended.
#[allow(clippy::too_many_arguments)]
pub(crate) async fn serve(
    socket: TcpStream,
    peer: SocketAddr,
    world: Arc<World>,
    keepalive_interval: Duration,
    timeouts: Timeouts,
    injector: FaultInjector,
    stats: Arc<SimStats>,
    cancel: CancellationToken,
) -> Result<(), ClientError> {
    let (read_half, write_half) = socket.into_split();
    let (tx, rx) = mpsc::channel(16);
    let reader = tokio::spawn(read_commands(read_half, tx, peer));
    let result = Writer {
        out: write_half,
        world,
        injector,
        stats,
        cancel,
        frame: BytesMut::with_capacity(8192),
        keepalive_interval,
        timeouts,
    }
    .run(rx)
    .await;
    reader.abort();
    result
}

/// How long a whole command the decoder holds back (its last bytes could start the next
/// frame's signature) waits for more bytes before it is taken as it is: Navtech's clients
/// send a command and wait for its effect.
pub const HELD_COMMAND_WAIT: Duration = Duration::from_millis(50);

async fn read_commands(mut socket: OwnedReadHalf, tx: mpsc::Sender<Command>, peer: SocketAddr) {
    let mut buf = BytesMut::with_capacity(4096);
    let mut decoder = FrameDecoder::new();
    // Set when no byte came for HELD_COMMAND_WAIT after a whole frame was held back.
    let mut take_held = false;
    loop {
        loop {
            let decoded = if std::mem::take(&mut take_held) {
                decoder.decode_eof(&mut buf)
            } else {
                decoder.decode(&mut buf)
            };
            let command = match decoded {
                Ok(Some(message)) => match message {
                    Message::StartFftData => Command::Start { contoured: true },
                    Message::StartNonContourFftData => Command::Start { contoured: false },
                    Message::ContourUpdate(update) => Command::Contour(update),
                    Message::SectorBlankingUpdate(update) => Command::Blanking(update),
                    Message::StopFftData => Command::Stop,
                    Message::ConfigurationRequest => Command::SendConfiguration,
                    Message::KeepAlive => continue,
                    other => {
                        tracing::debug!(%peer, id = other.id(), "ignoring a command the simulator does not implement");
                        continue;
                    }
                },
                Ok(None) => break,
                // A malformed contour or blanking update is refused; the session goes on.
                Err(protocol::DecodeError::Payload { message_id, source })
                    if message_id == protocol::message_id::CONTOUR_UPDATE
                        || message_id == protocol::message_id::SECTOR_BLANKING_UPDATE =>
                {
                    tracing::warn!(%peer, message_id, error = %source, "malformed update refused");
                    continue;
                }
                Err(error) => Command::Garbage(error.to_string()),
            };
            let stop = matches!(command, Command::Garbage(_));
            if tx.send(command).await.is_err() || stop {
                return;
            }
        }
        if buf.len() >= MAX_CLIENT_BUFFER {
            let _ = tx
                .send(Command::Garbage(format!(
                    "{} undecoded bytes: no client command is that long",
                    buf.len()
                )))
                .await;
            return;
        }
        buf.reserve(4096);
        let room = MAX_CLIENT_BUFFER - buf.len();
        let holding = decoder.holds_whole_frame(&buf);
        let mut limited = (&mut socket).take(room as u64);
        let read = limited.read_buf(&mut buf);
        let read = if holding {
            match tokio::time::timeout(HELD_COMMAND_WAIT, read).await {
                Ok(read) => read,
                Err(_) => {
                    take_held = true;
                    continue;
                }
            }
        } else {
            read.await
        };
        match read {
            Ok(0) => {
                // The client has closed its sending side; it may still be reading.
                let _ = tx.send(Command::Closed).await;
                return;
            }
            Ok(_) => {}
            Err(error) => {
                let _ = tx.send(Command::Failed(error)).await;
                return;
            }
        }
    }
}

struct Writer {
    out: OwnedWriteHalf,
    world: Arc<World>,
    injector: FaultInjector,
    stats: Arc<SimStats>,
    cancel: CancellationToken,
    frame: BytesMut,
    keepalive_interval: Duration,
    timeouts: Timeouts,
}

/// Whether the loop goes on after a write.
enum Flow {
    Continue,
    Close(&'static str),
}

impl Writer {
    async fn run(mut self, mut commands: mpsc::Receiver<Command>) -> Result<(), ClientError> {
        if let Flow::Close(why) = self
            .send_message(&Message::Configuration(Box::new(
                self.world.configuration.clone(),
            )))
            .await?
        {
            return Err(ClientError::Fault(why));
        }
        let start = tokio::time::Instant::now() + self.keepalive_interval;
        let mut keepalive = tokio::time::interval_at(start, self.keepalive_interval);
        keepalive.set_missed_tick_behavior(MissedTickBehavior::Delay);
        let mut stream: Option<AzimuthStream> = None;
        // The next azimuth, prepared: when it is due, and whether it is to be left out
        // (the skip fault) instead of written.
        let mut pending: Option<(Option<tokio::time::Instant>, bool)> = None;
        let mut azimuth = BytesMut::with_capacity(8192);
        // This client's contour and blanked sectors, and whether its stream is contoured.
        let mut shaping = ClientShaping::new(self.world.shaping.as_ref());
        let mut contoured = true;
        let encoder_size = self.world.configuration.encoder_size;
        // A client that never asks for data gives its slot back after the idle timeout.
        let idle_deadline = tokio::time::Instant::now() + self.timeouts.idle;
        let mut started = false;
        // Whether the client's commands can still come (its sending side is open).
        let mut reading = true;
        loop {
            // Skipped azimuths and fast clients may never make the socket wait: spend the
            // task's cooperative budget so other connections are not starved.
            tokio::task::consume_budget().await;
            if let (Some(s), None) = (stream.as_mut(), pending) {
                let skip = self.injector.skip_azimuth();
                match s.next(&mut azimuth, skip).await? {
                    None => {
                        tracing::info!("the stream has ended; keep-alives continue");
                        self.stats.streams_ended.fetch_add(1, Ordering::Relaxed);
                        stream = None;
                    }
                    Some(p) => {
                        pending = Some((p.due.map(tokio::time::Instant::from_std), p.skipped))
                    }
                }
            }
            let due = pending.and_then(|(due, _)| due);
            tokio::select! {
                biased;
                () = self.cancel.cancelled() => return Ok(()),
                command = commands.recv(), if reading => match command {
                    Some(Command::Start { contoured: c }) => {
                        contoured = c;
                        started = true;
                        if stream.is_none() {
                            stream = Some(AzimuthStream::open(&self.world, &self.stats).await?);
                        }
                    }
                    Some(Command::Contour(update)) => shaping.with(|s| s.set_contour(update)),
                    Some(Command::Blanking(update)) => {
                        if let Err(error) = shaping.with(|s| s.set_blanking(&update)) {
                            tracing::warn!(%error, "sector blanking refused");
                        }
                    }
                    Some(Command::Stop) => {
                        stream = None;
                        pending = None;
                    }
                    Some(Command::SendConfiguration) => {
                        let message = Message::Configuration(Box::new(self.world.configuration.clone()));
                        if let Flow::Close(why) = self.send_message(&message).await? {
                            return Err(ClientError::Fault(why));
                        }
                    }
                    // A client that has closed its sending side after asking for data
                    // still reads it (a shutdown(SHUT_WR) client): the stream goes on
                    // until a write fails or times out. One that never asked is done.
                    Some(Command::Closed) | None if started => reading = false,
                    Some(Command::Closed) | None => return Err(ClientError::Closed),
                    Some(Command::Garbage(reason)) => return Err(ClientError::Garbage(reason)),
                    Some(Command::Failed(error)) => return Err(ClientError::Io(error)),
                },
                () = tokio::time::sleep_until(idle_deadline), if !started => {
                    return Err(ClientError::Idle(self.timeouts.idle));
                }
                _ = keepalive.tick(), if self.injector.keepalives_enabled() => {
                    if let Flow::Close(why) = self.send_message(&Message::KeepAlive).await? {
                        return Err(ClientError::Fault(why));
                    }
                }
                () = sleep_until_opt(due), if pending.is_some() => {
                    let skipped = pending.is_some_and(|(_, skipped)| skipped);
                    pending = None;
                    if skipped {
                        self.stats.azimuths_skipped.fetch_add(1, Ordering::Relaxed);
                        continue;
                    }
                    self.injector.noise_burst(&mut azimuth[..]);
                    shaping.with(|s| s.apply(&mut azimuth, encoder_size, contoured));
                    std::mem::swap(&mut self.frame, &mut azimuth);
                    let flow = self.write_frame().await?;
                    std::mem::swap(&mut self.frame, &mut azimuth);
                    self.stats.azimuths_sent.fetch_add(1, Ordering::Relaxed);
                    match flow {
                        Flow::Continue => {}
                        Flow::Close(why) => return Err(ClientError::Fault(why)),
                    }
                }
            }
        }
    }

    async fn send_message(&mut self, message: &Message) -> Result<Flow, ClientError> {
        self.frame.clear();
        message.encode(&mut self.frame).map_err(|e| {
            ClientError::Internal(format!("encoding message {}: {e}", message.id()))
        })?;
        self.write_frame().await
    }

    /// Writes `self.frame` through the fault injector.
    async fn write_frame(&mut self) -> Result<Flow, ClientError> {
        let send = self.injector.before_send(&mut self.frame[..]);
        let bytes = match send {
            Send::Whole => &self.frame[..],
            Send::CutThenClose(n) => self.frame.get(..n).unwrap_or_default(),
        };
        tokio::select! {
            biased;
            () = self.cancel.cancelled() => return Ok(Flow::Close("server shutting down")),
            written = write_within(&mut self.out, bytes, self.timeouts.write) => {
                written.ok_or(ClientError::NotReading(self.timeouts.write))??
            }
        }
        self.stats
            .bytes_sent
            .fetch_add(bytes.len() as u64, Ordering::Relaxed);
        if let Send::CutThenClose(_) = send {
            let _ = self.out.shutdown().await;
            return Ok(Flow::Close("cut a frame in half"));
        }
        match self.injector.after_send() {
            After::Continue => Ok(Flow::Continue),
            After::Close => {
                let _ = self.out.shutdown().await;
                Ok(Flow::Close("dropping the connection after N messages"))
            }
            After::Stall(duration) => {
                tracing::info!(?duration, "stalling (fault injection)");
                tokio::select! {
                    () = self.cancel.cancelled() => return Ok(Flow::Close("server shutting down")),
                    () = tokio::time::sleep(duration) => {}
                }
                Ok(Flow::Continue)
            }
        }
    }
}

/// A write deadline noticed this long after it passed was not watched: this process (the
/// simulator, or the daemon it runs in) was not running (stopped, descheduled).
const LATE_NOTICE: Duration = Duration::from_millis(250);
/// After such a late notice, the client gets this long more (at most the write timeout):
/// one frozen with this process has not had the time to read.
const RESUME_GRACE: Duration = Duration::from_secs(1);

/// Writes `bytes`; `None` when the client has not taken them within `timeout`, counted
/// while this process runs: a deadline noticed late gives the client [`RESUME_GRACE`] more.
async fn write_within(
    out: &mut OwnedWriteHalf,
    bytes: &[u8],
    timeout: Duration,
) -> Option<std::io::Result<()>> {
    let write = out.write_all(bytes);
    tokio::pin!(write);
    let mut deadline = tokio::time::Instant::now() + timeout;
    loop {
        tokio::select! {
            biased;
            written = &mut write => return Some(written),
            () = tokio::time::sleep_until(deadline) => {
                let now = tokio::time::Instant::now();
                if now.saturating_duration_since(deadline) < LATE_NOTICE {
                    return None;
                }
                deadline = now + RESUME_GRACE.min(timeout);
            }
        }
    }
}

async fn sleep_until_opt(due: Option<tokio::time::Instant>) {
    if let Some(due) = due {
        tokio::time::sleep_until(due).await;
    }
}
