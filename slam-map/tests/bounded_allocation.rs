//! A payload whose collections declare absurd lengths costs no more memory than its bytes.
//! (Its own test binary: the allocation counter sees every thread.)

use slam_map::{FormatError, Limits, Map, MapProfile, FORMAT_VERSION, MAGIC};

#[test]
fn a_collection_declaring_two_to_the_sixty_elements_allocates_little_and_fails() {
    let mut payload = empty_payload();
    // The last six bytes are the submaps', loops', drive starts', joins', scans' and
    // paths' lengths.
    assert_eq!(&payload[payload.len() - 6..], &[0, 0, 0, 0, 0, 0]);
    payload.truncate(payload.len() - 6);
    // 2^60 as a LEB128 varint, then a few bytes of "submap".
    push_two_to_the_sixty(&mut payload);
    fails_allocating_little(payload);
}

#[test]
fn a_scan_declaring_two_to_the_sixty_points_allocates_little_and_fails() {
    let mut payload = empty_payload();
    // One scan, of submap 0, whose points claim 2^60 entries (the scans' and paths'
    // lengths replaced).
    payload.truncate(payload.len() - 2);
    payload.extend_from_slice(&[1, 0]);
    push_two_to_the_sixty(&mut payload);
    fails_allocating_little(payload);
}

#[test]
fn a_path_declaring_two_to_the_sixty_positions_allocates_little_and_fails() {
    let mut payload = empty_payload();
    // No scan; one path, of submap 0, whose positions claim 2^60 entries.
    payload.truncate(payload.len() - 1);
    payload.extend_from_slice(&[1, 0]);
    push_two_to_the_sixty(&mut payload);
    fails_allocating_little(payload);
}

/// The payload of a map with nothing in it.
fn empty_payload() -> Vec<u8> {
    let empty = Map {
        created_unix_s: 0,
        source: String::new(),
        profile: MapProfile::from(&radar_model::profile::CTS350X),
        submaps: Vec::new(),
        loops: Vec::new(),
        drive_starts: Vec::new(),
        joins: Vec::new(),
        scans: Vec::new(),
        paths: Vec::new(),
    };
    postcard::to_allocvec(&empty).unwrap()
}

/// 2^60 as a LEB128 varint (postcard's collection length).
fn push_two_to_the_sixty(payload: &mut Vec<u8>) {
    let mut n: u64 = 1 << 60;
    while n >= 0x80 {
        payload.push((n as u8) | 0x80);
        n >>= 7;
    }
    payload.push(n as u8);
}

/// `payload` and a few more bytes in a whole file: reading it fails as undecodable with
/// less than 4 MiB allocated at the peak.
fn fails_allocating_little(mut payload: Vec<u8>) {
    payload.extend_from_slice(&[0u8; 64]);
    let mut file = MAGIC.to_vec();
    file.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    file.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    file.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    file.extend_from_slice(&payload);
    let mut result = None;
    let info = allocation_counter::measure(|| {
        result = Some(Map::from_bytes(&file, &Limits::default()));
    });
    assert!(
        matches!(result, Some(Err(FormatError::Undecodable(_)))),
        "{result:?}"
    );
    println!("peak bytes allocated: {}", info.bytes_max);
    assert!(info.bytes_max < 4 << 20, "{} bytes", info.bytes_max);
}
