//! The file's bytes: a fixed header, then the payload.
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic `89 53 4c 4d 41 50 0d 0a` (`\x89SLMAP\r\n`) |
//! | 8 | 4 | format version, u32 little-endian ([`FORMAT_VERSION`]) |
//! | 12 | 4 | CRC32 (IEEE 802.3, as zlib's) of the payload, u32 little-endian |
//! | 16 | 8 | payload length in bytes, u64 little-endian |
//! | 24 | length | payload: the [`Map`] in postcard's format (version 1 wire format); a
//! version 1 file holds the map without its drives and joins |
//!
//! The magic and the version (the first 12 bytes) keep their place in every version; the
//! rest of the header is this version's. A reader checks, in this order: the magic, the
//! version, the declared length against its limit ([`Limits`]) and against the bytes
//! present, the CRC, and only then decodes; the decoded map is checked against the rules
//! of the format (`validate`). No memory is reserved from a declared length that has not
//! been checked against the bytes present (a file's size, or at most 1 MiB up front from a
//! stream): the payload is read through `Read::take`, and
//! postcard decodes from the bytes read, every collection's declared length bounded by
//! what is left of them.

use std::io::{self, Read, Write};

use crate::error::{FormatError, WriteError};
pub use crate::format::{FORMAT_VERSION, HEADER_LEN, MAGIC};
use crate::model::{Map, MapV1, MapV2, MapV3};
use crate::validate::validate;

/// What a reader accepts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// The largest payload read (bytes).
    pub max_payload_bytes: u64,
}

/// 1 GiB: a few hundred km of map at the figures measured (README, "Map size").
pub const DEFAULT_MAX_PAYLOAD_BYTES: u64 = 1 << 30;

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_payload_bytes: DEFAULT_MAX_PAYLOAD_BYTES,
        }
    }
}

/// The header's fields after the magic and the version were accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Header {
    pub version: u32,
    pub crc: u32,
    pub payload_len: u64,
}

/// Reads until `buf` is full or the input ends; returns the bytes read.
fn read_full<R: Read>(r: &mut R, buf: &mut [u8]) -> io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Reads and checks the header: magic, version, then the declared length against `limits`.
pub(crate) fn read_header<R: Read>(r: &mut R, limits: &Limits) -> Result<Header, FormatError> {
    let mut buf = [0u8; HEADER_LEN];
    let n = read_full(r, &mut buf)?;
    if n == 0 {
        return Err(FormatError::Empty);
    }
    let m = n.min(MAGIC.len());
    if buf[..m] != MAGIC[..m] {
        return Err(FormatError::BadMagic {
            found: buf[..m].to_vec(),
        });
    }
    if n < 12 {
        return Err(FormatError::Truncated {
            expected: HEADER_LEN as u64,
            found: n as u64,
        });
    }
    let version = u32::from_le_bytes([buf[8], buf[9], buf[10], buf[11]]);
    if version == 0 {
        return Err(FormatError::BadVersion(version));
    }
    if version > FORMAT_VERSION {
        return Err(FormatError::FutureVersion {
            file: version,
            supported: FORMAT_VERSION,
        });
    }
    if n < HEADER_LEN {
        return Err(FormatError::Truncated {
            expected: HEADER_LEN as u64,
            found: n as u64,
        });
    }
    let crc = u32::from_le_bytes([buf[12], buf[13], buf[14], buf[15]]);
    let mut len = [0u8; 8];
    len.copy_from_slice(&buf[16..24]);
    let payload_len = u64::from_le_bytes(len);
    if payload_len > limits.max_payload_bytes {
        return Err(FormatError::TooLarge {
            declared: payload_len,
            max: limits.max_payload_bytes,
        });
    }
    Ok(Header {
        version,
        crc,
        payload_len,
    })
}

/// Bytes reserved up front for a payload whose length has not been checked against the
/// bytes present (past it the buffer grows with what is read).
const UNCHECKED_RESERVE: u64 = 1 << 20;

/// Reads the payload the header declares, checks its CRC, decodes and validates it.
/// `length_checked`: the caller has checked the declared length against the bytes present
/// (a file's size), so the whole of it is reserved at once; otherwise at most 1 MiB is, and
/// the buffer grows with what is actually read.
pub(crate) fn read_payload<R: Read>(
    r: &mut R,
    header: &Header,
    length_checked: bool,
) -> Result<Map, FormatError> {
    let reserve = if length_checked {
        header.payload_len
    } else {
        header.payload_len.min(UNCHECKED_RESERVE)
    };
    let mut payload = Vec::with_capacity(usize::try_from(reserve).unwrap_or(0));
    r.take(header.payload_len).read_to_end(&mut payload)?;
    if (payload.len() as u64) < header.payload_len {
        return Err(FormatError::Truncated {
            expected: HEADER_LEN as u64 + header.payload_len,
            found: (HEADER_LEN + payload.len()) as u64,
        });
    }
    let computed = crc32fast::hash(&payload);
    if computed != header.crc {
        return Err(FormatError::Corrupt {
            stored: header.crc,
            computed,
        });
    }
    let (map, rest) = if header.version == 1 {
        postcard::take_from_bytes::<MapV1>(&payload)
            .map(|(m, rest)| (Map::from(m), rest))
            .map_err(FormatError::Undecodable)?
    } else if header.version == 2 {
        postcard::take_from_bytes::<MapV2>(&payload)
            .map(|(m, rest)| (Map::from(m), rest))
            .map_err(FormatError::Undecodable)?
    } else if header.version == 3 {
        postcard::take_from_bytes::<MapV3>(&payload)
            .map(|(m, rest)| (Map::from(m), rest))
            .map_err(FormatError::Undecodable)?
    } else {
        postcard::take_from_bytes::<Map>(&payload).map_err(FormatError::Undecodable)?
    };
    if !rest.is_empty() {
        return Err(FormatError::Invalid(format!(
            "{} bytes of the payload follow the map",
            rest.len()
        )));
    }
    validate(&map).map_err(FormatError::Invalid)?;
    Ok(map)
}

impl Map {
    /// The whole file's bytes: header and payload. Refuses a map that would not load back.
    pub fn to_bytes(&self) -> Result<Vec<u8>, WriteError> {
        validate(self).map_err(WriteError::Invalid)?;
        let payload = postcard::to_allocvec(self).map_err(WriteError::Encode)?;
        let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&payload);
        Ok(out)
    }

    /// Writes the whole file to `w`; returns the bytes written.
    pub fn write_to<W: Write>(&self, mut w: W) -> Result<u64, WriteError> {
        let bytes = self.to_bytes()?;
        w.write_all(&bytes)?;
        w.flush()?;
        Ok(bytes.len() as u64)
    }

    /// Reads one map from `r`: the header, then exactly the payload it declares (what
    /// follows is left unread).
    pub fn read_from<R: Read>(mut r: R, limits: &Limits) -> Result<Map, FormatError> {
        let header = read_header(&mut r, limits)?;
        read_payload(&mut r, &header, false)
    }

    /// A map from a whole file's bytes (bytes after the payload are an error).
    pub fn from_bytes(bytes: &[u8], limits: &Limits) -> Result<Map, FormatError> {
        let mut r = bytes;
        let header = read_header(&mut r, limits)?;
        let map = read_payload(&mut r, &header, false)?;
        if !r.is_empty() {
            return Err(FormatError::TrailingBytes(r.len() as u64));
        }
        Ok(map)
    }
}
