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
//! | `Payload` with `PayloadError::CutShort` | the stub before the signature found inside it |
//!
//! Cut-short frames: when a sender stops mid-frame and starts a new frame, a decoder that
//! trusts the header would swallow the start of the next frame as payload (and, for FFT
//! data, hand out a corrupted azimuth). So, by default, the bytes of the frame at the
//! front of the buffer are searched for the signature as they arrive (each byte once,
//! with `memmem`); a signature inside a frame's declared extent marks it cut short, the
//! stub is dropped, and decoding resumes at the signature, without waiting for the rest
//! of the declared length. The signature is 16 fixed bytes, so a false alarm in real data
//! is a 2^-128 event per position. [`FrameDecoder::set_cut_short_detection`] turns it off.

use bytes::{Buf, Bytes, BytesMut};
use memchr::memmem;

use crate::error::{DecodeError, PayloadError};
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
    /// Bytes of whole frames rejected for a malformed payload, and of cut-short stubs.
    pub bytes_bad_payload: u64,
    /// Frames cut short by the next frame's signature (also counted in
    /// `frames_bad_payload`).
    pub frames_cut_short: u64,
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
    /// Search frames in progress for a signature (cut-short detection).
    detect_cut_short: bool,
    /// Bytes at the front of the buffer already searched for a signature; reset whenever
    /// bytes are consumed.
    scanned: usize,
    /// Address of the buffer's first byte when `scanned` was recorded: if the caller moved
    /// the front (or the buffer was reallocated), the search starts again.
    scanned_front: usize,
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
            detect_cut_short: true,
            scanned: 0,
            scanned_front: 0,
        }
    }

    /// Turns cut-short detection (see the module docs) on or off; on by default. Off, a
    /// frame is trusted to its declared length.
    pub fn set_cut_short_detection(&mut self, enabled: bool) {
        self.detect_cut_short = enabled;
        self.scanned = 0;
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
        self.decode_inner(buf, false)
    }

    /// As [`FrameDecoder::decode`], for when no more bytes will come (end of a file or of
    /// a connection): a whole frame is never held back waiting to see whether a signature
    /// straddles its end.
    pub fn decode_eof(&mut self, buf: &mut BytesMut) -> Result<Option<Message>, DecodeError> {
        self.decode_inner(buf, true)
    }

    /// Whether `buf` starts with a whole frame that [`FrameDecoder::decode`] returned
    /// `Ok(None)` for: held back because its last bytes could be the start of the next
    /// frame's signature (a contour whose last value is `00 01`). A caller that has waited
    /// for more bytes and got none (a client sends one command and waits for the answer)
    /// calls [`FrameDecoder::decode_eof`] to take it.
    pub fn holds_whole_frame(&self, buf: &[u8]) -> bool {
        let Some(header) = buf.get(..HEADER_LEN) else {
            return false;
        };
        let mut bytes = [0u8; HEADER_LEN];
        bytes.copy_from_slice(header);
        FrameHeader::parse(&bytes).is_ok_and(|h| buf.len() >= h.frame_len())
    }

    fn decode_inner(
        &mut self,
        buf: &mut BytesMut,
        at_eof: bool,
    ) -> Result<Option<Message>, DecodeError> {
        let skip = self.garbage_len(buf);
        if skip > 0 {
            buf.advance(skip);
            self.scanned = 0;
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
                self.scanned = 0;
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
        if self.detect_cut_short {
            if let Some(stub_len) = self.find_cut(buf, frame_len) {
                buf.advance(stub_len);
                self.scanned = 0;
                self.stats.frames_bad_payload += 1;
                self.stats.frames_cut_short += 1;
                self.stats.bytes_bad_payload += stub_len as u64;
                return Err(DecodeError::Payload {
                    message_id: header.message_id,
                    source: PayloadError::CutShort {
                        declared: header.payload_size,
                        received: stub_len.saturating_sub(HEADER_LEN),
                    },
                });
            }
        }
        if buf.len() < frame_len {
            // The size is validated (< 1e6), so reserving it is bounded.
            buf.reserve(frame_len - buf.len());
            return Ok(None);
        }
        if self.detect_cut_short && !at_eof && self.signature_may_straddle_end(buf, &header) {
            // Wait for at most 15 more bytes to tell a cut frame from a whole one.
            return Ok(None);
        }
        self.scanned = 0;
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

    /// For a frame with a valid header at the front of `buf`, the position of a signature
    /// that starts inside the frame's extent, if any. A new signature can start no earlier
    /// than byte 17 (byte 16 is the version, 1, and the signature starts with 0). Bytes
    /// already searched are not searched again, except the 15 that a signature could
    /// straddle.
    fn find_cut(&mut self, buf: &[u8], frame_len: usize) -> Option<usize> {
        const EARLIEST: usize = SIGNATURE.len() + 1;
        let front = buf.as_ptr() as usize;
        if front != self.scanned_front {
            self.scanned = 0;
            self.scanned_front = front;
        }
        let end = buf.len().min(frame_len + SIGNATURE.len() - 1);
        let from = self
            .scanned
            .saturating_sub(SIGNATURE.len() - 1)
            .max(EARLIEST);
        let found = buf
            .get(from..end)
            .and_then(|window| self.finder.find(window))
            .map(|pos| from + pos)
            .filter(|&pos| pos < frame_len);
        self.scanned = self.scanned.max(end);
        found
    }

    /// Whether a whole frame at the front of `buf` ends in what may be the first bytes of
    /// a signature that the bytes received so far can neither confirm nor rule out: at
    /// least two bytes of a signature prefix ("00 01") starting inside the frame and
    /// running to the end of the buffer. A one-byte match (a lone 0x00 at the very end) is
    /// held back only when the frame's payload does not decode or its id is unknown (the
    /// payload is copied to be tried only then): such a frame is typically a stub whose size
    /// field was cut inside and completed by the next signature's first byte. A good frame of
    /// a known id ending in a zero byte is not held back; the cost is that a good-looking
    /// frame cut exactly one byte short also loses the next frame.
    fn signature_may_straddle_end(&self, buf: &[u8], header: &FrameHeader) -> bool {
        let frame_len = header.frame_len();
        let confirm_end = frame_len + SIGNATURE.len() - 1;
        if buf.len() >= confirm_end {
            return false; // `find_cut` has seen every signature that could straddle.
        }
        let from = frame_len
            .saturating_sub(SIGNATURE.len() - 1)
            .max(SIGNATURE.len() + 1);
        let prefix_from = |p: usize, min: usize| {
            buf.get(p..).is_some_and(|tail| {
                tail.len() >= min && tail.len() < SIGNATURE.len() && SIGNATURE.starts_with(tail)
            })
        };
        (from..frame_len).any(|p| prefix_from(p, 2))
            || (prefix_from(frame_len - 1, 1) && {
                let payload = Bytes::copy_from_slice(buf.get(HEADER_LEN..frame_len).unwrap_or(&[]));
                // An unknown id decodes from any bytes, so it is held back too: a stub of
                // one whose size field was completed by the next signature's 0x00 must not
                // take that byte (holding back a message the daemon ignores costs nothing).
                matches!(
                    Message::decode_payload(header.message_id, payload),
                    Err(_) | Ok(Message::Unknown { .. })
                )
            })
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

    #[test]
    fn a_frame_cut_short_by_the_next_frame_costs_only_the_stub() {
        let (msg, whole) = fft_frame();
        let mut buf = BytesMut::from(&whole[..HEADER_LEN + 3]);
        buf.extend_from_slice(&whole);
        let mut decoder = FrameDecoder::new();
        assert_eq!(
            decoder.decode(&mut buf),
            Err(DecodeError::Payload {
                message_id: 30,
                source: PayloadError::CutShort {
                    declared: 19,
                    received: 3
                }
            })
        );
        assert_eq!(decoder.decode(&mut buf), Ok(Some(msg)));
        assert!(buf.is_empty());
        assert_eq!(decoder.stats().frames_cut_short, 1);
    }

    #[test]
    fn a_cut_short_frame_is_detected_before_its_declared_length_arrives() {
        // A header declaring 3000 bytes, 10 bytes of it, then a keep-alive: the keep-alive
        // must come out now, not after 3000 more bytes.
        let mut buf = BytesMut::new();
        crate::frame::encode_header(&mut buf, 30, 3000).unwrap();
        buf.put_slice(&[7; 10]);
        Message::KeepAlive.encode(&mut buf).unwrap();
        let mut decoder = FrameDecoder::new();
        assert!(matches!(
            decoder.decode(&mut buf),
            Err(DecodeError::Payload {
                source: PayloadError::CutShort { .. },
                ..
            })
        ));
        assert_eq!(decoder.decode(&mut buf), Ok(Some(Message::KeepAlive)));
    }

    #[test]
    fn a_signature_arriving_a_byte_at_a_time_inside_a_frame_is_still_found() {
        let mut stream = BytesMut::new();
        crate::frame::encode_header(&mut stream, 30, 500).unwrap();
        stream.put_slice(&[9; 40]);
        Message::KeepAlive.encode(&mut stream).unwrap();
        let mut decoder = FrameDecoder::new();
        let mut buf = BytesMut::new();
        let mut out = Vec::new();
        for &b in stream.iter() {
            buf.put_u8(b);
            while let Some(r) = match decoder.decode(&mut buf) {
                Ok(None) => None,
                other => Some(other),
            } {
                out.push(r);
            }
        }
        assert_eq!(out.len(), 2, "{out:?}");
        assert_eq!(out[1], Ok(Some(Message::KeepAlive)));
        assert_eq!(decoder.stats().bytes_consumed(), stream.len() as u64);
    }

    /// A stub cut inside its size field, completed by the next signature's first byte
    /// (0x00) into a header that declares one byte more than the stub holds, arriving with
    /// only that byte of the next frame: its payload does not decode, so it waits for the
    /// bytes that tell, is found cut short, and the next frame is decoded. (Found by the
    /// stream property test `a_frame_cut_short_by_the_next_costs_only_itself`: the stub
    /// was emitted as a bad frame and took the next frame's first byte with it.)
    #[test]
    fn a_stub_whose_cut_size_field_claims_the_next_frames_first_byte_costs_only_itself() {
        let mut whole = BytesMut::new();
        Message::SetNavThreshold {
            threshold_db_x10: 8989,
        }
        .encode(&mut whole)
        .unwrap();
        let mut stream = BytesMut::from(&whole[..HEADER_LEN - 1]);
        Message::StopNavData.encode(&mut stream).unwrap();
        let mut decoder = FrameDecoder::new();
        let mut buf = BytesMut::from(&stream[..HEADER_LEN]);
        assert_eq!(decoder.decode(&mut buf), Ok(None), "a bad frame waits");
        buf.extend_from_slice(&stream[HEADER_LEN..]);
        assert!(matches!(
            decoder.decode(&mut buf),
            Err(DecodeError::Payload {
                source: PayloadError::CutShort { .. },
                ..
            })
        ));
        assert_eq!(decoder.decode(&mut buf), Ok(Some(Message::StopNavData)));
        assert!(buf.is_empty());
    }

    #[test]
    fn with_cut_short_detection_off_a_frame_is_trusted_to_its_length() {
        let (_, whole) = fft_frame();
        let mut buf = BytesMut::from(&whole[..HEADER_LEN + 3]);
        buf.extend_from_slice(&whole);
        let mut decoder = FrameDecoder::new();
        decoder.set_cut_short_detection(false);
        // The stub swallows the start of the next frame, which is then lost as garbage.
        let first = decoder.decode(&mut buf);
        assert!(
            !matches!(
                first,
                Err(DecodeError::Payload {
                    source: PayloadError::CutShort { .. },
                    ..
                })
            ),
            "{first:?}"
        );
        assert!(matches!(
            decoder.decode(&mut buf),
            Err(DecodeError::BadSignature { .. })
        ));
        assert_eq!(decoder.stats().frames_cut_short, 0);
    }

    #[test]
    fn a_frame_ending_in_a_possible_signature_start_waits_for_15_more_bytes_or_eof() {
        let msg = Message::Health(Bytes::from_static(&[9, 9, 0x00, 0x01, 0x03]));
        let mut whole = BytesMut::new();
        msg.encode(&mut whole).unwrap();
        let mut decoder = FrameDecoder::new();
        let mut buf = whole.clone();
        assert_eq!(decoder.decode(&mut buf), Ok(None));
        // Bytes that rule the signature out release it.
        buf.put_slice(&[0xAA]);
        assert_eq!(decoder.decode(&mut buf), Ok(Some(msg.clone())));
        // At the end of the input, it is released at once.
        let mut buf = whole.clone();
        assert_eq!(decoder.decode_eof(&mut buf), Ok(Some(msg)));
    }

    #[test]
    fn a_contour_ending_in_00_01_is_held_and_said_to_be_whole_so_a_caller_can_take_it() {
        // Navtech's clients send one contour and wait: its last value 1 (`00 01`) could
        // start a signature, so `decode` holds it; `holds_whole_frame` tells the caller
        // that a whole frame is there, and `decode_eof` takes it.
        let mut bins = Box::new([500u16; crate::CONTOUR_DEGREES]);
        bins[359] = 1;
        let msg = Message::ContourUpdate(crate::ContourUpdate::MaxBinPerDegree(bins));
        let mut buf = BytesMut::new();
        msg.encode(&mut buf).unwrap();
        let mut decoder = FrameDecoder::new();
        assert!(!decoder.holds_whole_frame(&buf[..buf.len() - 1]));
        assert_eq!(decoder.decode(&mut buf), Ok(None));
        assert!(decoder.holds_whole_frame(&buf));
        assert_eq!(decoder.decode_eof(&mut buf), Ok(Some(msg)));
        assert!(buf.is_empty() && !decoder.holds_whole_frame(&buf));
    }

    #[test]
    fn a_frame_cut_one_byte_short_is_not_held_back() {
        // A lone trailing zero is too common in real bins to wait on.
        let msg = Message::Health(Bytes::from_static(&[9, 9, 0x00]));
        let mut buf = BytesMut::new();
        msg.encode(&mut buf).unwrap();
        assert_eq!(FrameDecoder::new().decode(&mut buf), Ok(Some(msg)));
    }
}
