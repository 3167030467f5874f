//! Every fault option, observed on the wire by a client written here. Message numbers count
//! every message of the connection (the configuration is message 1); keep-alives are pushed
//! out of the way (30 s interval) unless the test is about them.

mod common;

use std::num::NonZeroU64;
use std::time::{Duration, Instant};

use bytes::BytesMut;
use common::{split_frames, TestClient};
use protocol::{FrameDecoder, Message, SIGNATURE};
use sim_sensor::faults::OVERSIZED_PAYLOAD;
use sim_sensor::scene::shipped;
use sim_sensor::{FaultScope, FaultSettings, SimHandle, SimOptions, SimServer, Stall};

fn nz(n: u64) -> Option<NonZeroU64> {
    NonZeroU64::new(n)
}

async fn server(faults: FaultSettings) -> SimHandle {
    let scene = shipped::load("outdoor-field").expect("scene");
    let mut options = SimOptions::for_tests(scene);
    options.keepalive_interval = Duration::from_secs(30);
    options.faults = faults;
    SimServer::spawn(options).await.expect("spawn")
}

/// Connects, reads the configuration frame's raw bytes, starts the stream.
async fn started(handle: &SimHandle) -> (TestClient, Vec<u8>) {
    let mut client = TestClient::connect(handle.local_addr()).await;
    // The configuration frame: header, then its payload.
    let header = client.read_raw(22).await;
    let size = u32::from_be_bytes([header[18], header[19], header[20], header[21]]) as usize;
    let mut config = header;
    config.extend(client.read_raw(size).await);
    client.send(Message::StartFftData).await;
    (client, config)
}

#[tokio::test]
async fn drop_after_n_messages_closes_the_connection_right_after_message_n() {
    let handle = server(FaultSettings {
        drop_after_messages: nz(6),
        ..FaultSettings::default()
    })
    .await;
    let (mut client, config) = started(&handle).await;
    let rest = client.read_to_end().await;
    let frames = split_frames(&rest);
    // Messages 2..=6 are FFT frames, all whole; then the connection ends.
    assert_eq!(frames.len(), 5, "frames after the configuration");
    let mut stream = BytesMut::from(&config[..]);
    stream.extend_from_slice(&rest);
    let mut decoder = FrameDecoder::new();
    let mut n = 0;
    while let Some(m) = decoder.decode(&mut stream).expect("every frame is whole") {
        n += 1;
        if n > 1 {
            assert!(matches!(m, Message::FftData(_)));
        }
    }
    assert_eq!(n, 6);
    assert!(stream.is_empty());
    assert_eq!(handle.stats().fault_closes, 1);
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn cut_frame_sends_half_of_message_n_and_then_closes() {
    let handle = server(FaultSettings {
        cut_frame_at_message: nz(4),
        ..FaultSettings::default()
    })
    .await;
    let (mut client, _config) = started(&handle).await;
    let rest = client.read_to_end().await;
    let frames = split_frames(&rest);
    assert_eq!(frames.len(), 3, "two whole FFT frames and a partial one");
    let whole = frames[0].len();
    assert_eq!(frames[1].len(), whole);
    assert_eq!(
        frames[2].len(),
        whole / 2,
        "exactly the first half of message 4"
    );
    assert_eq!(frames[2], &frames[2][..whole / 2]);
    // A decoder sees two frames and waits for the rest of the third.
    let mut stream = BytesMut::from(&rest[..]);
    let mut decoder = FrameDecoder::new();
    assert!(decoder.decode(&mut stream).expect("ok").is_some());
    assert!(decoder.decode(&mut stream).expect("ok").is_some());
    assert_eq!(decoder.decode(&mut stream).expect("ok"), None);
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn corruption_inverts_one_signature_byte_in_every_nth_message_and_a_decoder_resyncs() {
    let handle = server(FaultSettings {
        corrupt_every_n: nz(3),
        ..FaultSettings::default()
    })
    .await;
    let (mut client, config) = started(&handle).await;
    // The configuration is message 1: intact.
    assert_eq!(&config[..16], &SIGNATURE);
    let frame_len = {
        let header = client.read_raw(22).await;
        let size = u32::from_be_bytes([header[18], header[19], header[20], header[21]]) as usize;
        let mut frame = header;
        frame.extend(client.read_raw(size).await);
        let len = frame.len();
        client.buf = {
            let mut b = BytesMut::from(&frame[..]);
            b.extend_from_slice(&client.buf);
            b
        };
        len
    };
    let raw = client.read_raw(frame_len * 12).await;
    let mut corrupted = Vec::new();
    for (i, frame) in raw.chunks_exact(frame_len).enumerate() {
        let message = i as u64 + 2;
        let diffs: Vec<usize> = (0..16).filter(|&b| frame[b] != SIGNATURE[b]).collect();
        if message.is_multiple_of(3) {
            let position = (message * 7 % 16) as usize;
            assert_eq!(diffs, vec![position], "message {message}");
            assert_eq!(frame[position], !SIGNATURE[position]);
            corrupted.push(message);
        } else {
            assert!(diffs.is_empty(), "message {message} untouched");
        }
        assert_eq!(frame[16], 1, "version untouched");
    }
    assert_eq!(corrupted, vec![3, 6, 9, 12]);
    // A decoder loses exactly the corrupted frames and decodes every other one.
    let mut stream = BytesMut::from(&raw[..]);
    let mut decoder = FrameDecoder::new();
    let (mut ok, mut errors) = (0, 0);
    loop {
        match decoder.decode(&mut stream) {
            Ok(Some(_)) => ok += 1,
            Ok(None) => break,
            Err(_) => errors += 1,
        }
    }
    assert_eq!(ok, 12 - 4);
    assert!(errors >= 1);
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn skipping_leaves_out_every_nth_azimuth_and_the_gap_shows_in_encoder_and_sweep_counter() {
    let handle = server(FaultSettings {
        skip_azimuth_every_n: nz(4),
        ..FaultSettings::default()
    })
    .await;
    let (mut client, _) = started(&handle).await;
    let mut sweeps = Vec::new();
    let mut encoders = Vec::new();
    for _ in 0..15 {
        let fft = client.next_fft().await;
        sweeps.push(fft.sweep_counter);
        encoders.push(fft.azimuth);
    }
    // Azimuths 3, 7, 11, 15, 19 (the 4th, 8th, ...) never arrive.
    let expected: Vec<u16> = (0u16..20).filter(|k| (k + 1) % 4 != 0).collect();
    assert_eq!(sweeps, expected);
    assert_eq!(
        encoders,
        expected.iter().map(|k| k * 28).collect::<Vec<_>>()
    );
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn a_stall_sends_nothing_for_its_duration_after_message_n() {
    let handle = server(FaultSettings {
        stall: Some(Stall {
            after_messages: NonZeroU64::new(5).expect("nonzero"),
            duration: Duration::from_millis(600),
        }),
        ..FaultSettings::default()
    })
    .await;
    let (mut client, _) = started(&handle).await;
    for _ in 0..3 {
        client.next_fft().await;
    }
    let fourth = client.next_fft().await; // message 5
    let at_fourth = Instant::now();
    let fifth = client.next_fft().await; // message 6, after the stall
    let gap = at_fourth.elapsed();
    assert!(gap >= Duration::from_millis(550), "gap {gap:?}");
    assert_eq!(
        fifth.sweep_counter,
        fourth.sweep_counter + 1,
        "nothing lost, only late"
    );
    // Only once per connection: the next frames come at once.
    let at_fifth = Instant::now();
    for _ in 0..20 {
        client.next_fft().await;
    }
    assert!(at_fifth.elapsed() < Duration::from_millis(550));
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn no_keepalive_silences_keep_alives_that_otherwise_arrive() {
    let scene = shipped::load("penetration-wood").expect("scene");
    let mut options = SimOptions::for_tests(scene);
    options.keepalive_interval = Duration::from_millis(50);
    let control = SimServer::spawn(options.clone()).await.expect("spawn");
    options.faults.no_keepalive = true;
    let silent = SimServer::spawn(options).await.expect("spawn");

    async fn count_keepalives(handle: &SimHandle) -> usize {
        let mut client = TestClient::connect(handle.local_addr()).await;
        client.configuration().await;
        let start = Instant::now();
        let mut n = 0;
        while start.elapsed() < Duration::from_millis(500) {
            if let Some(m) = client.next_within(Duration::from_millis(100)).await {
                assert_eq!(m, Message::KeepAlive);
                n += 1;
            }
        }
        n
    }
    assert!(count_keepalives(&control).await >= 2);
    assert_eq!(count_keepalives(&silent).await, 0);
    control.shutdown().await.expect("shutdown");
    silent.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn an_oversized_announcement_rewrites_the_length_of_message_n_and_the_stream_recovers() {
    let handle = server(FaultSettings {
        oversized_at_message: nz(3),
        ..FaultSettings::default()
    })
    .await;
    let (mut client, _) = started(&handle).await;
    let first = client.next_fft().await; // message 2, decoded normally
                                         // Message 3's header announces OVERSIZED_PAYLOAD bytes.
    let header = client.read_raw(22).await;
    assert_eq!(&header[..16], &SIGNATURE);
    assert_eq!(
        u32::from_be_bytes([header[18], header[19], header[20], header[21]]),
        OVERSIZED_PAYLOAD
    );
    // The decoder rejects that length before buffering and finds the next frames.
    let mut stream = BytesMut::from(&header[..]);
    stream.extend_from_slice(&client.read_raw(40_000).await);
    let mut decoder = FrameDecoder::new();
    let mut errors = 0;
    let mut sweeps = Vec::new();
    loop {
        match decoder.decode(&mut stream) {
            Ok(Some(Message::FftData(f))) => sweeps.push(f.sweep_counter),
            Ok(Some(_)) => {}
            Ok(None) => break,
            Err(_) => errors += 1,
        }
    }
    assert!(errors >= 1);
    assert_eq!(
        sweeps.first().copied(),
        Some(first.sweep_counter + 2),
        "message 3 lost, message 4 decoded"
    );
    assert!(sweeps.windows(2).all(|w| w[1] == w[0] + 1));
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn a_fault_scope_of_one_connection_leaves_the_reconnection_clean() {
    let scene = shipped::load("outdoor-field").expect("scene");
    let mut options = SimOptions::for_tests(scene);
    options.keepalive_interval = Duration::from_secs(30);
    options.faults = FaultSettings {
        drop_after_messages: nz(3),
        ..FaultSettings::default()
    };
    options.fault_scope = FaultScope::FirstConnections(1);
    let handle = SimServer::spawn(options).await.expect("spawn");
    let (mut first, _) = started(&handle).await;
    let rest = first.read_to_end().await;
    assert_eq!(split_frames(&rest).len(), 2);
    let (mut second, _) = started(&handle).await;
    for _ in 0..50 {
        second.next_fft().await;
    }
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn skipping_every_azimuth_starves_nobody_on_a_single_threaded_runtime() {
    let handle = server(FaultSettings {
        skip_azimuth_every_n: nz(1),
        ..FaultSettings::default()
    })
    .await;
    let (mut client, _) = started(&handle).await;
    // No azimuth ever arrives, yet the same runtime keeps serving other connections.
    assert!(client
        .next_within(Duration::from_millis(200))
        .await
        .is_none());
    let mut other = TestClient::connect(handle.local_addr()).await;
    other.configuration().await;
    assert!(handle.stats().azimuths_skipped > 0);
    assert_eq!(handle.stats().azimuths_sent, 0);
    tokio::time::timeout(Duration::from_secs(10), handle.shutdown())
        .await
        .expect("shutdown in time")
        .expect("shutdown");
}
