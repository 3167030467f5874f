//! Loop-closure verification on hand-built submaps: a true revisit is accepted with the
//! right transform; repeated structure, a wrong prior and a material mismatch are refused.

use nalgebra::Matrix2;
use radar_model::geometry::Pose2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam_filter::{FeatureId, SubmapFeature};
use slam_graph::se2::{inverse, transform_point};
use slam_graph::{align, AlignSettings, Refusal};

const SIGMA_M: f64 = 0.15;

/// `world` points seen from a frame at `frame`, with noise, as a submap's features.
fn observe(
    world: &[([f64; 2], [f64; 2])],
    frame: &Pose2,
    rng: &mut ChaCha8Rng,
) -> Vec<SubmapFeature> {
    let noise = Normal::new(0.0, SIGMA_M).unwrap();
    let inv = inverse(frame);
    world
        .iter()
        .enumerate()
        .map(|(k, (p, uv))| {
            let q = transform_point(&inv, *p);
            SubmapFeature {
                id: FeatureId(k as u64),
                xy: [q[0] + noise.sample(rng), q[1] + noise.sample(rng)],
                xy_cov: Matrix2::from_diagonal_element(SIGMA_M * SIGMA_M),
                uv: *uv,
                uv_cov: Matrix2::from_diagonal_element(0.3 * 0.3),
                hits: 10,
            }
        })
        .collect()
}

fn scattered(n: usize, rng: &mut ChaCha8Rng) -> Vec<([f64; 2], [f64; 2])> {
    (0..n)
        .map(|_| {
            (
                [rng.gen_range(-40.0..40.0), rng.gen_range(-40.0..40.0)],
                [0.0, 0.0],
            )
        })
        .collect()
}

#[test]
fn a_true_revisit_is_accepted_with_the_transform_inside_its_uncertainty() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let world = scattered(40, &mut rng);
    let fa = Pose2::new(0.0, 0.0, 0.0);
    let fb = Pose2::new(6.0, -3.0, 0.4);
    let a = observe(&world, &fa, &mut rng);
    let b = observe(&world, &fb, &mut rng);
    // The prior is off by 2 m and 3 degrees and says so.
    let prior = Pose2::new(7.5, -1.8, 0.45);
    let prior_cov = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(4.0, 4.0, 0.01));
    let found = align(&a, &b, &prior, &prior_cov, &AlignSettings::default()).expect("accepted");
    assert!(found.matches.len() >= 35, "{} matches", found.matches.len());
    let e = nalgebra::Vector3::new(
        found.transform.x - fb.x,
        found.transform.y - fb.y,
        found.transform.theta - fb.theta,
    );
    let m = e.dot(&found.covariance.cholesky().unwrap().solve(&e));
    assert!(m < 11.34, "transform error outside its 99 % bound: {m}");
    assert!(found.nis <= found.dof as f64 * 2.0);
}

/// A regular grid of identical posts: the same pattern every 20 m.
fn grid() -> Vec<([f64; 2], [f64; 2])> {
    let mut out = Vec::new();
    for i in -4..=4 {
        for j in -4..=4 {
            for (dx, dy) in [(0.0, 0.0), (6.0, 0.0), (0.0, 9.0)] {
                out.push(([20.0 * i as f64 + dx, 20.0 * j as f64 + dy], [0.0, 0.0]));
            }
        }
    }
    out
}

#[test]
fn repeated_structure_with_a_wide_prior_is_refused_as_ambiguous() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let world = grid();
    let a = observe(&world, &Pose2::new(0.0, 0.0, 0.0), &mut rng);
    let fb = Pose2::new(3.0, 2.0, 0.0);
    let b = observe(&world, &fb, &mut rng);
    // 30 m of uncertainty: every block is as good as the next.
    let prior_cov = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(900.0, 900.0, 0.05));
    let r = align(
        &a,
        &b,
        &Pose2::new(10.0, -5.0, 0.0),
        &prior_cov,
        &AlignSettings::default(),
    );
    assert!(
        matches!(r, Err(Refusal::Ambiguous { .. })),
        "a repeated grid must not close a loop: {r:?}"
    );
}

#[test]
fn repeated_structure_with_a_tight_prior_closes_at_the_right_place() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let world = grid();
    let a = observe(&world, &Pose2::new(0.0, 0.0, 0.0), &mut rng);
    let fb = Pose2::new(3.0, 2.0, 0.0);
    let b = observe(&world, &fb, &mut rng);
    let prior_cov = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, 0.002));
    let found = align(
        &a,
        &b,
        &Pose2::new(3.8, 1.5, 0.01),
        &prior_cov,
        &AlignSettings::default(),
    )
    .expect("a tight prior leaves one block");
    assert!((found.transform.x - 3.0).abs() < 0.3 && (found.transform.y - 2.0).abs() < 0.3);
}

#[test]
fn a_prior_in_the_wrong_place_finds_nothing() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let world = scattered(40, &mut rng);
    let a = observe(&world, &Pose2::new(0.0, 0.0, 0.0), &mut rng);
    let b = observe(&world, &Pose2::new(5.0, 0.0, 0.0), &mut rng);
    let prior_cov = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(0.25, 0.25, 0.001));
    let r = align(
        &a,
        &b,
        &Pose2::new(25.0, 30.0, 1.0),
        &prior_cov,
        &AlignSettings::default(),
    );
    assert!(r.is_err(), "{r:?}");
}

#[test]
fn the_same_geometry_of_another_material_does_not_match() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let world = scattered(30, &mut rng);
    let a = observe(&world, &Pose2::new(0.0, 0.0, 0.0), &mut rng);
    let other: Vec<_> = world.iter().map(|(p, _)| (*p, [3.0, -2.0])).collect();
    let b = observe(&other, &Pose2::new(2.0, 1.0, 0.1), &mut rng);
    let prior_cov = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(4.0, 4.0, 0.01));
    let r = align(
        &a,
        &b,
        &Pose2::new(2.0, 1.0, 0.1),
        &prior_cov,
        &AlignSettings::default(),
    );
    assert!(matches!(r, Err(Refusal::TooFewCandidates(_))), "{r:?}");
}
