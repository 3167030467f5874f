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
    let map = older_golden("sample-v3.slmap", 3, 1191, 0x1621_0851);
    assert_eq!(map, common::sample_map_with_scans(2));
    assert!(map.paths.is_empty());
}

#[test]
fn paths_that_break_the_rules_are_refused() {
    let cases: Vec<(Map, &str)> = vec![
        (
            edited(common::sample_map_with_paths, |m| m.paths[1].submap = 3),
            "path 1 belongs to submap 3",
        ),
        (
            edited(common::sample_map_with_paths, |m| m.paths[1].submap = 0),
            "path 1 belongs to submap 0: the paths' submaps must increase",
        ),
        (
            edited(common::sample_map_with_paths, |m| {
                m.paths[0].points[2][1] = f32::INFINITY
            }),
            "path 0 (submap 0) holds a position that is not finite",
        ),
        (
            edited(common::sample_map_with_paths, |m| {
                m.paths[0].points = vec![[0.0, 0.0]; slam_map::MAX_PATH_POINTS + 1]
            }),
            "more than 4096",
        ),
    ];
    assert_refused(cases);
}

#[test]
fn a_version_2_file_reads_as_the_same_map_without_scans() {
    let map = older_golden("sample-v2.slmap", 2, 1154, 0x8bb6_1dfd);
    assert_eq!(map, common::sample_map(2));
    assert!(map.scans.is_empty());
}

#[test]
fn scans_that_break_the_rules_are_refused() {
    let cases: Vec<(Map, &str)> = vec![
        (
            edited(common::sample_map_with_scans, |m| m.scans[1].submap = 3),
            "scan 1 belongs to submap 3",
        ),
        (
            edited(common::sample_map_with_scans, |m| m.scans[1].submap = 0),
            "scan 1 belongs to submap 0: the scans' submaps must increase",
        ),
        (
            edited(common::sample_map_with_scans, |m| {
                m.scans[0].points[1][0] = f32::NAN
            }),
            "scan 0 (submap 0) holds a point that is not finite",
        ),
        (
            edited(common::sample_map_with_scans, |m| {
                m.scans[0].points = vec![[0.0, 0.0]; slam_map::MAX_SCAN_POINTS + 1]
            }),
            "more than 65536",
        ),
    ];
    assert_refused(cases);
}

#[test]
fn a_version_1_file_reads_as_the_same_map_of_one_drive() {
    let map = older_golden("sample-v1.slmap", 1, 1152, 0x37a4_762a);
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
    assert_refused(cases);
}

/// An older version's golden file in tests/data: its version field, length and CRC as
/// pinned, read as a map.
fn older_golden(name: &str, version: u32, len: usize, crc: u32) -> Map {
    let bytes = std::fs::read(format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"))).unwrap();
    assert_eq!(&bytes[8..12], &version.to_le_bytes());
    assert_eq!(bytes.len(), len);
    assert_eq!(
        crc32fast::hash(&bytes),
        crc,
        "the version {version} golden file"
    );
    Map::from_bytes(&bytes, &Limits::default()).unwrap()
}

/// `base(2)` changed by `edit`.
fn edited(base: fn(usize) -> Map, edit: impl FnOnce(&mut Map)) -> Map {
    let mut m = base(2);
    edit(&mut m);
    m
}

/// Each map is refused on writing, with its reason in the error.
fn assert_refused(cases: Vec<(Map, &str)>) {
    for (m, why) in cases {
        let e = m.to_bytes().unwrap_err().to_string();
        assert!(e.contains(why), "{why:?} not in {e:?}");
    }
}
