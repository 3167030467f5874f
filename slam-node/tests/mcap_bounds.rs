//! An MCAP file's length fields cannot make the replay allocate more than the file holds
//! (issue 38, item 8): a small file whose chunk header claims a compression string of
//! hundreds of MB, or whose record claims hundreds of MB, is refused with a typed error
//! before the claim is allocated. Peak allocation is counted by a counting global
//! allocator (`allocation-counter`, per thread) installed in this test binary only; the
//! records are read on the test's own thread.

use std::io::Write;
use std::ops::ControlFlow;
use std::path::Path;
use std::sync::atomic::AtomicBool;

use slam_node::source::mcap::{read_records, ChunkError, ChunkLimits, McapFileError, RecordsEnd};

const MAGIC: &[u8] = b"\x89MCAP0\r\n";
/// The replay's limits (records 256 MiB, chunks 64 MiB uncompressed).
const LIMIT: ChunkLimits = ChunkLimits {
    max_uncompressed: 64 << 20,
    max_record: 256 << 20,
};
/// No stop request.
static NO_STOP: AtomicBool = AtomicBool::new(false);
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
        result = Some(read_records(file, LIMIT, &NO_STOP, |_, _| {
            ControlFlow::Continue(())
        }));
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
    let end = read_records(file, LIMIT, &NO_STOP, |opcode, data| {
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
    let end = read_records(
        std::fs::File::open(&cut).expect("open"),
        LIMIT,
        &NO_STOP,
        |_, _| ControlFlow::Continue(()),
    );
    assert!(end.is_err(), "{end:?}");
}

/// A file of `chunk_records` in one zstd chunk whose header claims `claimed` uncompressed
/// bytes, then a data end record, a footer and the end magic.
fn zstd_chunk_file(chunk_records: &[u8], claimed: u64) -> (Vec<u8>, u64) {
    let packed = zstd::bulk::compress(chunk_records, 19).expect("compress");
    let mut buf = start();
    let chunk_at = buf.len() as u64;
    let mut chunk = Vec::new();
    chunk.extend([0u8; 16]); // message times
    chunk.extend(claimed.to_le_bytes());
    chunk.extend(0u32.to_le_bytes()); // no CRC
    chunk.extend(4u32.to_le_bytes());
    chunk.extend(b"zstd");
    chunk.extend((packed.len() as u64).to_le_bytes());
    chunk.extend(&packed);
    buf.push(0x06);
    buf.extend((chunk.len() as u64).to_le_bytes());
    buf.extend(chunk);
    buf.push(0x0F); // data end
    buf.extend(4u64.to_le_bytes());
    buf.extend(0u32.to_le_bytes());
    buf.push(0x02); // footer
    buf.extend(20u64.to_le_bytes());
    buf.extend([0u8; 20]);
    buf.extend(MAGIC);
    (buf, chunk_at)
}

/// An opcode and a length claimed, with `body` after it (shorter than claimed or not).
fn record_claiming(opcode: u8, len: u64, body: &[u8]) -> Vec<u8> {
    let mut r = vec![opcode];
    r.extend(len.to_le_bytes());
    r.extend(body);
    r
}

/// A compressed chunk of a few dozen bytes whose header claims 200 MiB, its one record
/// claiming as much: the `mcap` crate's reader sized its buffer by the record's claim and
/// allocated (and zeroed) 200 MiB before finding the data short. Refused now because zstd
/// cannot expand those bytes 200 MiB (at most 32,768-fold), before anything is allocated.
#[test]
fn a_small_compressed_chunk_claiming_200_mib_is_refused_without_allocating_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let claim = 200u64 << 20;
    let (bytes, chunk_at) = zstd_chunk_file(&record_claiming(0x05, claim - 9, &[1; 64]), claim);
    assert!(bytes.len() < 300, "{} bytes", bytes.len());
    let path = write(dir.path(), "claim.mcap", &bytes);
    let (result, peak) = read_counted(&path);
    assert!(peak < 1 << 20, "peak allocation {peak} bytes");
    let err = result.unwrap_err();
    let text = radar_driver::ErrorChain(&err).to_string();
    assert!(
        text.contains(&format!("chunk record at byte {chunk_at}"))
            && text.contains("more than zstd can expand to"),
        "{text}"
    );
}

/// A chunk whose claimed size its bytes could expand to, whose one record claims 200 MiB
/// inside a chunk of 1,000: the old reader allocated the record's claim; now the record is
/// refused against the chunk's decompressed bytes.
#[test]
fn a_record_claiming_more_than_its_chunk_holds_is_refused_without_allocating_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let records = record_claiming(0x05, 200 << 20, &[0; 991]);
    let (bytes, chunk_at) = zstd_chunk_file(&records, records.len() as u64);
    let path = write(dir.path(), "record.mcap", &bytes);
    let (result, peak) = read_counted(&path);
    assert!(peak < 1 << 20, "peak allocation {peak} bytes");
    assert!(
        matches!(
            result,
            Err(McapFileError::Chunk { offset, source: ChunkError::Record { at: 0, .. } })
                if offset == chunk_at
        ),
        "{result:?}"
    );
}

/// 200 MiB of zeros really compresses to a few KB (inside zstd's ratio): the cap refuses
/// it before decompressing; a cap above it reads it, growing the output as it comes.
#[test]
fn a_chunk_over_the_cap_is_refused_before_decompressing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let zeros = vec![0u8; 200 << 20];
    let (bytes, _) = zstd_chunk_file(&zeros, zeros.len() as u64);
    drop(zeros);
    assert!(bytes.len() < 10_000, "{} bytes", bytes.len());
    let path = write(dir.path(), "zeros.mcap", &bytes);
    let (result, peak) = read_counted(&path);
    assert!(peak < 1 << 20, "peak allocation {peak} bytes");
    assert!(
        matches!(
            result,
            Err(McapFileError::Chunk {
                source: ChunkError::OverCap { .. },
                ..
            })
        ),
        "{result:?}"
    );
    // Under a cap of 256 MiB it is read (records of opcode 0 and length 0), and a reader
    // that stops at the first record stops there.
    let limits = ChunkLimits {
        max_uncompressed: 256 << 20,
        ..LIMIT
    };
    let mut seen = 0u64;
    let end = read_records(
        std::fs::File::open(&path).expect("open"),
        limits,
        &NO_STOP,
        |_, _| {
            seen += 1;
            ControlFlow::Break(())
        },
    )
    .expect("read");
    assert_eq!((end, seen), (RecordsEnd::Stopped, 1));
}
