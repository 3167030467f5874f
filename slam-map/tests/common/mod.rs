//! A small map with every field written, shared by the tests.

use slam_map::{LoopEdge, Map, MapFeature, MapProfile, MapSubmap, PlaceDescriptor, Pose};

/// The CTS350-X's geometry under its profile's name.
pub fn profile() -> MapProfile {
    MapProfile::from(&radar_model::profile::CTS350X)
}

/// Three submaps of `per_submap` features each, a loop closure from the last to the first,
/// a descriptor on the second.
pub fn sample_map(per_submap: usize) -> Map {
    let submaps = (0..3u32)
        .map(|k| {
            let kf = f64::from(k);
            MapSubmap {
                frame: Pose {
                    x: 100.0 * kf,
                    y: -3.0 * kf,
                    theta: 0.1 * kf,
                },
                frame_cov: if k == 0 {
                    [0.0; 6]
                } else {
                    [0.04 * kf, 0.001, 0.0002, 0.03 * kf, -0.0001, 1e-4 * kf]
                },
                end_pose: Pose {
                    x: 99.5,
                    y: 2.5,
                    theta: 0.1,
                },
                end_cov: [0.04, 0.001, 0.0002, 0.03, -0.0001, 1e-4],
                end_s: 10.0 * (kf + 1.0),
                loss_db: 3.25,
                features: (0..per_submap)
                    .map(|i| {
                        let fi = i as f64;
                        MapFeature {
                            id: u64::from(k) * 1000 + i as u64,
                            xy: [fi * 1.5 - 40.0, 20.0 - fi * 0.75],
                            xy_cov: [0.01 + fi * 1e-4, -0.002, 0.02],
                            uv: [-1.25 + 0.01 * fi, -0.5],
                            uv_cov: [0.3, 0.05, 0.4],
                            hits: 3 + i as u64,
                        }
                    })
                    .collect(),
                descriptor: (k == 1).then(|| PlaceDescriptor {
                    kind: "ring-key".into(),
                    version: 2,
                    values: vec![0.0, 0.5, 1.25, -3.0],
                }),
            }
        })
        .collect();
    Map {
        created_unix_s: 1_795_000_000,
        source: "slam-map tests".into(),
        profile: profile(),
        submaps,
        loops: vec![LoopEdge {
            from: 0,
            to: 2,
            transform: Pose {
                x: 199.0,
                y: -6.0,
                theta: 0.2,
            },
            covariance: [0.01, 0.0, 0.0, 0.01, 0.0, 1e-5],
            matches: 14,
        }],
        drive_starts: Vec::new(),
        joins: Vec::new(),
        scans: Vec::new(),
        paths: Vec::new(),
    }
}

/// [`sample_map`] with scans of its first and third submaps (format version 3).
#[allow(dead_code)] // not every test binary uses it
pub fn sample_map_with_scans(per_submap: usize) -> Map {
    let mut m = sample_map(per_submap);
    m.scans = vec![
        slam_map::MapScan {
            submap: 0,
            points: vec![[1.5, -2.25], [30.0, 4.0], [-12.125, 0.5]],
        },
        slam_map::MapScan {
            submap: 2,
            points: vec![[0.25, 80.0]],
        },
    ];
    m
}

/// [`sample_map_with_scans`] with the paths of its first two submaps (format version 4).
#[allow(dead_code)] // not every test binary uses it
pub fn sample_map_with_paths(per_submap: usize) -> Map {
    let mut m = sample_map_with_scans(per_submap);
    m.paths = vec![
        slam_map::MapPath {
            submap: 0,
            points: vec![[0.0, 0.0], [2.0, 0.125], [4.5, -0.25]],
        },
        slam_map::MapPath {
            submap: 1,
            points: vec![[0.0, 0.0], [99.5, 2.5]],
        },
    ];
    m
}

/// [`sample_map`] with a second drive: its third submap starts a drive joined to the first
/// submap (the fix of extend mode), with no chain edge from the second.
#[allow(dead_code)] // not every test binary uses it
pub fn two_drive_map(per_submap: usize) -> Map {
    let mut m = sample_map(per_submap);
    m.drive_starts = vec![2];
    m.joins = vec![LoopEdge {
        from: 0,
        to: 2,
        transform: Pose {
            x: 200.0,
            y: -6.0,
            theta: 0.2,
        },
        covariance: [0.02, 0.001, 0.0, 0.03, 0.0, 2e-5],
        matches: 9,
    }];
    m
}
