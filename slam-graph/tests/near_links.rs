//! Near links: a chain of submaps along a street whose odometry turned 20 mrad in one
//! submap (a junction, where a rotation's registration pairs few returns) is pulled back
//! straight by registering each submap's scan against the scans two and three submaps
//! before it; without them the turn stays in every later frame.

use std::sync::Arc;

use nalgebra::{Matrix3, Vector3};
use radar_model::geometry::Pose2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slam_filter::FrozenSubmap;
use slam_graph::se2::{inverse, transform_point};
use slam_graph::{GlobalMap, GlobalSettings};

const SUBMAP_M: f64 = 50.0;
const SUBMAPS: usize = 7;

/// A street along x: two building fronts with gaps, set back unevenly, cross walls at
/// irregular spacing and posts, so that a scan pins all three directions.
fn street(rng: &mut ChaCha8Rng) -> Vec<[f64; 2]> {
    let mut pts = Vec::new();
    let mut x = -60.0;
    while x < SUBMAP_M * SUBMAPS as f64 + 60.0 {
        let len = rng.gen_range(8.0..25.0);
        let (south, north) = (rng.gen_range(-16.0..-12.0), rng.gen_range(12.0..16.0));
        let mut t = x;
        while t < x + len {
            pts.push([t, south]);
            pts.push([t, north]);
            t += 1.0;
        }
        // The front's ends run back from the street.
        for d in 0..6 {
            let d = f64::from(d);
            pts.push([x, south - d]);
            pts.push([x + len, north + d]);
        }
        x += len + rng.gen_range(3.0..9.0);
    }
    for _ in 0..250 {
        let x = rng.gen_range(-60.0..SUBMAP_M * SUBMAPS as f64 + 60.0);
        let y = if rng.gen_bool(0.5) {
            rng.gen_range(-11.0..-6.0)
        } else {
            rng.gen_range(6.0..11.0)
        };
        pts.push([x, y]);
    }
    pts
}

/// Submap `k`'s scan: what lies within the radar's reach (80 m) of its stretch of the
/// street, in its (true) frame.
fn scan(world: &[[f64; 2]], frame: &Pose2) -> Vec<[f64; 2]> {
    let inv = inverse(frame);
    world
        .iter()
        .map(|p| transform_point(&inv, *p))
        .filter(|p| p[0] > -80.0 && p[0] < SUBMAP_M + 80.0 && p[1].abs() < 80.0)
        .collect()
}

/// The chain's last frame's heading (rad) once every submap is joined; the odometry turns
/// `turn_rad` wrongly within submap 2.
fn last_heading(settings: GlobalSettings, turn_rad: f64) -> (f64, usize) {
    let (heading, links, _) = drive(settings, turn_rad, 1e-4, 0.0);
    (heading, links)
}

/// As [`last_heading`], with the chain's heading variance per submap `chain_var` (rad^2),
/// submap 4's scan placed `bent_rad` off about its origin (a scan the filter bent), and the
/// links the solve dropped.
fn drive(
    mut settings: GlobalSettings,
    turn_rad: f64,
    chain_var: f64,
    bent_rad: f64,
) -> (f64, usize, u64) {
    // No loop here to find: the place search would only cost time.
    settings.place.enabled = false;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let world = street(&mut rng);
    let mut map = GlobalMap::new(settings);
    for k in 0..SUBMAPS {
        let truth = Pose2::new(SUBMAP_M * k as f64, 0.0, 0.0);
        let end = Pose2::new(SUBMAP_M, 0.0, if k == 2 { turn_rad } else { 0.0 });
        let submap = Arc::new(FrozenSubmap {
            end_pose: end,
            end_cov: Matrix3::from_diagonal(&Vector3::new(0.04, 0.04, chain_var)),
            features: Vec::new(),
            loss_db: 0.0,
            end_s: k as f64,
        });
        let seen_from = if k == 4 {
            Pose2::new(truth.x, truth.y, truth.theta + bent_rad)
        } else {
            truth
        };
        map.add_submap_with_scan(submap, Some(scan(&world, &seen_from)));
    }
    let sol = map.solution(0.0);
    (
        sol.frames[SUBMAPS].theta,
        map.links().len(),
        map.stats().near_dropped,
    )
}

#[test]
fn near_links_pull_a_junctions_wrong_turn_out_of_the_chain() {
    let turn = 0.02;
    let off = GlobalSettings {
        near_links: 0,
        ..GlobalSettings::default()
    };
    let (without, none) = last_heading(off, turn);
    assert_eq!(none, 0);
    assert!(
        (without - turn).abs() < 1e-9,
        "without links the turn stays: {without}"
    );
    let (with, links) = last_heading(GlobalSettings::default(), turn);
    assert!(links >= 4, "near links added: {links}");
    assert!(
        with.abs() < 0.005,
        "with near links the last frame's heading is {with} rad (truth 0, chain {turn})"
    );
}

#[test]
fn a_straight_chain_is_left_straight() {
    let (with, links) = last_heading(GlobalSettings::default(), 0.0);
    assert!(links >= 4, "near links added: {links}");
    assert!(with.abs() < 0.003, "heading {with} rad");
}

#[test]
fn a_link_from_a_bent_scan_is_dropped_after_the_solve() {
    // The chain is sure of its heading (1 mrad a submap) and straight; submap 4's scan is
    // turned 15 mrad, inside the links' 20 mrad search window, so its links verify and
    // agree with the chain's prior but disagree with the chain and the other links once
    // solved: the solve drops them and the chain stays straight.
    let (heading, links, dropped) = drive(GlobalSettings::default(), 0.0, 1e-6, 0.015);
    assert!(dropped >= 1, "links dropped after the solve: {dropped}");
    assert!(links >= 3, "near links kept: {links}");
    assert!(heading.abs() < 0.003, "heading {heading} rad");
}
