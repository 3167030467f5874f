//! The front end at line rate: one CTS350-X rotation (400 azimuths x 3768 bins, 8-bit) through
//! the daemon's front end for current units (the learned floor and gain, detection on the
//! wire's bins, grouping, landmark test, beams; every 4th azimuth's spectrum kept in dB for
//! the spectrum comparison), against a memcpy of the same bins in the same run.
//!
//! `cargo bench -p slam-node --bench detect_line_rate`: prints ms per rotation and ns per bin
//! for both, and their ratio.

use std::sync::Arc;
use std::time::{Duration, Instant};

use bytes::Bytes;
use criterion::{criterion_group, criterion_main, Criterion};
use protocol::{BinWidth, Geometry};
use radar_driver::Azimuth;
use slam_node::pipeline::{FrontEnd, PipelineSettings};

const AZIMUTHS: u16 = 400;
const BINS: u16 = 3768;

fn geometry() -> Geometry {
    Geometry::cts350x()
}

/// A deterministic rotation: a speckled floor falling with range, with a few dozen strong
/// returns per azimuth (8-bit, 0.5 dB steps, as the wire carries them).
fn rotation(rotation: u64) -> Vec<Azimuth> {
    let g = Arc::new(geometry());
    let mut x = 0x9E37_79B9_7F4A_7C15u64 ^ rotation;
    (0..AZIMUTHS)
        .map(|a| {
            let bins: Vec<u8> = (0..BINS)
                .map(|b| {
                    x = x
                        .wrapping_mul(6_364_136_223_846_793_005)
                        .wrapping_add(1_442_695_040_888_963_407);
                    let speckle = ((x >> 58) & 0xF) as u8;
                    let floor = 60u8.saturating_sub((b / 100) as u8);
                    let target = if (b + 37 * a) % 97 < 2 { 80 } else { 0 };
                    floor.saturating_add(speckle).saturating_add(target)
                })
                .collect();
            let encoder = a * 14;
            Azimuth {
                encoder,
                angle_rad: g.azimuth_rad(encoder),
                timestamp_s: 1.7e9 + rotation as f64 * 0.25 + f64::from(a) * 0.25 / 400.0,
                sweep_counter: a,
                width: BinWidth::Eight,
                bins: Bytes::from(bins),
                geometry: Arc::clone(&g),
                rotation,
            }
        })
        .collect()
}

fn front_end_rotation(
    fe: &mut FrontEnd,
    azimuths: &[Azimuth],
    beams: &mut Vec<slam_node::pipeline::beams::OfferedBeam>,
) -> usize {
    let mut detections = 0;
    for az in azimuths {
        let index = az.geometry.azimuth_index(az.encoder).unwrap_or(0);
        detections += fe
            .process(az, index, az.angle_rad, 0.0, beams, |_| false)
            .detections;
        beams.clear();
    }
    detections
}

fn bench(c: &mut Criterion) {
    // The front end a current unit runs: the learned floor and gain, detection at line rate.
    let mut settings = PipelineSettings::from_config(&config::Config::default())
        .expect("shipped settings")
        .front_end();
    settings.detector.kind = slam_node::detect::DetectorKind::Learned;
    settings.detector.landmarks.points_only = true;
    settings.keep_spectrum_every = 4;
    let mut fe = FrontEnd::new(settings);
    fe.configure(&geometry()).expect("geometry");
    let rotations: Vec<Vec<Azimuth>> = (0..4).map(rotation).collect();
    let mut beams = Vec::new();
    // Warm the detector's memory (TPP's windows) over a few rotations.
    for r in &rotations {
        front_end_rotation(&mut fe, r, &mut beams);
    }
    let mut copy = vec![0u8; usize::from(BINS)];
    let mut group = c.benchmark_group("cts350x_rotation");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(8));
    group.bench_function("front_end", |b| {
        let mut k = 0;
        b.iter(|| {
            k += 1;
            front_end_rotation(&mut fe, &rotations[k % rotations.len()], &mut beams)
        })
    });
    group.bench_function("memcpy", |b| {
        let mut k = 0;
        b.iter(|| {
            k += 1;
            for az in &rotations[k % rotations.len()] {
                copy.copy_from_slice(&az.bins);
                std::hint::black_box(&copy);
            }
        })
    });
    group.finish();
    // The same two, timed directly, for a one-line summary.
    // The fastest of 20 runs: this machine is shared, and interference only adds time.
    let time = |f: &mut dyn FnMut()| {
        (0..20)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let mut k = 0;
    let fe_s = time(&mut || {
        k += 1;
        std::hint::black_box(front_end_rotation(&mut fe, &rotations[k % 4], &mut beams));
    });
    let copy_s = time(&mut || {
        for az in &rotations[0] {
            copy.copy_from_slice(&az.bins);
            std::hint::black_box(&copy);
        }
    });
    let bins = f64::from(AZIMUTHS) * f64::from(BINS);
    println!(
        "CTS350-X rotation ({} x {} bins): front end {:.2} ms ({:.1} ns/bin), memcpy {:.3} ms ({:.2} ns/bin); front end / memcpy {:.0}x; budget 5 ms",
        AZIMUTHS,
        BINS,
        fe_s * 1e3,
        fe_s * 1e9 / bins,
        copy_s * 1e3,
        copy_s * 1e9 / bins,
        fe_s / copy_s
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
