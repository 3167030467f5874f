//! Statistics of polar scans, computed the same way for real and simulated ones: level
//! distribution per range band (floor level = median, spread = interquartile range), the
//! two-sample Kolmogorov-Smirnov distance between two scans' distributions per band, the
//! fraction of bins above the floor, and the widths of isolated peaks in range and azimuth.

use crate::replay::png::PolarScan;

/// Range band edges used by every statistic, metres. The first 2 m (antenna leakage) are
/// left out.
pub const BAND_EDGES_M: [f64; 11] = [
    2.0, 5.0, 10.0, 20.0, 30.0, 45.0, 60.0, 80.0, 100.0, 130.0, 165.0,
];
/// A bin is above the floor when it is this far (dB) above its band's median.
pub const ABOVE_FLOOR_DB: f64 = 10.0;
/// A peak is measured when it stands this far (dB) above its band's median.
pub const PEAK_MIN_DB: f64 = 20.0;

/// Polar scans as the wire's 8-bit values (`dB = value / 2`), one row per azimuth.
#[derive(Debug, Clone, PartialEq)]
pub struct Scans {
    /// Azimuths per rotation.
    pub azimuths: usize,
    /// Bins per azimuth.
    pub bins: usize,
    /// Bin size, metres.
    pub bin_m: f64,
    /// Rotations, each `azimuths x bins` values row by row.
    pub rotations: Vec<Vec<u8>>,
}

impl Scans {
    /// An empty set for scans of this shape.
    pub fn new(azimuths: usize, bins: usize, bin_m: f64) -> Scans {
        Scans {
            azimuths,
            bins,
            bin_m,
            rotations: Vec::new(),
        }
    }

    /// Adds a decoded polar PNG (valid rows only; a scan with another shape is skipped and
    /// `false` returned).
    pub fn push_polar(&mut self, scan: &PolarScan) -> bool {
        let rows: Vec<&Vec<u8>> = scan
            .rows
            .iter()
            .filter(|r| r.valid)
            .map(|r| &r.bins)
            .collect();
        if rows.len() != self.azimuths || rows.iter().any(|r| r.len() != self.bins) {
            return false;
        }
        self.rotations
            .push(rows.into_iter().flat_map(|r| r.iter().copied()).collect());
        true
    }

    /// Adds one rotation of levels in dB, quantised as the 8-bit wire does.
    pub fn push_db(&mut self, rows_db: &[f64]) {
        self.rotations.push(
            rows_db
                .iter()
                .map(|&db| (db * 2.0).round().clamp(0.0, 255.0) as u8)
                .collect(),
        );
    }

    fn band_of_bin(&self, b: usize) -> Option<usize> {
        let r = b as f64 * self.bin_m;
        if r < BAND_EDGES_M[0] {
            return None;
        }
        BAND_EDGES_M.windows(2).position(|w| r >= w[0] && r < w[1])
    }

    /// Histograms of the 8-bit values per band.
    pub fn histograms(&self) -> Vec<[u64; 256]> {
        let mut h = vec![[0u64; 256]; BAND_EDGES_M.len() - 1];
        let bands: Vec<Option<usize>> = (0..self.bins).map(|b| self.band_of_bin(b)).collect();
        for rot in &self.rotations {
            for row in rot.chunks_exact(self.bins) {
                for (&v, band) in row.iter().zip(&bands) {
                    if let Some(hist) = band.and_then(|k| h.get_mut(k)) {
                        hist[usize::from(v)] += 1;
                    }
                }
            }
        }
        h
    }
}

/// Quantile (`q` in [0, 1]) of a histogram of 8-bit values, in dB.
pub fn quantile_db(h: &[u64; 256], q: f64) -> f64 {
    let total: u64 = h.iter().sum();
    if total == 0 {
        return f64::NAN;
    }
    let target = (q * (total - 1) as f64).round() as u64;
    let mut acc = 0u64;
    for (v, &c) in h.iter().enumerate() {
        acc += c;
        if acc > target {
            return v as f64 / 2.0;
        }
    }
    127.5
}

/// Two-sample Kolmogorov-Smirnov distance between two histograms over the same values.
pub fn ks_distance(a: &[u64; 256], b: &[u64; 256]) -> f64 {
    let (ta, tb) = (a.iter().sum::<u64>() as f64, b.iter().sum::<u64>() as f64);
    if ta == 0.0 || tb == 0.0 {
        return 1.0;
    }
    let (mut ca, mut cb, mut d) = (0.0, 0.0, 0.0f64);
    for (&x, &y) in a.iter().zip(b) {
        ca += x as f64;
        cb += y as f64;
        d = d.max((ca / ta - cb / tb).abs());
    }
    d
}

/// Per-band summary of a set of scans.
#[derive(Debug, Clone, PartialEq)]
pub struct BandStats {
    /// Band start and end, metres.
    pub range_m: (f64, f64),
    /// Median level (the floor's level), dB.
    pub median_db: f64,
    /// Interquartile range (the floor's spread), dB.
    pub iqr_db: f64,
    /// 90th and 99th percentiles, dB.
    pub p90_db: f64,
    /// 99th percentile, dB.
    pub p99_db: f64,
    /// Share of bins more than [`ABOVE_FLOOR_DB`] above the median.
    pub above_floor: f64,
}

/// Peak widths measured on a set of scans.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeakWidths {
    /// Peaks measured.
    pub peaks: usize,
    /// Median full width at half maximum in range, metres.
    pub range_fwhm_m: f64,
    /// Median full width at half maximum in azimuth, degrees.
    pub azimuth_fwhm_deg: f64,
}

/// Everything the comparison reports about one set of scans.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanStats {
    /// Per band.
    pub bands: Vec<BandStats>,
    /// Share of all bins (beyond 2 m) above their band's floor.
    pub above_floor: f64,
    /// Peak widths.
    pub widths: PeakWidths,
    /// The histograms (for KS distances).
    pub histograms: Vec<[u64; 256]>,
}

/// Computes the statistics of `scans`.
pub fn scan_stats(scans: &Scans) -> ScanStats {
    let histograms = scans.histograms();
    let mut bands = Vec::new();
    let (mut above_all, mut total_all) = (0u64, 0u64);
    for (k, h) in histograms.iter().enumerate() {
        let median = quantile_db(h, 0.5);
        let threshold = ((median + ABOVE_FLOOR_DB) * 2.0).floor() as usize;
        let total: u64 = h.iter().sum();
        let above: u64 = h.iter().skip(threshold + 1).sum();
        above_all += above;
        total_all += total;
        bands.push(BandStats {
            range_m: (BAND_EDGES_M[k], BAND_EDGES_M[k + 1]),
            median_db: median,
            iqr_db: quantile_db(h, 0.75) - quantile_db(h, 0.25),
            p90_db: quantile_db(h, 0.9),
            p99_db: quantile_db(h, 0.99),
            above_floor: if total > 0 {
                above as f64 / total as f64
            } else {
                f64::NAN
            },
        });
    }
    let medians: Vec<f64> = bands.iter().map(|b| b.median_db).collect();
    ScanStats {
        widths: peak_widths(scans, &medians),
        above_floor: if total_all > 0 {
            above_all as f64 / total_all as f64
        } else {
            f64::NAN
        },
        bands,
        histograms,
    }
}

/// Interpolated distance from `centre` to where `values` (walked by `step`) first fall to
/// `level` or below; `None` if they never do within `max_steps`.
fn half_width(
    value_at: impl Fn(i64) -> Option<f64>,
    peak: f64,
    level: f64,
    max: i64,
) -> Option<f64> {
    let mut prev = peak;
    for k in 1..=max {
        let v = value_at(k)?;
        if v <= level {
            let frac = if prev > v {
                (prev - level) / (prev - v)
            } else {
                0.0
            };
            return Some((k - 1) as f64 + frac);
        }
        if v > peak {
            return None;
        }
        prev = v;
    }
    None
}

/// Median range and azimuth widths (at half power, -3 dB) of isolated peaks: bins that are
/// the largest within 3 bins in range and 1 azimuth either side, stand [`PEAK_MIN_DB`]
/// above their band's median and are at least 3 dB below the largest level seen (not
/// clipped).
pub fn peak_widths(scans: &Scans, band_medians: &[f64]) -> PeakWidths {
    let (na, nb) = (scans.azimuths, scans.bins);
    let top = scans
        .rotations
        .iter()
        .flat_map(|r| r.iter())
        .copied()
        .max()
        .unwrap_or(0);
    let clip = f64::from(top) / 2.0 - 3.0;
    let mut range_w = Vec::new();
    let mut az_w = Vec::new();
    for rot in &scans.rotations {
        let at = |a: i64, b: i64| -> Option<f64> {
            if b < 0 || b >= nb as i64 {
                return None;
            }
            let a = a.rem_euclid(na as i64) as usize;
            rot.get(a * nb + b as usize).map(|&v| f64::from(v) / 2.0)
        };
        for a in 0..na as i64 {
            for b in 3..nb as i64 - 3 {
                let Some(band) = scans.band_of_bin(b as usize) else {
                    continue;
                };
                let Some(v) = at(a, b) else { continue };
                let Some(&median) = band_medians.get(band) else {
                    continue;
                };
                if v < median + PEAK_MIN_DB || v > clip {
                    continue;
                }
                let local_max = (-3..=3).all(|d| d == 0 || at(a, b + d).is_some_and(|x| x < v))
                    && at(a - 1, b).is_some_and(|x| x <= v)
                    && at(a + 1, b).is_some_and(|x| x <= v);
                if !local_max {
                    continue;
                }
                let level = v - 3.0;
                let r_right = half_width(|k| at(a, b + k), v, level, 40);
                let r_left = half_width(|k| at(a, b - k), v, level, 40);
                if let (Some(l), Some(r)) = (r_left, r_right) {
                    range_w.push((l + r) * scans.bin_m);
                }
                let a_right = half_width(|k| at(a + k, b), v, level, 20);
                let a_left = half_width(|k| at(a - k, b), v, level, 20);
                if let (Some(l), Some(r)) = (a_left, a_right) {
                    az_w.push((l + r) * 360.0 / na as f64);
                }
            }
        }
    }
    let median = |v: &mut Vec<f64>| {
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    PeakWidths {
        peaks: range_w.len(),
        range_fwhm_m: median(&mut range_w),
        azimuth_fwhm_deg: median(&mut az_w),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ks_distance_of_identical_histograms_is_zero_and_of_disjoint_ones_one() {
        let mut a = [0u64; 256];
        let mut b = [0u64; 256];
        a[10] = 5;
        a[20] = 5;
        assert_eq!(ks_distance(&a, &a), 0.0);
        b[100] = 3;
        assert_eq!(ks_distance(&a, &b), 1.0);
    }

    #[test]
    fn a_gaussian_peak_of_known_width_is_measured_at_that_width() {
        let (na, nb, bin_m) = (100usize, 400usize, 0.05);
        let mut scans = Scans::new(na, nb, bin_m);
        let mut rows = vec![0.0f64; na * nb];
        // Peak at azimuth 50, bin 200 (10 m): 40 dB with Gaussian shapes in power of FWHM
        // 0.3 m in range and 4 azimuths (14.4 degrees with 100 azimuths) in azimuth.
        let sr = 0.3 / 2.3548;
        let sa = 4.0 / 2.3548;
        for a in 0..na {
            for b in 0..nb {
                let dr = (b as f64 - 200.0) * bin_m;
                let da = a as f64 - 50.0;
                let p = 1e4 * (-0.5 * (dr / sr).powi(2) - 0.5 * (da / sa).powi(2)).exp();
                rows[a * nb + b] = 10.0 * (1.0 + p).log10();
            }
        }
        rows[0] = 60.0; // something brighter elsewhere, so the peak is not taken as clipped
        scans.push_db(&rows);
        let stats = scan_stats(&scans);
        assert_eq!(stats.widths.peaks, 1);
        assert!(
            (stats.widths.range_fwhm_m - 0.3).abs() < 0.03,
            "{:?}",
            stats.widths
        );
        assert!(
            (stats.widths.azimuth_fwhm_deg - 14.4).abs() < 1.0,
            "{:?}",
            stats.widths
        );
    }
}
