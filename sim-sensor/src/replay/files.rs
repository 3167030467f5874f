//! Reading a recording's files: every scan, scan index and ground-truth file of a replay
//! folder is read here ([`read_bounded`], [`read_bounded_text`]), and only here.
//!
//! Two rules, for every file:
//!
//! - **Regular files only.** What the path names, after following symlinks, must be a
//!   regular file: a FIFO, a device (`/dev/zero`), a socket or a directory is refused by its
//!   metadata, before it is opened, so opening cannot block (a FIFO's open waits for a writer)
//!   and reading cannot go on without end. What was opened is checked again, in case the
//!   path was swapped between the two.
//! - **A byte limit per kind of file** ([`FileKind::limit`]), generous for the real data
//!   sets: a file whose size is over it is refused without reading, and the read itself stops
//!   one byte past the limit (`Read::take`), so a file that grows while it is read cannot
//!   take more either.
//!
//! | kind | limit | the real data |
//! |---|---|---|
//! | [`FileKind::Scan`] | [`MAX_SCAN_BYTES`], 80 MiB | Oxford's and Boreas' scans are about 1.5 MB, RADIATE's 0.2 MB; the decoded image is limited to [`super::png::MAX_IMAGE_BYTES`] (64 MiB), and 80 MiB holds that image stored without compression with room for the PNG's framing and ancillary chunks |
//! | [`FileKind::ScanIndex`] | [`MAX_INDEX_BYTES`], 64 MiB | RADIATE's `Navtech_Polar.txt`: about 45 bytes a scan, 16 MB for a day at 4 Hz |
//! | [`FileKind::GroundTruth`] | [`MAX_TRUTH_BYTES`], 256 MiB | Oxford's `radar_odometry.csv` and Boreas' `radar_poses.csv` are a few MB an hour; a day (the longest span the ground truth may have, [`super::truth::MAX_SPAN_US`]) of Boreas poses is about 90 MB, of RADIATE's 20 Hz `GPS_IMU_Twist.txt` about 140 MB |
//! | [`FileKind::GpsRecord`] | [`MAX_GPS_RECORD_BYTES`], 1 MiB | one `GPS_IMU_Twist/<frame>.txt`: 18 lines, about 1 KB |
//!
//! Blocking file IO: call it from `spawn_blocking` in async code.

use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use crate::error::ReplayError;

/// Largest scan (PNG) file read (bytes): see the [module](self) for why.
pub const MAX_SCAN_BYTES: u64 = 80 << 20;
/// Largest scan index file read (bytes).
pub const MAX_INDEX_BYTES: u64 = 64 << 20;
/// Largest ground-truth table read (bytes): `radar_odometry.csv`, `radar_poses.csv`,
/// `GPS_IMU_Twist.txt`.
pub const MAX_TRUTH_BYTES: u64 = 256 << 20;
/// Largest single GPS record read (bytes): one `GPS_IMU_Twist/<frame>.txt`.
pub const MAX_GPS_RECORD_BYTES: u64 = 1 << 20;

/// The kinds of file a replay reads, each with its byte limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FileKind {
    /// A polar scan (PNG).
    Scan,
    /// A list of scans and their times (RADIATE's `Navtech_Polar.txt`).
    ScanIndex,
    /// A ground-truth table (`radar_odometry.csv`, `radar_poses.csv`, `GPS_IMU_Twist.txt`).
    GroundTruth,
    /// One GPS/INS record (RADIATE's `GPS_IMU_Twist/<frame>.txt`).
    GpsRecord,
}

impl FileKind {
    /// The most bytes read from a file of this kind.
    pub const fn limit(self) -> u64 {
        match self {
            FileKind::Scan => MAX_SCAN_BYTES,
            FileKind::ScanIndex => MAX_INDEX_BYTES,
            FileKind::GroundTruth => MAX_TRUTH_BYTES,
            FileKind::GpsRecord => MAX_GPS_RECORD_BYTES,
        }
    }

    /// What it is called in messages.
    pub const fn name(self) -> &'static str {
        match self {
            FileKind::Scan => "scan",
            FileKind::ScanIndex => "scan index",
            FileKind::GroundTruth => "ground-truth file",
            FileKind::GpsRecord => "GPS record",
        }
    }
}

impl std::fmt::Display for FileKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A path that names something other than a regular file, after following symlinks. In a
/// [`ReplayError`] it is the source of [`ReplayError::Io`] (see [`not_a_regular_file`]); in a
/// `TruthError` (the ground truth's readers) it is `TruthError::NotRegularFile`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("not a regular file but {what}; a {kind} must be a regular file")]
pub struct NotRegularFile {
    /// What the file was expected to be.
    pub kind: FileKind,
    /// What it is: "a FIFO", "a character device", "a directory"...
    pub what: &'static str,
}

/// Why [`read_bounded`] refused or failed a file.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// The OS refused or failed the read (a missing file, no permission, not UTF-8 text).
    #[error("reading {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Not a regular file.
    #[error("{path}: {refused}")]
    NotRegular {
        /// The file.
        path: PathBuf,
        /// What it is instead.
        refused: NotRegularFile,
    },
    /// Larger than its kind's limit.
    #[error("{path}: {bytes} bytes is larger than the {limit} a {kind} may have")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// What it was read as.
        kind: FileKind,
        /// Its size (at least this many when it grew while being read).
        bytes: u64,
        /// The limit, [`FileKind::limit`].
        limit: u64,
    },
}

impl From<FileError> for ReplayError {
    /// `NotRegular` becomes [`ReplayError::Io`] whose source is an `InvalidInput` error
    /// carrying the [`NotRegularFile`] ([`not_a_regular_file`] finds it).
    fn from(e: FileError) -> Self {
        match e {
            FileError::Io { path, source } => ReplayError::Io { path, source },
            FileError::NotRegular { path, refused } => ReplayError::Io {
                path,
                source: std::io::Error::new(std::io::ErrorKind::InvalidInput, refused),
            },
            FileError::TooLarge {
                path, bytes, limit, ..
            } => ReplayError::TooLarge { path, bytes, limit },
        }
    }
}

/// The [`NotRegularFile`] a [`ReplayError`] was made of, if it was.
pub fn not_a_regular_file(error: &ReplayError) -> Option<&NotRegularFile> {
    match error {
        ReplayError::Io { source, .. } => source.get_ref()?.downcast_ref::<NotRegularFile>(),
        _ => None,
    }
}

/// What a file type is, in words.
fn describe(file_type: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_fifo() {
            return "a FIFO";
        }
        if file_type.is_char_device() {
            return "a character device";
        }
        if file_type.is_block_device() {
            return "a block device";
        }
        if file_type.is_socket() {
            return "a socket";
        }
    }
    if file_type.is_dir() {
        "a directory"
    } else {
        "something else"
    }
}

/// Refuses what is not a regular file or is larger than `kind` allows.
fn check(path: &Path, kind: FileKind, metadata: &std::fs::Metadata) -> Result<(), FileError> {
    if !metadata.is_file() {
        return Err(FileError::NotRegular {
            path: path.to_path_buf(),
            refused: NotRegularFile {
                kind,
                what: describe(metadata.file_type()),
            },
        });
    }
    let limit = kind.limit();
    if metadata.len() > limit {
        return Err(FileError::TooLarge {
            path: path.to_path_buf(),
            kind,
            bytes: metadata.len(),
            limit,
        });
    }
    Ok(())
}

/// Appends at most `limit + 1` bytes of `reader` to `out`: more than `limit` appended means
/// the source is larger than the limit. Never reads further, whatever the source.
pub(crate) fn read_at_most(
    reader: impl Read,
    limit: u64,
    out: &mut Vec<u8>,
) -> std::io::Result<u64> {
    reader
        .take(limit.saturating_add(1))
        .read_to_end(out)
        .map(|n| n as u64)
}

/// Reads the whole file at `path`, a regular file (after following symlinks) of at most
/// `kind`'s [`FileKind::limit`] bytes. Its metadata is checked before it is opened, so a
/// FIFO or a device is refused without blocking or reading.
///
/// # Errors
/// [`FileError::NotRegular`], [`FileError::TooLarge`] (by its size, or by what was read when
/// it grew), [`FileError::Io`]; each names the file.
pub fn read_bounded(path: &Path, kind: FileKind) -> Result<Vec<u8>, FileError> {
    let io = |source| FileError::Io {
        path: path.to_path_buf(),
        source,
    };
    // `metadata` follows symlinks and opens nothing.
    check(path, kind, &std::fs::metadata(path).map_err(io)?)?;
    let file = File::open(path).map_err(io)?;
    // The same checks on what was opened.
    let metadata = file.metadata().map_err(io)?;
    check(path, kind, &metadata)?;
    let limit = kind.limit();
    // At most `limit` (checked above).
    let expected = usize::try_from(metadata.len().min(limit)).unwrap_or(0);
    let mut bytes = Vec::with_capacity(expected);
    let read = read_at_most(file, limit, &mut bytes).map_err(io)?;
    if read > limit {
        return Err(FileError::TooLarge {
            path: path.to_path_buf(),
            kind,
            bytes: read,
            limit,
        });
    }
    Ok(bytes)
}

/// [`read_bounded`] as UTF-8 text.
///
/// # Errors
/// Those of [`read_bounded`]; text that is not UTF-8 is [`FileError::Io`] (`InvalidData`).
pub fn read_bounded_text(path: &Path, kind: FileKind) -> Result<String, FileError> {
    String::from_utf8(read_bounded(path, kind)?).map_err(|e| FileError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidData, e.utf8_error()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_endless_source_is_read_only_one_byte_past_the_limit() {
        let mut out = Vec::new();
        let n = read_at_most(std::io::repeat(0), 1000, &mut out).unwrap();
        assert_eq!((n, out.len()), (1001, 1001));
        let mut out = Vec::new();
        let n = read_at_most(&b"abc"[..], 3, &mut out).unwrap();
        assert_eq!((n, out.as_slice()), (3, &b"abc"[..]));
    }

    #[test]
    fn each_kind_has_its_limit_and_the_limits_fit_the_data() {
        assert!(MAX_SCAN_BYTES > super::super::png::MAX_IMAGE_BYTES as u64);
        for kind in [
            FileKind::Scan,
            FileKind::ScanIndex,
            FileKind::GroundTruth,
            FileKind::GpsRecord,
        ] {
            assert!(kind.limit() >= 1 << 20, "{kind}");
            assert!(kind.limit() <= 1 << 30, "{kind}");
        }
    }

    #[test]
    fn a_regular_file_within_its_limit_reads_whole_and_a_directory_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("radar_odometry.csv");
        std::fs::write(&path, "header\n1,2\n").unwrap();
        assert_eq!(
            read_bounded_text(&path, FileKind::GroundTruth).unwrap(),
            "header\n1,2\n"
        );
        std::fs::write(&path, [0xff, 0xfe]).unwrap();
        let err = read_bounded_text(&path, FileKind::GroundTruth).unwrap_err();
        assert!(matches!(err, FileError::Io { .. }), "{err}");
        let err = read_bounded(dir.path(), FileKind::Scan).unwrap_err();
        assert!(
            matches!(
                err,
                FileError::NotRegular {
                    refused: NotRegularFile {
                        what: "a directory",
                        ..
                    },
                    ..
                }
            ),
            "{err}"
        );
        let replay: ReplayError = err.into();
        assert_eq!(
            not_a_regular_file(&replay).map(|r| r.kind),
            Some(FileKind::Scan)
        );
        assert!(
            replay.to_string().contains("not a regular file"),
            "{replay}"
        );
    }
}
