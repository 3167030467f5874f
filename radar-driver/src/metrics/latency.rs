//! A lock-free log-linear latency histogram (nanoseconds), for median and p99 without locks
//! or allocation on the hot path.
//!
//! Values below 32 ns have a bucket each; above that every power of two is split into 32
//! equal buckets, so a reported quantile is within 1/32 (about 3 %) of the true value.
//! Values at or above 2^41 ns (about 37 minutes) land in the last bucket.

use std::sync::atomic::{AtomicU64, Ordering};

const SUB_BITS: u32 = 5;
const SUB: usize = 1 << SUB_BITS;
/// Largest exponent (floor(log2 v)) with its own buckets.
const MAX_EXP: u32 = 40;
const BUCKETS: usize = (MAX_EXP - SUB_BITS + 2) as usize * SUB;

/// Median, p99 and extremes of the recorded latencies.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LatencySummary {
    /// Number of samples.
    pub count: u64,
    /// Median in nanoseconds (bucket midpoint; 0 when there are no samples).
    pub median_ns: u64,
    /// 99th percentile in nanoseconds (bucket midpoint).
    pub p99_ns: u64,
    /// Largest sample in nanoseconds (exact).
    pub max_ns: u64,
    /// Mean in nanoseconds (exact up to the sum's precision).
    pub mean_ns: f64,
}

/// A concurrent histogram of nanosecond latencies.
#[derive(Debug)]
pub struct LatencyHistogram {
    buckets: Box<[AtomicU64]>,
    count: AtomicU64,
    sum_ns: AtomicU64,
    max_ns: AtomicU64,
}

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self::new()
    }
}

fn bucket_of(value_ns: u64) -> usize {
    if value_ns < SUB as u64 {
        // Lossless: value_ns < 32.
        return value_ns as usize;
    }
    let exp = (63 - value_ns.leading_zeros()).min(MAX_EXP);
    if exp == MAX_EXP && value_ns >> (MAX_EXP + 1) != 0 {
        return BUCKETS - 1;
    }
    let shift = exp - SUB_BITS;
    // In [32, 64): fits any usize.
    let mantissa = (value_ns >> shift) as usize;
    (shift as usize + 1) * SUB + (mantissa - SUB)
}

/// The midpoint of a bucket's value range.
fn bucket_midpoint(index: usize) -> u64 {
    if index < SUB {
        return index as u64;
    }
    let shift = (index / SUB - 1) as u32;
    let mantissa = (index % SUB + SUB) as u64;
    let low = mantissa << shift;
    let width = 1u64 << shift;
    low + (width - 1) / 2
}

impl LatencyHistogram {
    /// An empty histogram.
    pub fn new() -> Self {
        Self {
            buckets: (0..BUCKETS).map(|_| AtomicU64::new(0)).collect(),
            count: AtomicU64::new(0),
            sum_ns: AtomicU64::new(0),
            max_ns: AtomicU64::new(0),
        }
    }

    /// Records one latency.
    pub fn record(&self, value_ns: u64) {
        if let Some(bucket) = self.buckets.get(bucket_of(value_ns)) {
            bucket.fetch_add(1, Ordering::Relaxed);
        }
        self.count.fetch_add(1, Ordering::Relaxed);
        self.sum_ns.fetch_add(value_ns, Ordering::Relaxed);
        self.max_ns.fetch_max(value_ns, Ordering::Relaxed);
    }

    /// The value at quantile `q` in [0, 1] (bucket midpoint), or 0 with no samples.
    pub fn quantile_ns(&self, q: f64) -> u64 {
        let counts: Vec<u64> = self
            .buckets
            .iter()
            .map(|b| b.load(Ordering::Relaxed))
            .collect();
        quantile_of(&counts, q)
    }

    /// Count, median, p99, max and mean in one pass.
    pub fn summary(&self) -> LatencySummary {
        let counts: Vec<u64> = self
            .buckets
            .iter()
            .map(|b| b.load(Ordering::Relaxed))
            .collect();
        let count: u64 = counts.iter().sum();
        let sum = self.sum_ns.load(Ordering::Relaxed);
        LatencySummary {
            count,
            median_ns: quantile_of(&counts, 0.5),
            p99_ns: quantile_of(&counts, 0.99),
            max_ns: self.max_ns.load(Ordering::Relaxed),
            mean_ns: if count == 0 {
                0.0
            } else {
                sum as f64 / count as f64
            },
        }
    }
}

fn quantile_of(counts: &[u64], q: f64) -> u64 {
    let total: u64 = counts.iter().sum();
    if total == 0 {
        return 0;
    }
    let q = if q.is_nan() { 0.5 } else { q.clamp(0.0, 1.0) };
    // Rank of the sample at quantile q, 1-based: ceil(q * n), at least 1.
    let rank = ((q * total as f64).ceil() as u64).clamp(1, total);
    let mut seen = 0u64;
    for (index, &c) in counts.iter().enumerate() {
        seen += c;
        if seen >= rank {
            return bucket_midpoint(index);
        }
    }
    bucket_midpoint(counts.len().saturating_sub(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_are_contiguous_and_increasing() {
        let mut last = 0;
        for v in [
            0u64,
            1,
            31,
            32,
            33,
            63,
            64,
            65,
            1000,
            1 << 20,
            (1 << 41) - 1,
        ] {
            let b = bucket_of(v);
            assert!(b >= last, "bucket of {v} went backwards");
            last = b;
        }
        assert_eq!(bucket_of(u64::MAX), BUCKETS - 1);
        assert_eq!(bucket_of(1 << 41), BUCKETS - 1);
    }

    #[test]
    fn a_bucket_midpoint_is_within_three_percent_of_every_value_in_it() {
        for v in (1u64..2_000_000).step_by(997) {
            let mid = bucket_midpoint(bucket_of(v)) as f64;
            assert!(
                (mid - v as f64).abs() <= v as f64 / 32.0 + 1.0,
                "{v} -> {mid}"
            );
        }
    }

    #[test]
    fn median_and_p99_of_a_known_distribution_are_reported() {
        let h = LatencyHistogram::new();
        for v in 1..=1000u64 {
            h.record(v * 1000);
        }
        let s = h.summary();
        assert_eq!(s.count, 1000);
        assert!((s.median_ns as f64 - 500_000.0).abs() < 500_000.0 / 32.0);
        assert!((s.p99_ns as f64 - 990_000.0).abs() < 990_000.0 / 32.0);
        assert_eq!(s.max_ns, 1_000_000);
        assert!((s.mean_ns - 500_500.0).abs() < 1e-6);
    }

    #[test]
    fn an_empty_histogram_reports_zeros() {
        assert_eq!(LatencyHistogram::new().summary(), LatencySummary::default());
    }
}
