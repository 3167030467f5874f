//! Detecting a frame cut short by the next frame.
//!
//! When a radar (or a faulty link) sends only the first part of a frame and then the next
//! frame, the decoder, trusting the header's payload size, would swallow the start of the
//! next frame as payload. The 16-byte signature is as good as impossible inside real data
//! (a chance of 2^-128 per position), so a signature found inside the payload of a frame
//! still being received marks that frame as cut short: the stub is dropped and decoding
//! resumes at the signature. The search covers each received byte once.

use memchr::memmem;
use protocol::{FrameHeader, HEADER_LEN, SIGNATURE};

/// Watches the frame at the front of the receive buffer while it is incomplete.
#[derive(Debug, Default)]
pub struct TruncationGuard {
    /// Bytes of the pending frame already searched.
    scanned: usize,
}

impl TruncationGuard {
    /// A guard with nothing scanned.
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets the scanned extent (call when the decoder consumed anything).
    pub fn reset(&mut self) {
        self.scanned = 0;
    }

    /// If `buf` starts with a valid header and a signature appears after the header but
    /// before the end the header claims, the number of bytes to drop (the stub).
    ///
    /// A complete frame is checked too (its payload is searched once, a few hundred
    /// nanoseconds for a 3.8 kB azimuth), so a stub is caught even when it arrives in the
    /// same read as the frames after it.
    pub fn check(&mut self, buf: &[u8]) -> Option<usize> {
        let header: &[u8; HEADER_LEN] = buf.get(..HEADER_LEN)?.try_into().ok()?;
        let Ok(parsed) = FrameHeader::parse(header) else {
            // Not a valid header: the decoder deals with it.
            return None;
        };
        let frame_len = parsed.frame_len();
        // A signature starting before `frame_len` may end up to 15 bytes after it.
        let end = buf.len().min(frame_len + SIGNATURE.len() - 1);
        // Re-search the last 15 bytes already scanned: a signature may straddle reads.
        let from = self
            .scanned
            .saturating_sub(SIGNATURE.len() - 1)
            .max(HEADER_LEN);
        let found = buf
            .get(from..end)
            .and_then(|window| memmem::find(window, &SIGNATURE))
            .map(|pos| from + pos)
            .filter(|&pos| pos < frame_len);
        self.scanned = end;
        if found.is_some() {
            self.scanned = 0;
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bytes::BytesMut;
    use protocol::Message;

    fn keepalive() -> Vec<u8> {
        let mut b = BytesMut::new();
        Message::KeepAlive.encode(&mut b).unwrap();
        b.to_vec()
    }

    fn header_claiming(payload: u32) -> Vec<u8> {
        let mut h = SIGNATURE.to_vec();
        h.extend_from_slice(&[1, 30]);
        h.extend_from_slice(&payload.to_be_bytes());
        h
    }

    #[test]
    fn a_stub_followed_by_a_signature_is_cut_at_the_signature() {
        let mut buf = header_claiming(1000);
        buf.extend_from_slice(&[7; 30]);
        let stub = buf.len();
        buf.extend_from_slice(&keepalive());
        assert_eq!(TruncationGuard::new().check(&buf), Some(stub));
    }

    #[test]
    fn an_incomplete_frame_without_a_signature_is_left_alone() {
        let mut g = TruncationGuard::new();
        let mut buf = header_claiming(1000);
        buf.extend_from_slice(&[7; 300]);
        assert_eq!(g.check(&buf), None);
        buf.extend_from_slice(&[8; 300]);
        assert_eq!(g.check(&buf), None);
    }

    #[test]
    fn a_signature_split_across_two_reads_is_found() {
        let mut g = TruncationGuard::new();
        let mut buf = header_claiming(1000);
        buf.extend_from_slice(&[7; 40]);
        let stub = buf.len();
        let ka = keepalive();
        buf.extend_from_slice(&ka[..8]);
        assert_eq!(g.check(&buf), None);
        buf.extend_from_slice(&ka[8..]);
        assert_eq!(g.check(&buf), Some(stub));
    }

    #[test]
    fn complete_frames_back_to_back_pass() {
        let mut buf = keepalive();
        buf.extend_from_slice(&keepalive());
        assert_eq!(TruncationGuard::new().check(&buf), None);
        let mut buf = header_claiming(100);
        buf.extend_from_slice(&[9; 100]);
        buf.extend_from_slice(&keepalive());
        assert_eq!(TruncationGuard::new().check(&buf), None);
    }

    #[test]
    fn a_stub_arriving_together_with_the_frames_after_it_is_caught() {
        let mut buf = header_claiming(40);
        buf.extend_from_slice(&[7; 10]);
        let stub = buf.len();
        for _ in 0..5 {
            buf.extend_from_slice(&keepalive());
        }
        assert_eq!(TruncationGuard::new().check(&buf), Some(stub));
    }
}
