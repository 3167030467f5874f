//! MCAP chunks compressed with lz4 (the frame format, as rosbag2 and the `mcap` tools write
//! them; here the `mcap` crate's writer over the C lz4 library) replay to the same poses as
//! the daemon's own zstd chunks; a corrupt lz4 chunk ends the replay there with a message
//! naming the file and the chunk's offset; a stop request while a large chunk decompresses
//! ends the replay without reading on.

mod mcap_support;

use std::fs::File;
use std::io::BufWriter;
use std::ops::Range;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use mcap_support::*;
use slam_node::output::recording::{TOPIC_BSCAN, TOPIC_POSE};

/// Rewrites `from`'s messages into `to`, chunks of `chunk_size` bytes compressed with
/// `compression`.
fn rewrite(from: &Path, to: &Path, compression: mcap::Compression, chunk_size: u64) {
    let bytes = std::fs::read(from).expect("recording");
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .compression(Some(compression))
        .chunk_size(Some(chunk_size))
        .create(BufWriter::new(File::create(to).expect("create")))
        .expect("writer");
    for m in mcap::MessageStream::new(&bytes).expect("mcap") {
        w.write(&m.expect("message")).expect("write");
    }
    w.finish().expect("finish");
}

/// A chunk record in a file: its offset, its compression, where its compressed data is.
#[derive(Debug)]
struct ChunkAt {
    offset: usize,
    compression: String,
    data: Range<usize>,
}

fn u64_at(b: &[u8], at: usize) -> usize {
    u64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes")) as usize
}

/// The file's chunk records, walking its records (opcode, u64 length, body) to the footer.
fn chunks(bytes: &[u8]) -> Vec<ChunkAt> {
    let mut out = Vec::new();
    let mut pos = 8;
    while pos + 9 <= bytes.len() && bytes[pos] != 0x02 {
        let len = u64_at(bytes, pos + 1);
        if bytes[pos] == 0x06 {
            // Times (16), uncompressed size (8), CRC (4), compression string, compressed size.
            let body = pos + 9;
            let name_len =
                u32::from_le_bytes(bytes[body + 28..body + 32].try_into().expect("4")) as usize;
            let name = &bytes[body + 32..body + 32 + name_len];
            let data_len = u64_at(bytes, body + 32 + name_len);
            let data = body + 40 + name_len;
            out.push(ChunkAt {
                offset: pos,
                compression: String::from_utf8_lossy(name).into_owned(),
                data: data..data + data_len,
            });
        }
        pos += 9 + len;
    }
    out
}

#[test]
fn an_lz4_recording_replays_to_the_same_poses_as_the_zstd_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let zstd_file = live_recording(dir.path());
    let lz4_file = dir.path().join("lz4.mcap");
    rewrite(&zstd_file, &lz4_file, mcap::Compression::Lz4, 256 << 10);
    let lz4_chunks = chunks(&std::fs::read(&lz4_file).expect("lz4"));
    assert!(lz4_chunks.len() > 2, "{lz4_chunks:?}");
    assert!(lz4_chunks.iter().all(|c| c.compression == "lz4"));
    let zstd_chunks = chunks(&std::fs::read(&zstd_file).expect("zstd"));
    assert!(zstd_chunks.iter().all(|c| c.compression == "zstd"));

    let (az, odo, handle) = replay(&zstd_file);
    let (zstd_tum, zstd_run) = run(dir.path(), "from-zstd", az, odo);
    let zstd_counts = handle.finish();
    let (az, odo, handle) = replay(&lz4_file);
    let (lz4_tum, lz4_run) = run(dir.path(), "from-lz4", az, odo);
    let lz4_counts = handle.finish();
    assert_eq!(lz4_counts.file_error, None);
    assert_eq!(lz4_counts.azimuths, ROTATIONS * AZIMUTHS);
    assert_eq!(lz4_counts, zstd_counts);
    let stamps = tum_stamps(&zstd_tum);
    assert_eq!(stamps.len() as u64, POSED_ROTATIONS, "{zstd_tum}");
    assert!(stamps.iter().all(|t| *t >= T0), "{zstd_tum}");
    assert_eq!(lz4_tum, zstd_tum);
    // The estimated poses, covariances included, to the bit.
    let poses = payloads(&zstd_run, TOPIC_POSE);
    assert_eq!(poses.len() as u64, POSED_ROTATIONS);
    assert_eq!(payloads(&lz4_run, TOPIC_POSE), poses);
}

#[test]
fn a_corrupt_lz4_chunk_ends_the_replay_there_naming_the_file_and_the_chunk() {
    let dir = tempfile::tempdir().expect("tempdir");
    let lz4_file = dir.path().join("lz4.mcap");
    rewrite(
        &live_recording(dir.path()),
        &lz4_file,
        mcap::Compression::Lz4,
        256 << 10,
    );
    let good = std::fs::read(&lz4_file).expect("lz4");
    let second = chunks(&good).into_iter().nth(1).expect("a second chunk");
    // Eight bytes inverted in the middle of its compressed data; its claimed size 1 too
    // large; its claimed size 1000 times its compressed bytes (more than lz4 can expand to).
    let mut flipped = good.clone();
    let mid = (second.data.start + second.data.end) / 2;
    for b in &mut flipped[mid..mid + 8] {
        *b ^= 0xff;
    }
    let size_at = second.offset + 9 + 16;
    let claimed = u64_at(&good, size_at) as u64;
    let mut longer = good.clone();
    longer[size_at..size_at + 8].copy_from_slice(&(claimed + 1).to_le_bytes());
    let mut beyond = good.clone();
    let ratio = 1000 * second.data.len() as u64;
    beyond[size_at..size_at + 8].copy_from_slice(&ratio.to_le_bytes());
    for (name, bytes, says) in [
        (
            "flipped.mcap",
            flipped,
            &["lz4", "CRC", "decompresses to"][..],
        ),
        ("longer.mcap", longer, &["decompresses to"][..]),
        ("beyond.mcap", beyond, &["more than lz4 can expand to"][..]),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).expect("write");
        let (done_tx, done_rx) = crossbeam_channel::bounded(1);
        let p = path.clone();
        std::thread::spawn(move || {
            let _ = done_tx.send(replay_counts(&p));
        });
        let counts = done_rx
            .recv_timeout(Duration::from_secs(20))
            .unwrap_or_else(|_| panic!("{name}: the replay did not end"));
        let error = counts.file_error.clone().unwrap_or_default();
        assert!(
            error.contains(&path.display().to_string())
                && error.contains(&format!("the chunk record at byte {}", second.offset))
                && says.iter().any(|s| error.contains(s)),
            "{name}: {error}"
        );
        // What came before the corrupt chunk was replayed, not the rest of the file.
        assert!(
            counts.rotations > 0 && counts.rotations < ROTATIONS,
            "{name}: {counts:?}"
        );
    }
}

/// A file of the test's recording with one chunk of 1 GiB (zeros on a topic the replay
/// ignores, 16,384 messages of 64 KiB: about 150 KB compressed) after its first rotation,
/// replayed under a cap of 1.5 GiB. A stop request set by this thread once the first
/// rotation has come (the reader going on into the large chunk) ends the replay within
/// 250 ms, and the rotations after the large chunk never come. Whether the request lands
/// just before the chunk or during its decompression is a race here: with decompression
/// deaf to the request (the check between blocks removed), one run in four took 846 ms,
/// the others under 0.5 ms. That the request is honoured at the next 1 MiB block is pinned
/// by `source::mcap::decompress`'s unit test.
#[test]
fn a_stop_request_during_a_large_chunk_ends_the_replay() {
    let dir = tempfile::tempdir().expect("tempdir");
    let recording = std::fs::read(live_recording(dir.path())).expect("recording");
    let messages: Vec<_> = mcap::MessageStream::new(&recording)
        .expect("mcap")
        .map(|m| m.expect("message"))
        .collect();
    let path = dir.path().join("large-chunk.mcap");
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .compression(Some(mcap::Compression::Zstd))
        .chunk_size(None)
        .create(BufWriter::new(File::create(&path).expect("create")))
        .expect("writer");
    // The recording holds all its odometry first (the test's odometry is read at once):
    // up to the first B-scan, whose rotation the replay hands on before the large chunk.
    let split = 1 + messages
        .iter()
        .position(|m| m.channel.topic == TOPIC_BSCAN)
        .expect("a b-scan");
    for m in &messages[..split] {
        w.write(m).expect("write");
    }
    w.flush().expect("chunk");
    let none = std::collections::BTreeMap::new();
    // Ids clear of the recording's own (it is written message by message, ids kept).
    let schema = w
        .add_schema_with_id(9000, "std_msgs/msg/Empty", "ros2msg", b"")
        .expect("schema");
    let channel = w
        .add_channel_with_id(9000, schema, "/blob", "cdr", &none)
        .expect("channel");
    let zeros = vec![0u8; 64 << 10];
    for sequence in 0..16_384 {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence,
            log_time: 1,
            publish_time: 1,
        };
        w.write_to_known_channel(&header, &zeros).expect("write");
    }
    w.flush().expect("chunk");
    for m in &messages[split..] {
        w.write(m).expect("write");
    }
    w.finish().expect("finish");
    drop(w);
    let large = chunks(&std::fs::read(&path).expect("file"))
        .into_iter()
        .max_by_key(|c| c.data.len())
        .expect("chunks");
    assert!(large.data.len() < 4 << 20, "{large:?}");

    let mut settings =
        slam_node::daemon::mcap_replay::McapReplaySettings::new(path.clone(), settings().motion);
    settings.max_chunk_bytes = 1536 << 20;
    let stop = std::sync::Arc::clone(&settings.stop);
    let (az, odo, handle) = slam_node::daemon::mcap_replay::start(settings).expect("starts");
    // The first rotation's azimuths, all sent before the reader goes on to the large chunk.
    for _ in 0..AZIMUTHS {
        let azimuth = az.recv_timeout(Duration::from_secs(20));
        assert!(azimuth.is_ok(), "the rotation before the large chunk");
    }
    stop.store(true, Ordering::Relaxed);
    let asked = Instant::now();
    let (done_tx, done_rx) = crossbeam_channel::bounded(1);
    std::thread::spawn(move || {
        let _ = done_tx.send(handle.finish());
    });
    let counts = done_rx
        .recv_timeout(Duration::from_secs(20))
        .expect("the replay ends");
    let took = asked.elapsed();
    drop((az, odo));
    assert!(counts.stopped, "{counts:?}");
    assert_eq!(counts.file_error, None);
    assert!(counts.azimuths < ROTATIONS * AZIMUTHS, "{counts:?}");
    assert!(counts.rotations < ROTATIONS, "{counts:?}");
    assert!(
        took < Duration::from_millis(250),
        "{took:?} after the stop request"
    );
}
