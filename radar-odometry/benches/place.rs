//! Place descriptors at the size the global layer describes a submap with: a query (the
//! descriptor around every shifted origin, 9 x 9 with the default settings) and a single
//! descriptor, over 3000 points of a block of streets (fronts every 20 m across and along,
//! posts and cars between) within the descriptor's 80 m.
//!
//! `cargo bench -p radar-odometry --bench place`: criterion's time per query and per
//! descriptor.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use radar_odometry::{PlaceDescriptor, PlaceQuery, PlaceSettings};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn block() -> Vec<[f64; 2]> {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut uniform = move || rng.gen::<f64>();
    let mut pts = Vec::with_capacity(3000);
    while pts.len() < 3000 {
        let along = -70.0 + 140.0 * uniform();
        let across = 20.0 * (uniform() * 7.0).floor() - 60.0 + 0.3 * uniform();
        pts.push(if uniform() < 0.5 {
            [along, across]
        } else {
            [across, along]
        });
    }
    pts
}

fn place(c: &mut Criterion) {
    let points = block();
    let settings = PlaceSettings::default();
    c.bench_function(
        "place query (9 x 9 shifted descriptors, 3000 points)",
        |b| b.iter(|| PlaceQuery::new(black_box(&points), &settings).unwrap()),
    );
    c.bench_function("place descriptor (3000 points)", |b| {
        b.iter(|| PlaceDescriptor::new(black_box(points.iter().copied()), &settings).unwrap())
    });
}

criterion_group!(benches, place);
criterion_main!(benches);
