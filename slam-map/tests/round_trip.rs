//! A map saved and loaded gives the same values; the global layer's map saved and loaded
//! gives back its submaps and a graph that solves to the saved frames.

mod common;

use std::sync::Arc;

use nalgebra::{Matrix2, Matrix3, Vector3};
use proptest::prelude::*;
use radar_model::geometry::Pose2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slam_filter::{FeatureId, FrozenSubmap, SubmapFeature};
use slam_graph::se2::{between, inverse, transform_point};
use slam_graph::{GlobalMap, GlobalSettings, SolveSettings};
use slam_map::{
    Limits, LoopEdge, Map, MapFeature, MapMeta, MapProfile, MapSubmap, PlaceDescriptor, Pose,
};

#[test]
fn a_small_map_saved_and_loaded_gives_the_same_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("map.slmap");
    let map = common::sample_map(25);
    let bytes = map.save(&path).unwrap();
    assert_eq!(bytes, std::fs::metadata(&path).unwrap().len());
    let back = Map::load(&path).unwrap();
    assert_eq!(back, map);
    assert_eq!(back.feature_count(), 75);
    // Saving again over it: same bytes (the encoding is deterministic).
    let first = std::fs::read(&path).unwrap();
    back.save(&path).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), first);
}

#[test]
fn the_same_radar_passes_the_profile_check_and_another_is_named() {
    let map = common::sample_map(1);
    map.check_profile(&radar_model::profile::CTS350X).unwrap();
    // The simulator's CTS350-X: same geometry, another name (a warning, not a refusal).
    let e = map
        .check_profile(&radar_model::profile::SIM_CTS350X)
        .unwrap_err();
    assert!(!e.geometry_differs(), "{e}");
    assert_eq!(e.differences.len(), 1, "{e}");
    let e = map
        .check_profile(&radar_model::profile::PAPER_2006)
        .unwrap_err();
    assert!(e.geometry_differs());
    let text = e.to_string();
    for part in [
        "\"cts350x\"",
        "\"paper-2006\"",
        "azimuths: 400 vs 200",
        "range bins: 3768 vs 800",
        "bin size: 0.0438 m vs 0.25 m",
    ] {
        assert!(text.contains(part), "{part} missing from {text}");
    }
}

/// A square loop of 25 m submaps over scattered posts, odometry heading biased so that the
/// loop closure has something to correct (as slam-graph's own test).
fn square_drive() -> Vec<FrozenSubmap> {
    let mut frames = Vec::new();
    for side in 0..4 {
        for step in 0..4 {
            let d = 25.0 * f64::from(step);
            let (x, y) = match side {
                0 => (d, 0.0),
                1 => (100.0, d),
                2 => (100.0 - d, 100.0),
                _ => (0.0, 100.0 - d),
            };
            frames.push(Pose2::new(
                x,
                y,
                f64::from(side) * std::f64::consts::FRAC_PI_2,
            ));
        }
    }
    frames.push(Pose2::new(0.0, 0.0, 0.0));
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let posts: Vec<[f64; 2]> = (0..400)
        .map(|_| [rng.gen_range(-40.0..140.0), rng.gen_range(-40.0..140.0)])
        .collect();
    (0..frames.len() - 1)
        .map(|k| {
            let inv = inverse(&frames[k]);
            let features = posts
                .iter()
                .enumerate()
                .filter(|(_, p)| (p[0] - frames[k].x).hypot(p[1] - frames[k].y) < 45.0)
                .map(|(i, p)| {
                    let q = transform_point(&inv, *p);
                    SubmapFeature {
                        id: FeatureId(i as u64),
                        xy: [
                            q[0] + rng.gen_range(-0.1..0.1),
                            q[1] + rng.gen_range(-0.1..0.1),
                        ],
                        xy_cov: Matrix2::new(0.01, 0.002, 0.002, 0.012),
                        uv: [rng.gen_range(-2.0..0.0), rng.gen_range(-2.0..0.0)],
                        uv_cov: Matrix2::from_diagonal_element(0.1),
                        hits: 10,
                    }
                })
                .collect();
            let mut end = between(&frames[k], &frames[k + 1]);
            end.theta += 0.006;
            FrozenSubmap {
                end_pose: end,
                end_cov: Matrix3::from_diagonal(&Vector3::new(0.04, 0.04, 1e-4)),
                features,
                loss_db: 1.5,
                end_s: k as f64 * 6.25,
            }
        })
        .collect()
}

#[test]
fn the_global_layers_map_comes_back_as_its_submaps_and_a_graph_that_solves_to_its_frames() {
    let drive = square_drive();
    let mut global = GlobalMap::new(GlobalSettings::default());
    for s in &drive {
        global.add_submap(Arc::new(s.clone()));
    }
    assert!(!global.loops().is_empty(), "the square closes its loop");
    let meta = MapMeta {
        profile: MapProfile::from(&radar_model::profile::CTS350X),
        source: "round_trip test".into(),
        created_unix_s: 1,
    };
    let (map, report) = Map::from_global(meta, &global).unwrap();
    assert_eq!(report, slam_map::BuildReport::default());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("square.slmap");
    map.save(&path).unwrap();
    let back = Map::load(&path).unwrap();
    assert_eq!(back, map);
    assert_eq!(back.submaps.len(), drive.len());
    assert_eq!(back.loops.len(), global.loops().len());
    // The submaps as the filter froze them, value for value.
    assert_eq!(back.frozen_submaps(), drive);
    // The frames and their covariances are the layer's solution.
    let sol = global.solution(0.0);
    for (s, (f, c)) in back
        .submaps
        .iter()
        .zip(sol.frames.iter().zip(&sol.covariances))
    {
        assert_eq!(Pose2::from(s.frame), *f);
        let d = slam_map::model::unpack3(&s.frame_cov) - c;
        assert!(d.abs().max() < 1e-15, "{d}");
    }
    // The rebuilt graph has the layer's nodes and edges and solves to the same frames.
    let g = back.pose_graph();
    assert_eq!(g.nodes().len(), global.graph().nodes().len());
    assert_eq!(g.edges().len(), global.graph().edges().len());
    let solved = g.solve(&SolveSettings::default()).unwrap();
    for (a, b) in solved.nodes.iter().zip(global.graph().nodes()) {
        assert!(
            (a.x - b.x).abs() < 1e-6 && (a.y - b.y).abs() < 1e-6,
            "{a:?} {b:?}"
        );
        assert!((a.theta - b.theta).abs() < 1e-8);
    }
}

#[test]
fn features_that_are_not_finite_are_left_out_and_counted() {
    let mut drive = square_drive();
    drive[3].features[0].xy[0] = f64::NAN;
    let frames: Vec<(&FrozenSubmap, Pose2, Matrix3<f64>)> = drive
        .iter()
        .map(|s| (s, Pose2::new(0.0, 0.0, 0.0), Matrix3::zeros()))
        .collect();
    let meta = MapMeta {
        profile: MapProfile::from(&radar_model::profile::CTS350X),
        source: String::new(),
        created_unix_s: 0,
    };
    let (map, report) = Map::from_parts(meta, frames, &[]).unwrap();
    assert_eq!(report.dropped_features, 1);
    assert_eq!(map.submaps[3].features.len(), drive[3].features.len() - 1);
    map.to_bytes().unwrap();
}

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e6..1e6f64,
        Just(0.0),
        Just(-0.0),
        Just(1e-300),
        Just(f64::MAX)
    ]
}

fn pose() -> impl Strategy<Value = Pose> {
    (finite(), finite(), -4.0..4.0f64).prop_map(|(x, y, theta)| Pose { x, y, theta })
}

fn feature() -> impl Strategy<Value = MapFeature> {
    (
        any::<u64>(),
        [finite(), finite()],
        [finite(), finite(), finite()],
        [finite(), finite()],
        [finite(), finite(), finite()],
        any::<u64>(),
    )
        .prop_map(|(id, xy, xy_cov, uv, uv_cov, hits)| MapFeature {
            id,
            xy,
            xy_cov,
            uv,
            uv_cov,
            hits,
        })
}

fn descriptor() -> impl Strategy<Value = Option<PlaceDescriptor>> {
    proptest::option::of(
        (
            "[a-z-]{1,12}",
            any::<u32>(),
            proptest::collection::vec(-1e3..1e3f32, 0..50),
        )
            .prop_map(|(kind, version, values)| PlaceDescriptor {
                kind,
                version,
                values,
            }),
    )
}

fn submap() -> impl Strategy<Value = MapSubmap> {
    (
        pose(),
        proptest::array::uniform6(finite()),
        pose(),
        proptest::array::uniform6(finite()),
        finite(),
        finite(),
        proptest::collection::vec(feature(), 0..8),
        descriptor(),
    )
        .prop_map(
            |(frame, frame_cov, end_pose, end_cov, end_s, loss_db, features, descriptor)| {
                MapSubmap {
                    frame,
                    frame_cov,
                    end_pose,
                    end_cov,
                    end_s,
                    loss_db,
                    features,
                    descriptor,
                }
            },
        )
}

fn map() -> impl Strategy<Value = Map> {
    (
        any::<u64>(),
        ".{0,40}",
        "[a-z0-9-]{1,20}",
        1..=u16::MAX,
        1..=u16::MAX,
        1..=u16::MAX,
        1e-4..10.0f64,
        proptest::collection::vec(submap(), 2..6),
        proptest::collection::vec(
            (pose(), proptest::array::uniform6(finite()), any::<u32>()),
            0..4,
        ),
        proptest::collection::vec([-1e4f32..1e4, -1e4f32..1e4], 0..12),
    )
        .prop_map(
            |(
                created,
                source,
                name,
                azimuths,
                encoder_size,
                range_bins,
                bin,
                submaps,
                loops,
                path,
            )| {
                let n = submaps.len() as u32;
                let loops = loops
                    .into_iter()
                    .enumerate()
                    .map(|(i, (transform, covariance, matches))| LoopEdge {
                        from: i as u32 % (n - 1),
                        to: n - 1,
                        transform,
                        covariance,
                        matches,
                    })
                    .collect();
                Map {
                    created_unix_s: created,
                    source,
                    profile: MapProfile {
                        name,
                        azimuths,
                        encoder_size,
                        range_bins,
                        bin_size_m: bin,
                    },
                    submaps,
                    loops,
                    drive_starts: Vec::new(),
                    joins: Vec::new(),
                    scans: Vec::new(),
                    // The last submap's path, when drawn non-empty (format version 4).
                    paths: (!path.is_empty())
                        .then(|| slam_map::MapPath {
                            submap: n - 1,
                            points: path,
                        })
                        .into_iter()
                        .collect(),
                }
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn any_valid_map_round_trips_bit_for_bit(map in map()) {
        let bytes = map.to_bytes().unwrap();
        let back = Map::from_bytes(&bytes, &Limits::default()).unwrap();
        // Bit for bit: -0.0 stays -0.0.
        prop_assert_eq!(postcard::to_allocvec(&back).unwrap(), postcard::to_allocvec(&map).unwrap());
        prop_assert_eq!(back, map);
    }

    #[test]
    fn no_byte_string_makes_the_reader_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let _ = Map::from_bytes(&bytes, &Limits::default());
        let mut framed = slam_map::MAGIC.to_vec();
        framed.extend_from_slice(&slam_map::FORMAT_VERSION.to_le_bytes());
        framed.extend_from_slice(&crc32fast::hash(&bytes).to_le_bytes());
        framed.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        framed.extend_from_slice(&bytes);
        let _ = Map::from_bytes(&framed, &Limits::default());
    }
}

#[test]
fn a_map_ending_in_an_empty_submap_with_no_uncertainty_still_gives_a_graph_that_solves() {
    // As a run saves it: the last submap just started, its vehicle at its origin with zero
    // covariance (its chain edge is taken as unknown, as the global layer takes it).
    let drive = square_drive();
    let mut global = GlobalMap::new(GlobalSettings::default());
    for s in &drive {
        global.add_submap(Arc::new(s.clone()));
    }
    let meta = MapMeta {
        profile: MapProfile::from(&radar_model::profile::CTS350X),
        source: String::new(),
        created_unix_s: 0,
    };
    let (mut map, _) = Map::from_global(meta, &global).unwrap();
    let last = *global.graph().nodes().last().unwrap();
    map.submaps.push(MapSubmap {
        frame: last.into(),
        frame_cov: [0.1, 0.0, 0.0, 0.1, 0.0, 1e-3],
        end_pose: Pose {
            x: 0.0,
            y: 0.0,
            theta: 0.0,
        },
        end_cov: [0.0; 6],
        end_s: 99.0,
        loss_db: 0.0,
        features: Vec::new(),
        descriptor: None,
    });
    let back = Map::from_bytes(&map.to_bytes().unwrap(), &Limits::default()).unwrap();
    let sol = back.pose_graph().solve(&SolveSettings::default()).unwrap();
    for (s, n) in back.submaps.iter().zip(&sol.nodes) {
        assert!(
            (s.frame.x - n.x).hypot(s.frame.y - n.y) < 1e-6,
            "{s:?} {n:?}"
        );
    }
}
