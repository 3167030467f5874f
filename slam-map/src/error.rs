//! What can go wrong reading or writing a map file.

use std::io;
use std::path::PathBuf;

use crate::format::{FORMAT_VERSION, MAGIC};

/// Why bytes are not a map this build can use.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// No file at the path.
    #[error("the file does not exist")]
    Missing,
    /// The path is a folder, a FIFO or a device: refused before reading.
    #[error("not a regular file")]
    NotAFile,
    /// Zero bytes.
    #[error("the file is empty")]
    Empty,
    /// Fewer bytes than the header, or than the header says the payload holds.
    #[error("truncated: {found} bytes where the header says {expected}")]
    Truncated {
        /// Bytes the header (or the header itself) needs.
        expected: u64,
        /// Bytes present.
        found: u64,
    },
    /// The first bytes are not the map file's magic.
    #[error("not a map file: it starts with {found:02x?}, a map file with {MAGIC:02x?}")]
    BadMagic {
        /// The bytes found (at most the magic's length).
        found: Vec<u8>,
    },
    /// A version newer than this build reads.
    #[error(
        "format version {file}: this build reads version {supported} (the file was written by a newer build)"
    )]
    FutureVersion {
        /// The file's version.
        file: u32,
        /// The version this build reads.
        supported: u32,
    },
    /// A version that never existed (0).
    #[error("format version {0} does not exist (this build reads version {FORMAT_VERSION})")]
    BadVersion(u32),
    /// The header declares a payload larger than this reader accepts.
    #[error("the header declares a payload of {declared} bytes, more than the {max} accepted")]
    TooLarge {
        /// Declared payload bytes.
        declared: u64,
        /// The reader's limit.
        max: u64,
    },
    /// Bytes after the payload the header declares.
    #[error("{0} bytes follow the payload the header declares")]
    TrailingBytes(u64),
    /// The payload's checksum does not match the header's.
    #[error("corrupt: the payload's CRC32 is {computed:08x}, the header says {stored:08x}")]
    Corrupt {
        /// CRC32 in the header.
        stored: u32,
        /// CRC32 of the payload read.
        computed: u32,
    },
    /// The checksum matched but the payload does not decode as this version's map.
    #[error("the payload does not decode as a version {FORMAT_VERSION} map: {0}")]
    Undecodable(postcard::Error),
    /// The payload decoded but breaks a rule of the format (an index out of range, a value
    /// not finite, a limit passed).
    #[error("the map is inconsistent: {0}")]
    Invalid(String),
    /// Reading failed.
    #[error("read failed: {0}")]
    Io(#[from] io::Error),
}

/// A map file that could not be loaded: the file and the reason.
#[derive(Debug, thiserror::Error)]
#[error("map file {}: {reason}", path.display())]
pub struct LoadError {
    /// The file.
    pub path: PathBuf,
    /// Why.
    pub reason: FormatError,
}

/// Why a map could not be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// The map breaks a rule of the format (it would not load back).
    #[error("the map is inconsistent: {0}")]
    Invalid(String),
    /// The payload could not be encoded.
    #[error("encoding failed: {0}")]
    Encode(postcard::Error),
    /// Writing failed.
    #[error("write failed: {0}")]
    Io(#[from] io::Error),
}

/// A map file that could not be saved: the file and the reason. The previous file at the
/// path, if any, is unchanged.
#[derive(Debug, thiserror::Error)]
#[error("map file {}: {reason} (any previous file there is unchanged)", path.display())]
pub struct SaveError {
    /// The file.
    pub path: PathBuf,
    /// Why.
    pub reason: WriteError,
}
