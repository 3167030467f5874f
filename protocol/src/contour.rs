//! Contour update (message 50): how far to send, per degree of azimuth
//! (`docs/colossus-protocol.md`, section 2). 360 x u16 BE; an empty payload resets the
//! contour.
//!
//! A value `v` is the number of bins to send for that degree's azimuths: bins `0..v`, not
//! `0..=v`. The protocol document's "max bin per degree" leaves it open; Navtech's C++
//! client turns a range into `ceil(range / bin size)` bins (the bins that cover it), and
//! Navtech's `colossus_protocol_test` sends 100 and expects contoured azimuths of exactly
//! 100 bins (see the crate's README).

use bytes::{BufMut, Bytes, BytesMut};

use crate::error::PayloadError;

/// Degrees in a contour: one u16 per degree.
pub const CONTOUR_DEGREES: usize = 360;

/// A contour update.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ContourUpdate {
    /// Empty payload: remove any contour.
    Reset,
    /// For each degree 0..360, the number of bins to send (bins `0..v`).
    MaxBinPerDegree(Box<[u16; CONTOUR_DEGREES]>),
}

impl ContourUpdate {
    /// Decodes a contour payload: 0 or 720 bytes.
    pub fn decode(payload: &Bytes) -> Result<Self, PayloadError> {
        if payload.is_empty() {
            return Ok(Self::Reset);
        }
        if payload.len() != 2 * CONTOUR_DEGREES {
            return Err(PayloadError::BadContourLength { len: payload.len() });
        }
        let mut bins = Box::new([0u16; CONTOUR_DEGREES]);
        for (slot, pair) in bins.iter_mut().zip(payload.chunks_exact(2)) {
            if let [hi, lo] = *pair {
                *slot = u16::from_be_bytes([hi, lo]);
            }
        }
        Ok(Self::MaxBinPerDegree(bins))
    }

    /// Payload length when encoded: 0 or 720.
    pub fn encoded_payload_len(&self) -> usize {
        match self {
            Self::Reset => 0,
            Self::MaxBinPerDegree(_) => 2 * CONTOUR_DEGREES,
        }
    }

    pub(crate) fn encode_payload(&self, dst: &mut BytesMut) {
        if let Self::MaxBinPerDegree(bins) = self {
            dst.reserve(2 * CONTOUR_DEGREES);
            for &b in bins.iter() {
                dst.put_u16(b);
            }
        }
    }
}
