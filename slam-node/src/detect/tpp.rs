//! Target presence probability (TPP), the authors' detector for noisy power-range spectra.
//!
//! Per azimuth slot and range bin, over successive rotations:
//! 1. smooth each spectrum across neighbouring bins (a short triangular kernel in linear
//!    power) and then recursively over scans of the same azimuth;
//! 2. track the minimum of the smoothed power per bin over a window of scans
//!    (windowed minimum with a running candidate, renewed every `min_window_scans` scans);
//!    the noise level of a bin is that minimum taken over a small range neighbourhood too,
//!    so that a stationary vehicle looking at a stationary point target does not learn the
//!    target as noise (its peak spans a few bins; the neighbourhood is wider);
//! 3. the indicator I = [smoothed power - noise level > `snr_threshold_db`];
//! 4. the recursive presence probability p <- alpha p + (1 - alpha) I, with the paper's
//!    alpha = 0.1, and a bin is a detection when p >= 0.8.
//!
//! With alpha = 0.1 the recursion is the form used in minima-controlled recursive averaging
//! (alpha weights the past): one scan above threshold already gives p >= 0.9, one below
//! brings p under 0.1. This is the convention that still detects a target that moves a few
//! bins between scans, as it does when the vehicle drives; the other reading (alpha as the
//! gain on the new indicator) needs about fifteen consecutive scans in the same bin.
//!
//! Memory: three f32 per (azimuth slot, bin): 18 MB for a 400 x 3768 CTS350-X rotation.
//! The first `warmup_scans` scans of a slot produce no detections: the minimum is not yet
//! a noise estimate.

/// Most azimuth slots (a rotation's azimuths) the detector keeps memory for; a slot past it
/// detects nothing rather than allocate without bound.
pub const MAX_SLOTS: usize = 1 << 16;

/// TPP settings (paper defaults in [`TppSettings::paper`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TppSettings {
    /// Half width of the triangular range smoothing kernel, bins.
    pub smooth_half_width_bins: usize,
    /// Weight of the previous scan in the recursive time smoothing (0 = none).
    pub time_smoothing: f64,
    /// A scan more than this far below a bin's smoothed level replaces the level instead of
    /// being averaged into it, dB (infinity: never): a one-scan spike (a corrupted bin,
    /// 50-80 dB over the noise) is not carried into the next rotation, whose second look
    /// would confirm it as a feature.
    pub drop_reset_db: f64,
    /// Scans over which the per-bin minimum is tracked.
    pub min_window_scans: u32,
    /// Half width of the range neighbourhood over which the noise minimum is taken, bins.
    pub noise_neighbourhood_bins: usize,
    /// Signal-to-noise threshold on the smoothed power, dB.
    pub snr_threshold_db: f64,
    /// Weight of the previous probability (the paper's alpha).
    pub alpha: f64,
    /// Presence probability at which a bin is a detection.
    pub detect_probability: f64,
    /// Scans of a slot before it may detect.
    pub warmup_scans: u32,
}

impl TppSettings {
    /// The paper's alpha 0.1 and threshold 0.8, with the smoothing, window sizes and SNR
    /// threshold chosen by measurement (see `slam-node/README.md`, "Detection").
    pub fn paper() -> Self {
        Self {
            smooth_half_width_bins: 1,
            time_smoothing: 0.3,
            drop_reset_db: 45.0,
            min_window_scans: 8,
            noise_neighbourhood_bins: 4,
            snr_threshold_db: 20.0,
            alpha: 0.1,
            detect_probability: 0.8,
            warmup_scans: 2,
        }
    }
}

/// The expected target-absent floor of a spectrum, per bin.
#[derive(Debug, Clone, Copy)]
pub struct Floor<'a> {
    /// Mean level, dB, in the detector's domain.
    pub mean_db: &'a [f64],
    /// Level above the mean that the floor exceeds with the configured small probability.
    pub tail_db: &'a [f64],
}

/// Per-slot state: smoothed power, windowed minimum (current and candidate), probability.
#[derive(Debug, Clone, Default)]
struct SlotState {
    smoothed: Vec<f32>,
    minimum: Vec<f32>,
    candidate: Vec<f32>,
    probability: Vec<f32>,
    scans: u32,
}

/// Bytes of state TPP keeps per bin of each azimuth (four f32 per bin).
pub const STATE_BYTES_PER_BIN: usize = 4 * std::mem::size_of::<f32>();

/// The TPP detector's memory across rotations, one slot per azimuth index.
#[derive(Debug, Clone)]
pub struct Tpp {
    settings: TppSettings,
    slots: Vec<SlotState>,
    scratch: Vec<f64>,
    linear: Vec<f64>,
    relative: Vec<f32>,
    noise: Vec<f64>,
    minima: (Vec<f32>, Vec<f32>),
}

impl Tpp {
    /// A detector with room for `slots` azimuths per rotation (grows on demand).
    pub fn new(settings: TppSettings, slots: usize) -> Self {
        Self {
            settings,
            slots: vec![SlotState::default(); slots],
            scratch: Vec::new(),
            linear: Vec::new(),
            relative: Vec::new(),
            noise: Vec::new(),
            minima: (Vec::new(), Vec::new()),
        }
    }

    /// Feeds one spectrum (dB) of azimuth slot `slot`; fills `detected` with one flag per
    /// bin. `snr_db` receives the smoothed power minus the noise level per bin.
    ///
    /// `floor`, when given (same length, same domain), is the expected target-absent level
    /// per bin and its upper tail: the range-neighbourhood minimum is then taken over the
    /// minima relative to the level, so a step or slope in the floor (the compensation's
    /// slope, the near-range to Weibull transition) does not drag the noise estimate of the
    /// bins beside it down; and a bin must also stand more than its tail above the level.
    /// The tail matters where the floor is heavy-tailed: the book chapter's exponential
    /// near-range floor, widening towards 45 m, throws spikes 20-30 dB over its mean that
    /// the minimum-based test alone takes for targets.
    pub fn process(
        &mut self,
        slot: usize,
        power_db: &[f64],
        floor: Option<Floor<'_>>,
        detected: &mut Vec<bool>,
        snr_db: &mut Vec<f64>,
    ) {
        let n = power_db.len();
        let s = self.settings;
        if slot >= MAX_SLOTS {
            detected.clear();
            detected.resize(n, false);
            snr_db.clear();
            snr_db.resize(n, 0.0);
            return;
        }
        if slot >= self.slots.len() {
            self.slots.resize(slot + 1, SlotState::default());
        }
        smooth_in_range(
            power_db,
            s.smooth_half_width_bins,
            &mut self.linear,
            &mut self.scratch,
        );
        let Some(state) = self.slots.get_mut(slot) else {
            return;
        };
        if state.smoothed.len() != n {
            // New slot or a different spectrum length (contour change): start afresh.
            *state = SlotState {
                smoothed: self.scratch.iter().map(|&v| v as f32).collect(),
                minimum: vec![f32::INFINITY; n],
                candidate: vec![f32::INFINITY; n],
                probability: vec![0.0; n],
                scans: 0,
            };
        }
        let a_s = s.time_smoothing.clamp(0.0, 0.999) as f32;
        let drop_reset = s.drop_reset_db as f32;
        // Time smoothing and the windowed minimum (current and candidate), in one pass.
        for (((sm, m), c), &x) in state
            .smoothed
            .iter_mut()
            .zip(state.minimum.iter_mut())
            .zip(state.candidate.iter_mut())
            .zip(&self.scratch)
        {
            let x = x as f32;
            let v = if x < *sm - drop_reset {
                x
            } else {
                a_s * *sm + (1.0 - a_s) * x
            };
            *sm = v;
            *m = m.min(v);
            *c = c.min(v);
        }
        state.scans = state.scans.saturating_add(1);
        if s.min_window_scans > 0 && state.scans % s.min_window_scans == 0 {
            std::mem::swap(&mut state.minimum, &mut state.candidate);
            // The new minimum is the last window's candidate; restart the candidate.
            state.candidate.iter_mut().for_each(|c| *c = f32::INFINITY);
            for (m, &sm) in state.minimum.iter_mut().zip(&state.smoothed) {
                *m = m.min(sm);
            }
        }
        let floor = floor.filter(|f| f.mean_db.len() == n && f.tail_db.len() == n);
        match floor.map(|f| f.mean_db) {
            Some(floor) => {
                self.relative.clear();
                self.relative.extend(
                    state
                        .minimum
                        .iter()
                        .zip(floor)
                        .map(|(&m, &f)| (f64::from(m) - f) as f32),
                );
                neighbourhood_min(
                    &self.relative,
                    s.noise_neighbourhood_bins,
                    &mut self.minima,
                    &mut self.noise,
                );
                for (v, &f) in self.noise.iter_mut().zip(floor) {
                    *v += f;
                }
            }
            None => neighbourhood_min(
                &state.minimum,
                s.noise_neighbourhood_bins,
                &mut self.minima,
                &mut self.noise,
            ),
        }
        detected.clear();
        snr_db.clear();
        let warm = state.scans > s.warmup_scans;
        let alpha = s.alpha.clamp(0.0, 1.0) as f32;
        let mut step = |p: &mut f32, sm: f32, noise: f64, above_tail: bool| {
            let snr = f64::from(sm) - noise;
            let indicator = if snr > s.snr_threshold_db && above_tail {
                1.0
            } else {
                0.0
            };
            *p = alpha * *p + (1.0 - alpha) * indicator;
            detected.push(warm && f64::from(*p) >= s.detect_probability);
            snr_db.push(snr);
        };
        let bins = state
            .probability
            .iter_mut()
            .zip(&state.smoothed)
            .zip(&self.noise);
        match floor {
            Some(f) => {
                for (((p, &sm), &noise), (&m, &t)) in bins.zip(f.mean_db.iter().zip(f.tail_db)) {
                    step(p, sm, noise, f64::from(sm) - m > t);
                }
            }
            None => {
                for ((p, &sm), &noise) in bins {
                    step(p, sm, noise, true);
                }
            }
        }
    }
}

/// `log2(10) / 10`: `10^(x / 10) = 2^(x * DB_TO_LOG2)`.
const DB_TO_LOG2: f64 = std::f64::consts::LOG2_10 / 10.0;
/// `10 log10(2)`: `10 log10(x) = log2(x) * LOG2_TO_DB`.
const LOG2_TO_DB: f64 = 10.0 * std::f64::consts::LOG10_2;

/// `10^(db / 10)` to about 1e-8 relative (1e-7 dB), without libm: the range detector
/// converts every bin of every azimuth twice, and libm's exp and log10 were two thirds of its
/// time. Non-finite input and results outside f64's normal range go to libm.
#[inline]
pub fn db_to_linear(db: f64) -> f64 {
    let y = db * DB_TO_LOG2;
    if !(-1000.0..1000.0).contains(&y) {
        return 10f64.powf(db / 10.0);
    }
    // floor(y) without a libm call: y is in (-1000, 1000).
    let t = y as i64;
    let i = (if (t as f64) > y { t - 1 } else { t }) as f64;
    // 2^f for f in [0, 1): 2^0.5 * 2^g with g in [-0.5, 0.5), Taylor series of exp(g ln 2)
    // to degree 8 (remainder below 2e-10).
    let g = (y - i - 0.5) * std::f64::consts::LN_2;
    let p = 1.0
        + g * (1.0
            + g * (0.5
                + g * (1.0 / 6.0
                    + g * (1.0 / 24.0
                        + g * (1.0 / 120.0
                            + g * (1.0 / 720.0 + g * (1.0 / 5040.0 + g * (1.0 / 40320.0))))))));
    // i is in (-1001, 1000): a normal exponent.
    let scale = f64::from_bits(((i as i64 + 1023) as u64) << 52);
    std::f64::consts::SQRT_2 * p * scale
}

/// `10 log10(x)` to about 1e-6 dB, without libm (see [`db_to_linear`]). Zero gives minus
/// infinity; negative, non-finite and subnormal input go to libm.
#[inline]
pub fn linear_to_db(x: f64) -> f64 {
    if !(x >= f64::MIN_POSITIVE && x.is_finite()) {
        return 10.0 * x.log10();
    }
    let bits = x.to_bits();
    let exponent = ((bits >> 52) & 0x7ff) as i64 - 1023;
    // Mantissa in [1, 2); log2 of it by the atanh series in t = (m - 1) / (m + 1) <= 1/3.
    let m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let series = t
        * (1.0
            + t2 * (1.0 / 3.0
                + t2 * (1.0 / 5.0
                    + t2 * (1.0 / 7.0
                        + t2 * (1.0 / 9.0 + t2 * (1.0 / 11.0 + t2 * (1.0 / 13.0)))))));
    let log2 = exponent as f64 + 2.0 * series * std::f64::consts::LOG2_E;
    log2 * LOG2_TO_DB
}

/// Triangular smoothing in linear power across `half` bins each side, result in dB. Each
/// bin is converted to linear power once; NaN bins count as zero power.
fn smooth_in_range(power_db: &[f64], half: usize, linear: &mut Vec<f64>, out: &mut Vec<f64>) {
    linear.clear();
    linear.extend(
        power_db
            .iter()
            .map(|&p| if p.is_nan() { 0.0 } else { db_to_linear(p) }),
    );
    out.clear();
    let n = linear.len();
    if half == 1 && n >= 2 {
        // The shipped kernel (1, 2, 1), edges (2, 1) / 3.
        out.push(linear_to_db((2.0 * linear[0] + linear[1]) / 3.0));
        out.extend(
            linear
                .windows(3)
                .map(|w| linear_to_db((w[0] + 2.0 * w[1] + w[2]) / 4.0)),
        );
        out.push(linear_to_db((linear[n - 2] + 2.0 * linear[n - 1]) / 3.0));
        return;
    }
    for i in 0..n {
        let lo = i.saturating_sub(half);
        let hi = (i + half + 1).min(n);
        let mut acc = 0.0;
        let mut wsum = 0.0;
        for (j, &lin) in linear.iter().enumerate().take(hi).skip(lo) {
            let w = (half + 1 - i.abs_diff(j)) as f64;
            acc += w * lin;
            wsum += w;
        }
        out.push(linear_to_db(acc / wsum));
    }
}

/// Minimum over a +-`half` bin neighbourhood (the window clipped at the ends), in O(n) by
/// van Herk / Gil-Werman: prefix and suffix minima over blocks of the window's width.
fn neighbourhood_min(
    values: &[f32],
    half: usize,
    scratch: &mut (Vec<f32>, Vec<f32>),
    out: &mut Vec<f64>,
) {
    out.clear();
    let n = values.len();
    if n == 0 {
        return;
    }
    let w = 2 * half + 1;
    // Pad by `half` on both sides with +inf so every window is whole.
    let len = n + 2 * half;
    let at = |i: usize| -> f32 {
        if i < half || i >= half + n {
            f32::INFINITY
        } else {
            values[i - half]
        }
    };
    let (prefix, suffix) = scratch;
    prefix.clear();
    prefix.resize(len, f32::INFINITY);
    suffix.clear();
    suffix.resize(len, f32::INFINITY);
    for i in 0..len {
        let v = at(i);
        prefix[i] = if i % w == 0 { v } else { prefix[i - 1].min(v) };
    }
    for i in (0..len).rev() {
        let v = at(i);
        suffix[i] = if i % w == w - 1 || i == len - 1 {
            v
        } else {
            suffix[i + 1].min(v)
        };
    }
    // Window of output i covers padded [i, i + w - 1].
    out.extend((0..n).map(|i| f64::from(suffix[i].min(prefix[i + w - 1]))));
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noisy_floor(seed: u64, n: usize) -> Vec<f64> {
        // A deterministic pseudo-random floor around 0 dB, +-2 dB.
        let mut x = seed;
        (0..n)
            .map(|_| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((x >> 33) as f64 / (1u64 << 31) as f64) * 4.0 - 2.0
            })
            .collect()
    }

    #[test]
    fn the_fast_decibel_conversions_agree_with_libm() {
        let mut worst = (0.0f64, 0.0f64);
        for k in -40_000..40_000 {
            let db = f64::from(k) * 0.01 + 0.003;
            let lin = db_to_linear(db);
            let exact = 10f64.powf(db / 10.0);
            worst.0 = worst.0.max(((lin - exact) / exact).abs());
            worst.1 = worst.1.max((linear_to_db(exact) - db).abs());
        }
        assert!(worst.0 < 1e-9, "relative error of 10^(x/10): {}", worst.0);
        assert!(worst.1 < 1e-6, "error of 10 log10(x): {} dB", worst.1);
        assert_eq!(linear_to_db(0.0), f64::NEG_INFINITY);
        assert!(linear_to_db(f64::NAN).is_nan());
        assert!(db_to_linear(f64::NAN).is_nan());
        assert_eq!(db_to_linear(f64::NEG_INFINITY), 0.0);
    }

    #[test]
    fn the_neighbourhood_minimum_matches_the_direct_form() {
        let values: Vec<f32> = noisy_floor(3, 101).iter().map(|&v| v as f32).collect();
        for half in [0usize, 1, 4, 7] {
            let mut out = Vec::new();
            neighbourhood_min(&values, half, &mut (Vec::new(), Vec::new()), &mut out);
            for (i, got) in out.iter().enumerate() {
                let lo = i.saturating_sub(half);
                let hi = (i + half + 1).min(values.len());
                let want = values[lo..hi].iter().copied().fold(f32::INFINITY, f32::min);
                assert_eq!(*got, f64::from(want), "half {half}, bin {i}");
            }
        }
    }

    #[test]
    fn a_target_that_appears_after_warmup_is_detected_and_the_floor_is_not() {
        let mut tpp = Tpp::new(TppSettings::paper(), 1);
        let (mut d, mut snr) = (Vec::new(), Vec::new());
        for scan in 0..20 {
            let mut p = noisy_floor(scan, 200);
            if scan >= 10 {
                p[100] = 40.0;
                p[101] = 35.0;
            }
            tpp.process(0, &p, None, &mut d, &mut snr);
            if scan >= 10 {
                assert!(d[100], "scan {scan}: target missed, snr {}", snr[100]);
            }
            if scan >= 3 {
                let false_alarms = d
                    .iter()
                    .enumerate()
                    .filter(|(i, &x)| x && !(95..=106).contains(i))
                    .count();
                assert_eq!(false_alarms, 0, "scan {scan}");
            }
        }
    }

    #[test]
    fn a_stationary_target_is_not_learnt_as_noise() {
        let mut tpp = Tpp::new(TppSettings::paper(), 1);
        let (mut d, mut snr) = (Vec::new(), Vec::new());
        for scan in 0..50 {
            let mut p = noisy_floor(scan, 200);
            p[60] = 40.0;
            tpp.process(0, &p, None, &mut d, &mut snr);
        }
        assert!(d[60]);
    }

    /// A one-scan spike (an inverted byte: 50-80 dB over the noise) is detected in its scan;
    /// carried by the time smoothing it was detected again the next rotation, a second look
    /// that confirms a feature (`tests/garbage_frames.rs`). Dropping back more than
    /// `drop_reset_db` below the smoothed level resets it: detected once only.
    #[test]
    fn a_one_scan_spike_is_not_carried_into_the_next_scan() {
        let spike = |settings: TppSettings| {
            let mut tpp = Tpp::new(settings, 1);
            let (mut d, mut snr) = (Vec::new(), Vec::new());
            let mut seen = Vec::new();
            for scan in 0..20u64 {
                // A floor of +-10 dB, the spread of a Rayleigh floor in dB.
                let mut p: Vec<f64> = noisy_floor(scan, 200).iter().map(|v| 5.0 * v).collect();
                if scan == 12 {
                    p[100] = 80.0;
                }
                tpp.process(0, &p, None, &mut d, &mut snr);
                if scan >= 12 {
                    seen.push(d[99..=101].iter().any(|&x| x));
                }
            }
            seen
        };
        let carried = spike(TppSettings {
            drop_reset_db: f64::INFINITY,
            ..TppSettings::paper()
        });
        assert_eq!(&carried[..2], &[true, true], "the mechanism: {carried:?}");
        let reset = spike(TppSettings::paper());
        assert!(reset[0], "{reset:?}");
        assert!(reset[1..].iter().all(|&x| !x), "{reset:?}");
    }
}
