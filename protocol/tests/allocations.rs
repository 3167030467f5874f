//! Heap allocations per decoded frame in steady state, counted by a counting global
//! allocator (`allocation-counter`, per thread) installed in this test binary only.
//!
//! The stream is 3768-bin 8-bit FFT frames (a CTS350-X), delivered in 64 KiB reads into
//! one reusable `BytesMut`, as a socket reader would. Each frame's bins are converted to
//! dB into a reused `Vec<f32>`. Two consumers:
//! - one that drops each message after use: the read buffer is reclaimed in place;
//! - one that keeps a whole rotation (400 azimuths) alive before dropping it, as rotation
//!   assembly does: the zero-copy bins pin the read buffer, so `BytesMut` has to allocate
//!   a fresh buffer when it cannot reclaim the old one.
//!
//! Counts are printed (run with `--nocapture`) and bounded: these are allocation counts,
//! not timings, so they are deterministic.

use bytes::BytesMut;
use protocol::{encode_fft_frame, BinWidth, FftData, FrameDecoder, Message, Timestamp};

const BINS: usize = 3768;
const READ_CHUNK: usize = 64 * 1024;
const ROTATION: usize = 400;

fn stream(frames: usize) -> Vec<u8> {
    let mut buf = BytesMut::new();
    let bins: Vec<u8> = (0..BINS).map(|i| (i % 251) as u8).collect();
    for i in 0..frames {
        let azimuth = u16::try_from((i % ROTATION) * 14).unwrap();
        let ts = Timestamp::new(1_600_000_000, u32::try_from(i).unwrap() * 625_000).unwrap();
        encode_fft_frame(&mut buf, BinWidth::Eight, i as u16, azimuth, ts, &bins).unwrap();
    }
    buf.to_vec()
}

struct Consumer {
    decoder: FrameDecoder,
    buf: BytesMut,
    db: Vec<f32>,
    rotation: Vec<FftData>,
    pos: usize,
}

impl Consumer {
    fn new() -> Self {
        Self {
            decoder: FrameDecoder::new(),
            buf: BytesMut::with_capacity(4 * READ_CHUNK),
            db: Vec::with_capacity(BINS),
            rotation: Vec::with_capacity(ROTATION),
            pos: 0,
        }
    }

    /// Reads and decodes until `frames` FFT frames have been consumed.
    fn pump(&mut self, stream: &[u8], frames: usize, keep_rotation: bool) -> usize {
        let mut n = 0;
        while n < frames {
            let end = (self.pos + READ_CHUNK).min(stream.len());
            self.buf.extend_from_slice(&stream[self.pos..end]);
            self.pos = if end == stream.len() { 0 } else { end };
            while let Some(m) = self.decoder.decode(&mut self.buf).expect("a clean stream") {
                let Message::FftData(fft) = m else {
                    panic!("only FFT data here")
                };
                fft.bins_db_into(&mut self.db);
                assert_eq!(self.db.len(), BINS);
                if keep_rotation {
                    if self.rotation.len() == ROTATION {
                        self.rotation.clear();
                    }
                    self.rotation.push(fft);
                }
                n += 1;
            }
        }
        n
    }
}

fn allocations_per_frame(keep_rotation: bool) -> (f64, f64, u64) {
    let stream = stream(ROTATION);
    let mut consumer = Consumer::new();
    consumer.pump(&stream, 2 * ROTATION, keep_rotation); // warm up
    let mut frames = 0;
    let info = allocation_counter::measure(|| {
        frames = consumer.pump(&stream, 10 * ROTATION, keep_rotation);
    });
    (
        info.count_total as f64 / frames as f64,
        info.bytes_total as f64 / frames as f64,
        frames as u64,
    )
}

#[test]
fn a_consumer_that_drops_each_frame_allocates_nothing_per_frame() {
    let (per_frame, bytes_per_frame, frames) = allocations_per_frame(false);
    println!(
        "drop each frame: {per_frame:.4} allocations/frame, {bytes_per_frame:.1} bytes/frame over {frames} frames"
    );
    assert_eq!(per_frame, 0.0);
}

#[test]
fn a_consumer_that_holds_a_rotation_allocates_only_read_buffers() {
    let (per_frame, bytes_per_frame, frames) = allocations_per_frame(true);
    println!(
        "hold a rotation: {per_frame:.4} allocations/frame, {bytes_per_frame:.1} bytes/frame over {frames} frames"
    );
    // Each fresh read buffer holds about 17 frames (64 KiB / 3790 B); fewer than one
    // allocation per frame means no per-frame allocation in the decoder.
    assert!(per_frame < 0.25, "{per_frame} allocations per frame");
}
