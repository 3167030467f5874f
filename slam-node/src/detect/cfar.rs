//! Constant-false-alarm-rate thresholds along one spectrum: cell averaging (CA) and ordered
//! statistic (OS).
//!
//! Both work on linear power (the mean or the k-th smallest of the reference cells) and
//! return a per-bin threshold in dB, so the caller compares dB with dB. Reference cells are
//! `reference_cells` bins on each side of the cell under test, beyond `guard_cells` bins that
//! keep a target's own skirt out of its noise estimate. Near either end of the spectrum the
//! window is one-sided; a bin with fewer than `min_reference_cells` usable cells gets an
//! infinite threshold (no detection), never a guess.
//!
//! CA-CFAR is O(n) by a running sum. OS-CFAR keeps the reference cells in a sorted window
//! updated by binary-search insertion and removal, O(n * N) memory moves of N floats, so it
//! stays well inside the budget for a 3768-bin CTS350-X spectrum.

/// Window shape shared by both CFAR variants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CfarWindow {
    /// Reference cells on each side of the cell under test.
    pub reference_cells: usize,
    /// Guard cells on each side between the cell under test and its reference cells.
    pub guard_cells: usize,
    /// Fewest usable reference cells (both sides together) for a bin to be tested at all.
    pub min_reference_cells: usize,
}

/// Converts dB to linear power.
fn db_to_linear(power_db: f64) -> f64 {
    (power_db * (std::f64::consts::LN_10 / 10.0)).exp()
}

/// Converts linear power to dB; zero maps to -inf, as it should.
fn linear_to_db(power: f64) -> f64 {
    10.0 * power.log10()
}

/// The reference cell index ranges `[lo, hi)` on the near and far side of bin `i`.
fn reference_ranges(i: usize, n: usize, w: &CfarWindow) -> ((usize, usize), (usize, usize)) {
    let near_hi = i.saturating_sub(w.guard_cells);
    let near_lo = i.saturating_sub(w.guard_cells + w.reference_cells);
    let far_lo = (i + w.guard_cells + 1).min(n);
    let far_hi = (i + w.guard_cells + 1 + w.reference_cells).min(n);
    ((near_lo, near_hi), (far_lo, far_hi))
}

/// Cell-averaging CFAR: threshold[i] = mean of the reference cells (linear) + `scale_db`.
///
/// `thresholds_db` is cleared and refilled with one value per input bin.
pub fn ca_cfar_thresholds(
    power_db: &[f64],
    window: &CfarWindow,
    scale_db: f64,
    thresholds_db: &mut Vec<f64>,
) {
    let n = power_db.len();
    thresholds_db.clear();
    thresholds_db.reserve(n);
    // Prefix sums of linear power give every window sum in O(1).
    let mut prefix = Vec::with_capacity(n + 1);
    prefix.push(0.0);
    let mut acc = 0.0;
    for &p in power_db {
        acc += db_to_linear(p);
        prefix.push(acc);
    }
    let sum = |lo: usize, hi: usize| -> f64 {
        match (prefix.get(hi), prefix.get(lo)) {
            (Some(h), Some(l)) if hi > lo => h - l,
            _ => 0.0,
        }
    };
    for i in 0..n {
        let ((a, b), (c, d)) = reference_ranges(i, n, window);
        let count = (b - a) + (d - c);
        if count < window.min_reference_cells.max(1) {
            thresholds_db.push(f64::INFINITY);
            continue;
        }
        let mean = (sum(a, b) + sum(c, d)) / count as f64;
        thresholds_db.push(linear_to_db(mean) + scale_db);
    }
}

/// A sorted multiset of f64 (no NaN: callers map NaN to -inf before inserting).
#[derive(Debug, Default)]
struct SortedWindow {
    values: Vec<f64>,
}

impl SortedWindow {
    fn insert(&mut self, v: f64) {
        let at = self.values.partition_point(|&x| x < v);
        self.values.insert(at, v);
    }

    fn remove(&mut self, v: f64) {
        let at = self.values.partition_point(|&x| x < v);
        if at < self.values.len() {
            self.values.remove(at);
        }
    }
}

/// Maps NaN to -inf so that a corrupt bin can never detect and never poisons the ordering.
fn sanitise(p: f64) -> f64 {
    if p.is_nan() {
        f64::NEG_INFINITY
    } else {
        p
    }
}

/// Ordered-statistic CFAR: threshold[i] = the `rank`-th smallest reference cell (as a
/// fraction of the cells present, e.g. 0.75) + `scale_db`.
///
/// Ranking is monotone, so it is done on dB values directly (same order as linear).
pub fn os_cfar_thresholds(
    power_db: &[f64],
    window: &CfarWindow,
    rank_fraction: f64,
    scale_db: f64,
    thresholds_db: &mut Vec<f64>,
) {
    let n = power_db.len();
    thresholds_db.clear();
    thresholds_db.reserve(n);
    let at = |j: usize| power_db.get(j).copied().map_or(f64::NEG_INFINITY, sanitise);
    let mut sorted = SortedWindow {
        values: Vec::with_capacity(2 * window.reference_cells + 1),
    };
    let mut prev: Option<((usize, usize), (usize, usize))> = None;
    for i in 0..n {
        let ranges = reference_ranges(i, n, window);
        match prev {
            None => {
                let ((a, b), (c, d)) = ranges;
                for j in (a..b).chain(c..d) {
                    sorted.insert(at(j));
                }
            }
            Some(((pa, pb), (pc, pd))) => {
                let ((a, b), (c, d)) = ranges;
                // Every bound moves forward by at most one bin per step.
                for j in pa..a {
                    sorted.remove(at(j));
                }
                for j in pb..b {
                    sorted.insert(at(j));
                }
                for j in pc..c {
                    sorted.remove(at(j));
                }
                for j in pd..d {
                    sorted.insert(at(j));
                }
            }
        }
        prev = Some(ranges);
        let count = sorted.values.len();
        if count < window.min_reference_cells.max(1) {
            thresholds_db.push(f64::INFINITY);
            continue;
        }
        let k =
            ((rank_fraction.clamp(0.0, 1.0) * count as f64).ceil() as usize).clamp(1, count) - 1;
        let level = sorted.values.get(k).copied().unwrap_or(f64::INFINITY);
        thresholds_db.push(level + scale_db);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const W: CfarWindow = CfarWindow {
        reference_cells: 8,
        guard_cells: 2,
        min_reference_cells: 4,
    };

    #[test]
    fn ca_cfar_on_a_flat_floor_sits_scale_above_it() {
        let p = vec![10.0; 100];
        let mut t = Vec::new();
        ca_cfar_thresholds(&p, &W, 6.0, &mut t);
        assert_eq!(t.len(), 100);
        for v in &t {
            assert!((v - 16.0).abs() < 1e-9, "{v}");
        }
    }

    #[test]
    fn os_cfar_matches_a_brute_force_sort() {
        let p: Vec<f64> = (0..200).map(|i| ((i * 37) % 23) as f64 - 5.0).collect();
        let mut t = Vec::new();
        os_cfar_thresholds(&p, &W, 0.75, 3.0, &mut t);
        for (i, ti) in t.iter().enumerate() {
            let ((a, b), (c, d)) = reference_ranges(i, p.len(), &W);
            let mut cells: Vec<f64> = p[a..b].iter().chain(&p[c..d]).copied().collect();
            if cells.len() < W.min_reference_cells {
                assert!(ti.is_infinite());
                continue;
            }
            cells.sort_by(f64::total_cmp);
            let k = ((0.75 * cells.len() as f64).ceil() as usize).clamp(1, cells.len()) - 1;
            assert!((ti - (cells[k] + 3.0)).abs() < 1e-12, "bin {i}");
        }
    }

    #[test]
    fn os_cfar_is_not_raised_by_a_second_target_inside_the_window() {
        // Two strong targets 6 bins apart: CA's mean is dragged up by the neighbour, the
        // 75th percentile of 16 cells is not.
        let mut p = vec![0.0; 100];
        p[50] = 30.0;
        p[56] = 30.0;
        let (mut ca, mut os) = (Vec::new(), Vec::new());
        ca_cfar_thresholds(&p, &W, 10.0, &mut ca);
        os_cfar_thresholds(&p, &W, 0.75, 10.0, &mut os);
        assert!(ca[50] > 20.0, "CA threshold {} is pulled up", ca[50]);
        assert!(os[50] < 11.0, "OS threshold {} stays at the floor", os[50]);
    }

    #[test]
    fn nan_bins_never_detect_and_never_panic() {
        let mut p = vec![0.0; 50];
        p[10] = f64::NAN;
        let mut t = Vec::new();
        os_cfar_thresholds(&p, &W, 0.75, 3.0, &mut t);
        ca_cfar_thresholds(&p, &W, 3.0, &mut t);
        assert_eq!(t.len(), 50);
    }
}
