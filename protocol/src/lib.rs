//! The Navtech Colossus TCP wire format: frames, every message, a streaming decoder that
//! resynchronises after garbage, encoders, and the unit conversions that turn wire integers
//! into angles, powers, ranges and times.
//!
//! This crate does **no IO and reads no clock** (in the style of `quinn-proto`): bytes come
//! in as [`bytes::BytesMut`] / [`bytes::Bytes`], messages go out into a [`bytes::BytesMut`].
//! The driver and the simulator own the sockets.
//!
//! # Frame layout (`docs/colossus-protocol.md`, section 1)
//!
//! | offset | size | field | encoding |
//! |---|---|---|---|
//! | 0 | 16 | signature | `00 01 03 03 07 07 0F 0F 1F 1F 3F 3F 7F 7F FE FE` |
//! | 16 | 1 | version | always 1 |
//! | 17 | 1 | message id | u8 |
//! | 18 | 4 | payload size | u32 big-endian |
//!
//! # Decoding a stream
//!
//! ```
//! use bytes::BytesMut;
//! use protocol::{FrameDecoder, Message};
//!
//! let mut wire = BytesMut::new();
//! Message::KeepAlive.encode(&mut wire).unwrap();
//! let mut decoder = FrameDecoder::new();
//! assert_eq!(decoder.decode(&mut wire).unwrap(), Some(Message::KeepAlive));
//! assert_eq!(decoder.decode(&mut wire).unwrap(), None); // needs more bytes
//! ```
//!
//! After an `Err`, the offending bytes have already been consumed: call `decode` again.
//! A bad frame costs that frame, never the stream: garbage is skipped up to the next
//! signature, a bad header loses its signature, a malformed payload its frame, and a
//! frame cut short by the next frame's signature only its stub (see [`FrameDecoder`]).
//! When no more bytes will come (end of a file), drain with
//! [`FrameDecoder::decode_eof`], which never holds back a whole frame.
//!
//! Decoded FFT bins, health payloads and unknown payloads are [`bytes::Bytes`] slices of
//! the input buffer: no bin is copied.

mod configuration;
mod contour;
mod decoder;
mod error;
mod fft;
mod frame;
mod ids;
mod message;
mod navigation;
mod proto;
mod reader;
mod sectors;
mod timestamp;
pub mod units;

pub use configuration::{Configuration, Geometry, CONFIGURATION_FIXED_LEN};
pub use contour::{ContourUpdate, CONTOUR_DEGREES};
pub use decoder::{DecoderStats, FrameDecoder};
pub use error::{ConversionError, DecodeError, EncodeError, GeometryError, PayloadError};
pub use fft::{encode_fft_frame, encode_fft_frame_from_db, BinWidth, FftData, FFT_HEADER_LEN};
pub use frame::{
    encode_header, encode_raw_frame, FrameHeader, HEADER_LEN, MAX_PAYLOAD_SIZE, PROTOCOL_VERSION,
    SIGNATURE,
};
pub use message::{message_id, Message};
pub use navigation::{NavigationData, NavigationTarget, NAVIGATION_TARGET_LEN};
pub use proto::{radar_features, ConfigurationData, RadarModel};
pub use sectors::{BlankingSector, SectorBlanking};
pub use timestamp::Timestamp;
pub use units::{
    azimuth_to_deg, azimuth_to_rad, bin16_to_db, bin8_to_db, bin_to_range_m,
    bin_to_range_m_by_resolution, db_to_bin16, db_to_bin8,
};
