//! Returns from a raw power profile, for users who have no detector of their own: per
//! azimuth the `k` strongest bins that stand `z` standard deviations above the azimuth's
//! mean power (the k-strongest filter of CFEAR, Adolfsson et al., T-RO 2023). The daemon
//! uses its own detector instead; this serves the examples and standalone callers.

use crate::matcher::Return;

/// The extraction's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KStrongest {
    /// Returns kept per azimuth at most.
    pub k: usize,
    /// A bin must exceed the azimuth's mean by this many standard deviations.
    pub z_min: f64,
    /// Bins nearer than this are skipped (m).
    pub min_range_m: f64,
}

impl Default for KStrongest {
    fn default() -> Self {
        Self {
            k: 12,
            z_min: 2.5,
            min_range_m: 4.0,
        }
    }
}

impl KStrongest {
    /// The returns of one azimuth's `power` (one value per bin, any monotonic scale: dB or
    /// the recordings' 8-bit values), bins `bin_size_m` long, bin `i` at `(i + 0.5)` bin
    /// sizes. Empty for an empty profile, a non-positive bin size or a flat profile.
    pub fn returns<P: Copy + Into<f64>>(&self, power: &[P], bin_size_m: f64) -> Vec<Return> {
        if power.is_empty() || !(bin_size_m.is_finite() && bin_size_m > 0.0) {
            return Vec::new();
        }
        let n = power.len() as f64;
        let (sum, sum2) = power.iter().fold((0.0, 0.0), |(s, s2), &p| {
            let v: f64 = p.into();
            (s + v, s2 + v * v)
        });
        let mean = sum / n;
        let sd = (sum2 / n - mean * mean).max(0.0).sqrt();
        if sd == 0.0 || !sd.is_finite() {
            return Vec::new();
        }
        let threshold = mean + self.z_min * sd;
        let first = (self.min_range_m / bin_size_m).ceil().max(0.0) as usize;
        let mut above: Vec<(usize, f64)> = power
            .iter()
            .enumerate()
            .skip(first)
            .map(|(i, &p)| (i, p.into()))
            .filter(|&(_, v)| v > threshold)
            .collect();
        let keep = self.k.min(above.len());
        if keep < above.len() {
            above.select_nth_unstable_by(keep, |a, b| b.1.total_cmp(&a.1));
            above.truncate(keep);
        }
        above
            .into_iter()
            .map(|(i, v)| Return {
                range_m: (i as f64 + 0.5) * bin_size_m,
                strength_db: v,
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_strongest_bins_above_the_floor_are_kept_and_the_near_ones_skipped() {
        let mut power = vec![10u8; 1000];
        power[5] = 250; // inside the minimum range
        power[300] = 200;
        power[301] = 180;
        power[700] = 120;
        let got = KStrongest {
            k: 2,
            z_min: 2.0,
            min_range_m: 4.0,
        }
        .returns(&power, 0.05);
        let mut ranges: Vec<f64> = got.iter().map(|r| r.range_m).collect();
        ranges.sort_by(f64::total_cmp);
        assert_eq!(ranges.len(), 2);
        assert!((ranges[0] - 15.025).abs() < 1e-9 && (ranges[1] - 15.075).abs() < 1e-9);
    }

    #[test]
    fn a_flat_or_empty_profile_or_a_bad_bin_size_gives_nothing() {
        let k = KStrongest::default();
        assert!(k.returns(&[7u8; 100], 0.05).is_empty());
        assert!(k.returns::<u8>(&[], 0.05).is_empty());
        assert!(k.returns(&[1.0f64, 9.0, 3.0], f64::NAN).is_empty());
        assert!(k.returns(&[1.0f64, 9.0, 3.0], 0.0).is_empty());
    }
}
