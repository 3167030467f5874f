//! One batched EKF update against the number of features in the state (20, 100, 500, 1000)
//! and in the batch (1, 10, 50 features, 3 rows each: range, bearing, power).
//!
//! `cargo bench -p slam-filter --bench filter_update`. The state is cloned before and dropped
//! after the timed region (criterion's `iter_batched`). Expected growth: O(n^2 m) for the covariance
//! update, n the state dimension (9 + 4 N) and m the rows.

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion};
use nalgebra::{DMatrix, DVector};
use slam_filter::observation::state_columns;
use slam_filter::state::{SlamState, FEATURE_BASE, FEATURE_DIM};
use slam_filter::{batched_update, LinearisedObservation};

/// A dense, well-conditioned covariance: `D + 0.5 u u^T / n` with a smooth u.
fn state(features: usize) -> SlamState {
    let n = FEATURE_BASE + FEATURE_DIM * features;
    let u = DVector::from_fn(n, |i, _| ((i as f64) * 0.37).sin());
    let mut cov = &u * u.transpose() * (0.5 / n as f64);
    for i in 0..n {
        cov[(i, i)] += 1.0 + 0.1 * ((i % 7) as f64);
    }
    let mean = DVector::from_fn(n, |i, _| 0.01 * i as f64);
    SlamState::from_parts(mean, cov, 0.0).expect("valid benchmark state")
}

/// A batch observing `observed` features spread through the state, 3 rows each, with a
/// Jacobian shaped like the radar's: dense over the pose, the beam's features and L.
fn batch(features: usize, observed: usize) -> LinearisedObservation {
    let step = (features / observed).max(1);
    let slots: Vec<usize> = (0..observed)
        .map(|k| (k * step).min(features - 1))
        .collect();
    let columns = state_columns(&slots);
    let m = 3 * observed;
    let jacobian = DMatrix::from_fn(m, columns.len(), |i, j| {
        (((i * 31 + j * 17) % 13) as f64 - 6.0) * 0.05
    });
    LinearisedObservation {
        columns,
        jacobian,
        innovation: DVector::from_fn(m, |i, _| 0.01 * ((i % 5) as f64 - 2.0)),
        noise: DMatrix::from_diagonal(&DVector::from_element(m, 1.0)),
    }
}

fn bench_update(c: &mut Criterion) {
    let mut group = c.benchmark_group("batched_update");
    group.sample_size(10);
    for &features in &[20usize, 100, 500, 1000] {
        let base = state(features);
        for &observed in &[1usize, 10, 50] {
            if observed > features {
                continue;
            }
            let obs = batch(features, observed);
            group.bench_with_input(
                BenchmarkId::new(format!("N{features}"), format!("batch{observed}")),
                &obs,
                |b, obs| {
                    b.iter_batched(
                        || base.clone(),
                        |mut s| {
                            batched_update(&mut s, obs).expect("update succeeds");
                            s // dropped by criterion outside the timed region
                        },
                        BatchSize::LargeInput,
                    )
                },
            );
        }
    }
    group.finish();
}

/// Baselines measured in the same run (this machine is shared and noisy): one in-place
/// read-and-write pass over an n x n matrix (the memory traffic floor of any update), and
/// the textbook dense update `(I - KH) P (I - KH)^T + K R K^T` with an explicit inverse.
fn bench_baselines(c: &mut Criterion) {
    let mut group = c.benchmark_group("baseline");
    group.sample_size(10);
    for &features in &[20usize, 100, 500, 1000] {
        let n = FEATURE_BASE + FEATURE_DIM * features;
        let mut p = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 3) % 11) as f64);
        group.bench_function(
            BenchmarkId::new("pass_over_P", format!("N{features}")),
            |b| {
                b.iter(|| {
                    p.as_mut_slice().iter_mut().for_each(|v| *v *= 1.000_000_1);
                    std::hint::black_box(&p);
                })
            },
        );
    }
    for &features in &[20usize, 100] {
        let base = state(features);
        let n = base.dim();
        let obs = batch(features, 10);
        let mut h = DMatrix::zeros(obs.jacobian.nrows(), n);
        for (local, &col) in obs.columns.iter().enumerate() {
            h.column_mut(col).copy_from(&obs.jacobian.column(local));
        }
        let cov = base.covariance().into_owned();
        group.bench_function(
            BenchmarkId::new("dense_joseph", format!("N{features}/batch10")),
            |b| {
                b.iter(|| {
                    let s = &h * &cov * h.transpose() + &obs.noise;
                    let k = &cov * h.transpose() * s.try_inverse().expect("invertible");
                    let ikh = DMatrix::identity(n, n) - &k * &h;
                    let p = &ikh * &cov * ikh.transpose() + &k * &obs.noise * k.transpose();
                    std::hint::black_box(p)
                })
            },
        );
    }
    group.finish();
}

criterion_group!(benches, bench_update, bench_baselines);
criterion_main!(benches);
