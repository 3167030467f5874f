//! A run-long series in bounded memory: every value is kept until the series holds
//! [`Thinned::capacity`], then every other one is dropped and from then on only every
//! second (fourth, ...) value is kept. Its values stay spread evenly over the whole run, so
//! the run's first and last tenths (or any share) can be compared however long it ran: at
//! 4 rotations a second the default 2^17 values cover the first 9 hours one for one.

/// A series of at most `capacity` values spread evenly over everything pushed.
#[derive(Debug, Clone)]
pub struct Thinned {
    values: Vec<f64>,
    capacity: usize,
    /// Values pushed per value kept (a power of two).
    stride: u64,
    /// Values pushed since the last one kept.
    skipped: u64,
}

/// The default capacity: 2^17 values (1 MiB).
pub const DEFAULT_CAPACITY: usize = 1 << 17;

impl Default for Thinned {
    fn default() -> Self {
        Self::with_capacity(DEFAULT_CAPACITY)
    }
}

impl Thinned {
    /// An empty series keeping at most `capacity` values (at least 2).
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            values: Vec::new(),
            capacity: capacity.max(2),
            stride: 1,
            skipped: 0,
        }
    }

    /// Its capacity.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// The values kept, in order.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// Pushes a value.
    pub fn push(&mut self, value: f64) {
        self.skipped += 1;
        if self.skipped < self.stride {
            return;
        }
        self.skipped = 0;
        if self.values.len() == self.capacity {
            let mut k = 0;
            self.values.retain(|_| {
                k += 1;
                k % 2 == 1
            });
            self.stride *= 2;
        }
        self.values.push(value);
    }

    /// Percentiles `ps` (0-100, nearest rank) of each of `parts` equal shares of the run in
    /// order; a share with no value is empty.
    pub fn percentiles_by_share(&self, parts: usize, ps: &[f64]) -> Vec<Vec<f64>> {
        let n = self.values.len();
        (0..parts)
            .map(|i| {
                let (a, b) = (i * n / parts.max(1), (i + 1) * n / parts.max(1));
                let mut share: Vec<f64> = self.values.get(a..b).unwrap_or(&[]).to_vec();
                share.sort_by(f64::total_cmp);
                if share.is_empty() {
                    return Vec::new();
                }
                ps.iter()
                    .map(|p| {
                        let k = ((p / 100.0) * (share.len() - 1) as f64).round();
                        let k = if k.is_finite() && k >= 0.0 {
                            k as usize
                        } else {
                            0
                        };
                        share[k.min(share.len() - 1)]
                    })
                    .collect()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_run_is_kept_evenly_in_bounded_memory() {
        let mut t = Thinned::with_capacity(100);
        for i in 0..10_000 {
            t.push(f64::from(i));
        }
        assert!(t.values().len() <= 100, "{}", t.values().len());
        assert!(t.values().len() >= 50);
        // Evenly spread: constant steps from the first value to near the last.
        let step = t.values()[1] - t.values()[0];
        assert!(t.values().windows(2).all(|w| w[1] - w[0] == step));
        assert_eq!(t.values()[0], 0.0);
        assert!(*t.values().last().unwrap() >= 10_000.0 - 2.0 * step);
    }

    #[test]
    fn the_first_and_last_tenths_are_told_apart() {
        let mut t = Thinned::with_capacity(64);
        // Slow at the start, fast after: the tenths show it however much was thinned.
        for i in 0..1000 {
            t.push(if i < 100 { 20.0 } else { 5.0 });
        }
        let by = t.percentiles_by_share(10, &[50.0, 99.0]);
        assert_eq!(by.len(), 10);
        assert_eq!(by[0], vec![20.0, 20.0]);
        assert_eq!(by[9], vec![5.0, 5.0]);
        assert!(Thinned::default().percentiles_by_share(10, &[50.0])[0].is_empty());
    }
}
