//! Rendering rate on one core: azimuths per second for both shipped radars, as a multiple of
//! the real radar's azimuth rate, and the cost per azimuth as the scene grows with features
//! out of range (it must not grow).
//!
//! Run: `cargo bench -p sim-sensor --bench render`

use std::hint::black_box;
use std::sync::Arc;
use std::time::{Duration, Instant};

use bytes::BytesMut;
use criterion::{criterion_group, Criterion, Throughput};
use protocol::Timestamp;
use sim_sensor::radar::RadarPreset;
use sim_sensor::render::SceneRenderer;
use sim_sensor::scene::{shipped, Feature, FeatureKind, Scene};

fn renderer(scene: &Scene) -> Arc<SceneRenderer> {
    Arc::new(SceneRenderer::new(scene, None, 600.0).expect("renderer"))
}

/// The scene with `extra` trees added on a ring 1 km out (beyond every radar's range).
fn with_far_features(mut scene: Scene, extra: usize) -> Scene {
    let base = scene.features.len();
    for i in 0..extra {
        let a = i as f64 / extra as f64 * std::f64::consts::TAU;
        let r = 1000.0 + (i % 97) as f64;
        scene.features.push(Feature {
            id: (base + i) as u32,
            kind: FeatureKind::Tree,
            x_m: r * a.cos(),
            y_m: r * a.sin(),
            rho: 0.02,
            alpha: 0.6,
        });
    }
    scene
}

fn cases() -> Vec<(&'static str, Scene)> {
    vec![
        (
            "paper-200/outdoor-field",
            shipped::load("outdoor-field").expect("scene"),
        ),
        (
            "cts350x-400/outdoor-field",
            shipped::load("outdoor-field")
                .expect("scene")
                .with_preset(RadarPreset::Cts350x400),
        ),
        (
            "cts350x-400/long-loop",
            shipped::load("long-loop").expect("scene"),
        ),
        (
            "paper-200/dense-clutter",
            shipped::load("dense-clutter").expect("scene"),
        ),
    ]
}

/// One criterion case: successive azimuths of `scene` rendered into a reused frame.
fn bench_azimuths(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: String,
    scene: &Scene,
) {
    let r = renderer(scene);
    let mut cursor = r.cursor();
    let mut frame = BytesMut::with_capacity(16 * 1024);
    let mut k = 0u64;
    group.bench_function(name, |b| {
        b.iter(|| {
            frame.clear();
            cursor
                .render(k, k as u16, Timestamp::EPOCH, &mut frame)
                .expect("render");
            k += 1;
            black_box(frame.len())
        })
    });
}

fn bench_render(c: &mut Criterion) {
    let mut group = c.benchmark_group("render_azimuth");
    group.throughput(Throughput::Elements(1));
    for (name, scene) in cases() {
        bench_azimuths(&mut group, name.to_string(), &scene);
    }
    group.finish();

    let mut group = c.benchmark_group("render_vs_scene_size");
    group.throughput(Throughput::Elements(1));
    for extra in [0usize, 10_000, 100_000] {
        let scene = with_far_features(shipped::load("outdoor-field").expect("scene"), extra);
        bench_azimuths(
            &mut group,
            format!("paper-200/outdoor-field+{extra}-far"),
            &scene,
        );
    }
    group.finish();
}

/// A plain timing loop after criterion's runs: the figure to quote, as a multiple of the
/// radar's own azimuth rate.
fn summary() {
    println!("\nrendering rate on one core (plain loop, 3 s per case):");
    for (name, scene) in cases() {
        let r = renderer(&scene);
        let mut cursor = r.cursor();
        let mut frame = BytesMut::with_capacity(16 * 1024);
        let start = Instant::now();
        let mut k = 0u64;
        while start.elapsed() < Duration::from_secs(3) {
            for _ in 0..100 {
                frame.clear();
                cursor
                    .render(k, k as u16, Timestamp::EPOCH, &mut frame)
                    .expect("render");
                k += 1;
            }
        }
        let rate = k as f64 / start.elapsed().as_secs_f64();
        let real = scene.radar.packet_rate_f64();
        println!(
            "  {name:28} {rate:>9.0} azimuths/s = {:>6.1} x the radar's {real:.0}/s ({} bins)",
            rate / real,
            scene.radar.range_bins
        );
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(Duration::from_secs(3));
    targets = bench_render
}

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
    summary();
}
