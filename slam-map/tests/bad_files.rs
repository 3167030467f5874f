//! Every way a map file can be wrong gives its own error naming the file and the reason,
//! before anything is decoded that the checks have not vouched for.

mod common;

use std::path::{Path, PathBuf};

use slam_map::{FormatError, Limits, LoadError, Map, FORMAT_VERSION, HEADER_LEN, MAGIC};

fn good_bytes() -> Vec<u8> {
    common::sample_map(20).to_bytes().unwrap()
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// A header around `payload` (with its true CRC and length).
fn framed(payload: &[u8]) -> Vec<u8> {
    let mut out = MAGIC.to_vec();
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(payload).to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(payload);
    out
}

fn load_err(path: &Path) -> LoadError {
    let e = Map::load(path).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains(&path.display().to_string()),
        "the error names the file: {text}"
    );
    assert_eq!(e.path, path);
    e
}

#[test]
fn a_missing_file_is_named_as_missing() {
    let dir = tempfile::tempdir().unwrap();
    let e = load_err(&dir.path().join("nowhere.slmap"));
    assert!(matches!(e.reason, FormatError::Missing), "{e}");
    assert!(e.to_string().contains("does not exist"));
}

#[test]
fn a_folder_and_a_fifo_are_refused_without_reading() {
    let dir = tempfile::tempdir().unwrap();
    let e = load_err(dir.path());
    assert!(matches!(e.reason, FormatError::NotAFile), "{e}");
    let fifo = dir.path().join("pipe.slmap");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .map(|s| s.success())
        .unwrap_or(false);
    if !made {
        eprintln!("skipped the FIFO case: mkfifo is not available");
        return;
    }
    // Opening a FIFO with no writer would block: the check comes first.
    let e = load_err(&fifo);
    assert!(matches!(e.reason, FormatError::NotAFile), "{e}");
}

#[test]
fn an_empty_file_is_named_as_empty() {
    let dir = tempfile::tempdir().unwrap();
    let e = load_err(&write(dir.path(), "empty.slmap", &[]));
    assert!(matches!(e.reason, FormatError::Empty), "{e}");
}

#[test]
fn a_file_cut_anywhere_is_truncated_with_the_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = good_bytes();
    let whole = bytes.len() as u64;
    for cut in [
        3,
        8,
        10,
        16,
        HEADER_LEN - 1,
        HEADER_LEN,
        bytes.len() / 2,
        bytes.len() - 1,
    ] {
        let e = load_err(&write(dir.path(), "cut.slmap", &bytes[..cut]));
        match e.reason {
            FormatError::Truncated { expected, found } => {
                assert_eq!(found, cut as u64);
                let want = if cut < HEADER_LEN {
                    HEADER_LEN as u64
                } else {
                    whole
                };
                assert_eq!(expected, want, "cut at {cut}");
            }
            other => panic!("cut at {cut}: {other}"),
        }
        // The same from a reader.
        assert!(matches!(
            Map::from_bytes(&bytes[..cut], &Limits::default()),
            Err(FormatError::Truncated { .. })
        ));
    }
}

#[test]
fn a_file_that_is_not_a_map_has_bad_magic() {
    let dir = tempfile::tempdir().unwrap();
    let e = load_err(&write(dir.path(), "map.csv", b"id,x_m,y_m\n1,2.0,3.0\n"));
    match &e.reason {
        FormatError::BadMagic { found } => assert_eq!(found, b"id,x_m,y"),
        other => panic!("{other}"),
    }
    // Two bytes that are not the magic's first two: bad magic, not truncated.
    let e = load_err(&write(dir.path(), "short", b"PK"));
    assert!(matches!(e.reason, FormatError::BadMagic { .. }), "{e}");
}

#[test]
fn a_future_version_says_which_version_the_file_is_and_which_this_build_reads() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = good_bytes();
    bytes[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    // A newer build may have changed the rest of the header and the payload: only the
    // magic and the version are read.
    bytes.truncate(12);
    let e = load_err(&write(dir.path(), "future.slmap", &bytes));
    match e.reason {
        FormatError::FutureVersion { file, supported } => {
            assert_eq!((file, supported), (FORMAT_VERSION + 1, FORMAT_VERSION))
        }
        ref other => panic!("{other}"),
    }
    let text = e.to_string();
    assert!(
        text.contains(&format!("format version {}", FORMAT_VERSION + 1)),
        "{text}"
    );
    assert!(
        text.contains(&format!("reads version {FORMAT_VERSION}")),
        "{text}"
    );
    let mut zero = good_bytes();
    zero[8..12].copy_from_slice(&0u32.to_le_bytes());
    let e = load_err(&write(dir.path(), "zero.slmap", &zero));
    assert!(matches!(e.reason, FormatError::BadVersion(0)), "{e}");
}

#[test]
fn a_flipped_bit_anywhere_in_the_payload_is_corrupt() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = good_bytes();
    for at in [
        HEADER_LEN,
        HEADER_LEN + 17,
        bytes.len() / 2,
        bytes.len() - 1,
    ] {
        let mut b = bytes.clone();
        b[at] ^= 0x10;
        let e = load_err(&write(dir.path(), "corrupt.slmap", &b));
        assert!(
            matches!(e.reason, FormatError::Corrupt { stored, computed } if stored != computed),
            "byte {at}: {e}"
        );
    }
    // A wrong CRC in the header is the same error.
    let mut b = bytes.clone();
    b[12] ^= 1;
    assert!(matches!(
        load_err(&write(dir.path(), "crc.slmap", &b)).reason,
        FormatError::Corrupt { .. }
    ));
}

#[test]
fn a_payload_with_a_good_checksum_that_does_not_decode_is_undecodable() {
    let dir = tempfile::tempdir().unwrap();
    // A varint that never ends.
    let e = load_err(&write(dir.path(), "garbage.slmap", &framed(&[0xff; 40])));
    assert!(matches!(e.reason, FormatError::Undecodable(_)), "{e}");
    // A map followed by bytes inside the payload.
    let mut payload = postcard::to_allocvec(&common::sample_map(2)).unwrap();
    payload.extend_from_slice(&[0, 0, 0]);
    let e = load_err(&write(dir.path(), "extra.slmap", &framed(&payload)));
    assert!(matches!(e.reason, FormatError::Invalid(_)), "{e}");
}

#[test]
fn a_map_that_breaks_the_format_rules_is_refused_on_load_and_on_save() {
    let dir = tempfile::tempdir().unwrap();
    let mut map = common::sample_map(3);
    map.loops[0].to = 7;
    let e = load_err(&write(
        dir.path(),
        "loop.slmap",
        &framed(&postcard::to_allocvec(&map).unwrap()),
    ));
    match &e.reason {
        FormatError::Invalid(why) => assert!(why.contains("joins submaps 0 and 7 of 3"), "{why}"),
        other => panic!("{other}"),
    }
    let path = dir.path().join("refused.slmap");
    let err = map.save(&path).unwrap_err();
    assert!(err.to_string().contains("joins submaps 0 and 7"), "{err}");
    assert!(!path.exists());
    let mut map = common::sample_map(3);
    map.submaps[1].features[2].xy_cov[1] = f64::NAN;
    let e = load_err(&write(
        dir.path(),
        "nan.slmap",
        &framed(&postcard::to_allocvec(&map).unwrap()),
    ));
    match &e.reason {
        FormatError::Invalid(why) => assert!(why.contains("submap 1, feature 2"), "{why}"),
        other => panic!("{other}"),
    }
}

#[test]
fn a_declared_length_past_the_limit_or_the_file_is_refused_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = good_bytes();
    let mut huge = bytes.clone();
    huge[16..24].copy_from_slice(&u64::MAX.to_le_bytes());
    let e = load_err(&write(dir.path(), "huge.slmap", &huge));
    assert!(
        matches!(
            e.reason,
            FormatError::TooLarge {
                declared: u64::MAX,
                ..
            }
        ),
        "{e}"
    );
    // Within the limit but longer than the file: truncated (from a reader as well).
    let mut long = bytes.clone();
    long[16..24].copy_from_slice(&(1u64 << 29).to_le_bytes());
    let e = load_err(&write(dir.path(), "long.slmap", &long));
    assert!(matches!(e.reason, FormatError::Truncated { .. }), "{e}");
    assert!(matches!(
        Map::read_from(&long[..], &Limits::default()),
        Err(FormatError::Truncated { .. })
    ));
    // A smaller limit refuses a good file.
    let path = write(dir.path(), "good.slmap", &bytes);
    let limits = Limits {
        max_payload_bytes: 100,
    };
    let e = Map::load_with(&path, &limits).unwrap_err();
    assert!(
        matches!(e.reason, FormatError::TooLarge { max: 100, .. }),
        "{e}"
    );
}

#[test]
fn bytes_after_the_payload_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = good_bytes();
    bytes.extend_from_slice(b"tail");
    let e = load_err(&write(dir.path(), "tail.slmap", &bytes));
    assert!(matches!(e.reason, FormatError::TrailingBytes(4)), "{e}");
    assert!(matches!(
        Map::from_bytes(&bytes, &Limits::default()),
        Err(FormatError::TrailingBytes(4))
    ));
    // A reader reads one map and leaves what follows.
    let mut r = &bytes[..];
    Map::read_from(&mut r, &Limits::default()).unwrap();
    assert_eq!(r, b"tail");
}
