//! The live view's door (network IO): the configured address is ours, not the Foxglove
//! SDK's. Each connection's HTTP request head is read (at most [`MAX_HEAD_BYTES`], within
//! [`HEAD_TIMEOUT`]) and parsed with `httparse`:
//!
//! - a WebSocket upgrade is handed, head and all, to the SDK's server listening on a
//!   loopback port of its own, and the bytes are relayed both ways (counted on the way out);
//! - `GET /` (and the page's script) serves the embedded view page when `[output.view]` is
//!   on;
//! - anything else (garbage, a slow or oversized head, another path) gets a 400 or 404 and
//!   is closed, counted.
//!
//! At most `max_clients` connections are served at once; more are answered 503 and closed,
//! counted. The frames a client sends are read on the way (headers parsed by `tungstenite`,
//! whole text frames unmasked and parsed as JSON) to count its subscriptions to channels that
//! do not exist, which the SDK answers with an error status (and an error in our log) and
//! otherwise ignores; a client naming more than [`MAX_UNKNOWN_SUBSCRIPTIONS`] is cut off. A
//! client may send at most a burst of [`CLIENT_BURST_BYTES`] and then [`CLIENT_BYTES_PER_S`]
//! (a subscriber sends a few hundred bytes); one sending more is cut off, counted. A client that stops reading stalls only its own relay: the SDK's queue for
//! it fills and drops its oldest messages, and the pipeline never waits.

use std::collections::HashSet;
use std::io::Cursor;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tracing::debug;

/// The longest request head read, bytes.
pub const MAX_HEAD_BYTES: usize = 8 * 1024;
/// How long a client has to send its request head.
pub const HEAD_TIMEOUT: Duration = Duration::from_secs(5);
/// A client may send this many bytes at once...
pub const CLIENT_BURST_BYTES: f64 = 64.0 * 1024.0;
/// ...and this many per second after that.
pub const CLIENT_BYTES_PER_S: f64 = 4.0 * 1024.0;
/// The most headers a request head may carry.
const MAX_HEADERS: usize = 32;
/// Relay buffer, bytes.
const RELAY_BUFFER: usize = 16 * 1024;

/// What the door saw.
#[derive(Debug, Default)]
pub struct GateCounters {
    /// WebSocket connections handed to the server.
    pub connections: AtomicU64,
    /// Connections refused because `max_clients` were being served.
    pub refused: AtomicU64,
    /// Requests that were not a WebSocket upgrade or a page request (garbage, a slow or
    /// oversized head, another path).
    pub bad_requests: AtomicU64,
    /// Clients cut off for sending more than they may.
    pub cut_off: AtomicU64,
    /// Bytes relayed to clients.
    pub bytes_sent: AtomicU64,
    /// Page requests served.
    pub pages: AtomicU64,
    /// Subscriptions to channel ids the server does not have.
    pub unknown_subscriptions: AtomicU64,
    /// Connections being served now.
    active: AtomicUsize,
}

impl GateCounters {
    /// Connections being served now (WebSocket relays and requests being read).
    pub fn active(&self) -> usize {
        self.active.load(Ordering::Relaxed)
    }
}

/// A file the door serves.
#[derive(Debug, Clone, Copy)]
pub struct Asset {
    /// Its path, `/` for the page.
    pub path: &'static str,
    /// Its content type.
    pub content_type: &'static str,
    /// Its bytes.
    pub body: &'static [u8],
}

/// The door's settings.
#[derive(Debug, Clone)]
pub struct Gate {
    /// The SDK's server.
    pub upstream: SocketAddr,
    /// Connections served at once.
    pub max_clients: usize,
    /// The files served (empty: no page).
    pub assets: &'static [Asset],
    /// The ids of the channels the server has.
    pub channels: Arc<HashSet<u64>>,
    /// Its counters.
    pub counters: Arc<GateCounters>,
}

/// Frees a connection's place when it ends.
struct Place(Arc<GateCounters>);

impl Drop for Place {
    fn drop(&mut self) {
        self.0.active.fetch_sub(1, Ordering::Relaxed);
    }
}

impl Gate {
    /// Accepts connections until the runtime is shut down.
    pub async fn serve(self, listener: TcpListener) {
        let gate = Arc::new(self);
        loop {
            let (stream, peer) = match listener.accept().await {
                Ok(c) => c,
                Err(e) => {
                    // Out of descriptors and the like: wait rather than spin.
                    debug!(error = %e, "live view: accept failed");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            };
            let counters = &gate.counters;
            let before = counters.active.fetch_add(1, Ordering::Relaxed);
            let place = Place(Arc::clone(counters));
            if before >= gate.max_clients {
                counters.refused.fetch_add(1, Ordering::Relaxed);
                tokio::spawn(async move {
                    let _place = place;
                    answer(stream, "503 Service Unavailable", "too many clients\n").await;
                });
                continue;
            }
            let gate = Arc::clone(&gate);
            tokio::spawn(async move {
                let _place = place;
                gate.handle(stream, peer).await;
            });
        }
    }

    async fn handle(&self, mut stream: TcpStream, peer: SocketAddr) {
        let _ = stream.set_nodelay(true);
        let mut head = Vec::with_capacity(1024);
        let request =
            match tokio::time::timeout(HEAD_TIMEOUT, read_head(&mut stream, &mut head)).await {
                Ok(Ok(r)) => r,
                Ok(Err(why)) => {
                    debug!(%peer, why, "live view: bad request");
                    self.counters.bad_requests.fetch_add(1, Ordering::Relaxed);
                    answer(
                        stream,
                        "400 Bad Request",
                        "not a request this server answers\n",
                    )
                    .await;
                    return;
                }
                Err(_) => {
                    debug!(%peer, "live view: no request head in time");
                    self.counters.bad_requests.fetch_add(1, Ordering::Relaxed);
                    answer(stream, "408 Request Timeout", "no request\n").await;
                    return;
                }
            };
        match request {
            Request::Upgrade => self.relay(stream, head).await,
            Request::Get(path) => match self.assets.iter().find(|a| a.path == path) {
                Some(asset) => {
                    self.counters.pages.fetch_add(1, Ordering::Relaxed);
                    let header = format!(
                        "HTTP/1.1 200 OK\r\nContent-Type: {}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
                        asset.content_type,
                        asset.body.len()
                    );
                    let _ = stream.write_all(header.as_bytes()).await;
                    let _ = stream.write_all(asset.body).await;
                    let _ = stream.shutdown().await;
                }
                None => {
                    self.counters.bad_requests.fetch_add(1, Ordering::Relaxed);
                    answer(stream, "404 Not Found", "not found\n").await;
                }
            },
        }
    }

    /// Hands the connection to the SDK's server and relays until either side ends.
    async fn relay(&self, client: TcpStream, head: Vec<u8>) {
        let Ok(mut upstream) = TcpStream::connect(self.upstream).await else {
            answer(client, "503 Service Unavailable", "server not running\n").await;
            return;
        };
        let _ = upstream.set_nodelay(true);
        if upstream.write_all(&head).await.is_err() {
            return;
        }
        self.counters.connections.fetch_add(1, Ordering::Relaxed);
        let (mut client_read, mut client_write) = client.into_split();
        let (mut up_read, mut up_write) = upstream.into_split();
        let counters = &self.counters;
        let mut watch = SubscribeWatch::new(&self.channels);
        let inbound = async {
            let mut buf = vec![0u8; RELAY_BUFFER];
            let mut allowance = CLIENT_BURST_BYTES - head.len() as f64;
            let mut since = Instant::now();
            let mut unknown_here = 0u64;
            loop {
                let n = match client_read.read(&mut buf).await {
                    Ok(0) | Err(_) => return,
                    Ok(n) => n,
                };
                let now = Instant::now();
                allowance = (allowance
                    + CLIENT_BYTES_PER_S * now.duration_since(since).as_secs_f64())
                .min(CLIENT_BURST_BYTES)
                    - n as f64;
                since = now;
                if allowance < 0.0 {
                    counters.cut_off.fetch_add(1, Ordering::Relaxed);
                    return;
                }
                let unknown = watch.take(&buf[..n]);
                if unknown > 0 {
                    counters
                        .unknown_subscriptions
                        .fetch_add(unknown, Ordering::Relaxed);
                    unknown_here += unknown;
                    if unknown_here > MAX_UNKNOWN_SUBSCRIPTIONS {
                        // The SDK logs an error for each: not a log to let a client fill.
                        counters.cut_off.fetch_add(1, Ordering::Relaxed);
                        return;
                    }
                }
                if up_write.write_all(&buf[..n]).await.is_err() {
                    return;
                }
            }
        };
        let outbound = async {
            let mut buf = vec![0u8; RELAY_BUFFER];
            loop {
                let n = match up_read.read(&mut buf).await {
                    Ok(0) | Err(_) => return,
                    Ok(n) => n,
                };
                if client_write.write_all(&buf[..n]).await.is_err() {
                    return;
                }
                counters.bytes_sent.fetch_add(n as u64, Ordering::Relaxed);
            }
        };
        tokio::select! {
            () = inbound => {}
            () = outbound => {}
        }
    }
}

/// A client naming more unknown channels than this is cut off (before the frames that pass
/// it reach the server, which logs an error for each).
pub const MAX_UNKNOWN_SUBSCRIPTIONS: u64 = 64;

/// The longest client frame read for subscriptions (longer ones are relayed unread: the
/// flood limit bounds them anyway).
const MAX_WATCHED_FRAME: u64 = 64 * 1024;

/// Follows a client's frames to count its subscriptions to unknown channels. Stops watching
/// (relaying on) at a frame it cannot read: fragmented, oversized or malformed frames are the
/// SDK's to refuse.
struct SubscribeWatch<'a> {
    known: &'a HashSet<u64>,
    pending: Vec<u8>,
    watching: bool,
}

impl<'a> SubscribeWatch<'a> {
    fn new(known: &'a HashSet<u64>) -> Self {
        Self {
            known,
            pending: Vec::new(),
            watching: true,
        }
    }

    /// Takes the next bytes from the client; returns the unknown channel ids subscribed to
    /// in the frames they complete.
    fn take(&mut self, bytes: &[u8]) -> u64 {
        if !self.watching {
            return 0;
        }
        self.pending.extend_from_slice(bytes);
        let mut unknown = 0;
        loop {
            let mut cursor = Cursor::new(&self.pending);
            let (header, len) = match tungstenite::protocol::frame::FrameHeader::parse(&mut cursor)
            {
                Ok(Some(h)) => h,
                Ok(None) => return unknown,
                Err(_) => {
                    self.stop();
                    return unknown;
                }
            };
            if len > MAX_WATCHED_FRAME {
                self.stop();
                return unknown;
            }
            let start = cursor.position() as usize;
            let end = start + len as usize;
            if self.pending.len() < end {
                return unknown;
            }
            use tungstenite::protocol::frame::coding::{Data, OpCode};
            if header.opcode == OpCode::Data(Data::Text) && header.is_final {
                let mut payload = self.pending[start..end].to_vec();
                if let Some(mask) = header.mask {
                    for (i, b) in payload.iter_mut().enumerate() {
                        *b ^= mask[i % 4];
                    }
                }
                unknown += self.unknown_in(&payload);
            } else if header.opcode == OpCode::Data(Data::Continue) || !header.is_final {
                self.stop();
                return unknown;
            }
            self.pending.drain(..end);
        }
    }

    /// Unknown channel ids in one text message, if it is a subscription.
    fn unknown_in(&self, text: &[u8]) -> u64 {
        let Ok(v) = serde_json::from_slice::<serde_json::Value>(text) else {
            return 0;
        };
        if v["op"] != "subscribe" {
            return 0;
        }
        v["subscriptions"].as_array().map_or(0, |subs| {
            subs.iter()
                .filter(|s| {
                    s["channelId"]
                        .as_u64()
                        .is_some_and(|id| !self.known.contains(&id))
                })
                .count() as u64
        })
    }

    fn stop(&mut self) {
        self.watching = false;
        self.pending = Vec::new();
    }
}

/// What a request asks for.
enum Request {
    /// A WebSocket upgrade.
    Upgrade,
    /// A plain `GET` of this path (query stripped).
    Get(String),
}

/// Reads one request head into `head` and says what it asks for.
async fn read_head(stream: &mut TcpStream, head: &mut Vec<u8>) -> Result<Request, &'static str> {
    let mut chunk = [0u8; 1024];
    loop {
        let n = stream.read(&mut chunk).await.map_err(|_| "read failed")?;
        if n == 0 {
            return Err("closed before the head ended");
        }
        head.extend_from_slice(&chunk[..n]);
        let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
        let mut req = httparse::Request::new(&mut headers);
        match req.parse(head) {
            Ok(httparse::Status::Complete(_)) => {
                if req.method != Some("GET") {
                    return Err("not a GET");
                }
                let upgrade = req.headers.iter().any(|h| {
                    h.name.eq_ignore_ascii_case("upgrade")
                        && std::str::from_utf8(h.value)
                            .is_ok_and(|v| v.trim().eq_ignore_ascii_case("websocket"))
                });
                if upgrade {
                    return Ok(Request::Upgrade);
                }
                let path = req.path.unwrap_or("/");
                let path = path.split('?').next().unwrap_or("/");
                return Ok(Request::Get(path.to_owned()));
            }
            Ok(httparse::Status::Partial) if head.len() < MAX_HEAD_BYTES => {}
            Ok(httparse::Status::Partial) => return Err("request head too long"),
            Err(_) => return Err("not HTTP"),
        }
    }
}

/// Answers with a status and a short text, then closes.
async fn answer(mut stream: TcpStream, status: &str, text: &str) {
    let reply = format!(
        "HTTP/1.1 {status}\r\nContent-Type: text/plain\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{text}",
        text.len()
    );
    let _ = tokio::time::timeout(Duration::from_secs(1), async {
        let _ = stream.write_all(reply.as_bytes()).await;
        let _ = stream.shutdown().await;
    })
    .await;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A masked client text frame.
    fn frame(text: &str, mask: [u8; 4]) -> Vec<u8> {
        let payload: Vec<u8> = text
            .bytes()
            .enumerate()
            .map(|(i, b)| b ^ mask[i % 4])
            .collect();
        let mut out = vec![0x81];
        if payload.len() < 126 {
            out.push(0x80 | payload.len() as u8);
        } else {
            out.push(0x80 | 126);
            out.extend_from_slice(&(payload.len() as u16).to_be_bytes());
        }
        out.extend_from_slice(&mask);
        out.extend_from_slice(&payload);
        out
    }

    #[test]
    fn subscriptions_to_unknown_channels_are_counted_across_reads() {
        let known: HashSet<u64> = [1, 2, 3].into_iter().collect();
        let mut w = SubscribeWatch::new(&known);
        let mut bytes = frame(
            r#"{"op":"subscribe","subscriptions":[{"id":0,"channelId":2},{"id":1,"channelId":99}]}"#,
            [1, 2, 3, 4],
        );
        bytes.extend(frame(
            r#"{"op":"unsubscribe","subscriptionIds":[0]}"#,
            [9, 8, 7, 6],
        ));
        bytes.extend(frame(
            &format!(
                r#"{{"op":"subscribe","subscriptions":[{{"id":5,"channelId":7}}],"pad":"{}"}}"#,
                "x".repeat(300)
            ),
            [5, 5, 5, 5],
        ));
        // Byte by byte: frames complete across reads.
        let counted: u64 = bytes.iter().map(|b| w.take(std::slice::from_ref(b))).sum();
        assert_eq!(counted, 2);
        assert!(w.pending.is_empty());
    }

    #[test]
    fn a_frame_it_cannot_read_stops_the_watch_without_buffering() {
        let known = HashSet::new();
        let mut w = SubscribeWatch::new(&known);
        // A fragmented text frame (FIN clear).
        let mut f = frame(
            r#"{"op":"subscribe","subscriptions":[{"id":0,"channelId":5}]}"#,
            [0; 4],
        );
        f[0] = 0x01;
        assert_eq!(w.take(&f), 0);
        assert!(!w.watching && w.pending.is_empty());
        assert_eq!(w.take(&frame("{}", [0; 4])), 0);
    }
}
