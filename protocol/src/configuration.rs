//! Configuration (message 10): the 20-byte fixed part and the `ConfigurationData` protobuf
//! tail (`docs/colossus-protocol.md`, section 3.1), and the [`Geometry`] summary derived
//! from it.
//!
//! | offset | type | field | unit |
//! |---|---|---|---|
//! | 0 | u16 BE | azimuth samples | azimuths per rotation |
//! | 2 | u16 BE | bin size | tenths of a millimetre |
//! | 4 | u16 BE | range in bins | bins per azimuth |
//! | 6 | u16 BE | encoder size | counts per revolution |
//! | 8 | u16 BE | rotation speed | millihertz |
//! | 10 | u16 BE | packet rate | azimuths per second |
//! | 12 | f32 BE | range gain | |
//! | 16 | f32 BE | range offset | metres |
//! | 20.. | protobuf | `ConfigurationData` | |

use bytes::{BufMut, Bytes, BytesMut};
use prost::Message as _;

use crate::error::{GeometryError, PayloadError};
use crate::fft::BinWidth;
use crate::proto::ConfigurationData;
use crate::reader::Reader;
use crate::units;

/// Length of the fixed part before the protobuf tail.
pub const CONFIGURATION_FIXED_LEN: usize = 20;

/// A decoded configuration message, wire values untouched.
#[derive(Debug, Clone, PartialEq)]
pub struct Configuration {
    /// Azimuths per rotation (400 on current units).
    pub azimuth_samples: u16,
    /// Bin size in tenths of a millimetre (0.0438 m is 438).
    pub bin_size: u16,
    /// Bins per azimuth.
    pub range_in_bins: u16,
    /// Encoder counts per revolution (5600 on current units).
    pub encoder_size: u16,
    /// Rotation speed in millihertz (4000 is 4 Hz).
    pub rotation_speed_millihertz: u16,
    /// Azimuths per second.
    pub packet_rate: u16,
    /// Range gain (dimensionless).
    pub range_gain: f32,
    /// Range offset in metres.
    pub range_offset_m: f32,
    /// The protobuf tail. Re-encoding writes it canonically (known fields, in field order).
    pub data: ConfigurationData,
}

impl Configuration {
    /// Decodes a configuration payload (fixed part, then protobuf to the end).
    pub fn decode(payload: &Bytes) -> Result<Self, PayloadError> {
        let mut r = Reader::new(payload);
        let azimuth_samples = r.u16_be()?;
        let bin_size = r.u16_be()?;
        let range_in_bins = r.u16_be()?;
        let encoder_size = r.u16_be()?;
        let rotation_speed_millihertz = r.u16_be()?;
        let packet_rate = r.u16_be()?;
        let range_gain = r.f32_be()?;
        let range_offset_m = r.f32_be()?;
        let tail = payload.slice(r.position()..);
        let data = ConfigurationData::decode(tail)?;
        Ok(Self {
            azimuth_samples,
            bin_size,
            range_in_bins,
            encoder_size,
            rotation_speed_millihertz,
            packet_rate,
            range_gain,
            range_offset_m,
            data,
        })
    }

    /// Payload length when encoded.
    pub fn encoded_payload_len(&self) -> usize {
        CONFIGURATION_FIXED_LEN + self.data.encoded_len()
    }

    /// Writes the payload (no frame header).
    pub(crate) fn encode_payload(&self, dst: &mut BytesMut) {
        dst.reserve(self.encoded_payload_len());
        dst.put_u16(self.azimuth_samples);
        dst.put_u16(self.bin_size);
        dst.put_u16(self.range_in_bins);
        dst.put_u16(self.encoder_size);
        dst.put_u16(self.rotation_speed_millihertz);
        dst.put_u16(self.packet_rate);
        dst.put_f32(self.range_gain);
        dst.put_f32(self.range_offset_m);
        // Configurations are rare (one per connection): an intermediate Vec is fine, and
        // `encode_to_vec` has no capacity error to handle.
        dst.put_slice(&self.data.encode_to_vec());
    }

    /// Bits per bin from the protobuf (`datawidth`), 8 when absent.
    pub fn data_width(&self) -> Result<BinWidth, GeometryError> {
        match self.data.datawidth {
            None | Some(8) => Ok(BinWidth::Eight),
            Some(16) => Ok(BinWidth::Sixteen),
            Some(other) => Err(GeometryError::BadDataWidth(other)),
        }
    }

    /// The validated geometry summary the driver and filter work with.
    pub fn geometry(&self) -> Result<Geometry, GeometryError> {
        if self.encoder_size == 0 {
            return Err(GeometryError::ZeroEncoderSize);
        }
        if self.azimuth_samples == 0 {
            return Err(GeometryError::ZeroAzimuthSamples);
        }
        if self.bin_size == 0 {
            return Err(GeometryError::ZeroBinSize);
        }
        if !self.range_gain.is_finite() || !self.range_offset_m.is_finite() {
            return Err(GeometryError::NonFiniteRangeCalibration {
                gain: self.range_gain,
                offset_m: self.range_offset_m,
            });
        }
        if self.range_gain <= 0.0 {
            return Err(GeometryError::NonPositiveRangeGain(self.range_gain));
        }
        Ok(Geometry {
            azimuth_samples: self.azimuth_samples,
            range_in_bins: self.range_in_bins,
            bin_size_m: f64::from(self.bin_size) / 10_000.0,
            encoder_size: self.encoder_size,
            rotation_hz: f64::from(self.rotation_speed_millihertz) / 1000.0,
            packet_rate: self.packet_rate,
            range_gain: f64::from(self.range_gain),
            range_offset_m: f64::from(self.range_offset_m),
            data_width: self.data_width()?,
            range_resolution_m: self
                .data
                .rangeresolutionmetres
                .filter(|r| r.is_finite() && *r > 0.0)
                .map(f64::from),
        })
    }
}

/// What a configuration says about the radar, in SI units, validated: encoder size,
/// azimuth samples and bin size are non-zero, gain and offset finite.
#[derive(Debug, Clone, PartialEq)]
pub struct Geometry {
    /// Azimuths per rotation.
    pub azimuth_samples: u16,
    /// Bins per azimuth (a contoured or blanked azimuth may carry fewer).
    pub range_in_bins: u16,
    /// Bin size in metres (before the range gain).
    pub bin_size_m: f64,
    /// Encoder counts per revolution, non-zero.
    pub encoder_size: u16,
    /// Rotations per second.
    pub rotation_hz: f64,
    /// Azimuths per second.
    pub packet_rate: u16,
    /// Range gain.
    pub range_gain: f64,
    /// Range offset in metres.
    pub range_offset_m: f64,
    /// Bits per bin: decides whether FFT data comes as message 30 or 31.
    pub data_width: BinWidth,
    /// `rangeresolutionmetres` from the protobuf, when present, finite and positive.
    pub range_resolution_m: Option<f64>,
}

impl Geometry {
    /// Azimuth in encoder counts to radians in [0, 2 pi).
    pub fn azimuth_rad(&self, azimuth: u16) -> f64 {
        f64::from(azimuth) * std::f64::consts::TAU / f64::from(self.encoder_size)
    }

    /// A CTS350-X as the Oxford Radar RobotCar data set records it: 400 azimuths of 3768
    /// 8-bit bins of 0.0438 m, 5600 encoder counts, 4 Hz. For tests, benchmarks and replays.
    pub fn cts350x() -> Self {
        Self {
            azimuth_samples: 400,
            range_in_bins: 3768,
            bin_size_m: 0.0438,
            encoder_size: 5600,
            rotation_hz: 4.0,
            packet_rate: 1600,
            range_gain: 1.0,
            range_offset_m: 0.0,
            data_width: BinWidth::Eight,
            range_resolution_m: None,
        }
    }

    /// Azimuth in encoder counts to the azimuth's index in the rotation,
    /// `encoder x azimuth_samples / encoder_size` rounded down, in `0..azimuth_samples` for
    /// encoder values inside the revolution (`None` past it, or for an empty geometry).
    /// With 5600 encoder counts and 400 azimuths, encoder 14 is azimuth 1.
    pub fn azimuth_index(&self, encoder: u16) -> Option<u16> {
        if encoder >= self.encoder_size || self.azimuth_samples == 0 {
            return None;
        }
        let index =
            u32::from(encoder) * u32::from(self.azimuth_samples) / u32::from(self.encoder_size);
        u16::try_from(index).ok()
    }

    /// Azimuth in encoder counts to degrees.
    pub fn azimuth_deg(&self, azimuth: u16) -> f64 {
        f64::from(azimuth) * 360.0 / f64::from(self.encoder_size)
    }

    /// Angular step between azimuths in radians: 2 pi / azimuth samples.
    pub fn azimuth_step_rad(&self) -> f64 {
        std::f64::consts::TAU / f64::from(self.azimuth_samples)
    }

    /// Encoder counts between consecutive azimuths (14 for 5600 / 400), rounded down.
    pub fn encoder_step(&self) -> u16 {
        self.encoder_size / self.azimuth_samples
    }

    /// Range of bin `bin` in metres: gain x bin x bin size + offset (section 5).
    pub fn bin_range_m(&self, bin: f64) -> f64 {
        self.range_gain * bin * self.bin_size_m + self.range_offset_m
    }

    /// Range of bin `bin` in metres from `rangeresolutionmetres`, when the radar sent it.
    pub fn bin_range_m_by_resolution(&self, bin: f64) -> Option<f64> {
        self.range_resolution_m
            .map(|res| units::bin_to_range_m_by_resolution(bin, res))
    }

    /// The (fractional) bin at `range_m`, inverting [`Geometry::bin_range_m`].
    pub fn range_m_to_bin(&self, range_m: f64) -> f64 {
        (range_m - self.range_offset_m) / (self.range_gain * self.bin_size_m)
    }

    /// Instrumented range of a full azimuth in metres: the range of bin `range_in_bins`.
    pub fn max_range_m(&self) -> f64 {
        self.bin_range_m(f64::from(self.range_in_bins))
    }

    /// Power in dB of a raw bin value of this radar's width.
    pub fn bin_to_db(&self, raw: u16) -> f64 {
        match self.data_width {
            BinWidth::Eight => units::bin8_to_db(u8::try_from(raw).unwrap_or(u8::MAX)),
            BinWidth::Sixteen => units::bin16_to_db(raw),
        }
    }
}

#[cfg(test)]
mod azimuth_index_tests {
    use super::*;

    #[test]
    fn a_range_gain_of_zero_or_below_is_refused_at_the_configuration_message() {
        let mut c = Configuration {
            azimuth_samples: 400,
            bin_size: 438,
            range_in_bins: 3768,
            encoder_size: 5600,
            rotation_speed_millihertz: 4000,
            packet_rate: 1600,
            range_gain: 0.0,
            range_offset_m: 0.0,
            data: ConfigurationData::minimal(8, 0.0438),
        };
        assert_eq!(c.geometry(), Err(GeometryError::NonPositiveRangeGain(0.0)));
        c.range_gain = -1.0;
        assert_eq!(c.geometry(), Err(GeometryError::NonPositiveRangeGain(-1.0)));
        c.range_gain = 1.0;
        assert!(c.geometry().is_ok());
    }

    fn cts350x() -> Geometry {
        Geometry::cts350x()
    }

    #[test]
    fn azimuth_index_counts_azimuths_not_encoder_values() {
        let g = cts350x();
        assert_eq!(g.azimuth_index(0), Some(0));
        assert_eq!(g.azimuth_index(13), Some(0));
        assert_eq!(g.azimuth_index(14), Some(1));
        assert_eq!(g.azimuth_index(56), Some(4));
        assert_eq!(g.azimuth_index(5599), Some(399));
        assert_eq!(g.azimuth_index(5600), None);
        let empty = Geometry {
            azimuth_samples: 0,
            ..cts350x()
        };
        assert_eq!(empty.azimuth_index(3), None);
    }
}
