//! The loop-closure verifier's search at its widest (`ScanAlignSettings`' defaults: 1 m
//! cells, 0.7 m kernel, a window of 40 m and 0.15 rad in 0.01 rad steps, 600 sampled
//! points), over a reference of 3000 points on a block of streets (fronts every 20 m
//! across and along).
//!
//! `cargo bench -p slam-graph --bench correlate`: criterion's time per search (the score
//! grid built outside it, as the verifier keeps one per submap).

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use radar_model::geometry::Pose2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slam_graph::correlate::{correlate, ScoreGrid, Window};

fn block(n: usize, seed: u64) -> Vec<[f64; 2]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut uniform = move || rng.gen::<f64>();
    (0..n)
        .map(|_| {
            let along = -70.0 + 140.0 * uniform();
            let across = 20.0 * (uniform() * 7.0).floor() - 60.0 + 0.3 * uniform();
            if uniform() < 0.5 {
                [along, across]
            } else {
                [across, along]
            }
        })
        .collect()
}

fn search(c: &mut Criterion) {
    let reference = block(3000, 7);
    let sample = block(600, 11);
    let grid = ScoreGrid::new(&reference, 1.0, 0.7, 1 << 22).expect("grid");
    let window = Window {
        half_m: 40.0,
        half_rad: 0.15,
        step_rad: 0.01,
    };
    let prior = Pose2::new(1.5, -2.0, 0.03);
    c.bench_function(
        "correlate (81 x 81 shifts x 31 headings, 600 points)",
        |b| b.iter(|| correlate(&grid, black_box(&sample), &prior, &window, 3.0, 3)),
    );
}

criterion_group!(benches, search);
criterion_main!(benches);
