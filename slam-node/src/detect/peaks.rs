//! From per-bin detection flags to targets: clusters of flagged bins, split at deep valleys,
//! one peak each with its range refined by parabolic interpolation of the dB values.

/// One target found down one beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peak {
    /// Interpolated bin position of the peak (fractional).
    pub bin: f64,
    /// Interpolated peak power, in the domain of the input spectrum (dB).
    pub power_db: f64,
    /// First and last flagged bin of the cluster the peak came from.
    pub first_bin: usize,
    /// Last flagged bin (inclusive).
    pub last_bin: usize,
}

/// Settings for peak extraction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeakSettings {
    /// Flagged runs separated by at most this many unflagged bins form one cluster.
    pub merge_gap_bins: usize,
    /// A second maximum inside a cluster is its own target when the valley between it and
    /// every stronger kept maximum is at least this deep below it, dB.
    pub min_prominence_db: f64,
    /// At most this many peaks per beam (the strongest are kept).
    pub max_peaks: usize,
}

/// Parabolic (three-point) interpolation of a peak at bin `i` in dB values: returns the
/// fractional offset in [-0.5, 0.5] and the interpolated peak value.
pub fn parabolic_peak(left: f64, centre: f64, right: f64) -> (f64, f64) {
    let denom = left - 2.0 * centre + right;
    if !denom.is_finite() || denom >= 0.0 {
        return (0.0, centre);
    }
    let delta = (0.5 * (left - right) / denom).clamp(-0.5, 0.5);
    (delta, centre - 0.25 * (left - right) * delta)
}

/// Finds the peaks of `power_db` among bins flagged in `detected`; appends to `out`.
pub fn extract_peaks(power_db: &[f64], detected: &[bool], s: &PeakSettings, out: &mut Vec<Peak>) {
    let start = out.len();
    let n = power_db.len().min(detected.len());
    let mut i = 0;
    while i < n {
        if !detected.get(i).copied().unwrap_or(false) {
            i += 1;
            continue;
        }
        let first = i;
        let mut last = i;
        let mut j = i + 1;
        while j < n {
            if detected.get(j).copied().unwrap_or(false) {
                last = j;
            } else if j - last > s.merge_gap_bins {
                break;
            }
            j += 1;
        }
        cluster_peaks(power_db, first, last, s.min_prominence_db, out);
        i = last + 1;
    }
    let found = out.get_mut(start..).unwrap_or_default();
    if found.len() > s.max_peaks {
        found.sort_by(|a, b| b.power_db.total_cmp(&a.power_db));
        out.truncate(start + s.max_peaks);
        if let Some(kept) = out.get_mut(start..) {
            kept.sort_by(|a, b| a.bin.total_cmp(&b.bin));
        }
    }
}

/// Peaks of one cluster `[first, last]`.
fn cluster_peaks(p: &[f64], first: usize, last: usize, prominence_db: f64, out: &mut Vec<Peak>) {
    let get = |k: usize| {
        p.get(k)
            .copied()
            .filter(|v| !v.is_nan())
            .unwrap_or(f64::NEG_INFINITY)
    };
    // Local maxima inside the cluster (plateaus count once, at their first bin).
    let mut maxima: Vec<usize> = (first..=last)
        .filter(|&k| {
            let v = get(k);
            let l = if k > first {
                get(k - 1)
            } else {
                f64::NEG_INFINITY
            };
            let r = if k < last {
                get(k + 1)
            } else {
                f64::NEG_INFINITY
            };
            v > l && v >= r && v.is_finite()
        })
        .collect();
    maxima.sort_by(|&a, &b| get(b).total_cmp(&get(a)));
    let mut kept: Vec<usize> = Vec::new();
    for &m in &maxima {
        let vm = get(m);
        let deep_enough = |other: usize| {
            let (lo, hi) = if other < m { (other, m) } else { (m, other) };
            let valley = (lo..=hi).map(get).fold(f64::INFINITY, f64::min);
            vm - valley >= prominence_db
        };
        let left = kept.iter().copied().filter(|&k| k < m).max();
        let right = kept.iter().copied().filter(|&k| k > m).min();
        let left_ok = match left {
            None => true,
            Some(k) => deep_enough(k),
        };
        let right_ok = match right {
            None => true,
            Some(k) => deep_enough(k),
        };
        if left_ok && right_ok {
            kept.push(m);
        }
    }
    kept.sort_unstable();
    for m in kept {
        let c = get(m);
        // Interpolate with the true neighbours (also outside the cluster) when finite.
        let l = if m > 0 { get(m - 1) } else { f64::NEG_INFINITY };
        let r = get(m + 1);
        let (delta, power_db) = if l.is_finite() && r.is_finite() {
            parabolic_peak(l, c, r)
        } else {
            (0.0, c)
        };
        out.push(Peak {
            bin: m as f64 + delta,
            power_db,
            first_bin: first,
            last_bin: last,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: PeakSettings = PeakSettings {
        merge_gap_bins: 1,
        min_prominence_db: 6.0,
        max_peaks: 16,
    };

    #[test]
    fn parabolic_interpolation_recovers_the_vertex_of_a_parabola() {
        // y = 10 - (x - 0.3)^2 sampled at -1, 0, 1.
        let f = |x: f64| 10.0 - (x - 0.3) * (x - 0.3);
        let (d, v) = parabolic_peak(f(-1.0), f(0.0), f(1.0));
        assert!((d - 0.3).abs() < 1e-12);
        assert!((v - 10.0).abs() < 1e-12);
    }

    #[test]
    fn two_peaks_with_a_deep_valley_are_two_targets_and_a_ripple_is_one() {
        let mut p = vec![0.0; 40];
        let mut d = vec![false; 40];
        for (k, v) in [(10, 20.0), (11, 30.0), (12, 10.0), (13, 28.0), (14, 20.0)] {
            p[k] = v;
            d[k] = true;
        }
        for (k, v) in [(30, 20.0), (31, 30.0), (32, 27.0), (33, 29.0), (34, 20.0)] {
            p[k] = v;
            d[k] = true;
        }
        let mut out = Vec::new();
        extract_peaks(&p, &d, &S, &mut out);
        let bins: Vec<usize> = out.iter().map(|q| q.bin.round() as usize).collect();
        assert_eq!(bins, vec![11, 13, 31]);
    }

    #[test]
    fn the_strongest_peaks_are_kept_when_there_are_too_many() {
        let mut p = vec![0.0; 100];
        let mut d = vec![false; 100];
        for k in 0..10 {
            p[k * 10] = 10.0 + k as f64;
            d[k * 10] = true;
        }
        let mut out = Vec::new();
        extract_peaks(&p, &d, &PeakSettings { max_peaks: 3, ..S }, &mut out);
        let bins: Vec<usize> = out.iter().map(|q| q.bin.round() as usize).collect();
        assert_eq!(bins, vec![70, 80, 90]);
    }
}
