//! CDR (OMG Common Data Representation, little-endian, plain CDR as ROS 2's rmw layers
//! write it) through the `cdr-encoding` crate, behind the 4-byte encapsulation header.
//!
//! | offset | size | what |
//! |---|---|---|
//! | 0 | 2 | representation identifier: `00 01` CDR little-endian (`00 00` big-endian) |
//! | 2 | 2 | representation options: `00 00` |
//! | 4 | .. | the message; alignment counts from offset 4 |
//!
//! Decoding takes a slice and never reserves more than the slice could hold: a sequence
//! length beyond the remaining bytes is an error, not an allocation.

use byteorder::{BigEndian, LittleEndian};
use serde::de::DeserializeOwned;
use serde::Serialize;

/// The encapsulation header this crate writes: CDR, little-endian, no options.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];
/// CDR, big-endian (read, never written).
pub const CDR_BE_HEADER: [u8; 4] = [0x00, 0x00, 0x00, 0x00];

/// Why a payload could not be decoded (or, rarely, a message encoded).
#[derive(Debug, thiserror::Error)]
pub enum CdrError {
    /// Fewer than 4 bytes: no encapsulation header.
    #[error("{0} bytes: too short for the 4-byte CDR encapsulation header")]
    TooShort(usize),
    /// A representation other than plain CDR (XCDR2, parameter lists...).
    #[error("unsupported CDR representation {0:02x} {1:02x} (plain CDR only: 00 00 or 00 01)")]
    Representation(u8, u8),
    /// The body did not match the type (truncated, bad length, bad UTF-8...).
    #[error("malformed CDR body: {0}")]
    Body(String),
    /// Bytes left over after the message.
    #[error("{extra} bytes left after the message (more than CDR's 3 bytes of padding)")]
    Trailing {
        /// How many.
        extra: usize,
    },
}

/// Serialises `msg` as CDR little-endian with its encapsulation header.
pub fn to_cdr<T: Serialize>(msg: &T) -> Result<Vec<u8>, CdrError> {
    let mut out = CDR_LE_HEADER.to_vec();
    let body =
        cdr_encoding::to_vec::<T, LittleEndian>(msg).map_err(|e| CdrError::Body(e.to_string()))?;
    out.extend_from_slice(&body);
    Ok(out)
}

/// Decodes a CDR payload (either endianness) with its encapsulation header. Up to 3 bytes of
/// trailing padding are allowed (rmw implementations pad to 4).
pub fn from_cdr<T: DeserializeOwned>(payload: &[u8]) -> Result<T, CdrError> {
    let (header, body) = payload
        .split_first_chunk::<4>()
        .ok_or(CdrError::TooShort(payload.len()))?;
    let (msg, used) = match (header[0], header[1]) {
        (0x00, 0x01) => cdr_encoding::from_bytes::<T, LittleEndian>(body),
        (0x00, 0x00) => cdr_encoding::from_bytes::<T, BigEndian>(body),
        (a, b) => return Err(CdrError::Representation(a, b)),
    }
    .map_err(|e| CdrError::Body(e.to_string()))?;
    let extra = body.len().saturating_sub(used);
    if extra > 3 {
        return Err(CdrError::Trailing { extra });
    }
    Ok(msg)
}
