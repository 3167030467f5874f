//! The encoding of a fixed map, pinned: a change to the schema (a field added, removed,
//! retyped or reordered in `model.rs`) changes these bytes and must come with a new
//! format version and an update of `docs/map-format.md`. Files of earlier versions still
//! read (`tests/data/sample-v1.slmap`, `sample-v2.slmap` and `sample-v3.slmap`, the same
//! map written by the version 1, 2 and 3 builds).

mod common;

use slam_map::{Limits, Map, FORMAT_VERSION, MAGIC};

/// Length and CRC32 of the whole file of `common::sample_map_with_paths(2)` in format
/// version 4.
const GOLDEN_LEN: usize = 1236;
const GOLDEN_CRC: u32 = 0xcabc_4691;

#[test]
fn the_encoding_of_a_fixed_map_is_unchanged() {
    let bytes = common::sample_map_with_paths(2).to_bytes().unwrap();
    assert_eq!(&bytes[..8], &MAGIC);
    assert_eq!(&bytes[8..12], &FORMAT_VERSION.to_le_bytes());
    assert_eq!(
        u64::from_le_bytes(bytes[16..24].try_into().unwrap()),
        (bytes.len() - 24) as u64
    );
    println!("len {} crc {:#010x}", bytes.len(), crc32fast::hash(&bytes));
    assert_eq!(FORMAT_VERSION, 4, "a new version needs its own golden file");
    assert_eq!(bytes.len(), GOLDEN_LEN);
    assert_eq!(crc32fast::hash(&bytes), GOLDEN_CRC);
    let map = Map::from_bytes(&bytes, &Limits::default()).unwrap();
    assert_eq!(map, common::sample_map_with_paths(2));
    assert_eq!(map.scan_of(0).map(<[_]>::len), Some(3));
    assert_eq!(map.scan_of(1), None);
    assert_eq!(map.scan_of(2), Some(&[[0.25f32, 80.0]][..]));
    assert_eq!(map.path_of(0).map(<[_]>::len), Some(3));
    assert_eq!(map.path_of(1), Some(&[[0.0f32, 0.0], [99.5, 2.5]][..]));
    assert_eq!(map.path_of(2), None);
}

#[test]
fn a_version_3_file_reads_as_the_same_map_without_paths() {
    let v3 = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/sample-v3.slmap"
    ))
    .unwrap();
    assert_eq!(&v3[8..12], &3u32.to_le_bytes());
    assert_eq!(v3.len(), 1191);
    assert_eq!(
        crc32fast::hash(&v3),
        0x1621_0851,
        "the version 3 golden file"
    );
    let map = Map::from_bytes(&v3, &Limits::default()).unwrap();
    assert_eq!(map, common::sample_map_with_scans(2));
    assert!(map.paths.is_empty());
}

#[test]
fn paths_that_break_the_rules_are_refused() {
    let cases: Vec<(Map, &str)> = vec![
        (
            {
                let mut m = common::sample_map_with_paths(2);
                m.paths[1].submap = 3;
                m
            },
            "path 1 belongs to submap 3",
        ),
        (
            {
                let mut m = common::sample_map_with_paths(2);
                m.paths[1].submap = 0;
                m
            },
            "path 1 belongs to submap 0: the paths' submaps must increase",
        ),
        (
            {
                let mut m = common::sample_map_with_paths(2);
                m.paths[0].points[2][1] = f32::INFINITY;
                m
            },
            "path 0 (submap 0) holds a position that is not finite",
        ),
        (
            {
                let mut m = common::sample_map_with_paths(2);
                m.paths[0].points = vec![[0.0, 0.0]; slam_map::MAX_PATH_POINTS + 1];
                m
            },
            "more than 4096",
        ),
    ];
    for (m, why) in cases {
        let e = m.to_bytes().unwrap_err().to_string();
        assert!(e.contains(why), "{why:?} not in {e:?}");
    }
}

#[test]
fn a_version_2_file_reads_as_the_same_map_without_scans() {
    let v2 = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/sample-v2.slmap"
    ))
    .unwrap();
    assert_eq!(&v2[8..12], &2u32.to_le_bytes());
    assert_eq!(v2.len(), 1154);
    assert_eq!(
        crc32fast::hash(&v2),
        0x8bb6_1dfd,
        "the version 2 golden file"
    );
    let map = Map::from_bytes(&v2, &Limits::default()).unwrap();
    assert_eq!(map, common::sample_map(2));
    assert!(map.scans.is_empty());
}

#[test]
fn scans_that_break_the_rules_are_refused() {
    let cases: Vec<(Map, &str)> = vec![
        (
            {
                let mut m = common::sample_map_with_scans(2);
                m.scans[1].submap = 3;
                m
            },
            "scan 1 belongs to submap 3",
        ),
        (
            {
                let mut m = common::sample_map_with_scans(2);
                m.scans[1].submap = 0;
                m
            },
            "scan 1 belongs to submap 0: the scans' submaps must increase",
        ),
        (
            {
                let mut m = common::sample_map_with_scans(2);
                m.scans[0].points[1][0] = f32::NAN;
                m
            },
            "scan 0 (submap 0) holds a point that is not finite",
        ),
        (
            {
                let mut m = common::sample_map_with_scans(2);
                m.scans[0].points = vec![[0.0, 0.0]; slam_map::MAX_SCAN_POINTS + 1];
                m
            },
            "more than 65536",
        ),
    ];
    for (m, why) in cases {
        let e = m.to_bytes().unwrap_err().to_string();
        assert!(e.contains(why), "{why:?} not in {e:?}");
    }
}

#[test]
fn a_version_1_file_reads_as_the_same_map_of_one_drive() {
    let v1 = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/sample-v1.slmap"
    ))
    .unwrap();
    assert_eq!(&v1[8..12], &1u32.to_le_bytes());
    assert_eq!(v1.len(), 1152);
    assert_eq!(
        crc32fast::hash(&v1),
        0x37a4_762a,
        "the version 1 golden file"
    );
    let map = Map::from_bytes(&v1, &Limits::default()).unwrap();
    assert_eq!(map, common::sample_map(2));
    assert!(map.drive_starts.is_empty() && map.joins.is_empty());
}

#[test]
fn a_map_of_two_drives_round_trips_and_its_graph_has_no_chain_edge_between_them() {
    let m = common::two_drive_map(2);
    let bytes = m.to_bytes().unwrap();
    assert_eq!(Map::from_bytes(&bytes, &Limits::default()).unwrap(), m);
    assert!(m.chained(1) && !m.chained(2) && !m.chained(0));
    assert_eq!((m.drive_of(1), m.drive_of(2)), (0, 1));
    let g = m.pose_graph();
    // 3 submaps and the end: chain 0->1 and 2->3 (none 1->2), the loop, the join.
    assert_eq!(g.nodes().len(), 4);
    let pairs: Vec<(usize, usize, slam_graph::EdgeKind)> =
        g.edges().iter().map(|e| (e.from, e.to, e.kind)).collect();
    use slam_graph::EdgeKind::{Chain, Join, Loop};
    assert_eq!(
        pairs,
        vec![(0, 1, Chain), (2, 3, Chain), (0, 2, Loop), (0, 2, Join)]
    );
}

#[test]
fn drives_and_joins_that_break_the_rules_are_refused() {
    let cases: Vec<(Map, &str)> = vec![
        (
            {
                let mut m = common::two_drive_map(2);
                m.drive_starts = vec![0];
                m
            },
            "drive 1 starts at submap 0",
        ),
        (
            {
                let mut m = common::two_drive_map(2);
                m.drive_starts = vec![3];
                m
            },
            "drive 1 starts at submap 3",
        ),
        (
            {
                let mut m = common::two_drive_map(2);
                m.joins[0].from = 2;
                m.joins[0].to = 1;
                m
            },
            "join 0 joins submaps 2 and 1",
        ),
        (
            {
                let mut m = common::two_drive_map(2);
                m.joins.clear();
                m.loops.clear();
                m
            },
            "drive 1 (from submap 2) has no join or loop closure",
        ),
        (
            {
                let mut m = common::two_drive_map(2);
                m.joins[0].covariance[0] = f64::NAN;
                m
            },
            "join 0: its transform or covariance is not finite",
        ),
    ];
    for (m, why) in cases {
        let e = m.to_bytes().unwrap_err().to_string();
        assert!(e.contains(why), "{why:?} not in {e:?}");
    }
}
