//! Decoding a stream of 400 CTS350-X azimuths (3768 8-bit bins each, ~1.5 MB) against a
//! memcpy of the same bytes measured in the same run, plus the encoders the simulator
//! uses. After criterion's report, a plain timing loop prints the ratios to memcpy
//! (medians of repeated runs), since these shared machines are noisy in absolute terms.
//!
//! Run: `cargo bench -p protocol --bench decode`

use std::hint::black_box;
use std::time::{Duration, Instant};

use bytes::BytesMut;
use criterion::{criterion_group, BatchSize, Criterion, Throughput};
use protocol::{
    encode_fft_frame, encode_fft_frame_from_db, BinWidth, FrameDecoder, Message, Timestamp,
};

const FRAMES: usize = 400;
const BINS: usize = 3768;
const READ_CHUNK: usize = 64 * 1024;

fn bins() -> Vec<u8> {
    (0..BINS).map(|i| ((i * 7) % 256) as u8).collect()
}

fn stream() -> Vec<u8> {
    let bins = bins();
    let mut buf = BytesMut::new();
    for i in 0..FRAMES {
        let ts = Timestamp::new(1_600_000_000, (i as u32) * 625_000).unwrap();
        encode_fft_frame(
            &mut buf,
            BinWidth::Eight,
            i as u16,
            (i * 14) as u16,
            ts,
            &bins,
        )
        .unwrap();
    }
    buf.to_vec()
}

/// Decodes every frame in `buf`, returning the number of bins seen.
fn decode_all(decoder: &mut FrameDecoder, buf: &mut BytesMut) -> usize {
    let mut bins = 0;
    while let Some(m) = decoder.decode(buf).expect("clean stream") {
        if let Message::FftData(f) = black_box(m) {
            bins += f.bin_count();
        }
    }
    bins
}

/// Decodes every frame and converts its bins to dB, as the driver does.
fn decode_all_to_db(decoder: &mut FrameDecoder, buf: &mut BytesMut, db: &mut Vec<f32>) -> usize {
    let mut bins = 0;
    while let Some(m) = decoder.decode(buf).expect("clean stream") {
        if let Message::FftData(f) = m {
            f.bins_db_into(db);
            bins += black_box(&*db).len();
        }
    }
    bins
}

/// Feeds the stream in 64 KiB reads into one reused buffer (the copy a socket read makes)
/// and decodes as it goes.
fn read_and_decode(stream: &[u8], decoder: &mut FrameDecoder, buf: &mut BytesMut) -> usize {
    let mut frames = 0;
    for chunk in stream.chunks(READ_CHUNK) {
        buf.extend_from_slice(chunk);
        while let Some(m) = decoder.decode(buf).expect("clean stream") {
            black_box(m);
            frames += 1;
        }
    }
    frames
}

fn bench_decode(c: &mut Criterion) {
    let stream = stream();
    let mut group = c.benchmark_group("fft_stream_400x3768");
    group.throughput(Throughput::Bytes(stream.len() as u64));
    group.measurement_time(Duration::from_secs(3));
    group.warm_up_time(Duration::from_secs(1));
    group.sample_size(30);

    let mut dst = vec![0u8; stream.len()];
    group.bench_function("memcpy", |b| {
        b.iter(|| {
            dst.copy_from_slice(black_box(&stream));
            black_box(&dst);
        })
    });
    let mut decoder = FrameDecoder::new();
    group.bench_function("decode", |b| {
        b.iter_batched_ref(
            || BytesMut::from(&stream[..]),
            |buf| decode_all(&mut decoder, buf),
            BatchSize::LargeInput,
        )
    });
    let mut db = Vec::with_capacity(BINS);
    group.bench_function("decode_and_bins_to_db", |b| {
        b.iter_batched_ref(
            || BytesMut::from(&stream[..]),
            |buf| decode_all_to_db(&mut decoder, buf, &mut db),
            BatchSize::LargeInput,
        )
    });
    let mut read_buf = BytesMut::with_capacity(4 * READ_CHUNK);
    group.bench_function("read_64k_chunks_and_decode", |b| {
        b.iter(|| read_and_decode(&stream, &mut decoder, &mut read_buf))
    });
    group.finish();
}

fn bench_encode(c: &mut Criterion) {
    let bins = bins();
    let db: Vec<f64> = bins.iter().map(|&b| f64::from(b) / 2.0).collect();
    let ts = Timestamp::new(1_600_000_000, 0).unwrap();
    let mut group = c.benchmark_group("encode_fft_3768");
    group.throughput(Throughput::Elements(1));
    group.measurement_time(Duration::from_secs(2));
    group.warm_up_time(Duration::from_millis(500));
    let mut buf = BytesMut::with_capacity(8192);
    group.bench_function("from_raw_bins", |b| {
        b.iter(|| {
            buf.clear();
            encode_fft_frame(&mut buf, BinWidth::Eight, 1, 14, ts, black_box(&bins)).unwrap();
        })
    });
    group.bench_function("from_db_8bit", |b| {
        b.iter(|| {
            buf.clear();
            encode_fft_frame_from_db(
                &mut buf,
                BinWidth::Eight,
                1,
                14,
                ts,
                black_box(&db).iter().copied(),
            )
            .unwrap();
        })
    });
    group.bench_function("from_db_16bit", |b| {
        b.iter(|| {
            buf.clear();
            encode_fft_frame_from_db(
                &mut buf,
                BinWidth::Sixteen,
                1,
                14,
                ts,
                black_box(&db).iter().copied(),
            )
            .unwrap();
        })
    });
    group.finish();
}

/// Median wall time of `reps` runs of `f` (each preceded by `setup`, untimed).
fn median_time<S, T>(
    reps: usize,
    mut setup: impl FnMut() -> S,
    mut f: impl FnMut(S) -> T,
) -> Duration {
    let mut times: Vec<Duration> = (0..reps)
        .map(|_| {
            let input = setup();
            let start = Instant::now();
            black_box(f(input));
            start.elapsed()
        })
        .collect();
    times.sort();
    times[reps / 2]
}

fn print_ratios() {
    let stream = stream();
    let mb = stream.len() as f64 / 1e6;
    let reps = 301;
    let mut dst = vec![0u8; stream.len()];
    let memcpy = median_time(
        reps,
        || (),
        |()| {
            dst.copy_from_slice(black_box(&stream));
            dst[0]
        },
    );
    let mut decoder = FrameDecoder::new();
    let decode = median_time(
        reps,
        || BytesMut::from(&stream[..]),
        |mut buf| decode_all(&mut decoder, &mut buf),
    );
    let mut trusting = FrameDecoder::new();
    trusting.set_cut_short_detection(false);
    let decode_trusting = median_time(
        reps,
        || BytesMut::from(&stream[..]),
        |mut buf| decode_all(&mut trusting, &mut buf),
    );
    let mut db = Vec::with_capacity(BINS);
    let to_db = median_time(
        reps,
        || BytesMut::from(&stream[..]),
        |mut buf| decode_all_to_db(&mut decoder, &mut buf, &mut db),
    );
    let mut read_buf = BytesMut::with_capacity(4 * READ_CHUNK);
    let read = median_time(
        reps,
        || (),
        |()| read_and_decode(&stream, &mut decoder, &mut read_buf),
    );
    println!("\n== ratios to memcpy, same run, medians of {reps} runs of {FRAMES} frames ({mb:.3} MB) ==");
    for (name, t) in [
        ("memcpy", memcpy),
        ("decode (zero-copy)", decode),
        ("decode, no cut-short scan", decode_trusting),
        ("decode + bins to dB", to_db),
        ("64 KiB reads + decode", read),
    ] {
        println!(
            "{name:<24} {:>9.1} us  {:>8.0} MB/s  {:>10.0} frames/s  {:>6.3} x memcpy",
            t.as_secs_f64() * 1e6,
            mb / t.as_secs_f64(),
            FRAMES as f64 / t.as_secs_f64(),
            t.as_secs_f64() / memcpy.as_secs_f64()
        );
    }
    println!("decoder stats after the ratio runs: {:?}", decoder.stats());
}

criterion_group!(benches, bench_decode, bench_encode);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
    print_ratios();
}
