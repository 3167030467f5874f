//! Memory bounded in bytes (issue 17, case 7): the worst legal input a radar can send, as
//! fast as loopback carries it, to a consumer that hardly reads, never makes the driver
//! hold more than its byte budget; and a small azimuth never pins the large read buffer it
//! was decoded from.
//!
//! Each test checks the driver's own accounting (`held_bytes_peak`) and, on Linux, the
//! process's resident memory. The tests of this file share the process, so they take a
//! lock and run one at a time: resident memory is only meaningful that way.

mod common;

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use bytes::Bytes;
use common::*;
use protocol::{BinWidth, FftData, Message, MAX_PAYLOAD_SIZE};
use radar_driver::{Driver, DropPolicy, HandoffSettings, AZIMUTH_OVERHEAD_BYTES};

/// One test at a time in this process (resident memory is the process's).
static ONE_AT_A_TIME: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

/// The bins of the largest azimuth the protocol accepts: a payload just under
/// `MAX_PAYLOAD_SIZE` (the 14-byte FFT header, then the bins).
const LARGEST_BINS: usize = MAX_PAYLOAD_SIZE as usize - 1 - 14;

/// Resident memory of this process in bytes (Linux), `None` elsewhere.
fn rss_bytes() -> Option<usize> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: usize = statm.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * 4096)
}

/// Samples resident memory every millisecond until stopped; returns the highest.
struct RssWatch {
    stop: Arc<AtomicBool>,
    peak: Arc<AtomicUsize>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl RssWatch {
    fn start() -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let peak = Arc::new(AtomicUsize::new(rss_bytes().unwrap_or(0)));
        let (s, p) = (Arc::clone(&stop), Arc::clone(&peak));
        let thread = std::thread::spawn(move || {
            while !s.load(Ordering::Relaxed) {
                p.fetch_max(rss_bytes().unwrap_or(0), Ordering::Relaxed);
                std::thread::sleep(Duration::from_millis(1));
            }
        });
        Self {
            stop,
            peak,
            thread: Some(thread),
        }
    }

    fn finish(mut self) -> usize {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            t.join().unwrap();
        }
        self.peak.load(Ordering::Relaxed)
    }
}

fn fft(config: &protocol::Configuration, sweep: u64, bins: Bytes) -> Vec<u8> {
    frame(&Message::FftData(FftData::new(
        BinWidth::Eight,
        (sweep % 65_536) as u16,
        encoder_of(config, sweep),
        timestamp_for(sweep),
        bins,
    )))
}

const MIB: usize = 1 << 20;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_largest_legal_azimuths_as_fast_as_possible_to_a_slow_consumer_never_exceed_the_byte_budget(
) {
    let _one = ONE_AT_A_TIME.lock().await;
    const BUDGET: usize = 16 * MIB;
    const FRAMES: u64 = 120;
    let radar = FakeRadar::bind().await;
    let mut settings = test_settings(radar.addr);
    // Counts that alone would let 4096 + 8 x 32 azimuths of ~1 MB through (4.3 GB).
    settings.handoff = HandoffSettings {
        azimuth_capacity: Some(4096),
        rotation_capacity: Some(8),
        drop_policy: DropPolicy::DropNewest,
    };
    settings.max_held_bytes = BUDGET;
    settings.socket.recv_buffer_bytes = Some(256 * 1024);
    let (driver, rx) = Driver::new(settings);
    let metrics = driver.metrics();
    let rss_before = rss_bytes();
    let watch = RssWatch::start();
    let handle = driver.spawn();
    // A slow consumer of both channels: one azimuth every 20 ms, each rotation held as long.
    let done = Arc::new(AtomicBool::new(false));
    let consumer = {
        let az = rx.azimuths.clone().unwrap();
        let rot = rx.rotations.clone().unwrap();
        let done = Arc::clone(&done);
        std::thread::spawn(move || {
            let mut taken = 0u64;
            while !done.load(Ordering::Relaxed) {
                if let Ok(a) = az.recv_timeout(Duration::from_millis(20)) {
                    taken += 1;
                    std::thread::sleep(Duration::from_millis(20));
                    drop(a);
                }
                if let Ok(r) = rot.try_recv() {
                    std::thread::sleep(Duration::from_millis(20));
                    drop(r);
                }
            }
            taken
        })
    };
    // The radar: 16 azimuths a rotation (rotations close every 16), each of the largest
    // legal size, written as fast as the socket takes them.
    let config = small_configuration();
    let mut conn = radar.accept().await;
    conn.handshake(&config).await;
    let bins = Bytes::from(vec![0x5a_u8; LARGEST_BINS]);
    for sweep in 0..FRAMES {
        let bytes = fft(&config, sweep, bins.clone());
        assert!(bytes.len() < 1_000_025, "{}", bytes.len());
        conn.send(&bytes).await.unwrap();
    }
    let processed = eventually(|| metrics.snapshot().fft_frames == FRAMES).await || {
        // A slow (debug, loaded) machine: give it longer.
        tokio::time::sleep(Duration::from_secs(20)).await;
        metrics.snapshot().fft_frames == FRAMES
    };
    done.store(true, Ordering::Relaxed);
    let taken = tokio::task::spawn_blocking(move || consumer.join().unwrap())
        .await
        .unwrap();
    let m = handle.stop().await.unwrap().metrics;
    let rss_peak = watch.finish();
    assert!(processed, "{} of {FRAMES} frames processed", m.fft_frames);
    println!(
        "held peak {} bytes of a {} budget; {} azimuths dropped by the budget, {} taken by the consumer",
        m.held_bytes_peak, m.max_held_bytes, m.budget_drops, taken
    );
    assert_eq!(m.max_held_bytes, BUDGET);
    assert!(
        m.held_bytes_peak <= BUDGET,
        "held {} bytes, over the budget of {BUDGET}",
        m.held_bytes_peak
    );
    assert!(
        m.held_bytes_peak > BUDGET - 2 * MIB,
        "the budget was reached ({} bytes held at most)",
        m.held_bytes_peak
    );
    assert!(m.budget_drops > 0, "the budget was hit and counted");
    assert_eq!(
        m.azimuths_sent + m.budget_drops,
        FRAMES,
        "every azimuth went to the channel or was dropped by the budget"
    );
    assert!(taken > 0);
    if let Some(before) = rss_before {
        let growth = rss_peak.saturating_sub(before);
        println!(
            "resident memory grew by at most {:.1} MiB",
            growth as f64 / MIB as f64
        );
        // The budget, plus what is not in it: one frame in the read buffer and its copy
        // in flight, the fake radar's frame being written, the allocator's slack.
        assert!(
            growth < BUDGET + 48 * MIB,
            "resident memory grew by {growth} bytes"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn small_azimuths_decoded_between_large_frames_do_not_pin_the_read_buffers() {
    let _one = ONE_AT_A_TIME.lock().await;
    const PAIRS: u64 = 200;
    let radar = FakeRadar::bind().await;
    let mut settings = test_settings(radar.addr);
    settings.handoff = HandoffSettings {
        azimuth_capacity: Some(4096),
        rotation_capacity: None,
        drop_policy: DropPolicy::DropNewest,
    };
    settings.socket.recv_buffer_bytes = Some(256 * 1024);
    let (driver, rx) = Driver::new(settings);
    let metrics = driver.metrics();
    let rss_before = rss_bytes();
    let watch = RssWatch::start();
    let handle = driver.spawn();
    let config = small_configuration();
    let mut conn = radar.accept().await;
    conn.handshake(&config).await;
    // Each tiny azimuth arrives right behind a large frame the driver skips (a message id
    // it does not use), so it is decoded from a read buffer of about 1 MB. Nobody reads
    // the azimuths: all 200 stay queued.
    let filler = frame(&Message::Unknown {
        id: 99,
        payload: Bytes::from(vec![0u8; 900_000]),
    });
    for sweep in 0..PAIRS {
        let mut bytes = filler.clone();
        bytes.extend_from_slice(&fft(&config, sweep, bins_for(sweep as u16, 32)));
        conn.send(&bytes).await.unwrap();
    }
    let all = eventually(|| metrics.snapshot().fft_frames == PAIRS).await;
    let held = metrics.snapshot().held_bytes;
    let rss_peak = watch.finish();
    let queued = rx.azimuths.as_ref().unwrap().len();
    let m = handle.stop().await.unwrap().metrics;
    assert!(all, "{} of {PAIRS} azimuths", m.fft_frames);
    assert_eq!(queued as u64, PAIRS, "every tiny azimuth is queued");
    let slots = HandoffSettings {
        azimuth_capacity: Some(4096),
        rotation_capacity: None,
        drop_policy: DropPolicy::DropNewest,
    }
    .slot_bytes();
    let per_azimuth = 32 + AZIMUTH_OVERHEAD_BYTES;
    println!(
        "{queued} tiny azimuths queued hold {held} bytes ({} for the channel's slots, {per_azimuth} each)",
        slots
    );
    assert_eq!(
        held,
        slots + PAIRS as usize * per_azimuth,
        "each holds its own bins and overhead, not a read buffer"
    );
    if let Some(before) = rss_before {
        let growth = rss_peak.saturating_sub(before);
        println!(
            "resident memory grew by at most {:.1} MiB",
            growth as f64 / MIB as f64
        );
        // Pinned read buffers would be ~200 x 1 MB.
        assert!(growth < 48 * MIB, "resident memory grew by {growth} bytes");
    }
}
