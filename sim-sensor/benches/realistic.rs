//! Realistic rendering rate on one core: a procedural street grid of about 100,000
//! scatterers seen by the CTS350-X-like unit (400 azimuths x 3768 bins) from a vehicle
//! driving down a street at 9 m/s. Target: 10x real time, a rotation (0.25 s of radar) in
//! at most 25 ms. Also the urban-street scene.
//!
//! Run: `cargo bench -p sim-sensor --bench realistic`

use std::hint::black_box;
use std::sync::Arc;
use std::time::Instant;

use bytes::BytesMut;
use criterion::{criterion_group, Criterion, Throughput};
use protocol::Timestamp;
use sim_sensor::render::SceneRenderer;
use sim_sensor::scene::{shipped, Scene};

/// The 100,000-scatterer grid: 4 x 4 blocks of 100 m x 60 m.
const GRID: &str = include_str!("street-grid-100k.toml");

fn grid() -> Scene {
    Scene::from_toml_str("street-grid-100k", GRID).expect("grid scene")
}

fn renderer(scene: &Scene) -> Arc<SceneRenderer> {
    Arc::new(SceneRenderer::new(scene, None, 120.0).expect("renderer"))
}

fn bench(c: &mut Criterion) {
    let cases = [
        ("cts350x-400/street-grid-100k", grid()),
        (
            "cts350x-400/urban-street",
            shipped::load("urban-street").expect("scene"),
        ),
    ];
    let mut group = c.benchmark_group("realistic_rotation");
    group.sample_size(10);
    group.throughput(Throughput::Elements(400));
    for (name, scene) in &cases {
        let r = renderer(scene);
        let scatterers = r.realistic().map_or(0, |m| m.world.scatterers.len());
        println!("{name}: {scatterers} scatterers");
        let mut cursor = r.cursor();
        let mut frame = BytesMut::new();
        let mut rotation = 0u64;
        group.bench_function(*name, |b| {
            b.iter(|| {
                // Rotations 4 to 40 (1 s to 10 s of the drive), one whole rotation each.
                let first = (4 + rotation % 36) * 400;
                rotation += 1;
                for k in first..first + 400 {
                    frame.clear();
                    let out = cursor
                        .render(k, 0, Timestamp::EPOCH, &mut frame)
                        .expect("render");
                    black_box(out);
                }
            })
        });
    }
    group.finish();
    // A plain loop: 40 rotations, milliseconds per rotation.
    for (name, scene) in &cases {
        let r = renderer(scene);
        let mut cursor = r.cursor();
        let mut frame = BytesMut::new();
        let started = Instant::now();
        let rotations = 40u64;
        for k in 400..400 * (rotations + 1) {
            frame.clear();
            black_box(
                cursor
                    .render(k, 0, Timestamp::EPOCH, &mut frame)
                    .expect("render"),
            );
        }
        let ms = started.elapsed().as_secs_f64() * 1e3 / rotations as f64;
        println!(
            "{name}: {ms:.1} ms per rotation in a plain loop = {:.1}x real time (250 ms a rotation)",
            250.0 / ms
        );
    }
}

criterion_group!(benches, bench);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
}
