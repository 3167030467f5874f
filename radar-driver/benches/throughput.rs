//! Sustained azimuths per second through the driver over loopback, as a multiple of a
//! CTS350-X's 1600 azimuths/s, against a raw TCP read of the same bytes in the same run;
//! and the latency from socket read to channel send, at full speed and paced at 1600/s.
//!
//! `cargo bench -p radar-driver --bench throughput`
//!
//! Each iteration: a loopback server sends a CTS350-X configuration (400 azimuths, 3768
//! 8-bit bins, ~3.8 kB frames), waits for the start message, then writes N pre-encoded
//! azimuths as fast as the socket takes them; the driver decodes, assembles rotations and
//! hands every azimuth to a consumer thread over a bounded crossbeam channel. The clock
//! runs from spawning the driver to the consumer receiving the last azimuth.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use bytes::{Bytes, BytesMut};
use criterion::{criterion_group, Criterion, Throughput};
use protocol::{BinWidth, Configuration, ConfigurationData, FftData, Message, Timestamp};
use radar_driver::{Driver, DriverSettings, DropPolicy, HandoffSettings, MetricsSnapshot};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::runtime::Runtime;

const CTS350X_AZIMUTHS_PER_S: f64 = 1600.0;
const N: u64 = 16_000; // ten seconds of a CTS350-X

fn configuration() -> Configuration {
    Configuration {
        azimuth_samples: 400,
        bin_size: 438,
        range_in_bins: 3768,
        encoder_size: 5600,
        rotation_speed_millihertz: 4000,
        packet_rate: 1600,
        range_gain: 1.0,
        range_offset_m: 0.0,
        data: ConfigurationData {
            datawidth: Some(8),
            rangeresolutionmetres: Some(0.0438),
            ..ConfigurationData::default()
        },
    }
}

fn encode(m: &Message) -> Bytes {
    let mut b = BytesMut::new();
    m.encode(&mut b).unwrap();
    b.freeze()
}

/// N azimuths of 3768 bins, as one byte stream.
fn stream(n: u64) -> Bytes {
    let mut out = BytesMut::new();
    let bins: Vec<u8> = (0..3768u32).map(|i| (i * 7 % 251) as u8).collect();
    let bins = Bytes::from(bins);
    for s in 0..n {
        let ns = s * 625_000;
        let t = Timestamp::new(
            1_700_000_000 + (ns / 1_000_000_000) as u32,
            (ns % 1_000_000_000) as u32,
        )
        .unwrap();
        let m = Message::FftData(FftData::new(
            BinWidth::Eight,
            (s % 65_536) as u16,
            ((s % 400) * 14) as u16,
            t,
            bins.clone(),
        ));
        m.encode(&mut out).unwrap();
    }
    out.freeze()
}

/// Serves every connection: configuration, wait for start, then the stream (all at once,
/// or paced frame by frame at `pace`), then hold until the client closes.
async fn serve(
    listener: TcpListener,
    config: Bytes,
    data: Bytes,
    frame_len: usize,
    pace: Option<Duration>,
) {
    loop {
        let Ok((mut sock, _)) = listener.accept().await else {
            return;
        };
        sock.set_nodelay(true).unwrap();
        let (config, data) = (config.clone(), data.clone());
        tokio::spawn(async move {
            if sock.write_all(&config).await.is_err() {
                return;
            }
            let mut start = [0u8; 22];
            if sock.read_exact(&mut start).await.is_err() {
                return;
            }
            match pace {
                None => {
                    let _ = sock.write_all(&data).await;
                }
                Some(period) => {
                    let mut tick = tokio::time::interval(period);
                    for frame in data.chunks(frame_len) {
                        tick.tick().await;
                        if sock.write_all(frame).await.is_err() {
                            return;
                        }
                    }
                }
            }
            let mut sink = [0u8; 64];
            while let Ok(n) = sock.read(&mut sink).await {
                if n == 0 {
                    break;
                }
            }
        });
    }
}

fn server(rt: &Runtime, n: u64, pace: Option<Duration>) -> SocketAddr {
    let config = encode(&Message::Configuration(Box::new(configuration())));
    let data = stream(n);
    let frame_len = data.len() / n as usize;
    let listener = rt.block_on(TcpListener::bind("127.0.0.1:0")).unwrap();
    let addr = listener.local_addr().unwrap();
    rt.spawn(serve(listener, config, data, frame_len, pace));
    addr
}

/// One run through the driver: elapsed until the consumer has the last azimuth.
fn through_driver(rt: &Runtime, addr: SocketAddr, n: u64) -> (Duration, MetricsSnapshot) {
    let mut settings = DriverSettings::new(addr);
    settings.handoff = HandoffSettings {
        azimuth_capacity: Some(4096),
        rotation_capacity: Some(8),
        drop_policy: DropPolicy::DropNewest,
    };
    let start = Instant::now();
    let (driver, rx) = Driver::new(settings);
    let metrics = driver.metrics();
    let handle = rt.block_on(async { driver.spawn() });
    let az = rx.azimuths.unwrap();
    let rot = rx.rotations.unwrap();
    let rotations = std::thread::spawn(move || rot.iter().count());
    let mut received = 0u64;
    let mut last = start;
    while received < n {
        match az.recv_timeout(Duration::from_millis(1)) {
            Ok(a) => {
                std::hint::black_box(&a);
                received += 1;
                last = Instant::now();
            }
            Err(crossbeam_channel::RecvTimeoutError::Timeout) => {
                // Only when idle: were the missing azimuths dropped?
                if received + metrics.snapshot().azimuth_drops + metrics.snapshot().budget_drops
                    >= n
                {
                    break;
                }
                assert!(
                    start.elapsed() < Duration::from_secs(120),
                    "the run stalled"
                );
            }
            Err(crossbeam_channel::RecvTimeoutError::Disconnected) => break,
        }
    }
    let exit = rt.block_on(handle.stop()).unwrap();
    drop(az);
    let _ = rotations.join();
    (last - start, exit.metrics)
}

/// The baseline: a plain TCP read of the same bytes, no decoding.
fn raw_read(rt: &Runtime, addr: SocketAddr, n_bytes: usize) -> Duration {
    rt.block_on(async {
        let start = Instant::now();
        let mut s = TcpStream::connect(addr).await.unwrap();
        let mut buf = BytesMut::with_capacity(1 << 16);
        // Skip the configuration frame, then ask for data.
        let mut header = [0u8; 22];
        s.read_exact(&mut header).await.unwrap();
        let len = u32::from_be_bytes([header[18], header[19], header[20], header[21]]) as usize;
        let mut cfg = vec![0u8; len];
        s.read_exact(&mut cfg).await.unwrap();
        s.write_all(&encode(&Message::StartFftData)).await.unwrap();
        let mut total = 0;
        while total < n_bytes {
            buf.clear();
            buf.reserve(1 << 16);
            let k = s.read_buf(&mut buf).await.unwrap();
            assert!(k > 0);
            total += k;
        }
        start.elapsed()
    })
}

fn bench(c: &mut Criterion) {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap();
    let addr = server(&rt, N, None);
    let bytes = stream(N).len();
    let mut g = c.benchmark_group("loopback");
    g.sample_size(10);
    g.throughput(Throughput::Elements(N));
    g.bench_function("driver_16000_cts350x_azimuths", |b| {
        b.iter_custom(|iters| (0..iters).map(|_| through_driver(&rt, addr, N).0).sum())
    });
    g.bench_function("raw_tcp_read_same_bytes", |b| {
        b.iter_custom(|iters| (0..iters).map(|_| raw_read(&rt, addr, bytes)).sum())
    });
    g.finish();
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// A summary in the figures the project reports, measured outside criterion's loop.
fn report() {
    let rt = Arc::new(
        tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .unwrap(),
    );
    let addr = server(&rt, N, None);
    let bytes = stream(N).len();
    let mut rates = Vec::new();
    let mut raw_rates = Vec::new();
    let mut last = MetricsSnapshot::default();
    for _ in 0..7 {
        let (t, m) = through_driver(&rt, addr, N);
        rates.push(N as f64 / t.as_secs_f64());
        raw_rates.push(N as f64 / raw_read(&rt, addr, bytes).as_secs_f64());
        last = m;
    }
    let rate = median(rates);
    let raw = median(raw_rates);
    println!("\n== radar-driver loopback figures (median of 7 runs of {N} CTS350-X azimuths, {:.1} MB each) ==", bytes as f64 / 1e6);
    println!(
        "driver:   {:>10.0} azimuths/s = {:>6.1} x CTS350-X (1600/s); drops {}",
        rate,
        rate / CTS350X_AZIMUTHS_PER_S,
        last.azimuth_drops
    );
    println!(
        "raw read: {:>10.0} azimuths/s = {:>6.1} x CTS350-X; driver / raw = {:.2}",
        raw,
        raw / CTS350X_AZIMUTHS_PER_S,
        rate / raw
    );
    println!(
        "full-speed latency, socket read -> channel send: median {:.1} us, p99 {:.1} us, max {:.1} us ({} samples, last run)",
        last.latency.median_ns as f64 / 1e3,
        last.latency.p99_ns as f64 / 1e3,
        last.latency.max_ns as f64 / 1e3,
        last.latency.count
    );
    // Paced at the radar's own rate: frames arrive one by one, as from a real unit.
    let paced_n = 3200;
    let paced = server(&rt, paced_n, Some(Duration::from_micros(625)));
    let (t, m) = through_driver(&rt, paced, paced_n);
    println!(
        "paced at 1600/s ({paced_n} azimuths, {:.2} s): latency median {:.1} us, p99 {:.1} us, max {:.1} us; drops {}",
        t.as_secs_f64(),
        m.latency.median_ns as f64 / 1e3,
        m.latency.p99_ns as f64 / 1e3,
        m.latency.max_ns as f64 / 1e3,
        m.azimuth_drops
    );
}

criterion_group!(benches, bench);

fn main() {
    benches();
    report();
    Criterion::default().configure_from_args().final_summary();
}
