//! FFT data (messages 30 and 31): one azimuth's power-range spectrum
//! (`docs/colossus-protocol.md`, section 3.2).
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | u16 BE | FFT data offset (where the bins start; 14 today, always read) |
//! | 2 | u16 BE | sweep counter |
//! | 4 | u16 BE | azimuth, encoder counts |
//! | 6 | u32 LE | seconds since the Unix epoch |
//! | 10 | u32 LE | nanoseconds within the second |
//! | offset.. | bytes | bins: 1 byte each (30) or 2 bytes LE each (31) |
//!
//! Decoded bins are a [`Bytes`] slice of the received buffer: nothing is copied.

use bytes::{BufMut, Bytes, BytesMut};

use crate::error::{EncodeError, PayloadError};
use crate::frame::{checked_payload_size, encode_header, HEADER_LEN};
use crate::ids::message_id;
use crate::reader::Reader;
use crate::timestamp::Timestamp;
use crate::units;

/// Length of the fixed FFT header inside the payload, and the usual FFT data offset.
pub const FFT_HEADER_LEN: usize = 14;

/// Bits per bin: message 30 carries 8-bit bins, message 31 16-bit little-endian bins.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum BinWidth {
    /// One byte a bin; dB = value / 2.
    #[default]
    Eight,
    /// Two bytes a bin, little-endian; dB = (raw / 256) x (96.5 / 141.5).
    Sixteen,
}

impl BinWidth {
    /// Bytes per bin: 1 or 2.
    pub fn bytes_per_bin(self) -> usize {
        match self {
            BinWidth::Eight => 1,
            BinWidth::Sixteen => 2,
        }
    }

    /// Bits per bin, as in the protobuf's `datawidth`: 8 or 16.
    pub fn bits(self) -> i32 {
        match self {
            BinWidth::Eight => 8,
            BinWidth::Sixteen => 16,
        }
    }

    /// The FFT message id for this width: 30 or 31.
    pub fn message_id(self) -> u8 {
        match self {
            BinWidth::Eight => message_id::FFT_DATA,
            BinWidth::Sixteen => message_id::HIGH_PRECISION_FFT_DATA,
        }
    }

    /// Power in dB of one bin given as its bytes (1 or 2, little-endian).
    fn db_of(self, bytes: &[u8]) -> f64 {
        match (self, bytes) {
            (BinWidth::Eight, [v, ..]) => units::bin8_to_db(*v),
            (BinWidth::Sixteen, [lo, hi, ..]) => units::bin16_to_db(u16::from_le_bytes([*lo, *hi])),
            _ => 0.0,
        }
    }
}

/// One azimuth of FFT data.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FftData {
    /// 8- or 16-bit bins (message 30 or 31).
    pub width: BinWidth,
    /// Where the bins start inside the payload (>= 14). Encoding pads bytes 14..offset
    /// with zeros.
    pub fft_data_offset: u16,
    /// +1 per azimuth message, wrapping.
    pub sweep_counter: u16,
    /// Azimuth in encoder counts.
    pub azimuth: u16,
    /// When the azimuth was measured.
    pub timestamp: Timestamp,
    /// Raw bin bytes: one per bin (8-bit), or two little-endian per bin (16-bit; always an
    /// even count when decoded).
    pub bins: Bytes,
}

impl FftData {
    /// An FFT message with the standard 14-byte data offset.
    pub fn new(
        width: BinWidth,
        sweep_counter: u16,
        azimuth: u16,
        timestamp: Timestamp,
        bins: Bytes,
    ) -> Self {
        Self {
            width,
            fft_data_offset: FFT_HEADER_LEN as u16,
            sweep_counter,
            azimuth,
            timestamp,
            bins,
        }
    }

    /// Decodes a message 30 (`BinWidth::Eight`) or 31 (`BinWidth::Sixteen`) payload. The
    /// bins are a slice of `payload`, not a copy.
    pub fn decode(payload: &Bytes, width: BinWidth) -> Result<Self, PayloadError> {
        let mut r = Reader::new(payload);
        let fft_data_offset = r.u16_be()?;
        let sweep_counter = r.u16_be()?;
        let azimuth = r.u16_be()?;
        let seconds = r.u32_le()?;
        let nanos = r.u32_le()?;
        let offset = usize::from(fft_data_offset);
        if offset < FFT_HEADER_LEN {
            return Err(PayloadError::FftDataOffsetTooSmall {
                offset: fft_data_offset,
            });
        }
        if offset > payload.len() {
            return Err(PayloadError::FftDataOffsetBeyondPayload {
                offset: fft_data_offset,
                payload_len: payload.len(),
            });
        }
        let bins = payload.slice(offset..);
        if width == BinWidth::Sixteen && !bins.len().is_multiple_of(2) {
            return Err(PayloadError::OddBinPayload { len: bins.len() });
        }
        let timestamp =
            Timestamp::new(seconds, nanos).map_err(|_| PayloadError::BadNanos { nanos })?;
        Ok(Self {
            width,
            fft_data_offset,
            sweep_counter,
            azimuth,
            timestamp,
            bins,
        })
    }

    /// Number of bins (payload size minus data offset, over the bytes per bin). May be
    /// fewer than the configuration's range in bins (contour) or zero (blanked sector).
    pub fn bin_count(&self) -> usize {
        self.bins.len() / self.width.bytes_per_bin()
    }

    /// Raw value of bin `index` (a u8 widened, or the LE u16), if it exists.
    pub fn bin_raw(&self, index: usize) -> Option<u16> {
        match self.width {
            BinWidth::Eight => self.bins.get(index).copied().map(u16::from),
            BinWidth::Sixteen => {
                let start = index.checked_mul(2)?;
                let pair = self.bins.get(start..start.checked_add(2)?)?;
                match pair {
                    [lo, hi] => Some(u16::from_le_bytes([*lo, *hi])),
                    _ => None,
                }
            }
        }
    }

    /// Power of bin `index` in dB, if it exists.
    pub fn power_db(&self, index: usize) -> Option<f64> {
        let raw = self.bin_raw(index)?;
        Some(match self.width {
            BinWidth::Eight => units::bin8_to_db(u8::try_from(raw).unwrap_or(u8::MAX)),
            BinWidth::Sixteen => units::bin16_to_db(raw),
        })
    }

    /// Iterates over the bins' powers in dB, without allocating.
    pub fn bins_db(&self) -> impl ExactSizeIterator<Item = f64> + '_ {
        let width = self.width;
        self.bins
            .chunks_exact(width.bytes_per_bin())
            .map(move |b| width.db_of(b))
    }

    /// Replaces the contents of `out` with the bins' powers in dB (reusing its capacity).
    /// Same values as [`FftData::bins_db`], rounded to f32; a loop per width so it
    /// vectorises.
    pub fn bins_db_into(&self, out: &mut Vec<f32>) {
        out.clear();
        match self.width {
            // v / 2 is exact in f32 for every u8.
            BinWidth::Eight => out.extend(self.bins.iter().map(|&v| f32::from(v) * 0.5)),
            BinWidth::Sixteen => out.extend(self.bins.chunks_exact(2).map(|pair| match pair {
                [lo, hi] => units::bin16_to_db(u16::from_le_bytes([*lo, *hi])) as f32,
                _ => 0.0,
            })),
        }
    }

    /// Payload length when encoded.
    pub fn encoded_payload_len(&self) -> usize {
        usize::from(self.fft_data_offset).max(FFT_HEADER_LEN) + self.bins.len()
    }

    /// Checks that this message can be encoded.
    pub(crate) fn validate_for_encoding(&self) -> Result<(), EncodeError> {
        if usize::from(self.fft_data_offset) < FFT_HEADER_LEN {
            return Err(EncodeError::FftDataOffsetTooSmall {
                offset: self.fft_data_offset,
            });
        }
        if self.width == BinWidth::Sixteen && !self.bins.len().is_multiple_of(2) {
            return Err(EncodeError::OddBinBytes {
                len: self.bins.len(),
            });
        }
        checked_payload_size(self.width.message_id(), self.encoded_payload_len())?;
        Ok(())
    }

    /// Writes the payload (no frame header). Call `validate_for_encoding` first.
    pub(crate) fn encode_payload(&self, dst: &mut BytesMut) {
        put_fft_header(
            dst,
            self.fft_data_offset,
            self.sweep_counter,
            self.azimuth,
            self.timestamp,
        );
        dst.put_slice(&self.bins);
    }
}

/// Writes the FFT header fields and any zero padding up to `fft_data_offset`.
fn put_fft_header(
    dst: &mut BytesMut,
    fft_data_offset: u16,
    sweep_counter: u16,
    azimuth: u16,
    timestamp: Timestamp,
) {
    dst.put_u16(fft_data_offset);
    dst.put_u16(sweep_counter);
    dst.put_u16(azimuth);
    dst.put_u32_le(timestamp.seconds());
    dst.put_u32_le(timestamp.nanos());
    let padding = usize::from(fft_data_offset).saturating_sub(FFT_HEADER_LEN);
    dst.put_bytes(0, padding);
}

/// Writes a whole FFT frame (header, FFT header, bins) straight into `dst` from raw bin
/// bytes: the bins are copied once, into the output. `bins` holds one byte per bin
/// (`Eight`) or two little-endian bytes per bin (`Sixteen`). Writes nothing on error.
pub fn encode_fft_frame(
    dst: &mut BytesMut,
    width: BinWidth,
    sweep_counter: u16,
    azimuth: u16,
    timestamp: Timestamp,
    bins: &[u8],
) -> Result<(), EncodeError> {
    if width == BinWidth::Sixteen && !bins.len().is_multiple_of(2) {
        return Err(EncodeError::OddBinBytes { len: bins.len() });
    }
    let payload_len = FFT_HEADER_LEN + bins.len();
    checked_payload_size(width.message_id(), payload_len)?;
    dst.reserve(HEADER_LEN + payload_len);
    encode_header(dst, width.message_id(), payload_len)?;
    put_fft_header(
        dst,
        FFT_HEADER_LEN as u16,
        sweep_counter,
        azimuth,
        timestamp,
    );
    dst.put_slice(bins);
    Ok(())
}

/// Writes a whole FFT frame into `dst`, quantising powers in dB to bins on the way (no
/// intermediate buffer): 8-bit bins are `round(2 x dB)`, 16-bit bins
/// `round(dB x 141.5 / 96.5 x 256)`, both saturating at the ends of their range.
/// A non-finite power is an error; nothing is written on error.
pub fn encode_fft_frame_from_db<I>(
    dst: &mut BytesMut,
    width: BinWidth,
    sweep_counter: u16,
    azimuth: u16,
    timestamp: Timestamp,
    power_db: I,
) -> Result<(), EncodeError>
where
    I: IntoIterator<Item = f64>,
    I::IntoIter: ExactSizeIterator,
{
    let powers = power_db.into_iter();
    let declared_bins = powers.len();
    let bin_bytes =
        declared_bins
            .checked_mul(width.bytes_per_bin())
            .ok_or(EncodeError::PayloadTooLarge {
                message_id: width.message_id(),
                payload_len: usize::MAX,
            })?;
    let payload_len = bin_bytes.saturating_add(FFT_HEADER_LEN);
    checked_payload_size(width.message_id(), payload_len)?;
    let start = dst.len();
    dst.reserve(HEADER_LEN + payload_len);
    encode_header(dst, width.message_id(), payload_len)?;
    put_fft_header(
        dst,
        FFT_HEADER_LEN as u16,
        sweep_counter,
        azimuth,
        timestamp,
    );
    // Quantise into a small stack buffer and copy it out in blocks: one capacity check per
    // block instead of per bin.
    let mut block = [0u8; 512];
    let mut filled = 0;
    // `take` bounds the output even if the iterator yields more than it declared.
    for (index, db) in powers.take(declared_bins).enumerate() {
        if !db.is_finite() {
            dst.truncate(start);
            return Err(EncodeError::NonFinitePower {
                index,
                power_db: db,
            });
        }
        let (bytes, n) = match width {
            BinWidth::Eight => ([units::db_to_bin8(db), 0], 1),
            BinWidth::Sixteen => (units::db_to_bin16(db).to_le_bytes(), 2),
        };
        if let Some(slot) = block.get_mut(filled..filled + n) {
            slot.copy_from_slice(&bytes[..n]);
            filled += n;
        }
        if filled + 2 > block.len() {
            dst.put_slice(&block[..filled]);
            filled = 0;
        }
    }
    dst.put_slice(&block[..filled]);
    // An ExactSizeIterator that lied about its length would leave a bad frame: undo it.
    if dst.len() - start != HEADER_LEN + payload_len {
        let written = dst.len() - start;
        dst.truncate(start);
        return Err(EncodeError::IteratorLengthMismatch {
            declared: bin_bytes,
            written: written.saturating_sub(HEADER_LEN + FFT_HEADER_LEN),
        });
    }
    Ok(())
}
