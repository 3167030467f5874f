//! A small fake radar for loopback tests, built from `protocol`'s encoders. Every wait is
//! bounded by a timeout so a broken driver fails a test instead of hanging it.

#![allow(dead_code)]

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use bytes::{Bytes, BytesMut};
use protocol::{
    BinWidth, Configuration, ConfigurationData, FftData, FrameDecoder, Message, Timestamp,
};
use radar_driver::{DriverSettings, HandoffSettings};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

/// The longest any single step of a test may take.
pub const STEP: Duration = Duration::from_secs(5);

/// A geometry small enough to reason about: 16 azimuths of 5600 / 16 = 350 counts, 32 bins.
pub fn small_configuration() -> Configuration {
    Configuration {
        azimuth_samples: 16,
        bin_size: 438,
        range_in_bins: 32,
        encoder_size: 5600,
        rotation_speed_millihertz: 4000,
        packet_rate: 64,
        range_gain: 1.0,
        range_offset_m: -0.25,
        data: ConfigurationData {
            datawidth: Some(8),
            rangeresolutionmetres: Some(0.0438),
            ..ConfigurationData::default()
        },
    }
}

/// A CTS350-X-like configuration: 400 azimuths, encoder 5600, 3768 bins of 0.0438 m.
pub fn cts350x_configuration() -> Configuration {
    Configuration {
        azimuth_samples: 400,
        bin_size: 438,
        range_in_bins: 3768,
        encoder_size: 5600,
        rotation_speed_millihertz: 4000,
        packet_rate: 1600,
        range_gain: 1.0,
        range_offset_m: 0.0,
        data: ConfigurationData {
            datawidth: Some(8),
            rangeresolutionmetres: Some(0.0438),
            ..ConfigurationData::default()
        },
    }
}

/// The deterministic bins of azimuth message number `sweep`.
pub fn bins_for(sweep: u16, count: usize) -> Bytes {
    (0..count)
        .map(|i| (usize::from(sweep).wrapping_mul(31).wrapping_add(i * 7) % 251) as u8)
        .collect::<Vec<u8>>()
        .into()
}

/// The timestamp of azimuth message number `sweep`: 1.7e9 s + 625 us per azimuth.
pub fn timestamp_for(sweep: u64) -> Timestamp {
    let ns = sweep * 625_000;
    Timestamp::new(
        1_700_000_000 + (ns / 1_000_000_000) as u32,
        (ns % 1_000_000_000) as u32,
    )
    .unwrap()
}

/// Encoder value of slot `slot` for a configuration.
pub fn encoder_of(config: &Configuration, slot: u64) -> u16 {
    let step = config.encoder_size / config.azimuth_samples;
    (slot % u64::from(config.azimuth_samples)) as u16 * step
}

/// Bytes of one frame.
pub fn frame(message: &Message) -> Vec<u8> {
    let mut b = BytesMut::new();
    message.encode(&mut b).unwrap();
    b.to_vec()
}

/// The FFT frame of azimuth message `sweep` (slot = sweep modulo the azimuth count).
pub fn fft_frame(config: &Configuration, sweep: u64) -> Vec<u8> {
    frame(&Message::FftData(FftData::new(
        BinWidth::Eight,
        (sweep % 65_536) as u16,
        encoder_of(config, sweep),
        timestamp_for(sweep),
        bins_for((sweep % 65_536) as u16, usize::from(config.range_in_bins)),
    )))
}

/// One accepted connection of the fake radar.
pub struct Conn {
    pub stream: TcpStream,
    decoder: FrameDecoder,
    buf: BytesMut,
}

impl Conn {
    pub async fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.stream.write_all(bytes).await
    }

    pub async fn send_message(&mut self, message: &Message) {
        self.send(&frame(message)).await.unwrap();
    }

    /// The next message the client sends, or None if it closed or `STEP` passed.
    pub async fn recv(&mut self) -> Option<Message> {
        let deadline = tokio::time::Instant::now() + STEP;
        loop {
            if let Ok(Some(m)) = self.decoder.decode(&mut self.buf) {
                return Some(m);
            }
            let read = tokio::time::timeout_at(deadline, self.stream.read_buf(&mut self.buf)).await;
            match read {
                Ok(Ok(0)) | Ok(Err(_)) | Err(_) => return None,
                Ok(Ok(_)) => {}
            }
        }
    }

    /// Sends the configuration and waits for the start message; returns its id.
    pub async fn handshake(&mut self, config: &Configuration) -> u8 {
        self.send_message(&Message::Configuration(Box::new(config.clone())))
            .await;
        let m = self
            .recv()
            .await
            .expect("the client answers the configuration");
        m.id()
    }

    /// True once the client has closed its side (EOF), within `STEP`.
    pub async fn closed_by_client(&mut self) -> bool {
        let mut scratch = [0u8; 1024];
        loop {
            match tokio::time::timeout(STEP, self.stream.read(&mut scratch)).await {
                Ok(Ok(0)) | Ok(Err(_)) => return true,
                Ok(Ok(_)) => {}
                Err(_) => return false,
            }
        }
    }
}

/// A listening fake radar on 127.0.0.1:0.
pub struct FakeRadar {
    pub listener: TcpListener,
    pub addr: SocketAddr,
}

impl FakeRadar {
    pub async fn bind() -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        Self { listener, addr }
    }

    pub async fn accept(&self) -> Conn {
        let (stream, _) = tokio::time::timeout(STEP, self.listener.accept())
            .await
            .expect("the driver connects in time")
            .unwrap();
        stream.set_nodelay(true).unwrap();
        Conn {
            stream,
            decoder: FrameDecoder::new(),
            buf: BytesMut::new(),
        }
    }
}

/// Driver settings for tests: fast reconnects, a 1 s watchdog (short, but long enough that
/// a loaded machine does not trip it by accident).
pub fn test_settings(addr: SocketAddr) -> DriverSettings {
    let mut s = DriverSettings::new(addr);
    s.watchdog_timeout = Duration::from_millis(1000);
    s.backoff.initial = Duration::from_millis(10);
    s.backoff.max = Duration::from_millis(50);
    s.socket.connect_timeout = Duration::from_secs(2);
    s.handoff = HandoffSettings {
        azimuth_capacity: Some(100_000),
        rotation_capacity: Some(1000),
        drop_policy: radar_driver::DropPolicy::DropNewest,
    };
    s
}

/// Receives `n` items from a crossbeam receiver, each within `STEP`.
pub fn take<T>(rx: &crossbeam_channel::Receiver<T>, n: usize) -> Vec<T> {
    (0..n)
        .map(|i| {
            rx.recv_timeout(STEP)
                .unwrap_or_else(|_| panic!("item {i} of {n} did not arrive"))
        })
        .collect()
}

/// Polls `cond` until it holds or `STEP` passes.
pub async fn eventually(mut cond: impl FnMut() -> bool) -> bool {
    let deadline = tokio::time::Instant::now() + STEP;
    while tokio::time::Instant::now() < deadline {
        if cond() {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    cond()
}

pub type Shared<T> = Arc<std::sync::Mutex<T>>;

/// [`take`] off the async runtime.
pub async fn take_async<T: Send + 'static>(
    rx: &crossbeam_channel::Receiver<T>,
    n: usize,
) -> Vec<T> {
    let rx = rx.clone();
    tokio::task::spawn_blocking(move || take(&rx, n))
        .await
        .unwrap()
}

/// Sweep counters of a batch of azimuths.
pub fn sweeps(azimuths: &[radar_driver::Azimuth]) -> Vec<u16> {
    azimuths.iter().map(|a| a.sweep_counter).collect()
}

/// Sends FFT frames `range` in one write.
pub async fn send_ffts(conn: &mut Conn, config: &Configuration, range: std::ops::Range<u64>) {
    let mut bytes = Vec::new();
    for s in range {
        bytes.extend_from_slice(&fft_frame(config, s));
    }
    conn.send(&bytes).await.unwrap();
}
