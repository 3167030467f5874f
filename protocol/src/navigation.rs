//! Navigation data (message 123): the radar's own peak detections for one azimuth
//! (`docs/colossus-protocol.md`, section 2). All fields big-endian:
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | u16 | azimuth, encoder counts |
//! | 2 | u32 | seconds since the Unix epoch |
//! | 6 | u32 | split seconds (nanoseconds) |
//! | 10.. | N x 6 | per target: u32 range in metres x 10^6, u16 power in dB x 10 |

use bytes::{BufMut, Bytes, BytesMut};

use crate::error::PayloadError;
use crate::reader::Reader;
use crate::timestamp::Timestamp;

/// Bytes per navigation target on the wire.
pub const NAVIGATION_TARGET_LEN: usize = 6;

/// Length of the fixed part before the targets.
const NAVIGATION_HEADER_LEN: usize = 10;

/// One detected target, wire units.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct NavigationTarget {
    /// Range in micrometres (metres x 10^6).
    pub range_um: u32,
    /// Power in tenths of a dB.
    pub power_db_x10: u16,
}

impl NavigationTarget {
    /// Range in metres.
    pub fn range_m(&self) -> f64 {
        f64::from(self.range_um) * 1e-6
    }

    /// Power in dB.
    pub fn power_db(&self) -> f64 {
        f64::from(self.power_db_x10) / 10.0
    }
}

/// Navigation data for one azimuth.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NavigationData {
    /// Azimuth in encoder counts.
    pub azimuth: u16,
    /// When the azimuth was measured.
    pub timestamp: Timestamp,
    /// Targets down the beam.
    pub targets: Vec<NavigationTarget>,
}

impl NavigationData {
    /// Decodes a navigation data payload. The target list must be a whole number of
    /// 6-byte targets; its length is bounded by the (already bounded) payload.
    pub fn decode(payload: &Bytes) -> Result<Self, PayloadError> {
        let mut r = Reader::new(payload);
        let azimuth = r.u16_be()?;
        let seconds = r.u32_be()?;
        let nanos = r.u32_be()?;
        let timestamp =
            Timestamp::new(seconds, nanos).map_err(|_| PayloadError::BadNanos { nanos })?;
        let target_bytes = payload.len().saturating_sub(NAVIGATION_HEADER_LEN);
        if !target_bytes.is_multiple_of(NAVIGATION_TARGET_LEN) {
            return Err(PayloadError::BadNavigationTargets { len: target_bytes });
        }
        let n = target_bytes / NAVIGATION_TARGET_LEN;
        let mut targets = Vec::with_capacity(n);
        for _ in 0..n {
            targets.push(NavigationTarget {
                range_um: r.u32_be()?,
                power_db_x10: r.u16_be()?,
            });
        }
        Ok(Self {
            azimuth,
            timestamp,
            targets,
        })
    }

    /// Payload length when encoded.
    pub fn encoded_payload_len(&self) -> usize {
        NAVIGATION_HEADER_LEN + NAVIGATION_TARGET_LEN * self.targets.len()
    }

    pub(crate) fn encode_payload(&self, dst: &mut BytesMut) {
        dst.reserve(self.encoded_payload_len());
        dst.put_u16(self.azimuth);
        dst.put_u32(self.timestamp.seconds());
        dst.put_u32(self.timestamp.nanos());
        for t in &self.targets {
            dst.put_u32(t.range_um);
            dst.put_u16(t.power_db_x10);
        }
    }
}
