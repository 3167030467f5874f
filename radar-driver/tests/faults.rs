//! Recovery from every fault mode over loopback: the frames after the fault are delivered,
//! the right counters move, and nothing panics.

mod common;

use std::time::Duration;

use common::*;
use protocol::{Message, SIGNATURE};
use radar_driver::{Driver, DriverHandle, Receivers};

const BOUND: Duration = Duration::from_secs(30);

async fn start(radar: &FakeRadar) -> (DriverHandle, Receivers) {
    let (driver, rx) = Driver::new(test_settings(radar.addr));
    (driver.spawn(), rx)
}

fn expected(ranges: &[std::ops::Range<u16>]) -> Vec<u16> {
    ranges.iter().cloned().flatten().collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_dropped_connection_costs_a_reconnect_and_the_rotation_in_progress_survives_it() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (handle, rx) = start(&radar).await;
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        send_ffts(&mut conn, &config, 0..20).await;
        drop(conn);
        let mut conn = radar.accept().await;
        assert_eq!(conn.handshake(&config).await, 21);
        send_ffts(&mut conn, &config, 20..40).await;
        let az = take_async(rx.azimuths.as_ref().unwrap(), 40).await;
        assert_eq!(sweeps(&az), (0..40).collect::<Vec<u16>>());
        // Rotation 1 (azimuths 16..31) straddles the reconnection and is whole.
        let rots = take_async(rx.rotations.as_ref().unwrap(), 2).await;
        assert!(rots[1].complete);
        assert_eq!(sweeps(&rots[1].azimuths), (16..32).collect::<Vec<u16>>());
        assert_eq!(rots[1].skipped_azimuths, 0);
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!((m.connections, m.reconnects, m.configurations), (2, 1, 2));
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn half_a_frame_followed_by_more_frames_costs_only_that_frame() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (handle, rx) = start(&radar).await;
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        send_ffts(&mut conn, &config, 0..10).await;
        let cut = fft_frame(&config, 10);
        conn.send(&cut[..cut.len() / 2]).await.unwrap();
        send_ffts(&mut conn, &config, 11..30).await;
        let az = take_async(rx.azimuths.as_ref().unwrap(), 29).await;
        assert_eq!(sweeps(&az), expected(&[0..10, 11..30]));
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!(m.decode_errors.truncated, 1);
        assert_eq!(
            (m.sweep_gaps, m.sweep_missing, m.skipped_azimuths),
            (1, 1, 1)
        );
        assert_eq!(m.reconnects, 0);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn half_a_frame_then_a_closed_connection_costs_that_frame_and_a_reconnect() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (handle, rx) = start(&radar).await;
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        send_ffts(&mut conn, &config, 0..10).await;
        let cut = fft_frame(&config, 10);
        conn.send(&cut[..30]).await.unwrap();
        drop(conn);
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        send_ffts(&mut conn, &config, 11..30).await;
        let az = take_async(rx.azimuths.as_ref().unwrap(), 29).await;
        assert_eq!(sweeps(&az), expected(&[0..10, 11..30]));
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!(m.reconnects, 1);
        assert_eq!(
            m.decode_errors.total(),
            0,
            "an unfinished frame at a disconnect is not a decode error"
        );
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn corrupt_bytes_between_frames_and_a_corrupt_signature_cost_only_what_they_hit() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (handle, rx) = start(&radar).await;
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        send_ffts(&mut conn, &config, 0..10).await;
        // Garbage with a near-signature in it.
        let mut garbage: Vec<u8> = (0..200u32).map(|i| (i * 37 % 256) as u8).collect();
        garbage.extend_from_slice(&SIGNATURE[..12]);
        garbage.extend_from_slice(&[0xAB; 50]);
        conn.send(&garbage).await.unwrap();
        send_ffts(&mut conn, &config, 10..20).await;
        // Frame 20 with one signature byte flipped: it is garbage now.
        let mut bad = fft_frame(&config, 20);
        bad[5] ^= 0xFF;
        conn.send(&bad).await.unwrap();
        // Frame 21 claims version 2: rejected.
        let mut v2 = fft_frame(&config, 21);
        v2[16] = 2;
        conn.send(&v2).await.unwrap();
        send_ffts(&mut conn, &config, 22..40).await;
        let az = take_async(rx.azimuths.as_ref().unwrap(), 38).await;
        assert_eq!(sweeps(&az), expected(&[0..20, 22..40]));
        let m = handle.stop().await.unwrap().metrics;
        assert!(m.decode_errors.signature >= 2, "{:?}", m.decode_errors);
        assert_eq!(m.decode_errors.version, 1);
        assert_eq!(m.reconnects, 0);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_oversized_length_is_rejected_without_reserving_it_and_the_stream_goes_on() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (handle, rx) = start(&radar).await;
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        send_ffts(&mut conn, &config, 0..10).await;
        let mut huge = SIGNATURE.to_vec();
        huge.extend_from_slice(&[1, 30]);
        huge.extend_from_slice(&4_000_000_000u32.to_be_bytes());
        huge.extend_from_slice(&[0x55; 64]);
        conn.send(&huge).await.unwrap();
        send_ffts(&mut conn, &config, 10..20).await;
        let az = take_async(rx.azimuths.as_ref().unwrap(), 20).await;
        assert_eq!(sweeps(&az), (0..20).collect::<Vec<u16>>());
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!(m.decode_errors.oversized, 1);
        assert_eq!(m.reconnects, 0);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stall_longer_than_the_watchdog_is_a_dead_link_and_the_driver_reconnects() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (handle, rx) = start(&radar).await;
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        send_ffts(&mut conn, &config, 0..10).await;
        // Hold the connection open and silent; the watchdog is 1 s.
        let mut conn2 = radar.accept().await;
        assert!(
            conn.closed_by_client().await,
            "the driver drops the dead link"
        );
        conn2.handshake(&config).await;
        send_ffts(&mut conn2, &config, 10..20).await;
        let az = take_async(rx.azimuths.as_ref().unwrap(), 20).await;
        assert_eq!(sweeps(&az), (0..20).collect::<Vec<u16>>());
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!((m.watchdog_timeouts, m.reconnects), (1, 1));
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn missing_keep_alives_on_an_idle_link_trip_the_watchdog_but_keep_alives_alone_keep_it_up() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (handle, rx) = start(&radar).await;
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        // Keep-alives every 100 ms for 2.5 s (two and a half watchdog periods): the link
        // stays up.
        for _ in 0..25 {
            conn.send_message(&Message::KeepAlive).await;
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        assert_eq!(handle.metrics().watchdog_timeouts, 0);
        assert!(handle.metrics().keep_alives >= 25);
        // Then silence: no keep-alives, no data.
        let mut conn2 = radar.accept().await;
        conn2.handshake(&config).await;
        send_ffts(&mut conn2, &config, 0..5).await;
        let az = take_async(rx.azimuths.as_ref().unwrap(), 5).await;
        assert_eq!(sweeps(&az), (0..5).collect::<Vec<u16>>());
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!((m.watchdog_timeouts, m.reconnects), (1, 1));
        drop(conn);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_radar_that_never_sends_its_configuration_is_abandoned_by_the_watchdog() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (handle, rx) = start(&radar).await;
        let config = small_configuration();
        let mut conn = radar.accept().await;
        // FFT data before any configuration cannot be interpreted.
        send_ffts(&mut conn, &config, 0..3).await;
        let mut conn2 = radar.accept().await;
        conn2.handshake(&config).await;
        send_ffts(&mut conn2, &config, 3..6).await;
        let az = take_async(rx.azimuths.as_ref().unwrap(), 3).await;
        assert_eq!(sweeps(&az), (3..6).collect::<Vec<u16>>());
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!(m.fft_before_configuration, 3);
        assert_eq!(m.watchdog_timeouts, 1);
        drop(conn);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_driver_gives_up_after_the_configured_attempts_with_a_typed_error() {
    tokio::time::timeout(BOUND, async {
        let addr = {
            let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
            l.local_addr().unwrap()
        };
        let mut settings = test_settings(addr);
        settings.max_attempts = std::num::NonZeroU32::new(3);
        let (driver, _rx) = Driver::new(settings);
        let metrics = driver.metrics();
        let err = driver.spawn().join().await.unwrap_err();
        assert!(
            matches!(err, radar_driver::DriverError::GaveUp { attempts: 3, .. }),
            "{err}"
        );
        assert_eq!(metrics.snapshot().connect_attempts, 3);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_driver_reconnects_forever_by_default_until_shut_down() {
    tokio::time::timeout(BOUND, async {
        let addr = {
            let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
            l.local_addr().unwrap()
        };
        let (driver, _rx) = Driver::new(test_settings(addr));
        let handle = driver.spawn();
        assert!(eventually(|| handle.metrics().connect_attempts >= 10).await);
        let exit = handle.stop().await.unwrap();
        assert_eq!(exit.metrics.connections, 0);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn random_garbage_and_random_write_splits_lose_no_frame() {
    use rand::{Rng, SeedableRng};
    tokio::time::timeout(BOUND, async {
        let mut rng = rand::rngs::StdRng::seed_from_u64(20_240_101);
        let radar = FakeRadar::bind().await;
        let (handle, rx) = start(&radar).await;
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        let mut wire = Vec::new();
        let mut runs = 0;
        for s in 0..500 {
            if rng.gen_bool(0.3) {
                let len = rng.gen_range(1..300);
                wire.extend((0..len).map(|_| rng.gen::<u8>()));
                runs += 1;
            }
            wire.extend_from_slice(&fft_frame(&config, s));
        }
        // Written in random pieces, so frames and garbage straddle reads.
        let mut rest = &wire[..];
        while !rest.is_empty() {
            let n = rng.gen_range(1..2000).min(rest.len());
            conn.send(&rest[..n]).await.unwrap();
            rest = &rest[n..];
        }
        let az = take_async(rx.azimuths.as_ref().unwrap(), 500).await;
        assert_eq!(sweeps(&az), (0..500).collect::<Vec<u16>>());
        let m = handle.stop().await.unwrap().metrics;
        assert!(runs > 100);
        assert!(
            m.decode_errors.signature >= runs,
            "{} runs, {:?}",
            runs,
            m.decode_errors
        );
        assert_eq!(m.reconnects, 0);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_link_that_carries_only_garbage_is_abandoned_politely_and_reconnected() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let mut settings = test_settings(radar.addr);
        settings.max_consecutive_decode_errors = 8;
        let (driver, rx) = Driver::new(settings);
        let handle = driver.spawn();
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        // Bytes keep flowing (so the watchdog stays quiet) but none of them is a frame.
        // (Keep sending until the driver has given the link up; the writes may coalesce.)
        for _ in 0..200 {
            if handle.metrics().connect_attempts >= 2 || conn.send(&[0x5A; 100]).await.is_err() {
                break;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        assert_eq!(
            conn.recv().await.map(|m| m.id()),
            Some(22),
            "stop before giving the link up"
        );
        assert!(conn.closed_by_client().await);
        let mut conn2 = radar.accept().await;
        conn2.handshake(&config).await;
        send_ffts(&mut conn2, &config, 0..5).await;
        let az = take_async(rx.azimuths.as_ref().unwrap(), 5).await;
        assert_eq!(sweeps(&az), (0..5).collect::<Vec<u16>>());
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!(m.reconnects, 1);
        assert_eq!(m.watchdog_timeouts, 0);
        assert!(m.decode_errors.signature >= 8);
    })
    .await
    .expect("bounded");
}

// Paused clock: virtual seconds pass at once whenever every task waits.
#[tokio::test(start_paused = true)]
async fn a_peer_trickling_bytes_that_never_complete_a_frame_is_declared_dead_and_reconnected() {
    let radar = FakeRadar::bind().await;
    let mut settings = test_settings(radar.addr);
    settings.watchdog_timeout = Duration::from_secs(3);
    let (driver, _rx) = Driver::new(settings);
    let handle = driver.spawn();
    let config = small_configuration();
    let mut conn = radar.accept().await;
    conn.handshake(&config).await;
    let configured_at = tokio::time::Instant::now();
    // One byte a second, forever: every frame takes longer than the watchdog to complete.
    let trickle = tokio::spawn(async move {
        for sweep in 0.. {
            for b in fft_frame(&config, sweep) {
                if conn.send(&[b]).await.is_err() {
                    return;
                }
                tokio::time::sleep(Duration::from_secs(1)).await;
            }
        }
    });
    let _conn2 = radar.accept().await;
    let dead_after = configured_at.elapsed();
    assert!(
        dead_after >= Duration::from_secs(3) && dead_after < Duration::from_millis(3200),
        "declared dead after {dead_after:?}"
    );
    assert!(eventually(|| handle.metrics().connections == 2).await);
    let m = handle.stop().await.unwrap().metrics;
    assert_eq!((m.watchdog_timeouts, m.reconnects), (1, 1));
    assert!(m.bytes > m.frames, "bytes kept arriving: {m:?}");
    trickle.abort();
}

/// A radar on a thread of its own (blocking sockets), so that it goes on sending while the
/// driver's runtime is frozen: the configuration, then, once the client has answered it,
/// FFT frames `0..count`, one every `every`, holding back while `paused` is set (a radar
/// frozen with the driver, as the simulator in the daemon's process is). It holds the
/// connection open until `done` fires (or `BOUND` passes) and returns how many connections
/// it accepted.
fn radar_on_its_own_thread(
    listener: std::net::TcpListener,
    count: u64,
    every: Duration,
    paused: std::sync::Arc<std::sync::atomic::AtomicBool>,
    done: std::sync::mpsc::Receiver<()>,
) -> std::thread::JoinHandle<usize> {
    use std::io::{Read, Write};
    std::thread::spawn(move || {
        let config = small_configuration();
        let deadline = std::time::Instant::now() + BOUND;
        listener.set_nonblocking(true).unwrap();
        let mut accepted = Vec::new();
        let accept = |accepted: &mut Vec<std::net::TcpStream>| -> bool {
            match listener.accept() {
                Ok((s, _)) => {
                    s.set_nonblocking(false).unwrap();
                    s.set_nodelay(true).unwrap();
                    s.set_read_timeout(Some(STEP)).unwrap();
                    accepted.push(s);
                    true
                }
                Err(_) => false,
            }
        };
        while !accept(&mut accepted) {
            assert!(std::time::Instant::now() < deadline, "the driver connects");
            std::thread::sleep(Duration::from_millis(5));
        }
        let conn = &mut accepted[0];
        conn.write_all(&frame(&Message::Configuration(Box::new(config.clone()))))
            .unwrap();
        // The start message (21): any bytes back mean the configuration was answered.
        let mut answer = [0u8; 64];
        assert!(conn.read(&mut answer).unwrap() > 0, "the client answers");
        for sweep in 0..count {
            while paused.load(std::sync::atomic::Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(1));
            }
            if conn.write_all(&fft_frame(&config, sweep)).is_err() {
                break; // The driver dropped the link (the failure this test is about).
            }
            std::thread::sleep(every);
        }
        // Hold the link (and take any reconnection, so the driver does not wait on a
        // backlog) until the test is done.
        while done.try_recv().is_err() && std::time::Instant::now() < deadline {
            accept(&mut accepted);
            std::thread::sleep(Duration::from_millis(5));
        }
        accepted.len()
    })
}

// The driver's process frozen (kill -STOP, or a stall of its runtime) for longer than the
// watchdog while the radar goes on sending: on resume the frames are in the socket's
// receive buffer. The watchdog judges the link by whether frames can be read, so the link
// is alive and every frame is delivered; before, the watchdog fired on resume (it was polled
// before the socket) and the reconnection threw away what the socket held.
#[test]
fn a_driver_frozen_past_its_watchdog_reads_the_frames_waiting_in_its_socket_instead_of_reconnecting(
) {
    // Frozen for 1.5 watchdog periods while the radar sends 150 more frames.
    frozen_driver_keeps_its_link_and_every_frame(|_| {
        std::thread::sleep(Duration::from_millis(1500));
        None
    });
}

// The driver and its radar frozen together past the watchdog (the simulator runs in the
// daemon's process: kill -STOP stops both), the radar resuming a moment after the driver:
// on resume nothing is in the socket yet. The deadline was noticed late (this process was
// not running), so the radar is given a moment before the link is judged, and the link
// stays up; before, the watchdog reconnected at once.
#[test]
fn a_driver_frozen_together_with_its_radar_gives_it_a_moment_on_resume_before_judging_the_link() {
    use std::sync::atomic::Ordering;
    // Both frozen for 1.5 watchdog periods; the radar resumes 100 ms after the driver.
    frozen_driver_keeps_its_link_and_every_frame(|paused| {
        paused.store(true, Ordering::Relaxed);
        std::thread::sleep(Duration::from_millis(1500));
        let resume = std::sync::Arc::clone(paused);
        Some(std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(100));
            resume.store(false, Ordering::Relaxed);
        }))
    });
}

/// The frozen-driver tests: a radar on its own thread sends 300 frames 10 ms apart to a
/// driver on a one-thread runtime (blocking that thread freezes the driver as a stopped
/// process is frozen; 1 s watchdog). After 20 frames `freeze` runs on the driver's thread
/// (it may pause the radar through the flag it is given, and return a thread to join once
/// every frame is in). The verdict: no watchdog trip, no reconnect, one connection, and
/// every frame delivered in order.
fn frozen_driver_keeps_its_link_and_every_frame(
    freeze: impl FnOnce(
        &std::sync::Arc<std::sync::atomic::AtomicBool>,
    ) -> Option<std::thread::JoinHandle<()>>,
) {
    const FRAMES: u64 = 300;
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let (done_tx, done_rx) = std::sync::mpsc::channel();
    let paused = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let radar = radar_on_its_own_thread(
        listener,
        FRAMES,
        Duration::from_millis(10),
        std::sync::Arc::clone(&paused),
        done_rx,
    );
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let (metrics, azimuths) = runtime.block_on(async {
        tokio::time::timeout(BOUND, async {
            let (driver, rx) = Driver::new(test_settings(addr)); // 1 s watchdog
            let handle = driver.spawn();
            assert!(eventually(|| handle.metrics().fft_frames >= 20).await);
            let after = freeze(&paused);
            let delivered = eventually(|| handle.metrics().fft_frames >= FRAMES).await;
            if let Some(thread) = after {
                thread.join().unwrap();
            }
            let metrics = handle.metrics();
            let exit = handle.stop().await.unwrap().metrics;
            let azimuths: Vec<_> = rx.azimuths.as_ref().unwrap().try_iter().collect();
            assert!(delivered, "every frame read: {metrics:?}");
            (exit, azimuths)
        })
        .await
        .expect("bounded")
    });
    done_tx.send(()).unwrap();
    let connections = radar.join().unwrap();
    assert_eq!(
        (metrics.watchdog_timeouts, metrics.reconnects, connections),
        (0, 0, 1),
        "{metrics:?}"
    );
    assert_eq!(sweeps(&azimuths), (0..FRAMES as u16).collect::<Vec<u16>>());
}
