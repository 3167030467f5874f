//! The radar's own noise floor and receiver gain, learned from the stream.
//!
//! The paper's unit had its floor measured once (exponential close in, Weibull beyond 45 m)
//! and its receiver compensation modelled as 60 dB per decade. A current unit is different
//! and differs between units, so both are learned from what the radar sends:
//!
//! - **Floor** ([`LearnedFloor`]): per block of range bins, a histogram of the range-smoothed
//!   spectrum over recent azimuths (every `sample_every`-th azimuth, all directions), halved
//!   when a block holds `max_samples` so old rotations fade. Most bins of most azimuths at
//!   one range hold no target, so the histogram's median is the target-absent level and its
//!   65th percentile gives the spread, `sigma = (q65 - q50) / 0.3853`, unmoved by the
//!   targets and clutter in the upper tail (robust up to about a third of the bins occupied):
//!   the detection threshold stands on these.
//! - **Background** (what a spectrum prediction puts where no mapped feature is): the mean
//!   and standard deviation in dB of the raw (unsmoothed) bins per block over the same
//!   azimuths, as running moments forgotten with the histograms. Only landmarks enter the
//!   map, so everything else the radar sees at that range (the receiver's noise, and in a
//!   street the walls, fences and cars kept out of the map) is background: its mean in dB
//!   is the prediction's unbiased level, and three of its standard deviations the bound
//!   (the paper's 99 % bound is three standard deviations of what the map does not
//!   predict). On the Oxford scans the floor alone (the mean of the samples below the
//!   median plus 3 robust sigma, bound three robust sigma, blind to the clutter tail by
//!   design) put 5.8 % of the compared bins outside its bound with a bias of -2.6 dB; the
//!   background, 2.6 % and -1.5 dB, with a wider bound (10.6-43.1 dB against 4.8-27.5).
//! - **Gain** ([`GainLearner`]): the receiver's range compensation, as the slope in dB per
//!   decade that makes the measured peak powers of detected targets fit the radar equation's
//!   `-40 log10 R`: the median measured peak power per tenth of a decade of range, a
//!   weighted least-squares line through those medians, and the compensation slope
//!   `40 + measured slope`. Its level at the reference range is the configured
//!   compensation's (a constant offset is the radar loss L's to estimate).
//!
//! Both work in the wire's 8-bit units (0.5 dB) and hold fixed-size tables sized from the
//! radar's geometry: nothing is allocated per azimuth. No IO, no clock.

/// Levels of the histograms: the smoothed spectrum in 0.5 dB steps, as the wire's 8 bits.
const LEVELS: usize = 256;
/// The smoothed spectrum is `v[b-1] + 2 v[b] + v[b+1]` of 8-bit values: 8 units per dB.
pub const SMOOTHED_UNITS_PER_DB: f64 = 8.0;

/// How the floor is learned.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorSettings {
    /// Range bins pooled into one histogram.
    pub block_bins: usize,
    /// Every this many azimuths one is added to the histograms once the floor is ready.
    pub sample_every: usize,
    /// A block's histogram is halved when it holds this many samples (forgetting).
    pub max_samples: u32,
    /// Samples a block needs before the floor is ready.
    pub min_samples: u32,
    /// The tables are recomputed every this many sampled azimuths.
    pub refresh_every: u32,
    /// A bin is a detection when it stands this many sigma above the floor's median...
    pub detect_sigma: f64,
    /// ...and at least this many dB.
    pub min_snr_db: f64,
    /// Smallest spread the floor is given, dB (a clipped floor can look perfectly flat).
    pub min_spread_db: f64,
}

impl Default for FloorSettings {
    fn default() -> Self {
        Self {
            block_bins: 8,
            sample_every: 4,
            max_samples: 4096,
            min_samples: 256,
            refresh_every: 50,
            detect_sigma: 4.0,
            min_snr_db: 12.0,
            min_spread_db: 1.0,
        }
    }
}

/// The floor learned so far, per range bin.
#[derive(Debug, Clone)]
pub struct LearnedFloor {
    settings: FloorSettings,
    bins: usize,
    hist: Vec<u32>,
    count: Vec<u32>,
    sampled: u64,
    since_refresh: u32,
    azimuths: u64,
    refreshes: u64,
    ready: bool,
    median_db: Vec<f64>,
    sigma_db: Vec<f64>,
    background_db: Vec<f64>,
    background_sigma_db: Vec<f64>,
    /// Per block, the raw bins' running moments `(n, sum, sum of squares)` in 8-bit units.
    moments: Vec<[f64; 3]>,
    threshold: Vec<u16>,
    block_stats: Vec<Option<BlockStats>>,
}

/// Per-block statistics of one histogram.
#[derive(Debug, Clone, Copy, PartialEq)]
struct BlockStats {
    median_db: f64,
    sigma_db: f64,
    background_db: f64,
    background_sigma_db: f64,
}

impl LearnedFloor {
    /// Bytes of state for `bins` range bins with `block_bins` per block.
    pub fn state_bytes(bins: usize, block_bins: usize) -> usize {
        let blocks = bins.div_ceil(block_bins.max(1));
        blocks * ((LEVELS + 1) * 4 + 3 * 8) + bins * (4 * 8 + 2)
    }

    /// An empty floor for spectra of `bins` bins.
    pub fn new(settings: FloorSettings, bins: usize) -> Self {
        let settings = FloorSettings {
            block_bins: settings.block_bins.max(1),
            sample_every: settings.sample_every.max(1),
            max_samples: settings.max_samples.max(2),
            refresh_every: settings.refresh_every.max(1),
            ..settings
        };
        let blocks = bins.div_ceil(settings.block_bins);
        Self {
            settings,
            bins,
            hist: vec![0; blocks * LEVELS],
            count: vec![0; blocks],
            sampled: 0,
            since_refresh: 0,
            azimuths: 0,
            refreshes: 0,
            ready: false,
            median_db: vec![0.0; bins],
            sigma_db: vec![0.0; bins],
            background_db: vec![0.0; bins],
            background_sigma_db: vec![0.0; bins],
            moments: vec![[0.0; 3]; blocks],
            threshold: vec![u16::MAX; bins],
            block_stats: Vec::with_capacity(blocks),
        }
    }

    /// The settings in force.
    pub fn settings(&self) -> &FloorSettings {
        &self.settings
    }

    /// Whether every block has enough samples for the tables to mean something.
    pub fn is_ready(&self) -> bool {
        self.ready
    }

    /// Azimuths sampled so far.
    pub fn sampled(&self) -> u64 {
        self.sampled
    }

    /// Times the tables were recomputed.
    pub fn refreshes(&self) -> u64 {
        self.refreshes
    }

    /// Median of the smoothed floor per bin, dB (as measured).
    pub fn median_db(&self) -> &[f64] {
        &self.median_db
    }

    /// Spread (one sigma) of the floor per bin, dB.
    pub fn sigma_db(&self) -> &[f64] {
        &self.sigma_db
    }

    /// Mean of the background per bin, dB (as measured, compensation not removed): what a
    /// spectrum prediction puts where no mapped feature is.
    pub fn background_db(&self) -> &[f64] {
        &self.background_db
    }

    /// Standard deviation of the background per bin, dB (at least `min_spread_db`).
    pub fn background_sigma_db(&self) -> &[f64] {
        &self.background_sigma_db
    }

    /// Detection threshold per bin in smoothed units ([`SMOOTHED_UNITS_PER_DB`] per dB);
    /// `u16::MAX` (nothing detected) until the floor is ready.
    pub fn threshold(&self) -> &[u16] {
        &self.threshold
    }

    /// Offers one azimuth: its raw 8-bit bins (0.5 dB steps) and their smoothed spectrum
    /// (`v[b-1] + 2 v[b] + v[b+1]`); it is added when it is due (every azimuth until the
    /// floor is ready, then every `sample_every`-th). Returns whether the tables were
    /// recomputed.
    pub fn offer(&mut self, smoothed: &[u16], raw: &[u8]) -> bool {
        self.azimuths += 1;
        let due = !self.ready
            || self
                .azimuths
                .is_multiple_of(self.settings.sample_every as u64);
        if !due {
            return false;
        }
        let block_bins = self.settings.block_bins;
        let n = smoothed.len().min(self.bins);
        let raw = raw.get(..n.min(raw.len())).unwrap_or_default();
        for (k, (chunk, (row, count))) in smoothed[..n]
            .chunks(block_bins)
            .zip(
                self.hist
                    .chunks_exact_mut(LEVELS)
                    .zip(self.count.iter_mut()),
            )
            .enumerate()
        {
            if let (Some(m), Some(r)) = (
                self.moments.get_mut(k),
                raw.get(k * block_bins..((k + 1) * block_bins).min(raw.len())),
            ) {
                let (mut sum, mut sq) = (0u32, 0u32);
                for &v in r {
                    let v = u32::from(v);
                    sum += v;
                    sq += v * v;
                }
                m[0] += r.len() as f64;
                m[1] += f64::from(sum);
                m[2] += f64::from(sq);
            }
            for &s in chunk {
                // (s + 2) / 4: the smoothed value back in 0.5 dB steps, rounded; s <= 1020.
                let level = usize::from((s.saturating_add(2) >> 2).min(LEVELS as u16 - 1));
                if let Some(h) = row.get_mut(level) {
                    *h += 1;
                }
            }
            *count += chunk.len() as u32;
            if *count >= self.settings.max_samples {
                row.iter_mut().for_each(|h| *h /= 2);
                *count = row.iter().sum();
                if let Some(m) = self.moments.get_mut(k) {
                    m.iter_mut().for_each(|x| *x *= 0.5);
                }
            }
        }
        self.sampled += 1;
        self.since_refresh += 1;
        let enough = self
            .count
            .iter()
            .all(|&c| c >= self.settings.min_samples.min(self.settings.max_samples / 2));
        if (!self.ready && enough)
            || (self.ready && self.since_refresh >= self.settings.refresh_every)
        {
            self.refresh();
            self.ready = true;
            return true;
        }
        false
    }

    fn block_stats(row: &[u32], count: u32, moments: [f64; 3]) -> Option<BlockStats> {
        if count == 0 {
            return None;
        }
        let total = f64::from(count);
        let quantile = |q: f64| -> f64 {
            let want = q * total;
            let mut acc = 0.0;
            for (level, &h) in row.iter().enumerate() {
                let next = acc + f64::from(h);
                if next >= want && h > 0 {
                    // Interpolate inside the level (values are spread over its 0.5 dB).
                    let frac = ((want - acc) / f64::from(h)).clamp(0.0, 1.0);
                    return 0.5 * (level as f64 - 0.5 + frac);
                }
                acc = next;
            }
            0.5 * (LEVELS - 1) as f64
        };
        let median_db = quantile(0.5).max(0.0);
        // The 65th percentile is 0.385 sigma above the median of a Gaussian: robust to a
        // third of the samples occupied, where the upper quartile is not.
        let q65 = quantile(0.65);
        let sigma_db = (q65 - median_db).max(0.0) / 0.3853;
        // The background's mean and spread from the raw bins' moments (0.5 dB a unit).
        let [n, sum, sq] = moments;
        let (background_db, background_sigma_db) = if n > 0.0 {
            let mean = sum / n;
            (0.5 * mean, 0.5 * (sq / n - mean * mean).max(0.0).sqrt())
        } else {
            (median_db, sigma_db)
        };
        Some(BlockStats {
            median_db,
            sigma_db,
            background_db,
            background_sigma_db,
        })
    }

    /// Recomputes the per-bin tables from the histograms: block statistics, linearly
    /// interpolated between block centres.
    pub fn refresh(&mut self) {
        self.since_refresh = 0;
        self.refreshes += 1;
        let s = self.settings;
        let mut stats = std::mem::take(&mut self.block_stats);
        stats.clear();
        stats.extend(
            self.hist
                .chunks_exact(LEVELS)
                .zip(&self.count)
                .zip(&self.moments)
                .map(|((row, &c), &m)| Self::block_stats(row, c, m)),
        );
        let blocks = stats.len();
        let centre = |k: usize| (k * s.block_bins) as f64 + 0.5 * (s.block_bins as f64 - 1.0);
        let get = |k: usize| {
            stats
                .get(k.min(blocks.saturating_sub(1)))
                .copied()
                .flatten()
        };
        for b in 0..self.bins {
            let x = b as f64;
            // The block below and the one above this bin's position.
            let k = b / s.block_bins;
            let (k0, k1) = if x < centre(k) {
                (k.saturating_sub(1), k)
            } else {
                (k, (k + 1).min(blocks.saturating_sub(1)))
            };
            let (a, c) = match (get(k0), get(k1)) {
                (Some(a), Some(c)) => (a, c),
                (Some(a), None) | (None, Some(a)) => (a, a),
                (None, None) => continue,
            };
            let t = if k1 > k0 {
                ((x - centre(k0)) / (centre(k1) - centre(k0))).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let lerp = |p: f64, q: f64| p + t * (q - p);
            let median = lerp(a.median_db, c.median_db);
            let sigma = lerp(a.sigma_db, c.sigma_db).max(s.min_spread_db);
            let background = lerp(a.background_db, c.background_db);
            let background_sigma =
                lerp(a.background_sigma_db, c.background_sigma_db).max(s.min_spread_db);
            let margin = (s.detect_sigma * sigma).max(s.min_snr_db);
            let threshold = ((median + margin) * SMOOTHED_UNITS_PER_DB).ceil();
            if let (Some(m), Some(sg), Some(l), Some(ls), Some(th)) = (
                self.median_db.get_mut(b),
                self.sigma_db.get_mut(b),
                self.background_db.get_mut(b),
                self.background_sigma_db.get_mut(b),
                self.threshold.get_mut(b),
            ) {
                *m = median;
                *sg = sigma;
                *l = background;
                *ls = background_sigma;
                // Finite and non-negative; saturates at u16::MAX (never detected).
                *th = threshold.clamp(0.0, f64::from(u16::MAX)) as u16;
            }
        }
        self.block_stats = stats;
    }
}

/// How the receiver gain is learned.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GainSettings {
    /// Range where the learned curve meets the configured one, metres.
    pub reference_range_m: f64,
    /// Nearest range whose peaks are used, metres.
    pub min_range_m: f64,
    /// Farthest range whose peaks are used, metres.
    pub max_range_m: f64,
    /// Peaks a range cell needs before its median is used.
    pub min_peaks_per_cell: u32,
    /// Decades of range the used cells must span before a slope is fitted.
    pub min_span_decades: f64,
    /// Bounds of the learned compensation slope, dB per decade.
    pub slope_bounds_db_per_decade: (f64, f64),
}

impl Default for GainSettings {
    fn default() -> Self {
        Self {
            reference_range_m: 20.0,
            min_range_m: 3.0,
            max_range_m: 500.0,
            min_peaks_per_cell: 20,
            min_span_decades: 0.5,
            slope_bounds_db_per_decade: (0.0, 80.0),
        }
    }
}

/// Cells of range per decade.
const CELLS_PER_DECADE: f64 = 10.0;

/// The receiver's compensation slope learned from detected peaks.
#[derive(Debug, Clone)]
pub struct GainLearner {
    settings: GainSettings,
    log_min: f64,
    hist: Vec<u32>,
    count: Vec<u32>,
    slope_db_per_decade: Option<f64>,
}

impl GainLearner {
    /// An empty learner.
    pub fn new(settings: GainSettings) -> Self {
        let log_min = settings.min_range_m.max(1e-3).log10();
        let log_max = settings
            .max_range_m
            .max(settings.min_range_m * 1.01)
            .log10();
        let cells = (((log_max - log_min) * CELLS_PER_DECADE).ceil() as usize).clamp(1, 64);
        Self {
            settings,
            log_min,
            hist: vec![0; cells * LEVELS],
            count: vec![0; cells],
            slope_db_per_decade: None,
        }
    }

    /// The learned compensation slope, dB per decade, once enough peaks were seen.
    pub fn slope_db_per_decade(&self) -> Option<f64> {
        self.slope_db_per_decade
    }

    /// Adds one detected peak: its range and its measured (compensated) power.
    pub fn add(&mut self, range_m: f64, measured_db: f64) {
        let usable = range_m >= self.settings.min_range_m
            && range_m <= self.settings.max_range_m
            && measured_db.is_finite();
        if !usable {
            return;
        }
        let cell = ((range_m.log10() - self.log_min) * CELLS_PER_DECADE) as usize;
        let level = (measured_db * 2.0).clamp(0.0, (LEVELS - 1) as f64) as usize;
        let Some(count) = self.count.get_mut(cell) else {
            return;
        };
        *count += 1;
        if let Some(row) = self.hist.get_mut(cell * LEVELS..(cell + 1) * LEVELS) {
            if let Some(h) = row.get_mut(level) {
                *h += 1;
            }
            if *count >= 1 << 14 {
                row.iter_mut().for_each(|h| *h /= 2);
                *count = row.iter().sum();
            }
        }
    }

    /// Refits the slope from the cells' medians; returns it when there is one.
    pub fn refit(&mut self) -> Option<f64> {
        let s = self.settings;
        let mut pts = Vec::new();
        for (k, (row, &c)) in self.hist.chunks_exact(LEVELS).zip(&self.count).enumerate() {
            if c < s.min_peaks_per_cell {
                continue;
            }
            let half = f64::from(c) / 2.0;
            let mut acc = 0.0;
            let mut median = 0.0;
            for (level, &h) in row.iter().enumerate() {
                acc += f64::from(h);
                if acc >= half {
                    median = 0.5 * level as f64;
                    break;
                }
            }
            let log_r = self.log_min + (k as f64 + 0.5) / CELLS_PER_DECADE;
            pts.push((log_r, median, f64::from(c).sqrt()));
        }
        let span = match (pts.first(), pts.last()) {
            (Some(a), Some(b)) => b.0 - a.0,
            _ => 0.0,
        };
        if pts.len() < 3 || span < s.min_span_decades {
            return self.slope_db_per_decade;
        }
        let w: f64 = pts.iter().map(|p| p.2).sum();
        let mx = pts.iter().map(|p| p.2 * p.0).sum::<f64>() / w;
        let my = pts.iter().map(|p| p.2 * p.1).sum::<f64>() / w;
        let sxx: f64 = pts.iter().map(|p| p.2 * (p.0 - mx).powi(2)).sum();
        let sxy: f64 = pts.iter().map(|p| p.2 * (p.0 - mx) * (p.1 - my)).sum();
        if sxx <= 0.0 {
            return self.slope_db_per_decade;
        }
        // Measured peaks fall by `-measured` per decade; the radar equation by 40.
        let (lo, hi) = s.slope_bounds_db_per_decade;
        let slope = (40.0 + sxy / sxx).clamp(lo, hi);
        self.slope_db_per_decade = Some(slope);
        Some(slope)
    }

    /// Compensation gain per bin: the configured gain at the reference range, then the
    /// learned slope in log range (the configured table where no slope is learned yet).
    pub fn gain_into(
        &self,
        configured_db: &[f64],
        range_of_bin: impl Fn(usize) -> f64,
        out: &mut [f64],
    ) {
        let r_ref = self.settings.reference_range_m;
        let Some(slope) = self.slope_db_per_decade else {
            for (o, &c) in out.iter_mut().zip(configured_db) {
                *o = c;
            }
            return;
        };
        // The configured gain at the reference range, by interpolation in the table.
        let g_ref = {
            let mut best = (f64::INFINITY, 0.0);
            for (b, &c) in configured_db.iter().enumerate() {
                let d = (range_of_bin(b) - r_ref).abs();
                if d < best.0 {
                    best = (d, c);
                }
            }
            best.1
        };
        let floor_range = self.settings.min_range_m.max(1e-3);
        for (b, o) in out.iter_mut().enumerate() {
            let r = range_of_bin(b).max(floor_range);
            *o = g_ref + slope * (r / r_ref).log10();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Smoothed spectrum of 8-bit values.
    fn smooth(v: &[u8]) -> Vec<u16> {
        let n = v.len();
        (0..n)
            .map(|b| {
                let l = u16::from(v[b.saturating_sub(1)]);
                let r = u16::from(v[(b + 1).min(n - 1)]);
                l + 2 * u16::from(v[b]) + r
            })
            .collect()
    }

    #[test]
    fn a_gaussian_floor_with_a_tenth_of_its_bins_occupied_is_learned_within_two_db() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let bins = 400;
        let mut floor = LearnedFloor::new(FloorSettings::default(), bins);
        // Floor rising from 10 dB to 30 dB with range, sigma 3 dB; a tenth of the bins hold
        // strong clutter (after three-bin smoothing it touches about a quarter of them).
        let truth = |b: usize| 10.0 + 20.0 * b as f64 / bins as f64;
        for _ in 0..800 {
            let v: Vec<u8> = (0..bins)
                .map(|b| {
                    let clutter = if rng.gen_bool(0.1) { 40.0 } else { 0.0 };
                    let n: f64 = rng.sample(rand_distr::StandardNormal);
                    ((truth(b) + 3.0 * n + clutter) * 2.0).clamp(0.0, 255.0) as u8
                })
                .collect();
            floor.offer(&smooth(&v), &v);
        }
        assert!(floor.is_ready());
        for b in [20, 100, 200, 380] {
            let m = floor.median_db()[b];
            // Smoothing over three bins lowers the spread, not the level; the clutter lifts
            // the median by a fraction of a sigma.
            assert!(
                (m - truth(b)).abs() < 2.0,
                "bin {b}: median {m} against {}",
                truth(b)
            );
            let s = floor.sigma_db()[b];
            // The smoothed floor's sigma is 1.8 dB; the clutter widens the estimate.
            assert!(s > 1.0 && s < 5.0, "bin {b}: sigma {s}");
        }
    }

    #[test]
    fn the_background_holds_the_clutter_that_the_floor_median_ignores() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let bins = 400;
        let mut floor = LearnedFloor::new(FloorSettings::default(), bins);
        // Floor at 20 dB, sigma 3 dB; a tenth of the bins 40 dB higher (walls kept out of
        // the map): the background's mean in dB is 24 dB, its spread sqrt(9 + 0.09 1600).
        for _ in 0..800 {
            let v: Vec<u8> = (0..bins)
                .map(|_| {
                    let clutter = if rng.gen_bool(0.1) { 40.0 } else { 0.0 };
                    let n: f64 = rng.sample(rand_distr::StandardNormal);
                    ((20.0 + 3.0 * n + clutter) * 2.0).clamp(0.0, 255.0) as u8
                })
                .collect();
            floor.offer(&smooth(&v), &v);
        }
        let spread = (9.0f64 + 0.09 * 1600.0).sqrt();
        for b in [20, 200, 380] {
            // The 8-bit cast truncates: 0.25 dB low on average.
            let mean = floor.background_db()[b];
            assert!((mean - 23.75).abs() < 1.0, "bin {b}: mean {mean}");
            let sigma = floor.background_sigma_db()[b];
            assert!((sigma - spread).abs() < 1.0, "bin {b}: sigma {sigma}");
            // The floor's median and robust sigma stay near the noise.
            assert!(floor.median_db()[b] < 22.0, "bin {b}: median");
            assert!(floor.sigma_db()[b] < 5.0, "bin {b}: robust sigma");
        }
    }

    #[test]
    fn nothing_is_detected_before_the_floor_is_ready() {
        let floor = LearnedFloor::new(FloorSettings::default(), 100);
        assert!(!floor.is_ready());
        assert!(floor.threshold().iter().all(|&t| t == u16::MAX));
    }

    #[test]
    fn the_learned_slope_recovers_a_receiver_that_compensates_thirty_db_per_decade() {
        let mut g = GainLearner::new(GainSettings::default());
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        // Peaks of targets of random reflectivity: measured = c - 40 log R + 30 log R.
        for _ in 0..20_000 {
            let r: f64 = 10f64.powf(rng.gen_range(0.6..2.2));
            let n: f64 = rng.sample(rand_distr::StandardNormal);
            g.add(r, 60.0 - 10.0 * r.log10() + 4.0 * n);
        }
        let slope = g.refit().unwrap();
        assert!((slope - 30.0).abs() < 1.0, "slope {slope}");
    }
}
