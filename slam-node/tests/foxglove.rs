//! The Foxglove live view against hostile and stalled clients, on loopback only: the daemon
//! (the binary, on its embedded simulator, as fast as it goes) binds 127.0.0.1:0 and logs the
//! address; raw WebSocket clients (tokio-tungstenite) and raw TCP connect to it. Each run
//! holds its start until a client subscribes to /slam/pose (`--foxglove-wait`), so that what
//! the clients do happens while it runs. Built only with the `foxglove` feature.

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

type Ws = WebSocketStream<MaybeTlsStream<TcpStream>>;

/// Every test ends within this.
const BOUND: Duration = Duration::from_secs(120);

/// A running daemon, its address, and its log (drained on a thread so that it never blocks).
struct Daemon {
    child: Child,
    address: SocketAddr,
    log: std::thread::JoinHandle<String>,
}

impl Daemon {
    fn start(out: &Path, duration_s: u32) -> Daemon {
        Self::start_with(out, duration_s, &[])
    }

    fn start_with(out: &Path, duration_s: u32, extra: &[&str]) -> Daemon {
        let mut child = Command::new(env!("CARGO_BIN_EXE_slam-node"))
            .args(extra)
            .args(["--fast", "--no-figures", "--progress-every", "0"])
            .args(["--duration", &duration_s.to_string()])
            .args(["--foxglove-bind", "127.0.0.1:0", "--foxglove-wait", "60"])
            .arg("--out")
            .arg(out)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("slam-node starts");
        let stderr = child.stderr.take().unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        let log = std::thread::spawn(move || {
            let mut all = String::new();
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if let Some(at) = line.find("Foxglove live view: ws://") {
                    let rest = &line[at + "Foxglove live view: ws://".len()..];
                    let addr = rest.split_whitespace().next().unwrap_or("");
                    let _ = tx.send(addr.parse::<SocketAddr>().ok());
                }
                all.push_str(&line);
                all.push('\n');
            }
            all
        });
        let address = rx
            .recv_timeout(Duration::from_secs(60))
            .ok()
            .flatten()
            .expect("the daemon logs where the live view listens");
        Daemon {
            child,
            address,
            log,
        }
    }

    /// Waits for the end (within [`BOUND`]); returns the summary (stdout) and the log.
    fn wait(mut self) -> (String, String) {
        let start = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                let mut out = String::new();
                std::io::Read::read_to_string(self.child.stdout.as_mut().unwrap(), &mut out)
                    .unwrap();
                let log = self.log.join().unwrap();
                assert!(status.success(), "slam-node failed:\n{out}\n{log}");
                return (out, log);
            }
            if start.elapsed() > BOUND {
                let _ = self.child.kill();
                panic!("slam-node did not end within {BOUND:?}");
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

/// The number before `label` in the Foxglove summary line.
fn count(summary: &str, label: &str) -> u64 {
    let line = summary
        .lines()
        .find(|l| l.trim_start().starts_with("Foxglove at"))
        .unwrap_or_else(|| panic!("no Foxglove line in\n{summary}"));
    let at = line
        .find(label)
        .unwrap_or_else(|| panic!("no {label:?} in {line}"));
    line[..at]
        .split_whitespace()
        .last()
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no number before {label:?} in {line}"))
}

async fn connect(address: SocketAddr) -> Result<Ws, tokio_tungstenite::tungstenite::Error> {
    let mut request = format!("ws://{address}/").into_client_request()?;
    request
        .headers_mut()
        .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
    Ok(tokio_tungstenite::connect_async(request).await?.0)
}

/// Connects, retrying while the door answers 503 (places are freed as refused clients go).
async fn connect_retrying(address: SocketAddr) -> Ws {
    let start = Instant::now();
    loop {
        match connect(address).await {
            Ok(ws) => return ws,
            Err(e) if start.elapsed() < Duration::from_secs(20) => {
                let _ = e;
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
            Err(e) => panic!("cannot connect to the live view: {e}"),
        }
    }
}

/// Reads text messages until every channel is advertised; returns (id, topic) pairs.
async fn advertised(ws: &mut Ws) -> Vec<(u64, String)> {
    let mut channels = Vec::new();
    while channels.len() < 10 {
        let msg = tokio::time::timeout(Duration::from_secs(10), ws.next())
            .await
            .expect("advertisements in time")
            .expect("the connection stays open")
            .expect("a message");
        if let Message::Text(text) = msg {
            let v: serde_json::Value = serde_json::from_str(&text).unwrap();
            if v["op"] == "advertise" {
                for c in v["channels"].as_array().unwrap() {
                    channels.push((
                        c["id"].as_u64().unwrap(),
                        c["topic"].as_str().unwrap().to_owned(),
                    ));
                }
            }
        }
    }
    channels
}

/// Subscribes to every channel, the pose last (the daemon starts on it).
async fn subscribe_all(ws: &mut Ws, channels: &[(u64, String)]) {
    let mut ordered: Vec<_> = channels.iter().collect();
    ordered.sort_by_key(|(_, topic)| topic == "/slam/pose");
    for (i, (id, _)) in ordered.iter().enumerate() {
        let msg =
            serde_json::json!({"op": "subscribe", "subscriptions": [{"id": i, "channelId": id}]});
        ws.send(Message::text(msg.to_string())).await.unwrap();
    }
}

fn poses_in(out: &Path) -> usize {
    std::fs::read_to_string(out.join("trajectory.tum"))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .count()
}

/// A client that subscribes to everything, the radar image included, and never reads:
/// the run ends in its normal time with every pose written, nothing dropped from the
/// pipeline's outputs; the server drops that client's oldest messages instead.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_never_reads_costs_the_pipeline_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), 60);
    let mut ws = connect(daemon.address).await.unwrap();
    let channels = advertised(&mut ws).await;
    subscribe_all(&mut ws, &channels).await;
    let started = Instant::now();
    // Never read again; keep the connection open until the daemon has ended.
    let (summary, _log) = tokio::task::spawn_blocking(move || daemon.wait())
        .await
        .unwrap();
    let took = started.elapsed();
    eprintln!("{summary}\nthe run took {took:?}");
    drop(ws);
    let rotations: usize = summary
        .lines()
        .find_map(|l| l.trim().strip_prefix("rotations "))
        .and_then(|r| r.split(',').next())
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("no rotation count in\n{summary}"));
    assert!(rotations > 100, "{summary}");
    assert_eq!(
        poses_in(dir.path()),
        rotations,
        "every rotation's pose written"
    );
    assert!(summary.contains("output events dropped 0"), "{summary}");
    assert_eq!(
        count(&summary, "events dropped (queue full)"),
        0,
        "{summary}"
    );
    // 60 s of stream as fast as a debug build goes, plus at most 2 s for clients to drain.
    assert!(took < Duration::from_secs(60), "the run took {took:?}");
    // The stalled client did receive the start of the stream: more than it read.
    assert!(count(&summary, "subscriptions") >= 10, "{summary}");
}

async fn raw_reply(address: SocketAddr, bytes: &[u8]) -> String {
    let mut s = TcpStream::connect(address).await.unwrap();
    s.write_all(bytes).await.unwrap();
    let mut reply = Vec::new();
    let _ = tokio::time::timeout(Duration::from_secs(10), s.read_to_end(&mut reply)).await;
    String::from_utf8_lossy(&reply).into_owned()
}

/// Garbage, another path, a hundred connections at once, subscriptions to channels that do
/// not exist and a client sending far more than a client sends: each is refused, answered
/// with an error or cut off, and counted; the run completes with every pose delivered to a
/// well-behaved client that came after them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hostile_clients_are_refused_or_ignored_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), 20);
    let address = daemon.address;
    let run = async {
        // Garbage bytes: not HTTP.
        let reply = raw_reply(address, b"\x00\xff\x13garbage\r\n\r\n").await;
        assert!(reply.starts_with("HTTP/1.1 400"), "{reply:?}");
        // A page that is not there (and no view page without --view).
        let reply = raw_reply(address, b"GET /etc/passwd HTTP/1.1\r\nHost: x\r\n\r\n").await;
        assert!(reply.starts_with("HTTP/1.1 404"), "{reply:?}");
        // A hundred WebSocket clients at once: eight are served, the rest refused.
        let attempts: Vec<_> = (0..100).map(|_| connect(address)).collect();
        let results = futures_util::future::join_all(attempts).await;
        let served = results.iter().filter(|r| r.is_ok()).count();
        assert_eq!(served, 8, "max_clients is 8 by default");
        drop(results);
        // A client subscribing to channels that do not exist is answered with an error
        // status and otherwise ignored.
        let mut ws = connect_retrying(address).await;
        let channels = advertised(&mut ws).await;
        let unknown = serde_json::json!({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 999_999}, {"id": 2, "channelId": 888_888}]});
        ws.send(Message::text(unknown.to_string())).await.unwrap();
        let mut answered = false;
        while let Ok(Some(Ok(msg))) = tokio::time::timeout(Duration::from_secs(5), ws.next()).await
        {
            if let Message::Text(t) = msg {
                if t.contains("Unknown channel ID") {
                    answered = true;
                    break;
                }
            }
        }
        assert!(
            answered,
            "an unknown channel is answered with an error status"
        );
        drop(ws);
        // A client naming a thousand unknown channels is cut off before they reach the
        // server (which would log an error for each).
        let mut spam = connect_retrying(address).await;
        let _ = advertised(&mut spam).await;
        let many: Vec<_> = (0..1000)
            .map(|i| serde_json::json!({"id": i, "channelId": 500_000 + i}))
            .collect();
        let msg = serde_json::json!({"op": "subscribe", "subscriptions": many});
        let _ = spam.send(Message::text(msg.to_string())).await;
        let closed = tokio::time::timeout(Duration::from_secs(5), async {
            loop {
                match spam.next().await {
                    None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return true,
                    Some(Ok(_)) => {}
                }
            }
        })
        .await
        .unwrap_or(false);
        assert!(closed, "a client naming 1000 unknown channels is cut off");
        // A client flooding the server is cut off.
        let mut flood = connect_retrying(address).await;
        let junk = Message::text("x".repeat(16 * 1024));
        let mut cut = false;
        for _ in 0..64 {
            if flood.send(junk.clone()).await.is_err() {
                cut = true;
                break;
            }
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        if !cut {
            // The door closed the connection; the client notices on reading.
            cut = tokio::time::timeout(Duration::from_secs(5), async {
                loop {
                    match flood.next().await {
                        None | Some(Err(_)) => return true,
                        Some(Ok(Message::Close(_))) => return true,
                        Some(Ok(_)) => {}
                    }
                }
            })
            .await
            .unwrap_or(false);
        }
        assert!(cut, "a flooding client is cut off");
        // A well-behaved client, after all that, gets every pose of the run.
        let mut ws = connect_retrying(address).await;
        let channels_again = advertised(&mut ws).await;
        assert_eq!(channels_again.len(), channels.len());
        let pose_id = channels_again
            .iter()
            .find(|(_, t)| t == "/slam/pose")
            .map(|(id, _)| *id)
            .unwrap();
        let msg = serde_json::json!({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": pose_id}]});
        ws.send(Message::text(msg.to_string())).await.unwrap();
        let mut poses = 0usize;
        while let Some(Ok(msg)) = ws.next().await {
            match msg {
                // Binary message data: opcode 1, subscription id 7 (little-endian u32).
                Message::Binary(b)
                    if b.len() > 13 && b[0] == 1 && b[1..5] == 7u32.to_le_bytes() =>
                {
                    poses += 1;
                }
                Message::Close(_) => break,
                _ => {}
            }
        }
        poses
    };
    let poses = tokio::time::timeout(BOUND, run).await.expect("bounded");
    let (summary, _log) = tokio::task::spawn_blocking(move || daemon.wait())
        .await
        .unwrap();
    assert_eq!(
        poses,
        poses_in(dir.path()),
        "every pose reached the good client\n{summary}"
    );
    assert!(count(&summary, "refused (too many)") >= 92, "{summary}");
    assert!(count(&summary, "bad requests") >= 2, "{summary}");
    assert!(count(&summary, "cut off") >= 2, "{summary}");
    assert_eq!(count(&summary, "to unknown channels"), 1002, "{summary}");
    assert!(summary.contains("output events dropped 0"), "{summary}");
}

/// `--view` serves the embedded page and its script on the live view's address; the page's
/// WebSocket is the same door.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_view_page_is_served_from_the_binary() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start_with(dir.path(), 5, &["--view"]);
    let address = daemon.address;
    let run = async {
        let page = raw_reply(address, b"GET / HTTP/1.1\r\nHost: x\r\n\r\n").await;
        assert!(page.starts_with("HTTP/1.1 200"), "{page:?}");
        assert!(
            page.contains("text/html") && page.contains("<canvas id=\"radar\""),
            "{page}"
        );
        let script = raw_reply(address, b"GET /view.js?v=1 HTTP/1.1\r\nHost: x\r\n\r\n").await;
        assert!(
            script.starts_with("HTTP/1.1 200"),
            "{}",
            &script[..script.len().min(200)]
        );
        assert!(script.contains("text/javascript") && script.contains("foxglove.sdk.v1"));
        // Start the run (it waits for the pose's subscription) and read it to the end.
        let mut ws = connect(address).await.unwrap();
        let channels = advertised(&mut ws).await;
        subscribe_all(&mut ws, &channels).await;
        while let Some(Ok(msg)) = ws.next().await {
            if matches!(msg, Message::Close(_)) {
                break;
            }
        }
    };
    tokio::time::timeout(BOUND, run).await.expect("bounded");
    let (summary, _log) = tokio::task::spawn_blocking(move || daemon.wait())
        .await
        .unwrap();
    assert_eq!(count(&summary, "pages"), 2, "{summary}");
}
