//! The global layer on a synthetic drive: submaps of a world of posts along a square loop,
//! chained by switch poses whose heading drifts; returning to the start closes the loop and
//! pulls the last frame back. Bad input (a submap with an unusable covariance) is absorbed.

use std::sync::Arc;

use nalgebra::{Matrix2, Matrix3, Vector3};
use radar_model::geometry::Pose2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam_filter::{FeatureId, FrozenSubmap, SubmapFeature};
use slam_graph::se2::{between, compose, inverse, transform_point};
use slam_graph::{GlobalLayer, GlobalMap, GlobalSettings};

/// True frames every 25 m around a 100 m x 100 m square, back to the start.
fn true_frames() -> Vec<Pose2> {
    let mut out = Vec::new();
    for side in 0..4 {
        for step in 0..4 {
            let d = 25.0 * step as f64;
            let (x, y) = match side {
                0 => (d, 0.0),
                1 => (100.0, d),
                2 => (100.0 - d, 100.0),
                _ => (0.0, 100.0 - d),
            };
            out.push(Pose2::new(x, y, side as f64 * std::f64::consts::FRAC_PI_2));
        }
    }
    out.push(Pose2::new(0.0, 0.0, 2.0 * std::f64::consts::PI));
    out
}

fn world(rng: &mut ChaCha8Rng) -> Vec<[f64; 2]> {
    (0..400)
        .map(|_| [rng.gen_range(-40.0..140.0), rng.gen_range(-40.0..140.0)])
        .collect()
}

/// The submaps (frame k's view within 45 m) with chained switch poses whose heading is
/// biased by `bias_rad` per submap.
fn submaps(bias_rad: f64, rng: &mut ChaCha8Rng) -> (Vec<FrozenSubmap>, Vec<Pose2>) {
    let frames = true_frames();
    let posts = world(rng);
    let noise = Normal::new(0.0, 0.1).unwrap();
    let mut out = Vec::new();
    for k in 0..frames.len() - 1 {
        let inv = inverse(&frames[k]);
        let features = posts
            .iter()
            .enumerate()
            .filter(|(_, p)| (p[0] - frames[k].x).hypot(p[1] - frames[k].y) < 45.0)
            .map(|(i, p)| {
                let q = transform_point(&inv, *p);
                SubmapFeature {
                    id: FeatureId(i as u64),
                    xy: [q[0] + noise.sample(rng), q[1] + noise.sample(rng)],
                    xy_cov: Matrix2::from_diagonal_element(0.01),
                    uv: [0.0, 0.0],
                    uv_cov: Matrix2::from_diagonal_element(0.1),
                    hits: 10,
                }
            })
            .collect();
        let mut end = between(&frames[k], &frames[k + 1]);
        end.theta += bias_rad;
        out.push(FrozenSubmap {
            end_pose: end,
            end_cov: Matrix3::from_diagonal(&Vector3::new(0.04, 0.04, 1e-4)),
            features,
            loss_db: 0.0,
            end_s: k as f64,
        });
    }
    (out, frames)
}

fn final_error(loops: bool) -> (f64, usize) {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let (maps, frames) = submaps(0.006, &mut rng);
    let mut g = GlobalMap::new(GlobalSettings {
        loop_closure: loops,
        ..GlobalSettings::default()
    });
    for m in maps {
        g.add_submap(Arc::new(m));
    }
    let last = *g.graph().nodes().last().unwrap();
    let truth = frames.last().unwrap();
    let truth = compose(&Pose2::new(0.0, 0.0, 0.0), truth);
    ((last.x - truth.x).hypot(last.y - truth.y), g.loops().len())
}

/// The layer on its thread, waited for after each submap (as a run paced by its pipeline
/// does), gives after every submap exactly the solution the synchronous map gives: the loop
/// closures land at the submap that found them, whatever the thread's timing.
#[test]
fn a_layer_waited_for_gives_each_submap_s_solution_at_once() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let (maps, _) = submaps(0.006, &mut rng);
    let mut sync = GlobalMap::new(GlobalSettings::default());
    let mut layer = GlobalLayer::spawn(GlobalSettings::default()).expect("the layer's thread");
    for m in maps {
        let m = Arc::new(m);
        sync.add_submap(Arc::clone(&m));
        assert!(layer.submit(m));
        assert!(layer.wait_for_joins(std::time::Duration::from_secs(30)));
        let solution = layer.poll().expect("a solution");
        assert_eq!(solution.frames, sync.graph().nodes().to_vec());
    }
    assert!(!sync.loops().is_empty(), "the return closes a loop");
    // Nothing more to wait for.
    assert!(layer.wait_for_joins(std::time::Duration::ZERO));
}

#[test]
fn closing_the_loop_cuts_the_final_frame_error_at_least_threefold() {
    let (open, none) = final_error(false);
    let (closed, loops) = final_error(true);
    assert_eq!(none, 0);
    assert!(loops >= 1, "the return to the start closes a loop");
    assert!(open > 1.0, "the drift to undo: {open:.2} m");
    assert!(
        closed * 3.0 <= open,
        "final error {closed:.2} m closed, {open:.2} m open"
    );
}

#[test]
fn a_submap_with_an_unusable_covariance_is_kept_as_an_unknown_link() {
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    let (mut maps, _) = submaps(0.006, &mut rng);
    maps[3].end_cov[(0, 0)] = f64::NAN;
    maps[5].end_pose.x = f64::INFINITY;
    let mut g = GlobalMap::new(GlobalSettings::default());
    for m in maps {
        let report = g.add_submap(Arc::new(m));
        assert!(!report.solve_failed);
    }
    assert_eq!(g.stats().bad_submaps, 2);
    assert!(g
        .graph()
        .nodes()
        .iter()
        .all(|p| p.x.is_finite() && p.y.is_finite()));
}
