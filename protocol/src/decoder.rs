//! The streaming frame decoder: tokio-util style, `Ok(None)` until a whole frame is in.
//!
//! Resynchronisation follows Navtech's 2016 SDK (on a bad signature, drop a byte and look
//! again), done efficiently: the buffer is searched for the 16-byte signature with
//! `memchr::memmem`, everything before it is dropped in one step, and a tail that could be
//! the start of a signature is kept. Header checks run in this order: signature, version,
//! size (< 1,000,000, checked before any memory is reserved).
//!
//! After every `Err` the bytes at fault have been consumed from the buffer, so the caller
//! calls `decode` again; a bad frame costs that frame and nothing after it:
//!
//! | error | bytes consumed |
//! |---|---|
//! | `BadSignature` | the garbage before the next (possible) signature |
//! | `BadVersion`, `Oversized` | the 16 signature bytes; the rest is skipped as garbage on the next call |
//! | `Payload` | the whole frame (its size was valid, so its extent is known) |

use bytes::{Buf, BytesMut};
use memchr::memmem;

use crate::error::DecodeError;
use crate::frame::{FrameHeader, HEADER_LEN, SIGNATURE};
use crate::message::Message;

/// Counters of what the decoder has seen, by kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DecoderStats {
    /// Frames decoded into a message (unknown ids included).
    pub frames_decoded: u64,
    /// Bytes of the frames decoded (headers included).
    pub bytes_decoded: u64,
    /// Of the frames decoded, those with an id this crate does not know.
    pub frames_unknown_id: u64,
    /// Bytes dropped while resynchronising (garbage and signatures of rejected headers).
    pub bytes_skipped: u64,
    /// Runs of garbage skipped (`BadSignature` errors returned).
    pub bad_signature_runs: u64,
    /// Headers rejected for their version.
    pub frames_bad_version: u64,
    /// Headers rejected for an oversized payload.
    pub frames_oversized: u64,
    /// Whole frames rejected for a malformed payload.
    pub frames_bad_payload: u64,
    /// Bytes of whole frames rejected for a malformed payload.
    pub bytes_bad_payload: u64,
}

impl DecoderStats {
    /// Frames rejected for any reason.
    pub fn frames_rejected(&self) -> u64 {
        self.frames_bad_version + self.frames_oversized + self.frames_bad_payload
    }

    /// Every byte the decoder has consumed: decoded, rejected or skipped.
    pub fn bytes_consumed(&self) -> u64 {
        self.bytes_decoded + self.bytes_skipped + self.bytes_bad_payload
    }
}

/// A streaming decoder for a Colossus byte stream. Holds no buffer of its own: the caller
/// owns the `BytesMut` it reads into, so decoding is zero-copy.
#[derive(Debug, Clone)]
pub struct FrameDecoder {
    finder: memmem::Finder<'static>,
    stats: DecoderStats,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// A decoder with zeroed counters.
    pub fn new() -> Self {
        Self {
            finder: memmem::Finder::new(&SIGNATURE),
            stats: DecoderStats::default(),
        }
    }

    /// What the decoder has seen so far.
    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    /// Decodes the next frame from the front of `buf`.
    ///
    /// - `Ok(Some(message))`: a whole frame was consumed. Bins and opaque payloads are
    ///   slices of `buf`'s allocation (no copy).
    /// - `Ok(None)`: more bytes are needed; `buf` may have had capacity reserved for the
    ///   rest of a frame whose header has been validated.
    /// - `Err(e)`: the bytes at fault were consumed; call again.
    pub fn decode(&mut self, buf: &mut BytesMut) -> Result<Option<Message>, DecodeError> {
        let skip = self.garbage_len(buf);
        if skip > 0 {
            buf.advance(skip);
            self.stats.bytes_skipped += skip as u64;
            self.stats.bad_signature_runs += 1;
            return Err(DecodeError::BadSignature {
                skipped_bytes: skip,
            });
        }
        let Some(header_bytes) = buf.get(..HEADER_LEN) else {
            return Ok(None);
        };
        let mut header = [0u8; HEADER_LEN];
        header.copy_from_slice(header_bytes);
        let header = match FrameHeader::parse(&header) {
            Ok(h) => h,
            Err(e) => {
                // Drop the signature only: a true frame can start in the bytes after it
                // (a truncated header followed by a good frame), and the next call
                // resynchronises from there.
                buf.advance(SIGNATURE.len());
                self.stats.bytes_skipped += SIGNATURE.len() as u64;
                match e {
                    DecodeError::BadVersion { .. } => self.stats.frames_bad_version += 1,
                    DecodeError::Oversized { .. } => self.stats.frames_oversized += 1,
                    _ => {}
                }
                return Err(e);
            }
        };
        let frame_len = header.frame_len();
        if buf.len() < frame_len {
            // The size is validated (< 1e6), so reserving it is bounded.
            buf.reserve(frame_len - buf.len());
            return Ok(None);
        }
        let frame = buf.split_to(frame_len).freeze();
        let payload = frame.slice(HEADER_LEN..);
        match Message::decode_payload(header.message_id, payload) {
            Ok(message) => {
                self.stats.frames_decoded += 1;
                self.stats.bytes_decoded += frame_len as u64;
                if matches!(message, Message::Unknown { .. }) {
                    self.stats.frames_unknown_id += 1;
                }
                Ok(Some(message))
            }
            Err(source) => {
                self.stats.frames_bad_payload += 1;
                self.stats.bytes_bad_payload += frame_len as u64;
                Err(DecodeError::Payload {
                    message_id: header.message_id,
                    source,
                })
            }
        }
    }

    /// How many leading bytes of `buf` cannot be the start of a frame: up to the first
    /// full signature, or, if there is none, up to the longest tail that is a prefix of
    /// the signature.
    fn garbage_len(&self, buf: &[u8]) -> usize {
        if buf.starts_with(&SIGNATURE) {
            return 0;
        }
        if let Some(pos) = self.finder.find(buf) {
            return pos;
        }
        // No whole signature: keep the longest tail (< 16 bytes) that a signature could
        // continue. The signature's only 0x00 is its first byte, so such a tail starts
        // at a 0x00.
        let tail_start = buf.len().saturating_sub(SIGNATURE.len() - 1);
        let tail = buf.get(tail_start..).unwrap_or_default();
        for (i, _) in tail.iter().enumerate().filter(|(_, &b)| b == SIGNATURE[0]) {
            let candidate = tail.get(i..).unwrap_or_default();
            if SIGNATURE.starts_with(candidate) {
                return tail_start + i;
            }
        }
        buf.len()
    }
}

#[cfg(test)]
mod tests {
    //! One test per situation, tokio-modbus style.
    use super::*;
    use crate::fft::{BinWidth, FftData};
    use crate::frame::encode_raw_frame;
    use crate::timestamp::Timestamp;
    use bytes::{BufMut, Bytes};

    fn fft_frame() -> (Message, BytesMut) {
        let msg = Message::FftData(FftData::new(
            BinWidth::Eight,
            7,
            1400,
            Timestamp::new(1_600_000_000, 5).unwrap(),
            Bytes::from_static(&[1, 2, 3, 4, 5]),
        ));
        let mut buf = BytesMut::new();
        msg.encode(&mut buf).unwrap();
        (msg, buf)
    }

    #[test]
    fn an_empty_buffer_needs_more_bytes() {
        let mut buf = BytesMut::new();
        assert_eq!(FrameDecoder::new().decode(&mut buf), Ok(None));
    }

    #[test]
    fn a_partial_header_needs_more_bytes_and_is_kept() {
        let (_, whole) = fft_frame();
        for n in 1..HEADER_LEN {
            let mut buf = BytesMut::from(&whole[..n]);
            assert_eq!(FrameDecoder::new().decode(&mut buf), Ok(None), "{n} bytes");
            assert_eq!(buf.len(), n);
        }
    }

    #[test]
    fn a_fragmented_frame_decodes_once_its_last_byte_arrives() {
        let (msg, whole) = fft_frame();
        let mut decoder = FrameDecoder::new();
        let mut buf = BytesMut::new();
        let (last, init) = whole.split_last().unwrap();
        for &b in init {
            buf.put_u8(b);
            assert_eq!(decoder.decode(&mut buf), Ok(None));
        }
        buf.put_u8(*last);
        assert_eq!(decoder.decode(&mut buf), Ok(Some(msg)));
        assert!(buf.is_empty());
    }

    #[test]
    fn two_frames_in_one_read_decode_one_after_the_other() {
        let (msg, whole) = fft_frame();
        let mut buf = BytesMut::new();
        buf.extend_from_slice(&whole);
        buf.extend_from_slice(&whole);
        let mut decoder = FrameDecoder::new();
        assert_eq!(decoder.decode(&mut buf), Ok(Some(msg.clone())));
        assert_eq!(decoder.decode(&mut buf), Ok(Some(msg)));
        assert_eq!(decoder.decode(&mut buf), Ok(None));
        assert_eq!(decoder.stats().frames_decoded, 2);
    }

    #[test]
    fn bad_magic_is_skipped_and_the_next_frame_still_decodes() {
        let (msg, whole) = fft_frame();
        let mut buf = BytesMut::from(&b"\x00\x01\x03garbage\xFE"[..]);
        buf.extend_from_slice(&whole);
        let mut decoder = FrameDecoder::new();
        assert_eq!(
            decoder.decode(&mut buf),
            Err(DecodeError::BadSignature { skipped_bytes: 11 })
        );
        assert_eq!(decoder.decode(&mut buf), Ok(Some(msg)));
        assert_eq!(decoder.stats().bytes_skipped, 11);
    }

    #[test]
    fn a_garbage_tail_that_may_start_a_signature_is_kept() {
        let mut buf = BytesMut::from(&[0xAA, 0xBB, 0x00, 0x01, 0x03][..]);
        let mut decoder = FrameDecoder::new();
        assert_eq!(
            decoder.decode(&mut buf),
            Err(DecodeError::BadSignature { skipped_bytes: 2 })
        );
        assert_eq!(&buf[..], &[0x00, 0x01, 0x03]);
        assert_eq!(decoder.decode(&mut buf), Ok(None));
    }

    #[test]
    fn an_oversized_length_is_rejected_without_reserving_and_the_stream_resyncs() {
        let mut buf = BytesMut::with_capacity(64);
        buf.put_slice(&SIGNATURE);
        buf.put_u8(1);
        buf.put_u8(30);
        buf.put_u32(0xFFFF_FFFF);
        let (msg, whole) = fft_frame();
        buf.extend_from_slice(&whole);
        let mut decoder = FrameDecoder::new();
        let capacity_before = buf.capacity();
        assert_eq!(
            decoder.decode(&mut buf),
            Err(DecodeError::Oversized {
                message_id: 30,
                payload_size: 0xFFFF_FFFF
            })
        );
        assert!(buf.capacity() <= capacity_before);
        assert_eq!(
            decoder.decode(&mut buf),
            Err(DecodeError::BadSignature { skipped_bytes: 6 })
        );
        assert_eq!(decoder.decode(&mut buf), Ok(Some(msg)));
        assert_eq!(decoder.stats().frames_oversized, 1);
    }

    #[test]
    fn a_bad_version_is_rejected_and_the_stream_resyncs() {
        let (msg, whole) = fft_frame();
        let mut bad = whole.clone();
        bad[16] = 2;
        let mut buf = bad;
        buf.extend_from_slice(&whole);
        let mut decoder = FrameDecoder::new();
        assert_eq!(
            decoder.decode(&mut buf),
            Err(DecodeError::BadVersion { version: 2 })
        );
        let skipped = decoder.decode(&mut buf);
        assert_eq!(
            skipped,
            Err(DecodeError::BadSignature {
                skipped_bytes: whole.len() - 16
            })
        );
        assert_eq!(decoder.decode(&mut buf), Ok(Some(msg)));
        assert_eq!(decoder.stats().frames_bad_version, 1);
    }

    #[test]
    fn a_malformed_payload_costs_only_its_frame() {
        let mut buf = BytesMut::new();
        // FFT data offset 200 in a 20-byte payload.
        let mut payload = vec![0u8; 20];
        payload[1] = 200;
        encode_raw_frame(&mut buf, 30, &payload).unwrap();
        let (msg, whole) = fft_frame();
        buf.extend_from_slice(&whole);
        let mut decoder = FrameDecoder::new();
        assert!(matches!(
            decoder.decode(&mut buf),
            Err(DecodeError::Payload { message_id: 30, .. })
        ));
        assert_eq!(decoder.decode(&mut buf), Ok(Some(msg)));
        assert_eq!(decoder.stats().frames_bad_payload, 1);
        assert_eq!(decoder.stats().bytes_skipped, 0);
    }

    #[test]
    fn a_header_declaring_more_than_has_arrived_reserves_room_for_it() {
        let (_, whole) = fft_frame();
        let mut buf = BytesMut::from(&whole[..HEADER_LEN]);
        assert_eq!(FrameDecoder::new().decode(&mut buf), Ok(None));
        assert!(buf.capacity() >= whole.len());
    }

    #[test]
    fn an_unknown_id_decodes_as_unknown_and_is_counted() {
        let mut buf = BytesMut::new();
        encode_raw_frame(&mut buf, 99, b"abc").unwrap();
        let mut decoder = FrameDecoder::new();
        assert_eq!(
            decoder.decode(&mut buf),
            Ok(Some(Message::Unknown {
                id: 99,
                payload: Bytes::from_static(b"abc")
            }))
        );
        assert_eq!(decoder.stats().frames_unknown_id, 1);
    }
}
