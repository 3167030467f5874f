//! The 22-byte frame header (`docs/colossus-protocol.md`, section 1) and raw frame writing.

use bytes::{BufMut, BytesMut};

use crate::error::{DecodeError, EncodeError};

/// The 16-byte signature that opens every frame.
pub const SIGNATURE: [u8; 16] = [
    0x00, 0x01, 0x03, 0x03, 0x07, 0x07, 0x0F, 0x0F, 0x1F, 0x1F, 0x3F, 0x3F, 0x7F, 0x7F, 0xFE, 0xFE,
];

/// The only protocol version there is.
pub const PROTOCOL_VERSION: u8 = 1;

/// Header length in bytes: signature, version, message id, payload size.
pub const HEADER_LEN: usize = 22;

/// Payload sizes at or above this are rejected, as Navtech's SDK does.
pub const MAX_PAYLOAD_SIZE: u32 = 1_000_000;

/// A validated frame header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FrameHeader {
    /// Message id (see [`crate::message_id`]).
    pub message_id: u8,
    /// Payload bytes after the header; always below [`MAX_PAYLOAD_SIZE`].
    pub payload_size: u32,
}

impl FrameHeader {
    /// Parses and validates a header. The signature must already match; `parse` checks it
    /// again, then the version, then the size.
    pub fn parse(header: &[u8; HEADER_LEN]) -> Result<Self, DecodeError> {
        let [sig @ .., version, message_id, s0, s1, s2, s3] = *header;
        if sig != SIGNATURE {
            return Err(DecodeError::BadSignature { skipped_bytes: 0 });
        }
        if version != PROTOCOL_VERSION {
            return Err(DecodeError::BadVersion { version });
        }
        let payload_size = u32::from_be_bytes([s0, s1, s2, s3]);
        if payload_size >= MAX_PAYLOAD_SIZE {
            return Err(DecodeError::Oversized {
                message_id,
                payload_size,
            });
        }
        Ok(Self {
            message_id,
            payload_size,
        })
    }

    /// Whole frame length, header included.
    pub fn frame_len(&self) -> usize {
        // payload_size < 1e6, so this cannot overflow on any platform with >= 32-bit usize.
        HEADER_LEN + self.payload_size as usize
    }
}

/// Checks a payload length against the protocol limit and returns it as the wire's u32.
pub(crate) fn checked_payload_size(message_id: u8, payload_len: usize) -> Result<u32, EncodeError> {
    u32::try_from(payload_len)
        .ok()
        .filter(|&n| n < MAX_PAYLOAD_SIZE)
        .ok_or(EncodeError::PayloadTooLarge {
            message_id,
            payload_len,
        })
}

/// Writes a 22-byte header for a payload of `payload_len` bytes. Writes nothing on error.
pub fn encode_header(
    dst: &mut BytesMut,
    message_id: u8,
    payload_len: usize,
) -> Result<(), EncodeError> {
    let size = checked_payload_size(message_id, payload_len)?;
    dst.reserve(HEADER_LEN);
    dst.put_slice(&SIGNATURE);
    dst.put_u8(PROTOCOL_VERSION);
    dst.put_u8(message_id);
    dst.put_u32(size);
    Ok(())
}

/// Writes a whole frame with an arbitrary id and payload, unchecked against the message's
/// layout: for tests and fault injection (a malformed FFT frame, say).
pub fn encode_raw_frame(
    dst: &mut BytesMut,
    message_id: u8,
    payload: &[u8],
) -> Result<(), EncodeError> {
    checked_payload_size(message_id, payload.len())?;
    dst.reserve(HEADER_LEN + payload.len());
    encode_header(dst, message_id, payload.len())?;
    dst.put_slice(payload);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(version: u8, id: u8, size: u32) -> [u8; HEADER_LEN] {
        let mut h = [0u8; HEADER_LEN];
        h[..16].copy_from_slice(&SIGNATURE);
        h[16] = version;
        h[17] = id;
        h[18..].copy_from_slice(&size.to_be_bytes());
        h
    }

    #[test]
    fn a_valid_header_parses_to_its_id_and_big_endian_size() {
        let h = FrameHeader::parse(&header(1, 30, 0x0000_0EC6)).unwrap();
        assert_eq!(h.message_id, 30);
        assert_eq!(h.payload_size, 3782);
        assert_eq!(h.frame_len(), 3804);
    }

    #[test]
    fn the_size_limit_is_exclusive_at_one_million() {
        assert!(FrameHeader::parse(&header(1, 30, 999_999)).is_ok());
        assert_eq!(
            FrameHeader::parse(&header(1, 30, 1_000_000)),
            Err(DecodeError::Oversized {
                message_id: 30,
                payload_size: 1_000_000
            })
        );
    }

    #[test]
    fn version_two_is_rejected() {
        assert_eq!(
            FrameHeader::parse(&header(2, 1, 0)),
            Err(DecodeError::BadVersion { version: 2 })
        );
    }

    #[test]
    fn encoding_an_oversized_payload_writes_nothing() {
        let mut dst = BytesMut::new();
        let err = encode_header(&mut dst, 30, 1_000_000).unwrap_err();
        assert_eq!(
            err,
            EncodeError::PayloadTooLarge {
                message_id: 30,
                payload_len: 1_000_000
            }
        );
        assert!(dst.is_empty());
    }
}
