//! Radar odometry's registration of one rotation against the last, at the size the replay
//! of a CTS350-X gives (6 points per azimuth x 400 azimuths): a street of two building
//! fronts, fences, parked cars and posts, each point jittered by a few centimetres, seen from
//! two poses 2 m apart, registered from a start 5 % off in distance.
//!
//! `cargo bench -p radar-odometry --bench register`: criterion's time per registration (the
//! reference's k-d tree, pair grid and normals built each time), with the nearest-neighbour
//! queries answered by the pair grid and by the k-d tree, then the pairs and residual of one
//! run of each; and the run without hard pairs from a registration's result
//! (`register_soft`, the reference built outside it), as the daemon runs it once a rotation.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use radar_model::geometry::Pose2;
use radar_odometry::{in_frame_of, register, register_soft, ReferenceCloud};

/// About 2400 points: what the strongest 6 detections of 400 azimuths make. Fronts with
/// set-backs every few metres, cars and posts at irregular places (a street without
/// irregularity has no along-track information for any registration).
fn street() -> Vec<[f64; 2]> {
    let mut x = 0x2545_F491_4F6C_DD1Du64;
    let mut uniform = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut pts = Vec::new();
    // Building fronts: segments 4-12 m long, each set back 0-1.5 m from the street.
    for (side, base) in [(1.0, 8.0), (-1.0, 7.5)] {
        let mut s = -60.0;
        while s < 60.0 {
            let len = 4.0 + 8.0 * uniform();
            let offset = base + 1.5 * uniform();
            let n = (len / 0.15) as usize;
            for i in 0..n {
                let along = s + len * i as f64 / n as f64;
                pts.push([
                    along + 0.03 * uniform(),
                    side * offset + 0.06 * (uniform() - 0.5),
                ]);
            }
            // The set-back's side wall.
            for j in 0..8 {
                pts.push([s + len, side * (offset + 0.2 * f64::from(j))]);
            }
            s += len;
        }
    }
    for _ in 0..18 {
        let x0 = -55.0 + 110.0 * uniform();
        let y0 = if uniform() < 0.5 { 3.5 } else { -3.2 };
        for j in 0..22 {
            pts.push([x0 + 0.2 * f64::from(j), y0 + 0.05 * uniform()]);
        }
        for j in 0..8 {
            pts.push([x0, y0 + 0.2 * f64::from(j) * y0.signum()]);
        }
    }
    for _ in 0..120 {
        pts.push([
            -60.0 + 120.0 * uniform(),
            if uniform() < 0.5 { 5.5 } else { -5.0 },
        ]);
    }
    pts
}

fn bench(c: &mut Criterion) {
    let world = street();
    let reference = in_frame_of(&Pose2::new(0.0, 0.0, 0.0), &world);
    let current = in_frame_of(&Pose2::new(2.0, 0.03, 0.01), &world);
    let start = Pose2::new(2.1, 0.0, 0.0);
    // The daemon's pair gate (0.6 m) and a wide one. The nearest-neighbour queries go to the
    // reference's pair grid, or, with no grid (a cloud built for a zero gate), to its k-d
    // tree: both paths, the same clouds, one run.
    for gate in [0.6, 1.5] {
        for (queries, grid_cell) in [("pair grid", gate), ("k-d tree", 0.0)] {
            c.bench_function(
                &format!(
                    "register 2 rotations, gate {gate} m, {queries} (reference's tree, grid and normals included)"
                ),
                |b| {
                    b.iter(|| {
                        let cloud =
                            ReferenceCloud::new(black_box(reference.clone()), 1.5, grid_cell);
                        register(&cloud, black_box(&current), start, gate, 100)
                    })
                },
            );
            let cloud = ReferenceCloud::new(reference.clone(), 1.5, grid_cell);
            let reg = register(&cloud, &current, start, gate, 100);
            println!(
                "gate {gate} m, {queries}: {} reference points, {} current points: {reg:?} (truth x 2.0, y 0.03, theta 0.01)",
                reference.len(),
                current.len()
            );
        }
    }
    // The run without hard pairs from a registration's result, as the daemon runs it once a
    // rotation (kernel 0.1 m, on the daemon's 0.6 m pair grid; the reference built outside).
    let cloud = ReferenceCloud::new(reference.clone(), 1.5, 0.6);
    let from = register(&cloud, &current, start, 0.6, 100).map_or(start, |r| r.pose);
    c.bench_function(
        "register without hard pairs from a registration's result, kernel 0.1 m",
        |b| b.iter(|| register_soft(&cloud, black_box(&current), from, 0.1, 100)),
    );
    let soft = register_soft(&cloud, &current, from, 0.1, 100);
    println!("without hard pairs, kernel 0.1 m: {soft:?} (truth x 2.0, y 0.03, theta 0.01)");
}

criterion_group!(benches, bench);
criterion_main!(benches);
