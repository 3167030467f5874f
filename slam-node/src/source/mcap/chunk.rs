//! One MCAP chunk record opened: its header parsed with every length checked against the
//! bytes present, its claimed uncompressed size bounded before anything is allocated for
//! it, its records decompressed (zstd, lz4 or none) in bounded blocks that a stop request
//! interrupts, and handed on one by one. No IO: the chunk record is already in memory
//! (bounded by the file, [`super::records`]).
//!
//! A compressed chunk's header claims its uncompressed size, and the `mcap` crate's reader
//! sized its buffers by the claims (the chunk's, and each record's inside it) before a byte
//! was decompressed: a 200-byte chunk claiming 200 MiB allocated 200 MiB. Here a claim is
//! refused unless both hold:
//!
//! - **the format could have produced it** from the compressed bytes present. zstd's largest
//!   block is 128 KiB and its cheapest is an RLE block of 4 bytes (3 of header, 1 repeated
//!   byte), so no zstd data expands more than 32,768-fold
//!   ([`super::decompress::ZSTD_MAX_RATIO`]; 200 MiB of zeros at `zstd -19` is 6,460 bytes,
//!   32,464-fold). An lz4 frame (the MCAP specification's `lz4`) adds at most 255 bytes of
//!   output per byte of a match's length, so it expands less than 256-fold
//!   ([`super::decompress::LZ4_MAX_RATIO`]; 200 MiB of zeros is 823,211 bytes from `lz4_flex`,
//!   254.8-fold). An uncompressed chunk's records
//!   are exactly its bytes.
//! - **it is under the absolute cap** ([`ChunkLimits::max_uncompressed`], 64 MiB by default,
//!   `--mcap-max-chunk-mib`): rosbag2 closes chunks at 768 KiB and the daemon at one rotation
//!   (a CTS350-X B-scan is 1.5 MB), so a larger chunk is a hostile or unusual file.
//!
//! Decompression ([`super::decompress`]) grows its output by what comes out, a block at a
//! time, never by the claim; it checks the stop request (Ctrl-C) between blocks and
//! stops at one byte over the claim. A chunk whose data disagrees with its claim (more or
//! fewer bytes, a CRC that does not match, a frame that does not decode, a record running
//! past the chunk's end) is an error naming the chunk's byte offset in the file. The whole
//! chunk is decompressed and its CRC checked before any of its records is handed on: a
//! corrupt chunk gives none of its records to the pipeline.

use std::ops::ControlFlow;
use std::sync::atomic::AtomicBool;

use super::decompress::{decompress, Compression};
use super::records::McapFileError;

/// The default absolute cap on a chunk's uncompressed size.
pub const DEFAULT_MAX_CHUNK_BYTES: u64 = 64 << 20;

/// Bounds on one chunk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChunkLimits {
    /// The largest uncompressed size a chunk may claim, bytes.
    pub max_uncompressed: u64,
    /// The largest record inside a chunk, bytes.
    pub max_record: u64,
}

impl Default for ChunkLimits {
    fn default() -> Self {
        Self {
            max_uncompressed: DEFAULT_MAX_CHUNK_BYTES,
            max_record: 256 << 20,
        }
    }
}

/// Why a chunk was refused.
#[derive(Debug, thiserror::Error)]
pub enum ChunkError {
    /// The header's fields run past the chunk record, or its sizes disagree with it.
    #[error("its header is cut short or its sizes disagree with the record ({0})")]
    Header(&'static str),
    /// The claimed uncompressed size is more than the compressed bytes could expand to.
    #[error(
        "it claims {claimed} uncompressed bytes from {compressed} {compression} bytes, more than \
         {compression} can expand to ({max})"
    )]
    BeyondRatio {
        /// The claimed uncompressed size.
        claimed: u64,
        /// The compressed bytes present.
        compressed: u64,
        /// The compression.
        compression: String,
        /// The most those bytes can expand to.
        max: u64,
    },
    /// The claimed uncompressed size is over the cap.
    #[error(
        "it claims {claimed} uncompressed bytes, over the cap of {cap} (--mcap-max-chunk-mib)"
    )]
    OverCap {
        /// The claimed uncompressed size.
        claimed: u64,
        /// The cap.
        cap: u64,
    },
    /// A compression this reader does not decompress.
    #[error("its compression {0:?} is not supported (zstd, lz4 or none)")]
    Unsupported(String),
    /// The compressed data did not decompress.
    #[error("its {compression} data does not decompress after {after} bytes")]
    Decompress {
        /// The compression.
        compression: &'static str,
        /// Bytes decompressed before the failure.
        after: u64,
        /// The decoder's complaint.
        #[source]
        source: std::io::Error,
    },
    /// The data decompressed to a size other than the claimed one.
    #[error("its data decompresses to {got} bytes where it claims {claimed}")]
    SizeMismatch {
        /// Bytes decompressed (at most one past the claim: decompression stops there).
        got: u64,
        /// The claimed uncompressed size.
        claimed: u64,
    },
    /// The records' CRC does not match the header's.
    #[error("its records' CRC is {calculated:#010x} where it saves {saved:#010x}")]
    Crc {
        /// The CRC in the header.
        saved: u32,
        /// The CRC of the records.
        calculated: u32,
    },
    /// A record inside runs past the chunk's records, or is over the record limit.
    #[error(
        "a record at byte {at} of its records claims {len} bytes where {left} are left \
         (limit {limit})"
    )]
    Record {
        /// The record's offset in the chunk's records.
        at: u64,
        /// The claimed length.
        len: u64,
        /// Bytes left after the record's opcode and length.
        left: u64,
        /// The record limit.
        limit: u64,
    },
}

/// A chunk's header, as far as reading its records needs.
struct Header<'a> {
    uncompressed_size: u64,
    crc: u32,
    compression: &'a str,
    data: &'a [u8],
}

/// Takes `n` bytes off the front of `rest`.
fn take<'a>(rest: &mut &'a [u8], n: usize, what: &'static str) -> Result<&'a [u8], ChunkError> {
    if rest.len() < n {
        return Err(ChunkError::Header(what));
    }
    let (head, tail) = rest.split_at(n);
    *rest = tail;
    Ok(head)
}

fn u64_le(b: &[u8]) -> u64 {
    u64::from_le_bytes(b.try_into().unwrap_or([0; 8]))
}

fn u32_le(b: &[u8]) -> u32 {
    u32::from_le_bytes(b.try_into().unwrap_or([0; 4]))
}

fn parse(record: &[u8]) -> Result<Header<'_>, ChunkError> {
    let mut rest = record;
    let _times = take(&mut rest, 16, "message times")?;
    let uncompressed_size = u64_le(take(&mut rest, 8, "uncompressed size")?);
    let crc = u32_le(take(&mut rest, 4, "uncompressed CRC")?);
    let compression_len = u32_le(take(&mut rest, 4, "compression length")?);
    let compression = take(&mut rest, compression_len as usize, "compression")?;
    let compression =
        std::str::from_utf8(compression).map_err(|_| ChunkError::Header("compression"))?;
    let compressed_size = u64_le(take(&mut rest, 8, "compressed size")?);
    // Bytes after the compressed data are padding, as the MCAP specification allows.
    let data = usize::try_from(compressed_size)
        .ok()
        .and_then(|n| rest.get(..n))
        .ok_or(ChunkError::Header("compressed size"))?;
    Ok(Header {
        uncompressed_size,
        crc,
        compression,
        data,
    })
}

/// Checks `claimed` against what `compressed` bytes of `compression` can expand to and the
/// cap, before anything is allocated for it.
fn check_claim(
    claimed: u64,
    compressed: u64,
    compression: Compression,
    cap: u64,
) -> Result<(), ChunkError> {
    if compression == Compression::None && claimed != compressed {
        return Err(ChunkError::SizeMismatch {
            got: compressed,
            claimed,
        });
    }
    let max = compression.max_expansion(compressed);
    if claimed > max {
        return Err(ChunkError::BeyondRatio {
            claimed,
            compressed,
            compression: compression.name().to_string(),
            max,
        });
    }
    if claimed > cap {
        return Err(ChunkError::OverCap { claimed, cap });
    }
    Ok(())
}

/// Hands the records of the chunk record `record` (its body, after opcode and length) to
/// `on_record` in order; `Ok(Break)` when `on_record` broke or `stop` was set during
/// decompression (checked every [`super::decompress::BLOCK_BYTES`] of output).
pub fn read_chunk(
    record: &[u8],
    limits: ChunkLimits,
    stop: &AtomicBool,
    on_record: &mut impl FnMut(u8, &[u8]) -> ControlFlow<()>,
) -> Result<ControlFlow<()>, ChunkError> {
    let header = parse(record)?;
    let compression = Compression::parse(header.compression)?;
    check_claim(
        header.uncompressed_size,
        header.data.len() as u64,
        compression,
        limits.max_uncompressed,
    )?;
    let Some(records) = decompress(compression, header.data, header.uncompressed_size, stop)?
    else {
        return Ok(ControlFlow::Break(()));
    };
    let records = &records[..];
    if header.crc != 0 {
        let calculated = crc32fast::hash(records);
        if calculated != header.crc {
            return Err(ChunkError::Crc {
                saved: header.crc,
                calculated,
            });
        }
    }
    let mut at = 0usize;
    while at < records.len() {
        let rest = &records[at..];
        let Some((&opcode, rest)) = rest.split_first() else {
            break;
        };
        let Some((len, body)) = rest.split_first_chunk::<8>() else {
            return Err(ChunkError::Record {
                at: at as u64,
                len: 0,
                left: rest.len() as u64,
                limit: limits.max_record,
            });
        };
        let len = u64::from_le_bytes(*len);
        let Some(data) = usize::try_from(len)
            .ok()
            .filter(|&n| n as u64 <= limits.max_record)
            .and_then(|n| body.get(..n))
        else {
            return Err(ChunkError::Record {
                at: at as u64,
                len,
                left: body.len() as u64,
                limit: limits.max_record,
            });
        };
        if on_record(opcode, data).is_break() {
            return Ok(ControlFlow::Break(()));
        }
        at += 9 + data.len();
    }
    Ok(ControlFlow::Continue(()))
}

impl ChunkError {
    /// This error for the chunk record starting at `offset` in the file.
    pub fn at(self, offset: u64) -> McapFileError {
        McapFileError::Chunk {
            offset,
            source: self,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chunk(claimed: u64, crc: u32, compression: &str, data: &[u8]) -> Vec<u8> {
        let mut b = vec![0u8; 16];
        b.extend(claimed.to_le_bytes());
        b.extend(crc.to_le_bytes());
        b.extend((compression.len() as u32).to_le_bytes());
        b.extend(compression.as_bytes());
        b.extend((data.len() as u64).to_le_bytes());
        b.extend(data);
        b
    }

    fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
        let mut b = vec![opcode];
        b.extend((body.len() as u64).to_le_bytes());
        b.extend(body);
        b
    }

    fn collect(c: &[u8]) -> Result<Vec<(u8, Vec<u8>)>, ChunkError> {
        let mut seen = Vec::new();
        let _ = read_chunk(
            c,
            ChunkLimits::default(),
            &AtomicBool::new(false),
            &mut |op, d| {
                seen.push((op, d.to_vec()));
                ControlFlow::Continue(())
            },
        )?;
        Ok(seen)
    }

    fn lz4(data: &[u8]) -> Vec<u8> {
        use std::io::Write;
        let mut e = lz4_flex::frame::FrameEncoder::new(Vec::new());
        e.write_all(data).expect("compress");
        e.finish().expect("finish")
    }

    #[test]
    fn zstd_lz4_and_uncompressed_chunks_give_their_records() {
        let mut records = record(5, &[1, 2, 3]);
        records.extend(record(4, &[9; 100]));
        let crc = crc32fast::hash(&records);
        let packed = zstd::bulk::compress(&records, 1).expect("compress");
        for c in [
            chunk(records.len() as u64, crc, "zstd", &packed),
            chunk(records.len() as u64, crc, "lz4", &lz4(&records)),
            chunk(records.len() as u64, 0, "", &records),
        ] {
            let seen = collect(&c).expect("read");
            assert_eq!(seen, vec![(5, vec![1, 2, 3]), (4, vec![9; 100])]);
        }
    }

    #[test]
    fn claims_the_data_disagrees_with_are_refused() {
        let records = record(5, &[1; 1000]);
        let packed = zstd::bulk::compress(&records, 1).expect("compress");
        let n = records.len() as u64;
        // One byte more or fewer than the data holds.
        for claim in [n - 1, n + 1] {
            let e = collect(&chunk(claim, 0, "zstd", &packed)).unwrap_err();
            assert!(matches!(e, ChunkError::SizeMismatch { .. }), "{e:?}");
        }
        // More than zstd can expand the bytes to, and over the cap.
        let e = collect(&chunk(packed.len() as u64 * 32_769, 0, "zstd", &packed)).unwrap_err();
        assert!(matches!(e, ChunkError::BeyondRatio { .. }), "{e:?}");
        let big = vec![7u8; 4000];
        let e = collect(&chunk(65 << 20, 0, "zstd", &big)).unwrap_err();
        assert!(matches!(e, ChunkError::OverCap { .. }), "{e:?}");
        // A wrong CRC, an unknown compression, an uncompressed chunk whose sizes differ.
        let e = collect(&chunk(n, 1, "zstd", &packed)).unwrap_err();
        assert!(matches!(e, ChunkError::Crc { .. }), "{e:?}");
        let e = collect(&chunk(n, 0, "lz5", &packed)).unwrap_err();
        assert!(matches!(e, ChunkError::Unsupported(_)), "{e:?}");
        let e = collect(&chunk(n + 1, 0, "", &records)).unwrap_err();
        assert!(matches!(e, ChunkError::SizeMismatch { .. }), "{e:?}");
        // lz4: more than it can expand to (256-fold), a wrong CRC, a frame that is not one.
        let packed = lz4(&records);
        let e = collect(&chunk(packed.len() as u64 * 257, 0, "lz4", &packed)).unwrap_err();
        assert!(
            matches!(&e, ChunkError::BeyondRatio { compression, .. } if compression == "lz4"),
            "{e:?}"
        );
        let e = collect(&chunk(n, 1, "lz4", &packed)).unwrap_err();
        assert!(matches!(e, ChunkError::Crc { .. }), "{e:?}");
        let e = collect(&chunk(n, 0, "lz4", &[0x5a; 200])).unwrap_err();
        assert!(matches!(e, ChunkError::Decompress { .. }), "{e:?}");
    }

    #[test]
    fn a_stop_request_before_a_compressed_chunk_hands_on_none_of_its_records() {
        let records = record(5, &[1; 1000]);
        let packed = zstd::bulk::compress(&records, 1).expect("compress");
        let mut seen = 0;
        let flow = read_chunk(
            &chunk(records.len() as u64, 0, "zstd", &packed),
            ChunkLimits::default(),
            &AtomicBool::new(true),
            &mut |_, _| {
                seen += 1;
                ControlFlow::Continue(())
            },
        )
        .expect("no error");
        assert_eq!((flow, seen), (ControlFlow::Break(()), 0));
    }

    #[test]
    fn a_record_running_past_the_chunk_is_refused() {
        let mut records = record(5, &[1; 10]);
        records.extend([5u8]);
        records.extend((1u64 << 40).to_le_bytes());
        let e = collect(&chunk(records.len() as u64, 0, "", &records)).unwrap_err();
        assert!(matches!(e, ChunkError::Record { at: 19, .. }), "{e:?}");
        // A header cut inside its compression string.
        let c = chunk(0, 0, "zstd", &[]);
        let e = collect(&c[..34]).unwrap_err();
        assert!(matches!(e, ChunkError::Header("compression")), "{e:?}");
    }
}
