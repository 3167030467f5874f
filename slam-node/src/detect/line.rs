//! Detection at line rate for current units: every target down one beam, found in the
//! wire's 8-bit bins against the floor learned from the stream ([`super::learned`]).
//!
//! Per azimuth, in integers until a target is found:
//! 1. the spectrum is smoothed over three bins, `s[b] = v[b-1] + 2 v[b] + v[b+1]` (8 units
//!    per dB), into a reused buffer;
//! 2. every `sample_every`-th smoothed spectrum feeds the learned floor;
//! 3. the bins above the floor's per-bin threshold (`median + max(k sigma, min SNR)`) are
//!    found 32 at a time (a block with none is skipped in a few vector instructions);
//! 4. each run of such bins (gaps of at most `merge_gap_bins` joined) becomes one target:
//!    range by parabolic interpolation at its maximum, its power, its SNR over the floor's
//!    median and its extent in range (a wall seen along the beam is a long run; a pole, a
//!    short one). The strongest `max_peaks` by SNR are kept, in range order.
//!
//! Nothing is allocated per azimuth once the buffers have their size.

use super::learned::{LearnedFloor, SMOOTHED_UNITS_PER_DB};
use super::peaks::parabolic_peak;
use super::RangeAxis;

/// Settings of the line-rate detector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineSettings {
    /// Runs separated by at most this many bins below threshold are one target.
    pub merge_gap_bins: usize,
    /// At most this many targets per azimuth (the strongest by SNR).
    pub max_peaks: usize,
    /// Nearest range searched, metres.
    pub min_range_m: f64,
    /// Farthest range searched, metres.
    pub max_range_m: f64,
}

/// One target found by the line-rate detector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinePeak {
    /// Interpolated bin position.
    pub bin: f64,
    /// Interpolated peak power of the smoothed spectrum, dB as measured.
    pub measured_db: f64,
    /// Peak minus the floor's median there, dB.
    pub snr_db: f64,
    /// Bins from the run's first to its last (inclusive).
    pub extent_bins: usize,
}

/// The line-rate detector's buffers.
#[derive(Debug, Default)]
pub struct LineDetector {
    smoothed: Vec<u16>,
    peaks: Vec<LinePeak>,
}

/// Bins looked at together when skipping empty stretches.
const CHUNK: usize = 32;

impl LineDetector {
    /// An empty detector.
    pub fn new() -> Self {
        Self::default()
    }

    /// The last azimuth's smoothed spectrum ([`SMOOTHED_UNITS_PER_DB`] per dB).
    pub fn smoothed(&self) -> &[u16] {
        &self.smoothed
    }

    /// Smooths `bins` (8-bit, 0.5 dB steps), offers them to `floor`, and finds the targets;
    /// they replace the contents of `out`, in range order.
    pub fn detect(
        &mut self,
        bins: &[u8],
        floor: &mut LearnedFloor,
        axis: &RangeAxis,
        s: &LineSettings,
        out: &mut Vec<LinePeak>,
    ) {
        out.clear();
        smooth3(bins, &mut self.smoothed);
        floor.offer(&self.smoothed, bins);
        if !floor.is_ready() {
            return;
        }
        let n = self.smoothed.len().min(floor.threshold().len());
        let lo = axis_bin(axis, s.min_range_m).clamp(1, n);
        let hi = (axis_bin(axis, s.max_range_m) + 1).clamp(lo, n.saturating_sub(1).max(lo));
        let sm = &self.smoothed[..n];
        let th = &floor.threshold()[..n];
        let median = &floor.median_db()[..n];
        let peaks = &mut self.peaks;
        peaks.clear();
        let mut run: Option<(usize, usize)> = None;
        let mut b = lo;
        while b < hi {
            let end = (b + CHUNK).min(hi);
            // Most 32-bin blocks hold nothing: one vectorised comparison skips them.
            let any = sm[b..end]
                .iter()
                .zip(&th[b..end])
                .fold(false, |acc, (v, t)| acc | (v > t));
            if !any {
                if let Some((first, last)) = run {
                    if end - last > s.merge_gap_bins {
                        close(first, last, sm, median, peaks);
                        run = None;
                    }
                }
                b = end;
                continue;
            }
            for k in b..end {
                if sm[k] > th[k] {
                    run = match run {
                        Some((first, last)) if k - last <= s.merge_gap_bins + 1 => Some((first, k)),
                        Some((first, last)) => {
                            close(first, last, sm, median, peaks);
                            Some((k, k))
                        }
                        None => Some((k, k)),
                    };
                }
            }
            b = end;
        }
        if let Some((first, last)) = run {
            close(first, last, sm, median, peaks);
        }
        // The runs are closed in bin order, so the peaks already are; only keeping the
        // strongest reorders them.
        if peaks.len() > s.max_peaks && s.max_peaks > 0 {
            // The strongest `max_peaks` (the nearer first among equals), in linear time.
            peaks.select_nth_unstable_by(s.max_peaks - 1, |a, b| {
                b.snr_db.total_cmp(&a.snr_db).then(a.bin.total_cmp(&b.bin))
            });
            peaks.truncate(s.max_peaks);
            peaks.sort_unstable_by(|a, b| a.bin.total_cmp(&b.bin));
        } else if s.max_peaks == 0 {
            peaks.clear();
        }
        out.extend_from_slice(peaks);
    }
}

/// One run of bins above threshold, `first..=last`, becomes one target at its maximum.
fn close(first: usize, last: usize, sm: &[u16], median: &[f64], peaks: &mut Vec<LinePeak>) {
    let Some(run) = sm.get(first..=last) else {
        return;
    };
    let Some((offset, _)) = run
        .iter()
        .enumerate()
        .max_by_key(|&(i, &v)| (v, std::cmp::Reverse(i)))
    else {
        return;
    };
    let p = first + offset;
    let at = |k: usize| f64::from(sm.get(k).copied().unwrap_or(0)) / SMOOTHED_UNITS_PER_DB;
    let (delta, peak_db) = parabolic_peak(at(p.saturating_sub(1)), at(p), at(p + 1));
    let snr_db = peak_db - median.get(p).copied().unwrap_or(0.0);
    peaks.push(LinePeak {
        bin: p as f64 + delta,
        measured_db: peak_db,
        snr_db,
        extent_bins: last - first + 1,
    });
}

/// The bin nearest range `range_m` (0 below the first bin).
fn axis_bin(axis: &RangeAxis, range_m: f64) -> usize {
    if axis.bin_m.is_nan() || axis.bin_m <= 0.0 {
        return 0;
    }
    let b = ((range_m - axis.first_bin_m) / axis.bin_m).round();
    if b.is_nan() || b < 0.0 {
        0
    } else {
        // Saturating float-to-int cast.
        b as usize
    }
}

/// `out[b] = v[b-1] + 2 v[b] + v[b+1]`, the ends taking their own value for the missing
/// neighbour.
pub fn smooth3(v: &[u8], out: &mut Vec<u16>) {
    let n = v.len();
    out.clear();
    out.resize(n, 0);
    if n == 0 {
        return;
    }
    if n == 1 {
        out[0] = 4 * u16::from(v[0]);
        return;
    }
    out[0] = 3 * u16::from(v[0]) + u16::from(v[1]);
    out[n - 1] = 3 * u16::from(v[n - 1]) + u16::from(v[n - 2]);
    for (o, w) in out[1..n - 1].iter_mut().zip(v.windows(3)) {
        *o = u16::from(w[0]) + 2 * u16::from(w[1]) + u16::from(w[2]);
    }
}

#[cfg(test)]
mod tests {
    use super::super::learned::FloorSettings;
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn axis() -> RangeAxis {
        RangeAxis {
            first_bin_m: 0.0,
            bin_m: 0.0438,
        }
    }

    fn settings() -> LineSettings {
        LineSettings {
            merge_gap_bins: 2,
            max_peaks: 16,
            min_range_m: 1.0,
            max_range_m: 1000.0,
        }
    }

    /// Floor 8 dB +- 3 dB (clipped at 0), with targets of `(bin, dB above floor, width)`.
    fn spectrum(rng: &mut ChaCha8Rng, bins: usize, targets: &[(usize, f64, usize)]) -> Vec<u8> {
        (0..bins)
            .map(|b| {
                let n: f64 = rng.sample(rand_distr::StandardNormal);
                let mut db = 8.0 + 3.0 * n;
                for &(c, h, w) in targets {
                    let d = b.abs_diff(c);
                    if d <= w / 2 {
                        db = db.max(8.0 + h - 2.0 * d as f64 / (w as f64).max(1.0));
                    }
                }
                (db * 2.0).clamp(0.0, 255.0) as u8
            })
            .collect()
    }

    #[test]
    fn two_targets_down_one_beam_are_both_found_and_the_floor_gives_no_false_alarm() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let bins = 3768;
        let mut floor = LearnedFloor::new(FloorSettings::default(), bins);
        let mut det = LineDetector::new();
        let mut out = Vec::new();
        let mut false_alarms = 0;
        for _ in 0..400 {
            let v = spectrum(&mut rng, bins, &[]);
            det.detect(&v, &mut floor, &axis(), &settings(), &mut out);
            false_alarms += out.len();
        }
        assert!(floor.is_ready());
        assert!(
            false_alarms < 4,
            "{false_alarms} false alarms in 400 azimuths"
        );
        let v = spectrum(&mut rng, bins, &[(500, 40.0, 5), (530, 30.0, 5)]);
        det.detect(&v, &mut floor, &axis(), &settings(), &mut out);
        assert_eq!(out.len(), 2, "{out:?}");
        assert!((out[0].bin - 500.0).abs() < 1.0 && (out[1].bin - 530.0).abs() < 1.0);
        assert!(out[0].snr_db > out[1].snr_db);
        assert!(out.iter().all(|p| p.extent_bins < 10));
    }

    #[test]
    fn a_wall_along_the_beam_is_one_long_run_not_a_row_of_targets() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let bins = 2000;
        let mut floor = LearnedFloor::new(FloorSettings::default(), bins);
        let mut det = LineDetector::new();
        let mut out = Vec::new();
        for _ in 0..300 {
            let v = spectrum(&mut rng, bins, &[]);
            det.detect(&v, &mut floor, &axis(), &settings(), &mut out);
        }
        let v = spectrum(&mut rng, bins, &[(1000, 35.0, 80)]);
        det.detect(&v, &mut floor, &axis(), &settings(), &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        assert!(out[0].extent_bins > 60, "{out:?}");
    }

    #[test]
    fn smoothing_weights_the_centre_twice() {
        let mut out = Vec::new();
        smooth3(&[1, 2, 3, 4], &mut out);
        assert_eq!(out, vec![5, 8, 12, 15]);
        smooth3(&[], &mut out);
        assert!(out.is_empty());
        smooth3(&[7], &mut out);
        assert_eq!(out, vec![28]);
    }
}
