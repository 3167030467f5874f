//! The encoding of a fixed map, pinned: a change to the schema (a field added, removed,
//! retyped or reordered in `model.rs`) changes these bytes and must come with a new
//! format version and an update of `docs/map-format.md`.

mod common;

use slam_map::{Limits, Map, FORMAT_VERSION, MAGIC};

/// Length and CRC32 of the whole file of `common::sample_map(2)` in format version 1.
const GOLDEN_LEN: usize = 1152;
const GOLDEN_CRC: u32 = 0x37a4_762a;

#[test]
fn the_encoding_of_a_fixed_map_is_unchanged() {
    let bytes = common::sample_map(2).to_bytes().unwrap();
    assert_eq!(&bytes[..8], &MAGIC);
    assert_eq!(&bytes[8..12], &FORMAT_VERSION.to_le_bytes());
    assert_eq!(
        u64::from_le_bytes(bytes[16..24].try_into().unwrap()),
        (bytes.len() - 24) as u64
    );
    println!("len {} crc {:#010x}", bytes.len(), crc32fast::hash(&bytes));
    assert_eq!(FORMAT_VERSION, 1, "a new version needs its own golden file");
    assert_eq!(bytes.len(), GOLDEN_LEN);
    assert_eq!(crc32fast::hash(&bytes), GOLDEN_CRC);
    assert_eq!(
        Map::from_bytes(&bytes, &Limits::default()).unwrap(),
        common::sample_map(2)
    );
}
