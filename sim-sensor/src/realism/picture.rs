//! Cartesian pictures of polar scans (for the side-by-side comparison of a real and a
//! simulated scan).

use std::path::Path;

use super::stats::Scans;

/// Renders rotation `rotation` of `scans` as a square grey image of `size` pixels covering
/// `+/- half_m` metres about the radar (x forward = up, azimuth 0 forward and clockwise as
/// the encoder counts), levels scaled so `max_db` is white.
pub fn cartesian(scans: &Scans, rotation: usize, size: usize, half_m: f64, max_db: f64) -> Vec<u8> {
    let mut img = vec![0u8; size * size];
    let Some(rot) = scans.rotations.get(rotation) else {
        return img;
    };
    let (na, nb) = (scans.azimuths, scans.bins);
    let m_per_px = 2.0 * half_m / size as f64;
    for py in 0..size {
        for px in 0..size {
            // Up = forward (+x of the vehicle), right = the vehicle's right.
            let fwd = half_m - (py as f64 + 0.5) * m_per_px;
            let right = (px as f64 + 0.5) * m_per_px - half_m;
            let r = fwd.hypot(right);
            let b = (r / scans.bin_m).round() as usize;
            if b >= nb {
                continue;
            }
            // Bearing clockwise from forward.
            let bearing = right.atan2(fwd).rem_euclid(std::f64::consts::TAU);
            let a = ((bearing / std::f64::consts::TAU * na as f64).round() as usize) % na;
            let v = f64::from(rot[a * nb + b]) / 2.0;
            img[py * size + px] = (v / max_db * 255.0).clamp(0.0, 255.0) as u8;
        }
    }
    img
}

/// Writes grey images side by side (each `size` x `size`) as one PNG.
pub fn write_side_by_side(
    path: &Path,
    images: &[Vec<u8>],
    size: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    let width = size * images.len();
    let mut data = vec![0u8; width * size];
    for (i, img) in images.iter().enumerate() {
        for y in 0..size {
            let src = img.get(y * size..(y + 1) * size).unwrap_or_default();
            let start = y * width + i * size;
            if let Some(dst) = data.get_mut(start..start + src.len()) {
                dst.copy_from_slice(src);
            }
        }
    }
    let file = std::fs::File::create(path)?;
    let mut enc = png::Encoder::new(
        std::io::BufWriter::new(file),
        u32::try_from(width)?,
        u32::try_from(size)?,
    );
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header()?;
    writer.write_image_data(&data)?;
    Ok(())
}
