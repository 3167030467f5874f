//! Oxford Radar RobotCar / Boreas polar scans stored as PNG images.
//!
//! Layout (8-bit grayscale, one row per azimuth; pyboreas' `load_radar` reads Boreas' the
//! same way, and Boreas leaves column 10 unused):
//!
//! | columns | content |
//! |---|---|
//! | 0-7 | little-endian i64 timestamp of the azimuth, microseconds since the Unix epoch |
//! | 8-9 | little-endian u16 encoder value (out of 5600) |
//! | 10 | 255 where the row is valid |
//! | 11.. | the power bins, 8-bit, as the radar sent them (dB = value / 2) |
//!
//! Reading is blocking file IO (call it from `spawn_blocking` in async code).

use std::path::Path;

use protocol::Timestamp;

use super::files::{read_bounded, FileKind};
use crate::error::ReplayError;

/// Columns before the bins.
pub const META_COLUMNS: usize = 11;
/// Largest decoded image accepted (a 400 x 3779 scan is 1.5 MB).
pub const MAX_IMAGE_BYTES: usize = 64 << 20;

/// One row of a polar scan.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PolarRow {
    /// Microseconds since the Unix epoch.
    pub timestamp_us: i64,
    /// Encoder value.
    pub encoder: u16,
    /// Column 10 was 255.
    pub valid: bool,
    /// The bins (one byte each).
    pub bins: Vec<u8>,
}

impl PolarRow {
    /// The row's timestamp as the wire's seconds + nanoseconds.
    pub fn wire_timestamp(&self) -> Result<Timestamp, String> {
        let us = self.timestamp_us;
        if us < 0 {
            return Err(format!("negative timestamp {us} us"));
        }
        let secs =
            u32::try_from(us / 1_000_000).map_err(|_| format!("timestamp {us} us is past 2106"))?;
        let nanos = u32::try_from((us % 1_000_000) * 1000)
            .map_err(|_| "bad sub-second part".to_string())?;
        Timestamp::new(secs, nanos).map_err(|e| e.to_string())
    }
}

/// A whole polar scan (one rotation).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PolarScan {
    /// The rows, in image order.
    pub rows: Vec<PolarRow>,
    /// Bins per row.
    pub bins: usize,
}

/// Decodes one polar PNG from bytes (`path` is only used in errors).
pub fn decode_polar_png(bytes: &[u8], path: &Path) -> Result<PolarScan, ReplayError> {
    let layout = |reason: String| ReplayError::Layout {
        path: path.to_path_buf(),
        reason,
    };
    let png_err = |source| ReplayError::Png {
        path: path.to_path_buf(),
        source,
    };
    let mut decoder = png::Decoder::new(bytes);
    decoder.set_limits(png::Limits {
        bytes: MAX_IMAGE_BYTES,
    });
    let mut reader = decoder.read_info().map_err(png_err)?;
    let (color, depth) = reader.output_color_type();
    if color != png::ColorType::Grayscale || depth != png::BitDepth::Eight {
        return Err(layout(format!(
            "expected 8-bit grayscale, got {color:?} {depth:?}"
        )));
    }
    let info = reader.info();
    let width = usize::try_from(info.width).map_err(|_| layout("width does not fit".into()))?;
    let height = usize::try_from(info.height).map_err(|_| layout("height does not fit".into()))?;
    if width <= META_COLUMNS || width > META_COLUMNS + usize::from(u16::MAX) {
        return Err(layout(format!(
            "width {width}: expected {META_COLUMNS} metadata columns and 1 to 65535 bins"
        )));
    }
    if height == 0 || height > usize::from(u16::MAX) {
        return Err(layout(format!(
            "height {height}: expected 1 to 65535 azimuth rows"
        )));
    }
    let size = reader.output_buffer_size();
    if size > MAX_IMAGE_BYTES {
        return Err(layout(format!(
            "{size} bytes decoded exceeds {MAX_IMAGE_BYTES}"
        )));
    }
    let mut buf = vec![0u8; size];
    let frame = reader.next_frame(&mut buf).map_err(png_err)?;
    let stride = frame.line_size;
    if stride < width {
        return Err(layout(format!("line size {stride} below width {width}")));
    }
    let mut rows = Vec::with_capacity(height);
    for line in buf.chunks_exact(stride).take(height) {
        let (Some(ts), Some(enc), Some(&valid), Some(bins)) = (
            line.get(0..8),
            line.get(8..10),
            line.get(10),
            line.get(META_COLUMNS..width),
        ) else {
            return Err(layout("short row".into()));
        };
        let mut ts_bytes = [0u8; 8];
        ts_bytes.copy_from_slice(ts);
        rows.push(PolarRow {
            timestamp_us: i64::from_le_bytes(ts_bytes),
            encoder: u16::from_le_bytes([enc[0], enc[1]]),
            valid: valid == 255,
            bins: bins.to_vec(),
        });
    }
    if rows.len() != height {
        return Err(layout(format!("decoded {} rows of {height}", rows.len())));
    }
    Ok(PolarScan {
        rows,
        bins: width - META_COLUMNS,
    })
}

/// Reads and decodes one polar PNG file: a regular file of at most
/// [`super::files::MAX_SCAN_BYTES`] ([`read_bounded`]).
///
/// # Errors
/// A file that is not a regular file ([`super::files::not_a_regular_file`]), is too large
/// ([`ReplayError::TooLarge`]), cannot be read, or does not decode as a polar scan.
pub fn read_polar_png(path: &Path) -> Result<PolarScan, ReplayError> {
    let bytes = read_bounded(path, FileKind::Scan)?;
    decode_polar_png(&bytes, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encode_png(width: u32, height: u32, data: &[u8], color: png::ColorType) -> Vec<u8> {
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, width, height);
            enc.set_color(color);
            enc.set_depth(png::BitDepth::Eight);
            let mut w = enc.write_header().expect("header");
            w.write_image_data(data).expect("data");
        }
        out
    }

    #[test]
    fn a_hand_built_scan_decodes_to_its_timestamps_encoders_and_bins() {
        let width = META_COLUMNS + 4;
        let mut data = Vec::new();
        for row in 0..3u16 {
            data.extend_from_slice(
                &(1_547_131_046_353_776i64 + i64::from(row) * 625).to_le_bytes(),
            );
            data.extend_from_slice(&(row * 14).to_le_bytes());
            data.push(255);
            data.extend_from_slice(&[row as u8, 10, 20, 255]);
        }
        let bytes = encode_png(width as u32, 3, &data, png::ColorType::Grayscale);
        let scan = decode_polar_png(&bytes, Path::new("t.png")).expect("decodes");
        assert_eq!(scan.bins, 4);
        assert_eq!(scan.rows[2].timestamp_us, 1_547_131_046_355_026);
        assert_eq!(scan.rows[2].encoder, 28);
        assert!(scan.rows[2].valid);
        assert_eq!(scan.rows[2].bins, vec![2, 10, 20, 255]);
        let ts = scan.rows[0].wire_timestamp().expect("ts");
        assert_eq!((ts.seconds(), ts.nanos()), (1_547_131_046, 353_776_000));
    }

    #[test]
    fn an_rgb_image_is_a_layout_error_not_a_panic() {
        let bytes = encode_png(12, 1, &[0; 36], png::ColorType::Rgb);
        let err = decode_polar_png(&bytes, Path::new("rgb.png")).expect_err("rgb");
        assert!(matches!(err, ReplayError::Layout { .. }), "{err}");
    }

    #[test]
    fn an_image_without_bins_is_rejected() {
        let bytes = encode_png(11, 2, &[0; 22], png::ColorType::Grayscale);
        assert!(matches!(
            decode_polar_png(&bytes, Path::new("narrow.png")),
            Err(ReplayError::Layout { .. })
        ));
    }

    #[test]
    fn png_bytes_truncated_before_the_image_data_ends_are_a_decode_error() {
        // (A cut inside the final IEND chunk loses nothing of the image and decodes.)
        let bytes = encode_png(20, 4, &[7; 80], png::ColorType::Grayscale);
        for cut in [0, 8, 20, bytes.len() / 2] {
            assert!(
                decode_polar_png(&bytes[..cut], Path::new("cut.png")).is_err(),
                "cut {cut}"
            );
        }
    }

    #[test]
    fn a_negative_timestamp_is_reported() {
        let row = PolarRow {
            timestamp_us: -1,
            encoder: 0,
            valid: true,
            bins: vec![],
        };
        assert!(row.wire_timestamp().is_err());
    }
}
