//! A minimal Colossus client for the loopback tests: written here on purpose (not the
//! project's driver), using only protocol's decoder and encoder.

#![allow(dead_code)]

use std::net::SocketAddr;
use std::time::Duration;

use bytes::BytesMut;
use protocol::{Configuration, FftData, FrameDecoder, Message};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::time::timeout;

/// Every wait in these tests is bounded by this.
pub const STEP: Duration = Duration::from_secs(10);

pub struct TestClient {
    pub stream: TcpStream,
    pub buf: BytesMut,
    pub decoder: FrameDecoder,
    pub decode_errors: Vec<String>,
}

impl TestClient {
    pub async fn connect(addr: SocketAddr) -> TestClient {
        let stream = timeout(STEP, TcpStream::connect(addr))
            .await
            .expect("connect in time")
            .expect("connect");
        TestClient {
            stream,
            buf: BytesMut::with_capacity(1 << 16),
            decoder: FrameDecoder::new(),
            decode_errors: Vec::new(),
        }
    }

    pub async fn send(&mut self, message: Message) {
        let mut out = BytesMut::new();
        message.encode(&mut out).expect("encode");
        self.stream.write_all(&out).await.expect("send");
    }

    /// Reads more bytes; `false` at end of stream.
    pub async fn fill(&mut self, wait: Duration) -> Option<bool> {
        self.buf.reserve(1 << 16);
        match timeout(wait, self.stream.read_buf(&mut self.buf)).await {
            Err(_) => None,
            Ok(Ok(0)) | Ok(Err(_)) => Some(false),
            Ok(Ok(_)) => Some(true),
        }
    }

    /// The next decodable message within `wait`; `None` on timeout or end of stream.
    /// Decode errors are recorded and skipped.
    pub async fn next_within(&mut self, wait: Duration) -> Option<Message> {
        let deadline = tokio::time::Instant::now() + wait;
        loop {
            match self.decoder.decode(&mut self.buf) {
                Ok(Some(m)) => return Some(m),
                Ok(None) => {}
                Err(e) => {
                    self.decode_errors.push(e.to_string());
                    continue;
                }
            }
            let left = deadline.saturating_duration_since(tokio::time::Instant::now());
            if left.is_zero() {
                return None;
            }
            match self.fill(left).await {
                Some(true) => {}
                _ => return None,
            }
        }
    }

    pub async fn next(&mut self) -> Message {
        self.next_within(STEP).await.expect("a message in time")
    }

    pub async fn configuration(&mut self) -> Configuration {
        match self.next().await {
            Message::Configuration(c) => *c,
            other => panic!(
                "expected the configuration first, got message {}",
                other.id()
            ),
        }
    }

    /// The next FFT message, skipping keep-alives.
    pub async fn next_fft(&mut self) -> FftData {
        loop {
            match self.next().await {
                Message::FftData(f) => return f,
                Message::KeepAlive => {}
                other => panic!("unexpected message {}", other.id()),
            }
        }
    }

    /// Reads raw bytes until the server closes the connection (bounded).
    pub async fn read_to_end(&mut self) -> Vec<u8> {
        let mut all = self.buf.split().to_vec();
        let mut chunk = vec![0u8; 1 << 16];
        loop {
            match timeout(STEP, self.stream.read(&mut chunk))
                .await
                .expect("server closes in time")
            {
                Ok(0) | Err(_) => return all,
                Ok(n) => all.extend_from_slice(&chunk[..n]),
            }
        }
    }

    /// Reads raw bytes until at least `n` are in.
    pub async fn read_raw(&mut self, n: usize) -> Vec<u8> {
        while self.buf.len() < n {
            assert_eq!(self.fill(STEP).await, Some(true), "stream ended early");
        }
        self.buf.split_to(n).to_vec()
    }
}

/// Splits a raw byte stream into frames by their length fields (no validation).
pub fn split_frames(bytes: &[u8]) -> Vec<&[u8]> {
    let mut frames = Vec::new();
    let mut at = 0;
    while at + 22 <= bytes.len() {
        let size = u32::from_be_bytes([
            bytes[at + 18],
            bytes[at + 19],
            bytes[at + 20],
            bytes[at + 21],
        ]) as usize;
        let end = (at + 22).saturating_add(size);
        if end > bytes.len() {
            frames.push(&bytes[at..]);
            return frames;
        }
        frames.push(&bytes[at..end]);
        at = end;
    }
    if at < bytes.len() {
        frames.push(&bytes[at..]);
    }
    frames
}
