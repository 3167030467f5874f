//! Whole-spectrum prediction and noisy synthesis on a 3768-bin (CTS350-X) spectrum with
//! 0 (baseline: floor only), 1, 3 and 10 targets in the beam, plus the per-beam
//! observation with its Jacobian. Criterion reports throughput in bins per second; the
//! summary printed at the end gives ns per bin from a plain timed loop in the same run.

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use radar_model::material::Material;
use radar_model::noise::{seeded_rng, NoiseModel};
use radar_model::power::{PowerModel, PowerTarget};
use radar_model::spectrum::{
    beam_spectrum_targets, SpectrumGeometry, SpectrumModel, SpectrumTarget,
};
use radar_model::{observe_beam, BeamFeature, Compensation, Pose2};
use rand::Rng;
use std::time::Instant;

fn targets(n: usize) -> Vec<SpectrumTarget> {
    let power_model = PowerModel::default();
    let m = Material::from_rho_alpha(0.3, 0.2).unwrap();
    let pts: Vec<PowerTarget> = (0..n)
        .map(|i| PowerTarget {
            range_m: 8.0 + 14.0 * i as f64,
            material: m,
        })
        .collect();
    let mut out = Vec::new();
    beam_spectrum_targets(&power_model, &pts, 0.0, &mut out).unwrap();
    out
}

fn model() -> SpectrumModel {
    SpectrumModel::new(
        SpectrumGeometry::default(),
        &Compensation::default(),
        NoiseModel::default(),
    )
    .unwrap()
}

fn bench_spectrum(c: &mut Criterion) {
    let model = model();
    let bins = model.geometry().bins;
    let mut out = vec![0.0; bins];
    let mut group = c.benchmark_group("spectrum_3768_bins");
    group.throughput(Throughput::Elements(bins as u64));
    for n in [0usize, 1, 3, 10] {
        let t = targets(n);
        group.bench_with_input(BenchmarkId::new("predict", n), &t, |b, t| {
            b.iter(|| model.predict_into(black_box(t), &mut out).unwrap())
        });
        let mut rng = seeded_rng(1);
        group.bench_with_input(BenchmarkId::new("synthesize", n), &t, |b, t| {
            b.iter(|| {
                model
                    .synthesize_into(black_box(t), &mut rng, &mut out)
                    .unwrap()
            })
        });
    }
    group.finish();
}

fn bench_observe(c: &mut Criterion) {
    let pose = Pose2::new(1.0, 2.0, 0.3);
    let m = Material::from_rho_alpha(0.3, 0.2).unwrap();
    let mut group = c.benchmark_group("observe_beam");
    for n in [1usize, 3, 10] {
        let feats: Vec<BeamFeature> = (0..n)
            .map(|i| BeamFeature {
                xy: pose.point_at(8.0 + 14.0 * i as f64, 0.1),
                material: m,
            })
            .collect();
        group.bench_with_input(BenchmarkId::from_parameter(n), &feats, |b, f| {
            b.iter(|| observe_beam(&pose, black_box(f), 0.0, &PowerModel::default()).unwrap())
        });
    }
    group.finish();
}

/// Plain timed loops, printed as ns per bin, with the floor-only prediction (a copy of
/// the precomputed floor) as the baseline of the same run.
fn summary(_c: &mut Criterion) {
    let model = model();
    let bins = model.geometry().bins;
    let mut out = vec![0.0; bins];
    let reps = 2000;
    let mut rng = seeded_rng(2);
    let mut time = |f: &mut dyn FnMut(&mut [f64])| {
        let start = Instant::now();
        for _ in 0..reps {
            f(&mut out);
            black_box(&out);
        }
        start.elapsed().as_nanos() as f64 / (reps * bins) as f64
    };
    let base = time(&mut |o| model.predict_into(&[], o).unwrap());
    let mut rng_only = seeded_rng(3);
    let rng_base = time(&mut |o| {
        for v in o.iter_mut() {
            *v = rng_only.gen::<f64>();
        }
    });
    println!("\nsummary (3768 bins, {reps} repetitions each):");
    println!("  predict, 0 targets (baseline, copy of the floor): {base:.3} ns/bin");
    println!("  one ChaCha8 uniform per bin (baseline for synthesis): {rng_base:.3} ns/bin");
    for n in [1usize, 3, 10] {
        let t = targets(n);
        let p = time(&mut |o| model.predict_into(&t, o).unwrap());
        let s = time(&mut |o| model.synthesize_into(&t, &mut rng, o).unwrap());
        println!(
            "  {n:2} targets: predict {p:.3} ns/bin ({:.1} x copy, {:.1} us/spectrum), \
             synthesize {s:.3} ns/bin ({:.1} x uniform draws, {:.1} us/spectrum)",
            p / base,
            p * bins as f64 / 1e3,
            s / rng_base,
            s * bins as f64 / 1e3
        );
    }
}

criterion_group!(benches, bench_spectrum, bench_observe, summary);
criterion_main!(benches);
