//! The driver's output types: one [`Azimuth`] per FFT message, whole [`Rotation`]s.
//!
//! Bins stay as the wire's bytes ([`Bytes`]) plus their width; [`Azimuth::power_db`] and
//! [`Azimuth::bins_db`] convert on demand. The driver copies them out of its read buffer
//! into an allocation charged to its byte budget ([`crate::budget`]), so an azimuth never
//! pins a read buffer and its bytes are counted until its last copy is dropped.

use std::sync::Arc;

use bytes::Bytes;
use protocol::{BinWidth, FftData, Geometry};

/// One azimuth: a power-range spectrum and where and when it was measured.
#[derive(Debug, Clone, PartialEq)]
pub struct Azimuth {
    /// Azimuth in encoder counts.
    pub encoder: u16,
    /// Azimuth angle in radians in [0, 2 pi): encoder x 2 pi / encoder size. Increases
    /// clockwise seen from above: it is the bearing `beta` of `docs/contracts.md`.
    pub angle_rad: f64,
    /// When the radar measured it, Unix seconds (the radar's own clock).
    pub timestamp_s: f64,
    /// The radar's sweep counter.
    pub sweep_counter: u16,
    /// Bits per bin.
    pub width: BinWidth,
    /// Raw bins: one byte each (8-bit) or two little-endian bytes each (16-bit).
    pub bins: Bytes,
    /// The radar geometry in force when this azimuth arrived.
    pub geometry: Arc<Geometry>,
    /// The rotation this azimuth belongs to, as the driver's assembler counts them (it
    /// rises by one whenever the encoder wraps, a rotation is closed as overlong, or the
    /// geometry changes): rotation boundaries have one owner, and consumers compare this
    /// instead of watching encoder values. 0 for azimuths built outside the driver.
    pub rotation: u64,
}

impl Azimuth {
    /// Builds an azimuth from a decoded FFT message and the geometry in force.
    pub fn from_fft(fft: FftData, geometry: Arc<Geometry>) -> Self {
        Self {
            encoder: fft.azimuth,
            angle_rad: geometry.azimuth_rad(fft.azimuth),
            timestamp_s: fft.timestamp.as_secs_f64(),
            sweep_counter: fft.sweep_counter,
            width: fft.width,
            bins: fft.bins,
            geometry,
            rotation: 0,
        }
    }

    /// Number of bins (may be fewer than the geometry's range in bins, or zero).
    pub fn bin_count(&self) -> usize {
        self.bins.len() / self.width.bytes_per_bin()
    }

    /// Power of bin `index` in dB, if it exists.
    pub fn power_db(&self, index: usize) -> Option<f64> {
        match self.width {
            BinWidth::Eight => self.bins.get(index).map(|&v| protocol::bin8_to_db(v)),
            BinWidth::Sixteen => {
                let start = index.checked_mul(2)?;
                let pair = self.bins.get(start..start.checked_add(2)?)?;
                match pair {
                    [lo, hi] => Some(protocol::bin16_to_db(u16::from_le_bytes([*lo, *hi]))),
                    _ => None,
                }
            }
        }
    }

    /// Every bin's power in dB, without allocating.
    pub fn bins_db(&self) -> impl ExactSizeIterator<Item = f64> + '_ {
        let width = self.width;
        self.bins
            .chunks_exact(width.bytes_per_bin())
            .map(move |b| match (width, b) {
                (BinWidth::Eight, [v, ..]) => protocol::bin8_to_db(*v),
                (BinWidth::Sixteen, [lo, hi, ..]) => {
                    protocol::bin16_to_db(u16::from_le_bytes([*lo, *hi]))
                }
                _ => 0.0,
            })
    }

    /// Every bin's power in dB as f32, into `out` (cleared first; reuse it to avoid
    /// allocating per azimuth).
    pub fn bins_db_into(&self, out: &mut Vec<f32>) {
        out.clear();
        out.extend(self.bins_db().map(|p| p as f32));
    }

    /// Range in metres of the centre of bin `bin` from the geometry's calibration.
    pub fn range_m(&self, bin: f64) -> f64 {
        self.geometry.bin_range_m(bin)
    }
}

/// One revolution of azimuths in encoder order.
#[derive(Debug, Clone, PartialEq)]
pub struct Rotation {
    /// 0 for the first rotation the driver assembled, +1 for each after.
    pub sequence: u64,
    /// The azimuths in arrival order, which is encoder order (non-decreasing encoder).
    pub azimuths: Vec<Azimuth>,
    /// The geometry of every azimuth in it.
    pub geometry: Arc<Geometry>,
    /// Azimuth slots missing, judged from the encoder values (step = encoder size /
    /// azimuth samples), including slots missing at either end of a complete rotation.
    pub skipped_azimuths: u32,
    /// Sweep-counter discontinuities among this rotation's azimuths (and at its first
    /// azimuth, against the previous azimuth received).
    pub sweep_gaps: u32,
    /// Azimuth messages missing according to the sweep counter.
    pub sweep_missing: u32,
    /// Azimuths whose encoder value repeated the previous one.
    pub duplicate_azimuths: u32,
    /// Azimuths received but not in `azimuths`: the driver's byte budget was full.
    pub dropped_azimuths: u32,
    /// True when the rotation began at an encoder wrap (or, the very first one, at slot 0)
    /// and ended at the next wrap. A first rotation starting mid-way, and one cut short by
    /// a geometry change or shutdown, is partial.
    pub complete: bool,
}

impl Rotation {
    /// Timestamp of the first azimuth, if any.
    pub fn start_s(&self) -> Option<f64> {
        self.azimuths.first().map(|a| a.timestamp_s)
    }

    /// Timestamp of the last azimuth, if any.
    pub fn end_s(&self) -> Option<f64> {
        self.azimuths.last().map(|a| a.timestamp_s)
    }
}
