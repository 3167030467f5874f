//! The radar's latest rotation as a Cartesian image (no IO): a square of `size` x `size`
//! pixels covering `range_m` metres on each side of the radar, forward up and left to the
//! left, each pixel the raw bin (8-bit, or the high byte of a 16-bit bin) of the nearest
//! azimuth at the nearest range; pixels no azimuth of the rotation covered, or beyond the
//! radar's range, are 0.
//!
//! Azimuths are kept as they arrive (only the bins the image reaches); when an azimuth of the
//! next rotation arrives the finished one is drawn through a lookup table made once per
//! geometry. Memory is bounded: a geometry needing more than [`MAX_ROTATION_BYTES`] is
//! refused (counted by the caller) rather than allocated.

use std::sync::Arc;

use protocol::{BinWidth, Geometry};
use radar_driver::Azimuth;

/// The most bytes one rotation's kept bins may take.
pub const MAX_ROTATION_BYTES: usize = 64 << 20;

/// A finished rotation's image.
#[derive(Debug, Clone, PartialEq)]
pub struct RotationImage {
    /// Time of the rotation's last azimuth, Unix seconds.
    pub timestamp_s: f64,
    /// Side, pixels.
    pub size: u32,
    /// Row-major `mono8` pixels, `size * size` of them.
    pub pixels: Vec<u8>,
    /// Azimuths of the rotation that reached the image.
    pub azimuths: u32,
}

/// Builds images from azimuths.
#[derive(Debug)]
pub struct ImageBuilder {
    size: u32,
    range_m: f64,
    geometry: Option<Arc<Geometry>>,
    /// Per pixel: the index into `bins` it shows, or `u32::MAX`.
    lookup: Vec<u32>,
    /// Bins kept per azimuth.
    kept: usize,
    bins: Vec<u8>,
    filled: Vec<bool>,
    rotation: Option<u64>,
    last_time_s: f64,
    /// Azimuths refused (a geometry too large to keep): the caller's counter.
    pub refused: u64,
}

impl ImageBuilder {
    /// An image of `size` x `size` pixels, `range_m` metres from the centre to each edge.
    pub fn new(size: u32, range_m: f64) -> Self {
        Self {
            size: size.max(1),
            range_m: range_m.max(f64::MIN_POSITIVE),
            geometry: None,
            lookup: Vec::new(),
            kept: 0,
            bins: Vec::new(),
            filled: Vec::new(),
            rotation: None,
            last_time_s: 0.0,
            refused: 0,
        }
    }

    /// Takes one azimuth; returns the previous rotation's image when `az` starts another.
    pub fn push(&mut self, az: &Azimuth) -> Option<RotationImage> {
        let new_geometry = self
            .geometry
            .as_ref()
            .is_none_or(|g| !(Arc::ptr_eq(g, &az.geometry) || **g == *az.geometry));
        let finished = if self.rotation.is_some_and(|r| r != az.rotation) || new_geometry {
            self.finish()
        } else {
            None
        };
        if new_geometry && !self.prepare(&az.geometry) {
            self.refused += 1;
            return finished;
        }
        if self.geometry.is_none() {
            self.refused += 1;
            return finished;
        }
        self.rotation = Some(az.rotation);
        self.last_time_s = az.timestamp_s;
        let Some(row) = self
            .geometry
            .as_ref()
            .and_then(|g| g.azimuth_index(az.encoder))
            .map(usize::from)
        else {
            return finished;
        };
        let out = &mut self.bins[row * self.kept..(row + 1) * self.kept];
        match az.width {
            BinWidth::Eight => {
                let n = az.bins.len().min(out.len());
                out[..n].copy_from_slice(&az.bins[..n]);
                out[n..].fill(0);
            }
            BinWidth::Sixteen => {
                let mut pairs = az.bins.chunks_exact(2);
                for o in out.iter_mut() {
                    // Little-endian: the high byte is the second.
                    *o = pairs.next().map_or(0, |p| p[1]);
                }
            }
        }
        self.filled[row] = true;
        finished
    }

    /// Draws the rotation in progress, if any azimuth of it arrived, and starts afresh.
    pub fn finish(&mut self) -> Option<RotationImage> {
        self.rotation.take()?;
        let azimuths = self.filled.iter().filter(|f| **f).count();
        let pixels = self
            .lookup
            .iter()
            .map(|&i| {
                if i == u32::MAX {
                    return 0;
                }
                let i = i as usize;
                if self.filled[i / self.kept.max(1)] {
                    self.bins[i]
                } else {
                    0
                }
            })
            .collect();
        self.filled.fill(false);
        Some(RotationImage {
            timestamp_s: self.last_time_s,
            size: self.size,
            pixels,
            azimuths: u32::try_from(azimuths).unwrap_or(u32::MAX),
        })
    }

    /// Makes the lookup table for `g`; false (and no geometry) when it cannot be kept.
    fn prepare(&mut self, g: &Arc<Geometry>) -> bool {
        self.geometry = None;
        let samples = usize::from(g.azimuth_samples);
        let corner_m = self.range_m * std::f64::consts::SQRT_2;
        let reach = g.range_m_to_bin(corner_m).ceil();
        if samples == 0 || !reach.is_finite() || g.range_in_bins == 0 {
            return false;
        }
        let kept = (reach.max(1.0) as usize).min(usize::from(g.range_in_bins));
        if samples.saturating_mul(kept) > MAX_ROTATION_BYTES {
            return false;
        }
        let n = self.size as usize;
        let pixel_m = 2.0 * self.range_m / n as f64;
        let step = g.azimuth_step_rad();
        let mut lookup = Vec::with_capacity(n * n);
        for row in 0..n {
            let forward = self.range_m - (row as f64 + 0.5) * pixel_m;
            for col in 0..n {
                let left = self.range_m - (col as f64 + 0.5) * pixel_m;
                let range = forward.hypot(left);
                // Bearing clockwise from forward, in [0, 2 pi).
                let bearing = (-left).atan2(forward).rem_euclid(std::f64::consts::TAU);
                let azimuth = ((bearing / step).round() as usize) % samples;
                let bin = g.range_m_to_bin(range).round();
                lookup.push(if bin >= 0.0 && (bin as usize) < kept {
                    u32::try_from(azimuth * kept + bin as usize).unwrap_or(u32::MAX)
                } else {
                    u32::MAX
                });
            }
        }
        self.lookup = lookup;
        self.kept = kept;
        self.bins = vec![0; samples * kept];
        self.filled = vec![false; samples];
        self.geometry = Some(Arc::clone(g));
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bytes::Bytes;

    fn geometry() -> Arc<Geometry> {
        Arc::new(Geometry::cts350x())
    }

    fn azimuth(g: &Arc<Geometry>, index: u16, rotation: u64, bins: Vec<u8>) -> Azimuth {
        let encoder = index * g.encoder_step();
        Azimuth {
            encoder,
            angle_rad: g.azimuth_rad(encoder),
            timestamp_s: 100.0 + f64::from(index) * 1e-3,
            sweep_counter: index,
            width: BinWidth::Eight,
            bins: Bytes::from(bins),
            geometry: Arc::clone(g),
            rotation,
        }
    }

    #[test]
    fn a_target_ahead_is_drawn_above_the_centre_and_one_to_the_right_on_the_right() {
        let g = geometry();
        let mut b = ImageBuilder::new(101, 50.0);
        let bin_25m = g.range_m_to_bin(25.0).round() as usize;
        let samples = g.azimuth_samples;
        for i in 0..samples {
            let mut bins = vec![0u8; usize::from(g.range_in_bins)];
            // Forward (azimuth 0) and 90 degrees clockwise (to the right).
            if i == 0 || i == samples / 4 {
                for b in &mut bins[bin_25m - 12..=bin_25m + 12] {
                    *b = 200;
                }
            }
            assert!(b.push(&azimuth(&g, i, 7, bins)).is_none());
        }
        let img = b
            .push(&azimuth(&g, 0, 8, vec![0; 10]))
            .expect("rotation 7 finished");
        assert_eq!(img.azimuths, u32::from(samples));
        assert_eq!(img.pixels.len(), 101 * 101);
        let at = |row: usize, col: usize| img.pixels[row * 101 + col];
        // 25 m ahead: a quarter of the image above the centre (row 50), centre column.
        assert_eq!(at(25, 50), 200);
        // 25 m to the right: centre row, three quarters across.
        assert_eq!(at(50, 75), 200);
        // Not to the left, not behind.
        assert_eq!(at(50, 25), 0);
        assert_eq!(at(75, 50), 0);
    }

    #[test]
    fn missing_azimuths_are_black_and_counted() {
        let g = geometry();
        let mut b = ImageBuilder::new(64, 50.0);
        b.push(&azimuth(&g, 3, 1, vec![255; 3768]));
        let img = b.finish().unwrap();
        assert_eq!(img.azimuths, 1);
        let lit = img.pixels.iter().filter(|p| **p == 255).count();
        assert!(lit > 0 && lit < 64 * 64 / 50, "{lit}");
        assert!(b.finish().is_none(), "nothing in progress after a finish");
    }

    #[test]
    fn a_geometry_too_large_to_keep_is_refused_not_allocated() {
        let g = Arc::new(Geometry {
            azimuth_samples: u16::MAX,
            range_in_bins: u16::MAX,
            bin_size_m: 1.0,
            ..Geometry::cts350x()
        });
        let mut b = ImageBuilder::new(32, 10_000.0);
        let az = Azimuth {
            encoder: 0,
            angle_rad: 0.0,
            timestamp_s: 1.0,
            sweep_counter: 0,
            width: BinWidth::Eight,
            bins: Bytes::from(vec![1u8; 8]),
            geometry: g,
            rotation: 1,
        };
        assert!(b.push(&az).is_none());
        assert_eq!(b.refused, 1);
        assert!(b.finish().is_none());
    }
}
