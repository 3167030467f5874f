//! Typed errors: one named variant per kind of malformed input.

/// A payload that does not match its message's layout (`docs/colossus-protocol.md`, s. 2-3).
///
/// Produced by [`crate::Message::decode_payload`]; the streaming decoder wraps it in
/// [`DecodeError::Payload`] together with the message id.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PayloadError {
    /// The payload ends before a fixed field does.
    #[error("payload truncated: needs at least {needed} bytes, has {got}")]
    Truncated { needed: usize, got: usize },
    /// A fixed-size payload (header-only messages, the navigation threshold) has the
    /// wrong size.
    #[error("payload has {got} bytes where exactly {expected} are expected")]
    WrongLength { expected: usize, got: usize },
    /// The FFT data offset points inside the 14-byte FFT header.
    #[error("FFT data offset {offset} lies inside the 14-byte FFT header")]
    FftDataOffsetTooSmall { offset: u16 },
    /// The FFT data offset points past the end of the payload.
    #[error("FFT data offset {offset} lies beyond the payload of {payload_len} bytes")]
    FftDataOffsetBeyondPayload { offset: u16, payload_len: usize },
    /// A 16-bit FFT message whose bin bytes are not a whole number of bins.
    #[error("16-bit FFT message has an odd number of bin bytes ({len})")]
    OddBinPayload { len: usize },
    /// Split seconds of a timestamp are not below 10^9.
    #[error("timestamp nanoseconds {nanos} are not below 1e9")]
    BadNanos { nanos: u32 },
    /// The configuration's protobuf tail does not decode.
    #[error("configuration protobuf does not decode: {0}")]
    Protobuf(#[from] prost::DecodeError),
    /// A sector blanking update whose count disagrees with its length.
    #[error(
        "sector blanking update declares {count} sectors but its payload has {payload_len} bytes"
    )]
    BadSectorCount { count: u8, payload_len: usize },
    /// A contour update that is neither empty nor 360 x u16.
    #[error("contour update has {len} bytes; expected 0 (reset) or 720")]
    BadContourLength { len: usize },
    /// The next frame's signature appeared inside this frame's declared payload: the frame
    /// was cut short (its sender stopped mid-frame and started a new one). Only the stub,
    /// up to that signature, was consumed.
    #[error("frame cut short: the next signature starts {received} payload bytes into a declared {declared}")]
    CutShort { declared: u32, received: usize },
    /// Navigation data whose target list is not a whole number of 6-byte targets.
    #[error("navigation data has {len} target bytes, not a multiple of 6")]
    BadNavigationTargets { len: usize },
}

/// An error from the streaming [`crate::FrameDecoder`]. The bytes at fault have already
/// been consumed when this is returned: call `decode` again to carry on.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// Bytes that do not start a frame were skipped while looking for the signature.
    #[error("bad signature: skipped {skipped_bytes} bytes to resynchronise")]
    BadSignature { skipped_bytes: usize },
    /// A frame header with a version other than 1; its signature was skipped.
    #[error("unsupported protocol version {version}")]
    BadVersion { version: u8 },
    /// A frame header declaring a payload of 1,000,000 bytes or more; rejected before any
    /// memory was reserved, and its signature skipped.
    #[error("message {message_id} declares an oversized payload of {payload_size} bytes")]
    Oversized { message_id: u8, payload_size: u32 },
    /// A whole frame arrived but its payload is malformed; the frame was consumed.
    #[error("message {message_id}: {source}")]
    Payload {
        message_id: u8,
        #[source]
        source: PayloadError,
    },
}

/// A message that cannot be put on the wire as it stands. Nothing is written to the
/// destination buffer when this is returned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EncodeError {
    /// The payload would be 1,000,000 bytes or more, which every receiver rejects.
    #[error("message {message_id} payload of {payload_len} bytes exceeds the protocol limit")]
    PayloadTooLarge { message_id: u8, payload_len: usize },
    /// 16-bit FFT bins given as an odd number of bytes.
    #[error("16-bit FFT bins given as an odd number of bytes ({len})")]
    OddBinBytes { len: usize },
    /// An FFT data offset below the 14-byte FFT header.
    #[error("FFT data offset {offset} lies inside the 14-byte FFT header")]
    FftDataOffsetTooSmall { offset: u16 },
    /// More than 255 blanking sectors.
    #[error("{count} blanking sectors; at most 255 fit the count byte")]
    TooManySectors { count: usize },
    /// A dB value that is not finite cannot be quantised to a bin.
    #[error("power {power_db} dB at bin {index} is not finite")]
    NonFinitePower { index: usize, power_db: f64 },
    /// An `ExactSizeIterator` of powers yielded a different number of items than it
    /// declared; the partial frame was removed.
    #[error("power iterator declared {declared} bin bytes but yielded {written}")]
    IteratorLengthMismatch { declared: usize, written: usize },
}

/// A conversion between wire integers and physical values that has no answer.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ConversionError {
    /// Encoder size 0: angles are undefined.
    #[error("encoder size is 0: azimuth angles are undefined")]
    ZeroEncoderSize,
    /// A time that does not fit the wire's u32 seconds + nanoseconds.
    #[error("time {seconds} s does not fit u32 seconds since the Unix epoch")]
    TimeOutOfRange { seconds: f64 },
    /// Nanoseconds not below 10^9.
    #[error("timestamp nanoseconds {nanos} are not below 1e9")]
    BadNanos { nanos: u32 },
}

/// A configuration that does not describe a usable radar geometry.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GeometryError {
    /// Encoder size 0.
    #[error("encoder size is 0")]
    ZeroEncoderSize,
    /// Zero azimuths per rotation.
    #[error("azimuth samples is 0")]
    ZeroAzimuthSamples,
    /// Bin size 0.
    #[error("bin size is 0")]
    ZeroBinSize,
    /// A protobuf `datawidth` other than 8 or 16.
    #[error("data width {0} bits is neither 8 nor 16")]
    BadDataWidth(i32),
    /// Range gain or offset not finite.
    #[error("range gain {gain} or offset {offset_m} m is not finite")]
    NonFiniteRangeCalibration { gain: f32, offset_m: f32 },
    /// A range gain of zero or below: every bin would map to the same range (or behind the
    /// radar), and ranges could not be turned back into bins.
    #[error("range gain {0} is not positive")]
    NonPositiveRangeGain(f32),
}
