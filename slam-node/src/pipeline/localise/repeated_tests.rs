//! The search on a map that holds one place twice: never a fix there.
//!
//! A street's landmarks (a fixed pseudo-random pattern) are mapped twice, 1 km apart: once
//! cleanly, once as a mapping run that drifted would leave them (each landmark half a metre
//! off, with the tight covariance the run believed, and some clutter mapped there only, so
//! the two copies' descriptors differ). The verifier refuses the second copy (its landmarks
//! are not jointly compatible with the local map's), but the local map fits it as well as
//! the first: the vehicle may be at either, and the search must wait. Before the rival test
//! counted what each place explains, this fixed on the clean copy at the second attempt.

use nalgebra::Matrix2;
use radar_model::geometry::Pose2;
use slam_filter::{FeatureId, FrozenSubmap, SubmapFeature};
use slam_graph::se2::{inverse, transform_point};

use super::known::{MapFeatures, WorldFeature};
use super::search::{Attempt, PlaceSearcher};

/// A deterministic pseudo-random sequence in [0, 1) (the scan search's tests use it too).
pub(crate) struct Lcg(pub(crate) u64);

impl Lcg {
    pub(crate) fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A street's landmarks around the origin: two rows of kerbside objects either side of a
/// 200 m street, irregularly spaced, and some buildings' corners further back.
fn street(rng: &mut Lcg) -> Vec<[f64; 2]> {
    let mut out = Vec::new();
    for side in [-1.0, 1.0] {
        let mut x = -100.0;
        while x < 100.0 {
            out.push([x, side * (7.0 + 2.0 * rng.next())]);
            x += 4.0 + 8.0 * rng.next();
        }
        for _ in 0..25 {
            out.push([
                200.0 * rng.next() - 100.0,
                side * (15.0 + 40.0 * rng.next()),
            ]);
        }
    }
    out
}

fn world(submap: usize, xy: [f64; 2]) -> WorldFeature {
    WorldFeature {
        submap,
        xy,
        xy_cov: Matrix2::identity() * 0.01,
        uv: [0.5, -0.5],
        uv_cov: Matrix2::identity() * 0.2,
        hits: 10,
    }
}

fn map_of(pattern: &[[f64; 2]], rng: &mut Lcg, copy_at: f64) -> MapFeatures {
    let mut features: Vec<WorldFeature> = pattern.iter().map(|p| world(0, *p)).collect();
    // The second copy: each landmark up to half a metre off (the run believed 0.1 m), and
    // clutter mapped there only.
    for p in pattern {
        let off = [rng.next() - 0.5, rng.next() - 0.5];
        features.push(world(1, [p[0] + copy_at + off[0], p[1] + off[1]]));
    }
    for _ in 0..40 {
        let xy = [
            copy_at + 200.0 * rng.next() - 100.0,
            80.0 * rng.next() - 40.0,
        ];
        features.push(world(1, xy));
    }
    let zero = nalgebra::Matrix3::zeros();
    MapFeatures {
        features,
        frames: vec![
            (Pose2::new(-100.0, 0.0, 0.0), zero),
            (Pose2::new(copy_at - 100.0, 0.0, 0.0), zero),
        ],
        ends: vec![
            Pose2::new(100.0, 0.0, 0.0),
            Pose2::new(copy_at + 100.0, 0.0, 0.0),
        ],
        end_local: vec![
            (Pose2::new(200.0, 0.0, 0.0), zero),
            (Pose2::new(200.0, 0.0, 0.0), zero),
        ],
        paths: Vec::new(),
    }
}

/// The local map: the street's landmarks as a filter in a frame of its own would hold
/// them, the vehicle in the street's middle.
fn local_map(pattern: &[[f64; 2]], frame_in_map: &Pose2) -> FrozenSubmap {
    let to_local = inverse(frame_in_map);
    FrozenSubmap {
        end_pose: Pose2::new(0.0, 0.0, 0.0),
        end_cov: nalgebra::Matrix3::zeros(),
        features: pattern
            .iter()
            .filter(|p| p[0].abs() <= 60.0)
            .enumerate()
            .map(|(k, p)| SubmapFeature {
                id: FeatureId(k as u64),
                xy: transform_point(&to_local, *p),
                xy_cov: Matrix2::identity() * 0.01,
                uv: [0.5, -0.5],
                uv_cov: Matrix2::identity() * 0.2,
                hits: 10,
            })
            .collect(),
        loss_db: 0.0,
        end_s: 0.0,
    }
}

#[test]
fn a_place_the_map_holds_twice_is_never_fixed_on() {
    let mut rng = Lcg(7);
    let pattern = street(&mut rng);
    let map = map_of(&pattern, &mut rng, 1000.0);
    let mut searcher = PlaceSearcher::new(&map, 3);
    // The local frame somewhere in the map's; the vehicle at the street's middle, heading
    // along it.
    let frame = Pose2::new(-40.0, 12.0, 0.5);
    let local = local_map(&pattern, &frame);
    let vehicle = slam_graph::se2::compose(&inverse(&frame), &Pose2::new(0.0, 0.0, 0.0));
    for k in 0..4 {
        let attempt = searcher.attempt(&map, &local, &vehicle);
        assert!(
            !matches!(attempt, Attempt::Fix(_)),
            "attempt {k}: a fix on a place the map holds twice: {attempt:?}"
        );
    }
}

#[test]
fn the_same_street_held_once_is_fixed_on() {
    // The control: without the second copy the same local map fixes, at the right place.
    let mut rng = Lcg(7);
    let pattern = street(&mut rng);
    let mut map = map_of(&pattern, &mut rng, 1000.0);
    map.features.retain(|f| f.submap == 0);
    map.frames.truncate(1);
    map.ends.truncate(1);
    map.end_local.truncate(1);
    let mut searcher = PlaceSearcher::new(&map, 3);
    let frame = Pose2::new(-40.0, 12.0, 0.5);
    let local = local_map(&pattern, &frame);
    let vehicle = slam_graph::se2::compose(&inverse(&frame), &Pose2::new(0.0, 0.0, 0.0));
    let mut fix = None;
    for _ in 0..4 {
        if let Attempt::Fix(v) = searcher.attempt(&map, &local, &vehicle) {
            fix = Some(v);
            break;
        }
    }
    let v = fix.expect("no fix on a street the map holds once");
    assert!(
        (v.transform.x - frame.x).hypot(v.transform.y - frame.y) < 0.3,
        "{v:?}"
    );
    assert!(radar_model::geometry::wrap_angle(v.transform.theta - frame.theta).abs() < 0.01);
}
