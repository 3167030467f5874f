//! Wire integers to physical values (`docs/colossus-protocol.md`, sections 3.2 and 5).
//!
//! Pure functions, no state. Angles follow the radar: an azimuth increases clockwise seen
//! from above, which is the project's bearing convention (`docs/contracts.md`).

use crate::error::ConversionError;

/// Full scale of a 16-bit bin in dB per raw/256 unit: 96.5 / 141.5.
pub const BIN16_DB_SCALE: f64 = 96.5 / 141.5;

/// Azimuth in encoder counts to radians in [0, 2 pi): `azimuth x 2 pi / encoder_size`.
pub fn azimuth_to_rad(azimuth: u16, encoder_size: u16) -> Result<f64, ConversionError> {
    if encoder_size == 0 {
        return Err(ConversionError::ZeroEncoderSize);
    }
    Ok(f64::from(azimuth) * std::f64::consts::TAU / f64::from(encoder_size))
}

/// Azimuth in encoder counts to degrees: `azimuth x 360 / encoder_size` (section 5).
pub fn azimuth_to_deg(azimuth: u16, encoder_size: u16) -> Result<f64, ConversionError> {
    if encoder_size == 0 {
        return Err(ConversionError::ZeroEncoderSize);
    }
    Ok(f64::from(azimuth) * 360.0 / f64::from(encoder_size))
}

/// An 8-bit bin to dB: `value / 2` (section 3.2).
pub fn bin8_to_db(value: u8) -> f64 {
    f64::from(value) * 0.5
}

/// A 16-bit bin (already assembled from its little-endian bytes) to dB:
/// `(raw / 256) x (96.5 / 141.5)` (section 3.2).
pub fn bin16_to_db(raw: u16) -> f64 {
    f64::from(raw) / 256.0 * BIN16_DB_SCALE
}

/// dB to the nearest 8-bit bin (ties up), saturating at 0 and 127.5 dB. NaN maps to 0.
pub fn db_to_bin8(power_db: f64) -> u8 {
    // Adding 0.5 and truncating rounds to nearest for the non-negative values that can
    // survive the cast; `as` from f64 saturates (negatives to 0) and maps NaN to 0. This
    // avoids `f64::round`, a libm call on baseline x86-64, in the simulator's hot loop.
    (power_db * 2.0 + 0.5) as u8
}

/// dB to the nearest 16-bit bin (ties up), saturating at 0 and about 174.3 dB. NaN maps
/// to 0.
pub fn db_to_bin16(power_db: f64) -> u16 {
    // Round-by-truncation and saturating cast, as above.
    (power_db * (256.0 / BIN16_DB_SCALE) + 0.5) as u16
}

/// Range of bin `bin` in metres from the fixed configuration (section 5):
/// `range_gain x (bin x bin_size / 10000) + range_offset`, with `bin_size` in tenths of a
/// millimetre. `bin` may be fractional (an interpolated peak).
pub fn bin_to_range_m(bin: f64, bin_size: u16, range_gain: f64, range_offset_m: f64) -> f64 {
    range_gain * (bin * f64::from(bin_size) / 10_000.0) + range_offset_m
}

/// Range of bin `bin` in metres from the protobuf's `rangeresolutionmetres`:
/// `bin x range_resolution_m`, the form some tools use (section 5).
pub fn bin_to_range_m_by_resolution(bin: f64, range_resolution_m: f64) -> f64 {
    bin * range_resolution_m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoder_counts_map_to_angles_and_a_zero_encoder_size_is_an_error() {
        assert_eq!(azimuth_to_deg(1400, 5600).unwrap(), 90.0);
        assert!((azimuth_to_rad(2800, 5600).unwrap() - std::f64::consts::PI).abs() < 1e-15);
        assert_eq!(azimuth_to_rad(1, 0), Err(ConversionError::ZeroEncoderSize));
        assert_eq!(azimuth_to_deg(1, 0), Err(ConversionError::ZeroEncoderSize));
    }

    #[test]
    fn eight_bit_bins_are_half_decibels() {
        assert_eq!(bin8_to_db(0), 0.0);
        assert_eq!(bin8_to_db(181), 90.5);
        assert_eq!(bin8_to_db(255), 127.5);
        for v in 0..=255u8 {
            assert_eq!(db_to_bin8(bin8_to_db(v)), v);
        }
        assert_eq!(db_to_bin8(-3.0), 0);
        assert_eq!(db_to_bin8(500.0), 255);
        assert_eq!(db_to_bin8(f64::NAN), 0);
    }

    #[test]
    fn sixteen_bit_bins_use_the_96_5_over_141_5_scale() {
        // raw 256 * 141.5 = 36224 is exactly 96.5 dB.
        assert!((bin16_to_db(36_224) - 96.5).abs() < 1e-12);
        for raw in [0u16, 1, 255, 256, 36_224, 65_535] {
            assert_eq!(db_to_bin16(bin16_to_db(raw)), raw);
        }
        assert_eq!(db_to_bin16(1e9), u16::MAX);
    }

    #[test]
    fn bin_range_uses_gain_bin_size_and_offset() {
        // Navtech's worked example: bin size 1752, gain 0.999691, offset -0.3199 m.
        let r = bin_to_range_m(100.0, 1752, 0.999_691, -0.3199);
        assert!((r - (0.999_691 * 17.52 - 0.3199)).abs() < 1e-12);
        assert_eq!(bin_to_range_m(0.0, 438, 1.0, 0.0), 0.0);
        assert!((bin_to_range_m_by_resolution(10.0, 0.0438) - 0.438).abs() < 1e-12);
    }
}
