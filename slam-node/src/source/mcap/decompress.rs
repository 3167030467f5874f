//! A chunk's compressed bytes decompressed in bounded blocks: zstd, lz4 (the frame format,
//! as the MCAP specification says) or none. The output grows by what comes out,
//! [`BLOCK_BYTES`] at a time and never by the header's claim, stops one byte past the claim,
//! and the stop request is checked between blocks. No IO: the bytes are in memory.
//!
//! Both decoders are streaming ones that hold at most a block of their own (zstd's window,
//! 128 KiB for what `mcap` writes; lz4's 4 MiB block, twice in linked mode), so what the
//! chunk costs is its output, bounded by the claim, which [`super::chunk`] bounds by the
//! format's ratio and the cap before anything is decompressed.

use std::borrow::Cow;
use std::io::Read;
use std::sync::atomic::{AtomicBool, Ordering};

use super::chunk::ChunkError;

/// How far zstd data can expand: a 128 KiB RLE block from 4 bytes.
pub const ZSTD_MAX_RATIO: u64 = 32_768;

/// How far an lz4 frame can expand: past a sequence's 3-byte token and offset, each byte of
/// a match length adds at most 255 bytes.
pub const LZ4_MAX_RATIO: u64 = 256;

/// Output decompressed between checks of the stop request and the claim (zstd or lz4 make
/// 1 MiB in about a millisecond on one core of the development machine).
pub const BLOCK_BYTES: u64 = 1 << 20;

/// A chunk's compression, as the MCAP specification names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compression {
    /// The empty string: the records as they are.
    None,
    /// `zstd`.
    Zstd,
    /// `lz4`: an lz4 frame.
    Lz4,
}

impl Compression {
    /// The compression a chunk header names.
    pub fn parse(name: &str) -> Result<Self, ChunkError> {
        match name {
            "" => Ok(Self::None),
            "zstd" => Ok(Self::Zstd),
            "lz4" => Ok(Self::Lz4),
            other => Err(ChunkError::Unsupported(other.to_string())),
        }
    }

    /// Its name in messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "uncompressed",
            Self::Zstd => "zstd",
            Self::Lz4 => "lz4",
        }
    }

    /// The most `compressed` bytes can expand to.
    pub fn max_expansion(self, compressed: u64) -> u64 {
        match self {
            Self::None => compressed,
            Self::Zstd => compressed.saturating_mul(ZSTD_MAX_RATIO),
            Self::Lz4 => compressed.saturating_mul(LZ4_MAX_RATIO),
        }
    }
}

/// `data` decompressed, claimed to be `claimed` bytes; `Ok(None)` when `stop` was set
/// before the output was complete.
pub fn decompress<'a>(
    compression: Compression,
    data: &'a [u8],
    claimed: u64,
    stop: &AtomicBool,
) -> Result<Option<Cow<'a, [u8]>>, ChunkError> {
    let out = match compression {
        Compression::None => {
            if data.len() as u64 != claimed {
                return Err(ChunkError::SizeMismatch {
                    got: data.len() as u64,
                    claimed,
                });
            }
            return Ok(Some(Cow::Borrowed(data)));
        }
        Compression::Zstd => {
            let decoder = zstd::stream::read::Decoder::with_buffer(data).map_err(|source| {
                ChunkError::Decompress {
                    compression: compression.name(),
                    after: 0,
                    source,
                }
            })?;
            in_blocks(decoder, compression, claimed, stop)?
        }
        Compression::Lz4 => {
            let decoder = lz4_flex::frame::FrameDecoder::new(data);
            in_blocks(decoder, compression, claimed, stop)?
        }
    };
    Ok(out.map(Cow::Owned))
}

/// Reads `decoder` to its end, [`BLOCK_BYTES`] at a time, `stop` checked before each block,
/// at most one byte past `claimed`; the output must be `claimed` bytes.
fn in_blocks(
    decoder: impl Read,
    compression: Compression,
    claimed: u64,
    stop: &AtomicBool,
) -> Result<Option<Vec<u8>>, ChunkError> {
    // One byte past the claim is enough to know the claim is a lie.
    let mut decoder = decoder.take(claimed.saturating_add(1));
    let mut out = Vec::new();
    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(None);
        }
        let read = (&mut decoder)
            .take(BLOCK_BYTES)
            .read_to_end(&mut out)
            .map_err(|source| ChunkError::Decompress {
                compression: compression.name(),
                after: out.len() as u64,
                source,
            })?;
        if read == 0 {
            break;
        }
    }
    if out.len() as u64 != claimed {
        return Err(ChunkError::SizeMismatch {
            got: out.len() as u64,
            claimed,
        });
    }
    Ok(Some(out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;
    use std::sync::Arc;

    fn lz4(data: &[u8]) -> Vec<u8> {
        let mut e = lz4_flex::frame::FrameEncoder::new(Vec::new());
        e.write_all(data).expect("compress");
        e.finish().expect("finish")
    }

    fn run(c: Compression, data: &[u8], claimed: u64) -> Result<Option<Vec<u8>>, ChunkError> {
        decompress(c, data, claimed, &AtomicBool::new(false)).map(|o| o.map(Cow::into_owned))
    }

    #[test]
    fn lz4_and_zstd_frames_give_back_their_bytes() {
        let data: Vec<u8> = (0..300_000u32).map(|i| (i % 251) as u8 ^ 0x5a).collect();
        let n = data.len() as u64;
        for (c, packed) in [
            (Compression::Lz4, lz4(&data)),
            (
                Compression::Zstd,
                zstd::bulk::compress(&data, 1).expect("zstd"),
            ),
        ] {
            assert_eq!(
                run(c, &packed, n).expect("decompresses"),
                Some(data.clone())
            );
            // A claim one byte off either way is refused, whatever the frame says.
            for claim in [n - 1, n + 1] {
                let e = run(c, &packed, claim).unwrap_err();
                assert!(
                    matches!(e, ChunkError::SizeMismatch { got, .. } if got == n.min(claim + 1)),
                    "{e:?}"
                );
            }
        }
    }

    #[test]
    fn a_corrupt_or_cut_lz4_frame_is_refused() {
        let data: Vec<u8> = (0..100_000u32).map(|i| (i * 7 % 13) as u8).collect();
        let packed = lz4(&data);
        let n = data.len() as u64;
        // Not an lz4 frame at all.
        let e = run(Compression::Lz4, &[0x5a; 64], n).unwrap_err();
        assert!(
            matches!(
                e,
                ChunkError::Decompress {
                    compression: "lz4",
                    ..
                }
            ),
            "{e:?}"
        );
        // Cut in its middle.
        let e = run(Compression::Lz4, &packed[..packed.len() / 2], n).unwrap_err();
        assert!(
            matches!(
                e,
                ChunkError::Decompress { .. } | ChunkError::SizeMismatch { .. }
            ),
            "{e:?}"
        );
        // A block's length field bigger than the block size in its frame header.
        let mut bad = packed.clone();
        bad[7..11].copy_from_slice(&0x00ff_ffffu32.to_le_bytes());
        let e = run(Compression::Lz4, &bad, n).unwrap_err();
        assert!(matches!(e, ChunkError::Decompress { .. }), "{e:?}");
        let text = e.to_string();
        assert!(
            text.contains("lz4") && text.contains("does not decompress"),
            "{text}"
        );
    }

    /// The largest expansions the formats reach on the most compressible data there is:
    /// under their ratio bounds, which are therefore never too tight for a real file.
    #[test]
    fn the_ratio_bounds_hold_for_zeros() {
        let zeros = vec![0u8; 64 << 20];
        let n = zeros.len() as u64;
        let l = lz4(&zeros);
        assert!(
            Compression::Lz4.max_expansion(l.len() as u64) >= n,
            "lz4 {} bytes",
            l.len()
        );
        let z = zstd::bulk::compress(&zeros, 19).expect("zstd");
        assert!(
            Compression::Zstd.max_expansion(z.len() as u64) >= n,
            "zstd {} bytes",
            z.len()
        );
    }

    /// A stop request set by another thread while a 32 MiB chunk decompresses ends the
    /// decompression at the next block: the decoder's output is read through a probe that,
    /// on the first read, lets the other thread set the flag and waits until it has, and
    /// counts what the decoder produced.
    #[test]
    fn a_stop_request_during_decompression_ends_it_at_the_next_block() {
        let zeros = vec![0u8; 32 << 20];
        for (c, packed) in [
            (Compression::Lz4, lz4(&zeros)),
            (
                Compression::Zstd,
                zstd::bulk::compress(&zeros, 1).expect("zstd"),
            ),
        ] {
            let stop = Arc::new(AtomicBool::new(false));
            let (started_tx, started_rx) = std::sync::mpsc::sync_channel::<()>(0);
            let (set_tx, set_rx) = std::sync::mpsc::sync_channel::<()>(0);
            let setter = {
                let stop = Arc::clone(&stop);
                std::thread::spawn(move || {
                    started_rx.recv().expect("decompression started");
                    stop.store(true, Ordering::Relaxed);
                    set_tx.send(()).expect("flag set");
                })
            };
            let decoder: Box<dyn Read + '_> = match c {
                Compression::Lz4 => Box::new(lz4_flex::frame::FrameDecoder::new(&packed[..])),
                _ => Box::new(zstd::stream::read::Decoder::new(&packed[..]).expect("zstd")),
            };
            let mut produced = 0u64;
            let probe = Probe {
                inner: decoder,
                on_first_read: Some(Box::new(move || {
                    started_tx.send(()).expect("setter waits");
                    set_rx.recv().expect("setter answers");
                })),
                produced: &mut produced,
            };
            let out = in_blocks(probe, c, zeros.len() as u64, &stop).expect("no error");
            setter.join().expect("setter");
            assert!(out.is_none(), "{c:?}: stopped, not finished");
            assert!(
                produced <= BLOCK_BYTES,
                "{c:?}: {produced} of {} bytes decompressed after the stop request",
                zeros.len()
            );
        }
    }

    /// A reader that runs a hook on its first read and counts the bytes it hands on.
    struct Probe<'a> {
        inner: Box<dyn Read + 'a>,
        on_first_read: Option<Box<dyn FnOnce() + Send>>,
        produced: &'a mut u64,
    }

    impl Read for Probe<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if let Some(hook) = self.on_first_read.take() {
                hook();
            }
            let n = self.inner.read(buf)?;
            *self.produced += n as u64;
            Ok(n)
        }
    }
}
