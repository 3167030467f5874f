//! What a misbehaving radar can make the driver log: a configuration re-sent over and over
//! is logged once (and its repeats rate-limited), undecodable configurations warn at most
//! once per interval.

mod common;

use std::io::Write;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use bytes::BytesMut;
use common::*;
use radar_driver::Driver;

/// Log output captured as text.
#[derive(Clone, Default)]
struct Captured(Arc<Mutex<Vec<u8>>>);

impl Write for Captured {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Captured {
    fn lines_with(&self, level: &str, text: &str) -> usize {
        let bytes = self.0.lock().unwrap().clone();
        String::from_utf8_lossy(&bytes)
            .lines()
            .filter(|l| l.contains(level) && l.contains(text))
            .count()
    }
}

/// INFO and above logged on this thread, captured as text until the guard is dropped.
fn capture() -> (Captured, tracing::subscriber::DefaultGuard) {
    let captured = Captured::default();
    let writer = captured.clone();
    let subscriber = tracing_subscriber::fmt()
        .with_ansi(false)
        .with_max_level(tracing::Level::INFO)
        .with_writer(move || writer.clone())
        .finish();
    (captured, tracing::subscriber::set_default(subscriber))
}

// A current-thread runtime: the driver's task runs on this thread, under this thread's
// default subscriber.
#[tokio::test]
async fn ten_identical_configurations_log_once_and_undecodable_ones_warn_once() {
    let (captured, _guard) = capture();
    tokio::time::timeout(Duration::from_secs(30), async {
        let radar = FakeRadar::bind().await;
        let (driver, receivers) = Driver::new(test_settings(radar.addr));
        let handle = driver.spawn();
        let azimuths = receivers.azimuths.unwrap();
        let mut conn = radar.accept().await;
        let config = small_configuration();
        assert_eq!(conn.handshake(&config).await, 21);
        for _ in 0..9 {
            assert_eq!(conn.handshake(&config).await, 21);
        }
        let mut bad = BytesMut::new();
        for _ in 0..10 {
            protocol::encode_raw_frame(&mut bad, 10, &[0, 16, 1]).unwrap();
        }
        conn.send(&bad).await.unwrap();
        send_ffts(&mut conn, &config, 0..4).await;
        take_async(&azimuths, 4).await;
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!((m.configurations, m.configurations_repeated), (10, 9));
        assert_eq!(m.decode_errors.truncated, 10);
    })
    .await
    .expect("bounded");
    assert_eq!(
        captured.lines_with("INFO", "radar configuration azimuths=16"),
        1
    );
    assert_eq!(
        captured.lines_with("INFO", "radar re-sent its configuration, unchanged"),
        1
    );
    assert_eq!(
        captured.lines_with("WARN", "undecodable radar configuration message skipped"),
        1
    );
}

// A radar that alternates between two configurations (issue 38, item 12): each change used
// to log an INFO line, at the rate the radar sent them. Now the changes are rate-limited as
// the repeats are.
#[tokio::test]
async fn a_radar_alternating_between_two_configurations_logs_once_per_interval() {
    let (captured, _guard) = capture();
    tokio::time::timeout(Duration::from_secs(30), async {
        let radar = FakeRadar::bind().await;
        let (driver, receivers) = Driver::new(test_settings(radar.addr));
        let handle = driver.spawn();
        let azimuths = receivers.azimuths.unwrap();
        let mut conn = radar.accept().await;
        let a = small_configuration();
        let mut b = a.clone();
        b.range_in_bins = a.range_in_bins + 8;
        for _ in 0..20 {
            assert_eq!(conn.handshake(&a).await, 21);
            assert_eq!(conn.handshake(&b).await, 21);
        }
        assert_eq!(conn.handshake(&a).await, 21);
        send_ffts(&mut conn, &a, 0..4).await;
        take_async(&azimuths, 4).await;
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!(m.configurations, 41);
    })
    .await
    .expect("bounded");
    assert_eq!(
        captured.lines_with("INFO", "radar configuration azimuths=16"),
        1,
        "41 changes within the interval log once"
    );
}
