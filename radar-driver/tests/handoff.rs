//! The hand-off under a slow consumer, the recording, and the `Sink` and `Clock` seams.

mod common;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use bytes::BytesMut;
use common::*;
use protocol::{FrameDecoder, Message};
use radar_driver::{Azimuth, Clock, Delivery, Driver, DropPolicy, HandoffSettings, Rotation, Sink};

const BOUND: Duration = Duration::from_secs(60);

async fn slow_consumer(policy: DropPolicy) {
    let radar = FakeRadar::bind().await;
    let mut settings = test_settings(radar.addr);
    settings.handoff = HandoffSettings {
        azimuth_capacity: Some(16),
        rotation_capacity: Some(2),
        drop_policy: policy,
    };
    let (driver, rx) = Driver::new(settings);
    let handle = driver.spawn();
    let config = small_configuration();
    let mut conn = radar.accept().await;
    conn.handshake(&config).await;
    // 2000 azimuths (125 rotations) while nobody reads.
    send_ffts(&mut conn, &config, 0..2000).await;
    assert!(eventually(|| handle.metrics().azimuths_sent == 2000).await);
    let az_rx = rx.azimuths.clone().unwrap();
    let rot_rx = rx.rotations.clone().unwrap();
    assert!(
        az_rx.len() <= 16,
        "the channel never holds more than its capacity"
    );
    assert!(rot_rx.len() <= 2);
    let azimuths: Vec<Azimuth> = az_rx.try_iter().collect();
    let m = handle.stop().await.unwrap().metrics;
    let rotations: Vec<Rotation> = rot_rx.try_iter().collect();
    assert_eq!(azimuths.len(), 16);
    assert_eq!(m.azimuths_sent, 2000);
    assert_eq!(
        azimuths.len() as u64 + m.azimuth_drops,
        m.azimuths_sent,
        "sent = delivered + dropped"
    );
    // 124 rotations closed by a wrap while streaming, plus the partial one at shutdown.
    assert_eq!(m.rotations_sent, 125);
    assert_eq!(rotations.len() as u64 + m.rotation_drops, m.rotations_sent);
    match policy {
        DropPolicy::DropNewest => {
            assert_eq!(
                sweeps(&azimuths),
                (0..16).collect::<Vec<u16>>(),
                "the oldest are kept"
            );
            assert_eq!(rotations[0].sequence, 0);
        }
        DropPolicy::DropOldest => {
            assert_eq!(
                sweeps(&azimuths),
                (1984..2000).collect::<Vec<u16>>(),
                "the newest are kept"
            );
            assert_eq!(rotations.last().unwrap().sequence, 124);
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_consumer_under_drop_newest_keeps_the_oldest_and_every_drop_is_counted() {
    tokio::time::timeout(BOUND, slow_consumer(DropPolicy::DropNewest))
        .await
        .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_consumer_under_drop_oldest_keeps_the_newest_and_every_drop_is_counted() {
    tokio::time::timeout(BOUND, slow_consumer(DropPolicy::DropOldest))
        .await
        .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_recording_is_the_byte_stream_as_received_ending_each_connection_on_a_frame() {
    tokio::time::timeout(BOUND, async {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("radar.colossus");
        let radar = FakeRadar::bind().await;
        let mut settings = test_settings(radar.addr);
        settings.record_path = Some(path.clone());
        let (driver, rx) = Driver::new(settings);
        let handle = driver.spawn();
        let config = small_configuration();
        let mut expected_bytes = Vec::new();

        let mut conn = radar.accept().await;
        let config_frame = frame(&Message::Configuration(Box::new(config.clone())));
        conn.handshake(&config).await;
        let mut sent = config_frame.clone();
        for s in 0..20 {
            sent.extend_from_slice(&fft_frame(&config, s));
        }
        sent.extend_from_slice(&[0xEE; 37]);
        sent.extend_from_slice(&frame(&Message::KeepAlive));
        conn.send(&sent[config_frame.len()..]).await.unwrap();
        expected_bytes.extend_from_slice(&sent);
        let stub = fft_frame(&config, 20);
        conn.send(&stub[..40]).await.unwrap();
        take_async(rx.azimuths.as_ref().unwrap(), 20).await;
        drop(conn);

        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        expected_bytes.extend_from_slice(&config_frame);
        let mut second = Vec::new();
        for s in 21..30 {
            second.extend_from_slice(&fft_frame(&config, s));
        }
        conn.send(&second).await.unwrap();
        expected_bytes.extend_from_slice(&second);
        take_async(rx.azimuths.as_ref().unwrap(), 9).await;
        let exit = handle.stop().await.unwrap();
        let summary = exit.recording.unwrap();
        assert_eq!(summary.error, None);
        assert_eq!(summary.chunks_dropped, 0);
        let recorded = std::fs::read(&path).unwrap();
        assert_eq!(summary.bytes_written, recorded.len() as u64);
        assert_eq!(exit.metrics.record_bytes, recorded.len() as u64);
        assert_eq!(recorded.len(), expected_bytes.len());
        assert!(
            recorded == expected_bytes,
            "the recording differs from the bytes sent"
        );

        // And it decodes back into the same messages.
        let mut buf = BytesMut::from(&recorded[..]);
        let mut decoder = FrameDecoder::new();
        let mut ffts = 0;
        let mut configs = 0;
        loop {
            match decoder.decode(&mut buf) {
                Ok(Some(Message::FftData(_))) => ffts += 1,
                Ok(Some(Message::Configuration(_))) => configs += 1,
                Ok(Some(_)) | Err(_) => {}
                Ok(None) => break,
            }
        }
        assert_eq!((ffts, configs), (29, 2));
    })
    .await
    .expect("bounded");
}

mockall::mock! {
    pub TestSink {}
    impl Sink for TestSink {
        fn send_azimuth(&mut self, azimuth: Azimuth) -> Delivery;
        fn send_rotation(&mut self, rotation: Rotation) -> Delivery;
        fn wants_rotations(&self) -> bool;
        fn wants_azimuths(&self) -> bool;
    }
}

impl std::fmt::Debug for MockTestSink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("MockTestSink")
    }
}

mockall::mock! {
    pub TestClock {}
    impl Clock for TestClock {
        fn unix_now_s(&self) -> f64;
        fn monotonic_ns(&self) -> u64;
    }
}

impl std::fmt::Debug for MockTestClock {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("MockTestClock")
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_driver_counts_exactly_what_the_sink_reports_and_offers_in_order() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let seen = Arc::new(Mutex::new(Vec::new()));
        let mut sink = MockTestSink::new();
        sink.expect_wants_azimuths().return_const(true);
        sink.expect_wants_rotations().return_const(true);
        let s = Arc::clone(&seen);
        sink.expect_send_azimuth().times(40).returning(move |az| {
            s.lock().unwrap().push(az.sweep_counter);
            // Every third offer is refused (as a full channel would).
            if az.sweep_counter % 3 == 0 {
                Delivery::DroppedNewest
            } else if az.sweep_counter % 3 == 1 {
                Delivery::DeliveredDroppingOldest
            } else {
                Delivery::Delivered
            }
        });
        sink.expect_send_rotation().times(3).returning(|r| {
            if r.sequence == 1 {
                Delivery::DroppedNewest
            } else {
                Delivery::Delivered
            }
        });
        let driver = Driver::with_sink(test_settings(radar.addr), Box::new(sink));
        let handle = driver.spawn();
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        send_ffts(&mut conn, &config, 0..40).await;
        assert!(eventually(|| handle.metrics().azimuths_sent == 40).await);
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!(*seen.lock().unwrap(), (0..40).collect::<Vec<u16>>());
        // sweeps % 3 == 0: 14 dropped-newest; % 3 == 1: 13 delivered after dropping an old one.
        assert_eq!(m.azimuth_drops, 14 + 13);
        assert_eq!(m.azimuths_delivered, 40 - 14);
        assert_eq!(
            (m.rotations_sent, m.rotation_drops, m.rotations_delivered),
            (3, 1, 2)
        );
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn latency_is_measured_from_the_socket_read_to_the_channel_send_on_the_given_clock() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        // Each reading of the clock is 17 ns after the previous one. With one frame per
        // socket read, each azimuth's latency is exactly one tick.
        let ticks = Arc::new(AtomicU64::new(1_000_000));
        let mut clock = MockTestClock::new();
        let t = Arc::clone(&ticks);
        clock
            .expect_monotonic_ns()
            .returning(move || t.fetch_add(17, Ordering::SeqCst));
        clock.expect_unix_now_s().return_const(1.7e9);
        let (driver, rx) = Driver::new(test_settings(radar.addr));
        let handle = driver.with_clock(Arc::new(clock)).spawn();
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        for s in 0..20 {
            conn.send(&fft_frame(&config, s)).await.unwrap();
            take_async(rx.azimuths.as_ref().unwrap(), 1).await;
        }
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!(m.latency.count, 20);
        assert_eq!(
            (m.latency.median_ns, m.latency.p99_ns, m.latency.max_ns),
            (17, 17, 17)
        );
    })
    .await
    .expect("bounded");
}
