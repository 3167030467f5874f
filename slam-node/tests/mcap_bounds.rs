//! An MCAP file's length fields cannot make the replay allocate more than the file holds
//! (issue 38, item 8): a small file whose chunk header claims a compression string of
//! hundreds of MB, or whose record claims hundreds of MB, is refused with a typed error
//! before the claim is allocated. Peak allocation is counted by a counting global
//! allocator (`allocation-counter`, per thread) installed in this test binary only; the
//! records are read on the test's own thread.

use std::io::Write;
use std::ops::ControlFlow;
use std::path::Path;

use slam_node::source::mcap::{read_records, McapFileError, RecordsEnd};

const MAGIC: &[u8] = b"\x89MCAP0\r\n";
/// The replay's record limit (256 MiB).
const LIMIT: usize = 256 << 20;
/// The size of the issue's crafted file.
const FILE_BYTES: usize = 191 * 1024;
/// What reading any of these files may allocate at its peak: the file's size and change.
const PEAK_BOUND: u64 = 2 * FILE_BYTES as u64 + (1 << 20);

/// The magic and an empty header record.
fn start() -> Vec<u8> {
    let mut buf = MAGIC.to_vec();
    buf.push(0x01);
    buf.extend(8u64.to_le_bytes());
    buf.extend(0u32.to_le_bytes());
    buf.extend(0u32.to_le_bytes());
    buf
}

/// A chunk record of `record_len` whose header claims a compression string of
/// `compression_len` bytes, padded with zeros to `FILE_BYTES`.
fn chunk_claiming(compression_len: u32, record_len: u64) -> Vec<u8> {
    let mut buf = start();
    buf.push(0x06);
    buf.extend(record_len.to_le_bytes());
    buf.extend(0u64.to_le_bytes()); // message start time
    buf.extend(0u64.to_le_bytes()); // message end time
    buf.extend(0u64.to_le_bytes()); // uncompressed size
    buf.extend(0u32.to_le_bytes()); // uncompressed crc
    buf.extend(compression_len.to_le_bytes());
    buf.resize(FILE_BYTES, 0);
    buf
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let path = dir.join(name);
    let mut f = std::fs::File::create(&path).expect("create");
    f.write_all(bytes).expect("write");
    path
}

/// Reads `path`'s records on this thread: the outcome and the peak bytes allocated.
fn read_counted(path: &Path) -> (Result<RecordsEnd, McapFileError>, u64) {
    let file = std::fs::File::open(path).expect("open");
    let mut result = None;
    let info = allocation_counter::measure(|| {
        result = Some(read_records(file, LIMIT, |_, _| ControlFlow::Continue(())));
    });
    (result.expect("ran"), info.bytes_max)
}

#[test]
fn a_chunk_claiming_a_huge_compression_string_is_refused_before_it_is_allocated() {
    let dir = tempfile::tempdir().expect("tempdir");
    // 200 MiB: under the record limit, with a record length that agrees with it, so only
    // the file's size can refuse it (the reader asked for, and allocated, 200 MiB before).
    let claim = 200u32 << 20;
    let path = write(
        dir.path(),
        "string.mcap",
        &chunk_claiming(claim, 40 + u64::from(claim)),
    );
    let (result, peak) = read_counted(&path);
    assert!(peak < PEAK_BOUND, "peak allocation {peak} bytes");
    assert!(
        matches!(
            result,
            Err(McapFileError::ClaimBeyondFile { need, left, .. })
                if need >= u64::from(claim) && left < FILE_BYTES as u64
        ),
        "{result:?}"
    );
    let text = result.unwrap_err().to_string();
    assert!(text.contains("corrupt") && text.contains("left"), "{text}");
}

#[test]
fn the_issues_file_a_compression_string_of_1_6_gb_is_refused_without_allocating_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    const HUGE: u32 = 1_687_060_480;
    for (name, record_len) in [("short.mcap", 40), ("agreeing.mcap", 40 + u64::from(HUGE))] {
        let path = write(dir.path(), name, &chunk_claiming(HUGE, record_len));
        let (result, peak) = read_counted(&path);
        assert!(result.is_err(), "{name}: {result:?}");
        assert!(peak < PEAK_BOUND, "{name}: peak allocation {peak} bytes");
    }
}

#[test]
fn a_record_claiming_more_than_the_file_holds_is_refused_before_it_is_allocated() {
    let dir = tempfile::tempdir().expect("tempdir");
    // A message record claiming 250 MiB, and a record inside an uncompressed chunk
    // claiming as much.
    let mut message = start();
    message.push(0x05);
    message.extend((250u64 << 20).to_le_bytes());
    message.resize(FILE_BYTES, 0);
    let mut inner = start();
    let records_len = FILE_BYTES as u64;
    inner.push(0x06);
    inner.extend((40 + records_len).to_le_bytes());
    inner.extend([0u8; 24]); // times, uncompressed size
    inner.extend(0u32.to_le_bytes()); // crc
    inner.extend(0u32.to_le_bytes()); // no compression
    inner.extend(records_len.to_le_bytes());
    inner.push(0x05);
    inner.extend((250u64 << 20).to_le_bytes());
    inner.resize(FILE_BYTES + 64, 0);
    for (name, bytes) in [("message.mcap", message), ("inner.mcap", inner)] {
        let path = write(dir.path(), name, &bytes);
        let (result, peak) = read_counted(&path);
        assert!(peak < PEAK_BOUND, "{name}: peak allocation {peak} bytes");
        assert!(
            matches!(result, Err(McapFileError::ClaimBeyondFile { .. })),
            "{name}: {result:?}"
        );
    }
}

#[test]
fn a_well_formed_file_is_read_to_its_end() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("good.mcap");
    let mut w = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .create(std::io::BufWriter::new(
            std::fs::File::create(&path).expect("create"),
        ))
        .expect("writer");
    let channel = w
        .add_channel(0, "/t", "cdr", &Default::default())
        .expect("channel");
    for k in 0..100u64 {
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: channel,
                sequence: k as u32,
                log_time: k,
                publish_time: k,
            },
            &[7u8; 1000],
        )
        .expect("message");
    }
    w.finish().expect("finish");
    drop(w);
    let file = std::fs::File::open(&path).expect("open");
    let mut messages = 0;
    let end = read_records(file, LIMIT, |opcode, data| {
        if opcode == mcap::records::op::MESSAGE {
            messages += 1;
            assert_eq!(data.len(), 22 + 1000);
        }
        ControlFlow::Continue(())
    })
    .expect("read");
    assert_eq!(end, RecordsEnd::Complete);
    assert_eq!(messages, 100);
    // Cut short at the half: an error, the messages before it read.
    let bytes = std::fs::read(&path).expect("read");
    let cut = write(dir.path(), "cut.mcap", &bytes[..bytes.len() / 2]);
    let end = read_records(std::fs::File::open(&cut).expect("open"), LIMIT, |_, _| {
        ControlFlow::Continue(())
    });
    assert!(end.is_err(), "{end:?}");
}
