//! Replays over loopback: the Oxford Radar RobotCar scans (read from
//! `../shared/data/oxford-radar-robotcar`, skipped with a message when absent) reproduce
//! every bin, encoder value and timestamp of the PNGs; a raw Colossus recording is re-served
//! frame for frame.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use bytes::BytesMut;
use common::TestClient;
use protocol::{FftData, FrameDecoder, Message};
use sim_sensor::scene::shipped;
use sim_sensor::{SimOptions, SimServer, SourceSpec};
use tokio::io::AsyncReadExt;

fn oxford_dir() -> Option<PathBuf> {
    let dir =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/oxford-radar-robotcar/radar");
    if dir.is_dir() {
        Some(dir)
    } else {
        println!(
            "SKIPPED: the Oxford Radar RobotCar scans are not at {} (they live in ../shared beside the workspace)",
            dir.display()
        );
        None
    }
}

/// Decodes a polar PNG independently of the simulator's own reader: the png crate alone.
fn reference_rows(path: &Path) -> Vec<(i64, u16, Vec<u8>)> {
    let decoder = png::Decoder::new(std::fs::File::open(path).expect("open"));
    let mut reader = decoder.read_info().expect("info");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("frame");
    assert_eq!(info.color_type, png::ColorType::Grayscale);
    let width = info.width as usize;
    assert_eq!((width, info.height), (3779, 400));
    buf.chunks_exact(info.line_size)
        .map(|row| {
            let ts = i64::from_le_bytes(row[0..8].try_into().expect("8 bytes"));
            let enc = u16::from_le_bytes([row[8], row[9]]);
            assert_eq!(row[10], 255, "valid flag");
            (ts, enc, row[11..width].to_vec())
        })
        .collect()
}

#[tokio::test]
async fn replaying_the_oxford_scans_reproduces_every_bin_encoder_and_timestamp() {
    let Some(dir) = oxford_dir() else { return };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("dir")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    files.sort();
    assert!(!files.is_empty());
    let mut options = SimOptions::for_tests(shipped::load("penetration-wood").expect("scene"));
    options.source = SourceSpec::OxfordPng(dir.clone());
    options.keepalive_interval = Duration::from_secs(30);
    let handle = SimServer::spawn(options).await.expect("spawn");
    assert!(
        handle.odometry_addr().is_none(),
        "a replay serves no odometry"
    );
    let mut client = TestClient::connect(handle.local_addr()).await;
    let config = client.configuration().await;
    assert_eq!(
        (
            config.azimuth_samples,
            config.bin_size,
            config.range_in_bins,
            config.encoder_size
        ),
        (400, 438, 3768, 5600)
    );
    // The rotation rate is the recording's own: its median interval between scans.
    let mut intervals: Vec<i64> = files
        .windows(2)
        .map(|w| {
            let us =
                |p: &PathBuf| -> i64 { p.file_stem().unwrap().to_str().unwrap().parse().unwrap() };
            us(&w[1]) - us(&w[0])
        })
        .collect();
    intervals.sort_unstable();
    let rotation_mhz = (1e9 / intervals[intervals.len() / 2] as f64).round() as u16;
    assert!((3900..4100).contains(&rotation_mhz), "{rotation_mhz}");
    assert_eq!(
        (config.rotation_speed_millihertz, config.packet_rate),
        (rotation_mhz, (400 * u32::from(rotation_mhz) / 1000) as u16)
    );
    client.send(Message::StartFftData).await;
    let mut served = 0usize;
    for (n, file) in files.iter().enumerate() {
        for (row, (ts_us, encoder, bins)) in reference_rows(file).into_iter().enumerate() {
            let fft = client.next_fft().await;
            let wire_us = i64::from(fft.timestamp.seconds()) * 1_000_000
                + i64::from(fft.timestamp.nanos()) / 1000;
            assert_eq!(
                fft.timestamp.nanos() % 1000,
                0,
                "microsecond timestamps stay exact"
            );
            assert_eq!(wire_us, ts_us, "scan {n} row {row} timestamp");
            assert_eq!(fft.azimuth, encoder, "scan {n} row {row} encoder");
            assert_eq!(
                fft.bins.as_ref(),
                bins.as_slice(),
                "scan {n} row {row} bins"
            );
            served += 1;
        }
    }
    assert_eq!(served, files.len() * 400);
    // The recording has ended: nothing more but keep-alives.
    assert!(client
        .next_within(Duration::from_millis(300))
        .await
        .is_none());
    handle.shutdown().await.expect("shutdown");
}

async fn record_raw_stream(frames: usize) -> (tempfile::TempDir, PathBuf, Vec<FftData>) {
    let scene = shipped::load("penetration-wood").expect("scene");
    let handle = SimServer::spawn(SimOptions::for_tests(scene))
        .await
        .expect("spawn");
    let mut client = TestClient::connect(handle.local_addr()).await;
    client.send(Message::StartFftData).await;
    // Record raw bytes exactly as a recorder would, until enough frames are in.
    let mut raw = Vec::new();
    let mut decoder = FrameDecoder::new();
    let mut pending = BytesMut::new();
    let mut ffts = Vec::new();
    let mut chunk = vec![0u8; 4096];
    while ffts.len() < frames {
        let n = tokio::time::timeout(common::STEP, client.stream.read(&mut chunk))
            .await
            .expect("in time")
            .expect("read");
        assert!(n > 0);
        raw.extend_from_slice(&chunk[..n]);
        pending.extend_from_slice(&chunk[..n]);
        while let Some(m) = decoder.decode(&mut pending).expect("clean stream") {
            if let Message::FftData(f) = m {
                ffts.push(f);
            }
        }
    }
    // Cut the recording at the last whole frame, and put garbage in the middle of it.
    raw.truncate(raw.len() - pending.len());
    let middle = raw.len() / 2;
    let cut = {
        let mut d = FrameDecoder::new();
        let mut b = BytesMut::from(&raw[..]);
        let mut consumed = 0;
        while let Some(_m) = d.decode(&mut b).expect("clean") {
            consumed = raw.len() - b.len();
            if consumed >= middle {
                break;
            }
        }
        consumed
    };
    raw.splice(cut..cut, b"\x00garbage between frames\xff".iter().copied());
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("recording.colossus");
    std::fs::write(&path, &raw).expect("write");
    handle.shutdown().await.expect("shutdown");
    (dir, path, ffts)
}

#[tokio::test]
async fn a_raw_recording_is_re_served_frame_for_frame_despite_garbage_in_it() {
    let (_dir, path, recorded) = record_raw_stream(300).await;
    let mut options = SimOptions::for_tests(shipped::load("penetration-wood").expect("scene"));
    options.source = SourceSpec::RawStream(path);
    options.keepalive_interval = Duration::from_secs(30);
    let handle = SimServer::spawn(options).await.expect("spawn");
    let mut client = TestClient::connect(handle.local_addr()).await;
    let config = client.configuration().await;
    assert_eq!(config.azimuth_samples, 200);
    client.send(Message::StartFftData).await;
    for (i, original) in recorded.iter().enumerate() {
        let replayed = client.next_fft().await;
        assert_eq!(&replayed, original, "frame {i}");
    }
    assert!(client
        .next_within(Duration::from_millis(300))
        .await
        .is_none());
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn a_raw_file_without_a_configuration_is_refused_with_a_typed_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("junk.bin");
    std::fs::write(&path, vec![0xAB; 10_000]).expect("write");
    let mut options = SimOptions::for_tests(shipped::load("penetration-wood").expect("scene"));
    options.source = SourceSpec::RawStream(path);
    let err = SimServer::spawn(options)
        .await
        .expect_err("no configuration");
    assert!(matches!(err, sim_sensor::SimError::Replay(_)), "{err}");
    let mut options = SimOptions::for_tests(shipped::load("penetration-wood").expect("scene"));
    options.source = SourceSpec::OxfordPng(dir.path().to_path_buf());
    let err = SimServer::spawn(options).await.expect_err("no scans");
    assert!(err.to_string().contains("no .png"), "{err}");
}

#[test]
fn a_scene_file_past_the_size_limit_or_the_feature_limit_is_refused_without_reading_it_all() {
    use sim_sensor::scene::{Scene, MAX_FEATURES};
    // /dev/zero never ends: the reader stops one byte past the limit.
    if std::path::Path::new("/dev/zero").exists() {
        let err = Scene::load(std::path::Path::new("/dev/zero")).unwrap_err();
        assert!(err.to_string().contains("larger than"), "{err}");
    }
    // More individual features than a scene may hold.
    let mut text = String::from("[radar]\npreset = \"paper-200\"\n");
    for k in 0..=MAX_FEATURES {
        text.push_str(&format!(
            "[[features]]\nkind = \"lamp-post\"\nx_m = {}\ny_m = 1.0\n",
            k % 1000
        ));
    }
    let err = Scene::from_toml_str("huge", &text).unwrap_err();
    assert!(err.to_string().contains("at most"), "{err}");
}

#[tokio::test]
async fn a_raw_replay_of_something_that_holds_no_frame_fails_instead_of_reading_for_ever() {
    let zero = std::path::Path::new("/dev/zero");
    if !zero.exists() {
        return;
    }
    let err = tokio::time::timeout(
        std::time::Duration::from_secs(60),
        sim_sensor::replay::raw::RawRecording::open(zero),
    )
    .await
    .expect("bounded")
    .unwrap_err();
    assert!(err.to_string().contains("no"), "{err}");
}
