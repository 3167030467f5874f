//! Sector blanking update (message 51): sectors in which the radar transmits nothing
//! (`docs/colossus-protocol.md`, section 2). A u8 count, then per sector its start and
//! end angles as f32 BE in tenths of a degree.

use bytes::{BufMut, Bytes, BytesMut};

use crate::error::{EncodeError, PayloadError};
use crate::reader::Reader;

/// One blanked sector, angles as on the wire (degrees x 10).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlankingSector {
    /// Start angle in tenths of a degree.
    pub start_deg_x10: f32,
    /// End angle in tenths of a degree.
    pub end_deg_x10: f32,
}

impl BlankingSector {
    /// A sector from its start and end in degrees.
    pub fn from_degrees(start_deg: f64, end_deg: f64) -> Self {
        Self {
            start_deg_x10: (start_deg * 10.0) as f32,
            end_deg_x10: (end_deg * 10.0) as f32,
        }
    }

    /// Start angle in degrees.
    pub fn start_deg(&self) -> f64 {
        f64::from(self.start_deg_x10) / 10.0
    }

    /// End angle in degrees.
    pub fn end_deg(&self) -> f64 {
        f64::from(self.end_deg_x10) / 10.0
    }
}

/// A sector blanking update: up to 255 sectors (an empty list clears blanking).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SectorBlanking {
    /// The blanked sectors.
    pub sectors: Vec<BlankingSector>,
}

/// Bytes per sector on the wire.
const SECTOR_LEN: usize = 8;

impl SectorBlanking {
    /// Decodes a sector blanking payload; the count must match the payload length.
    pub fn decode(payload: &Bytes) -> Result<Self, PayloadError> {
        let mut r = Reader::new(payload);
        let count = r.u8()?;
        let expected = 1 + SECTOR_LEN * usize::from(count);
        if payload.len() != expected {
            return Err(PayloadError::BadSectorCount {
                count,
                payload_len: payload.len(),
            });
        }
        let mut sectors = Vec::with_capacity(usize::from(count));
        for _ in 0..count {
            sectors.push(BlankingSector {
                start_deg_x10: r.f32_be()?,
                end_deg_x10: r.f32_be()?,
            });
        }
        Ok(Self { sectors })
    }

    /// Payload length when encoded.
    pub fn encoded_payload_len(&self) -> usize {
        1 + SECTOR_LEN * self.sectors.len()
    }

    pub(crate) fn validate_for_encoding(&self) -> Result<u8, EncodeError> {
        u8::try_from(self.sectors.len()).map_err(|_| EncodeError::TooManySectors {
            count: self.sectors.len(),
        })
    }

    /// Writes the payload. Call `validate_for_encoding` first; it returns the count.
    pub(crate) fn encode_payload(&self, count: u8, dst: &mut BytesMut) {
        dst.reserve(self.encoded_payload_len());
        dst.put_u8(count);
        for s in self.sectors.iter().take(usize::from(count)) {
            dst.put_f32(s.start_deg_x10);
            dst.put_f32(s.end_deg_x10);
        }
    }
}
