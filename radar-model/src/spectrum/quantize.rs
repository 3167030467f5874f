//! Quantisation of dB values to the Colossus wire's bins: 8-bit (`value = round(2 dB)`,
//! 0.5 dB steps, 0 to 127.5 dB) and 16-bit (`dB = raw / 256 * 96.5 / 141.5`). Values are
//! clamped to the representable range; NaN maps to 0.

use crate::error::ModelError;

/// dB per 16-bit count: `96.5 / 141.5 / 256`.
pub const DB_PER_16BIT_COUNT: f64 = 96.5 / 141.5 / 256.0;

/// 8-bit wire value of a power: `round(2 dB)` clamped to 0..=255 (NaN gives 0).
pub fn quantize_8bit(power_db: f64) -> u8 {
    let v = (2.0 * power_db).round();
    if v.is_nan() {
        0
    } else {
        // Clamped to the u8 range first, so the cast is exact.
        v.clamp(0.0, 255.0) as u8
    }
}

/// 16-bit wire value of a power: `round(dB / DB_PER_16BIT_COUNT)` clamped to 0..=65535.
pub fn quantize_16bit(power_db: f64) -> u16 {
    let v = (power_db / DB_PER_16BIT_COUNT).round();
    if v.is_nan() {
        0
    } else {
        v.clamp(0.0, 65535.0) as u16
    }
}

/// Power (dB) of a 16-bit wire value.
pub fn wire_16bit_to_db(raw: u16) -> f64 {
    f64::from(raw) * DB_PER_16BIT_COUNT
}

/// Quantises a spectrum to 8-bit bins.
///
/// # Errors
/// Lengths differ.
pub fn quantize_spectrum_8bit(power_db: &[f64], out: &mut [u8]) -> Result<(), ModelError> {
    if power_db.len() != out.len() {
        return Err(ModelError::BufferTooSmall {
            needed: power_db.len(),
            got: out.len(),
        });
    }
    for (o, p) in out.iter_mut().zip(power_db) {
        *o = quantize_8bit(*p);
    }
    Ok(())
}

/// Quantises a spectrum to 16-bit bins (values, not bytes; the wire is little-endian).
///
/// # Errors
/// Lengths differ.
pub fn quantize_spectrum_16bit(power_db: &[f64], out: &mut [u16]) -> Result<(), ModelError> {
    if power_db.len() != out.len() {
        return Err(ModelError::BufferTooSmall {
            needed: power_db.len(),
            got: out.len(),
        });
    }
    for (o, p) in out.iter_mut().zip(power_db) {
        *o = quantize_16bit(*p);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eight_bit_values_are_twice_the_db_rounded_and_clamped() {
        assert_eq!(quantize_8bit(0.0), 0);
        assert_eq!(quantize_8bit(0.26), 1);
        assert_eq!(quantize_8bit(63.7), 127);
        assert_eq!(quantize_8bit(127.5), 255);
        assert_eq!(quantize_8bit(500.0), 255);
        assert_eq!(quantize_8bit(-3.0), 0);
        assert_eq!(quantize_8bit(f64::NAN), 0);
    }

    #[test]
    fn sixteen_bit_values_round_trip_within_half_a_count() {
        for db in [0.0, 0.1, 12.34, 50.0, 96.5] {
            let raw = quantize_16bit(db);
            assert!((wire_16bit_to_db(raw) - db).abs() <= 0.5 * DB_PER_16BIT_COUNT + 1e-12);
        }
        assert_eq!(quantize_16bit(1e9), u16::MAX);
        assert_eq!(quantize_16bit(-1.0), 0);
        let mut out = [0u8; 2];
        assert!(quantize_spectrum_8bit(&[1.0], &mut out).is_err());
    }
}
