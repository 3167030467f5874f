//! The receiver's side of the realistic renderer: the range kernel of the FMCW window, the
//! antenna's two-way azimuth pattern, the fitted noise floor, the speckle tables and the
//! unit's output quantisation. Everything is tabulated once per scene.
//!
//! - Range kernel: the power spectrum `|W(f)|^2` of the window the range FFT is taken
//!   with, normalised to 1 at its centre, its frequency axis scaled so that its full width
//!   at half maximum is `range_fwhm_m`, sampled at whole bins out to where it falls below
//!   -100 dB (or 600 bins). Its sidelobes are the window's (Hann: -31.5 dB first sidelobe).
//! - Azimuth pattern: an aperture with illumination `p + (1 - p) cos(pi x / 2)` on
//!   `x in [-1, 1]` (`p` the pedestal); one-way field by numerical integration, two-way
//!   power `|E(u) / E(0)|^4`, scaled so its full width at half maximum is `beam_fwhm_deg`;
//!   tabulated against the tangent of the angle off the beam's axis out to 30 widths.
//! - Floor: in the unit's integer power units, gamma distributed with shape `floor_shape`
//!   and a mean per range; drawn by table (1024 quantiles at mid-probabilities). Receiver
//!   noise leaves the range FFT correlated over the window's main lobe (the unit's bins
//!   are about an eighth of it), so with `floor_correlated` the draws are too: a standard
//!   normal draw a bin (by table), smoothed along the range by two first-order recursions
//!   with coefficient `rho = exp(-bin / (0.45 FWHM))` (0.75 on the CTS350-X's bins) and
//!   rescaled to unit variance, is mapped through the normal and gamma distributions (a
//!   Gaussian copula: every bin keeps the fitted gamma level distribution). Its
//!   correlation between bins 1 to 7 apart, `rho^k (1 + k (1 - rho^2) / (1 + rho^2))`:
//!   0.96, 0.88, 0.78, 0.67, 0.57, 0.48, 0.40, as white noise through the fitted Hann
//!   window gives in dB (0.96, 0.88, 0.78, 0.68, 0.57, 0.47, 0.38) and as the real floor
//!   shows 131-162 m out (0.94, 0.87, 0.77, 0.65, 0.54, 0.44, 0.35).
//! - Output: `k = floor(floor + signal)` (integer power), `dB = log_scale x 10 log10
//!   max(k, 1)` clipped at `saturation_db`. The real unit's low levels take only the
//!   values 0, 3, 4.5, 6, 7, 7.5, 8.5 ... dB (`10 log10` of small integers): this is what
//!   makes them so.

use protocol::units::{db_to_bin16, db_to_bin8};
use statrs::distribution::{ContinuousCDF, Gamma, Normal};

use crate::error::SceneError;
use crate::scene::realism_spec::{RangeWindow, RealismSpec};

/// Samples of the window used for its spectrum.
const WINDOW_TAPS: usize = 256;
/// Entries of the floor's quantile table (10 random bits a bin).
pub const FLOOR_QUANTILES: usize = 1024;
/// Entries of the table from a standard normal value to a floor draw.
pub const COPULA_ENTRIES: usize = 4096;
/// The copula table covers standard normal values in `[-COPULA_REACH, COPULA_REACH]`.
pub const COPULA_REACH: f32 = 4.0;
/// The floor's correlation length over the range kernel's FWHM (see the module docs).
const FLOOR_CORRELATION_PER_FWHM: f64 = 0.45;
/// Entries of the speckle tables (12 random bits a look).
pub const SPECKLE_QUANTILES: usize = 4096;
/// Entries of the output table (integer powers below this are looked up; 32 KiB, so it
/// stays in the first-level cache).
pub(crate) const DB_TABLE: usize = 1 << 12;
/// Entries of the antenna pattern table.
const PATTERN_ENTRIES: usize = 8192;
/// The antenna table reaches this many two-way widths off axis.
const PATTERN_REACH_WIDTHS: f64 = 30.0;
/// Longest one-sided range kernel, bins.
const MAX_KERNEL_HALF: usize = 600;
/// Range envelopes of the receiver's gain, over 1, 2, 4 ... 1024 bins either side.
const GAIN_ENVELOPES: usize = 11;
/// A contribution below this (integer power units) cannot move the floor's quantisation.
pub const NEGLIGIBLE_POWER: f32 = 0.05;

/// The tabulated receiver of one scene.
#[derive(Debug, Clone)]
pub struct Receiver {
    /// Range kernel, `kernel[half + d]` for offsets `d in [-half, half]` bins.
    pub kernel: Vec<f32>,
    /// One-sided half length of the kernel, bins.
    pub kernel_half: usize,
    /// `envelope[l]` = the kernel's largest value at `|d| >= l`.
    pub envelope: Vec<f32>,
    /// Two-way antenna power against `|tan(offset)|`, uniform steps.
    pub pattern: Vec<f32>,
    /// `pattern_envelope[i]` = the pattern's largest value at index `>= i`.
    pub pattern_envelope: Vec<f32>,
    /// Entries per unit of `tan(offset)`.
    pub pattern_per_tan: f64,
    /// The tangent the table reaches.
    pub pattern_max_tan: f64,
    /// Mean floor (integer power units) per bin.
    pub floor_mean: Vec<f32>,
    /// Standard gamma quantiles of mean 1 (shape `floor_shape`).
    pub floor_quantiles: Vec<f32>,
    /// The floor's correlation in range: the recursions' coefficient per bin (0: an
    /// independent draw a bin).
    pub floor_rho: f32,
    /// Standard normal quantiles at the same mid-probabilities as `floor_quantiles`.
    pub normal_quantiles: Vec<f32>,
    /// The floor draw (mean 1) at standard normal values evenly spaced over
    /// `[-COPULA_REACH, COPULA_REACH]`: the gamma quantile at their normal probability.
    pub floor_of_normal: Vec<f32>,
    /// Exponential quantiles of mean 1 (Swerling 1/2).
    pub exp_quantiles: Vec<f32>,
    /// Chi-square (4 dof) quantiles of mean 1 (Swerling 3/4).
    pub chi4_quantiles: Vec<f32>,
    /// Integer power units per m^2 of cross section, per bin.
    pub signal_per_m2: Vec<f32>,
    /// `gain_envelopes[j][b]`: the largest `signal_per_m2` within `2^j` bins of bin `b`
    /// (the last: the largest anywhere).
    pub gain_envelopes: Vec<Vec<f32>>,
    /// Output dB of integer power `k < 4096`.
    pub db_of_power: Vec<f64>,
    /// The 8-bit wire value of integer power `k < 4096` (`db_to_bin8` of its dB).
    pub wire8_of_power: Vec<u8>,
    /// The 16-bit wire value of integer power `k < 4096` (`db_to_bin16` of its dB).
    pub wire16_of_power: Vec<u16>,
    /// `dB = log_scale x 10 log10 k`.
    pub log_scale: f64,
    /// Output clip, dB.
    pub saturation_db: f64,
    /// Kernel reach by the top 12 bits of a deposit's `f32` power (sign, exponent and the
    /// mantissa's top 3 bits): computed for the largest power of each bucket.
    pub reach_by_bits: Vec<u16>,
    /// Bin size, metres.
    pub bin_m: f64,
    /// Range of bin 0, metres.
    pub first_bin_m: f64,
}

fn window(kind: RangeWindow, n: usize) -> Vec<f64> {
    let m = (n - 1) as f64;
    (0..n)
        .map(|i| {
            let x = std::f64::consts::TAU * i as f64 / m;
            match kind {
                RangeWindow::Rectangular => 1.0,
                RangeWindow::Hann => 0.5 - 0.5 * x.cos(),
                RangeWindow::Hamming => 0.54 - 0.46 * x.cos(),
                RangeWindow::Blackman => 0.42 - 0.5 * x.cos() + 0.08 * (2.0 * x).cos(),
            }
        })
        .collect()
}

/// `|W(f)|^2 / |W(0)|^2` at `f` in resolution cells (1 cell = one FFT bin of the unpadded
/// transform).
fn window_power(w: &[f64], f: f64) -> f64 {
    let n = w.len() as f64;
    let (mut re, mut im) = (0.0, 0.0);
    for (i, &v) in w.iter().enumerate() {
        let ph = -std::f64::consts::TAU * f * i as f64 / n;
        re += v * ph.cos();
        im += v * ph.sin();
    }
    let sum: f64 = w.iter().sum();
    (re * re + im * im) / (sum * sum)
}

/// Where a decreasing-from-1 function first reaches 0.5 on `[0, hi]`, by bisection.
fn half_power_point(f: impl Fn(f64) -> f64, hi: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, hi);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if f(mid) > 0.5 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The range kernel for `spec` on bins of `bin_m` (centre value 1).
pub fn range_kernel(spec: &RealismSpec, bin_m: f64) -> Vec<f32> {
    let w = window(spec.range_window, WINDOW_TAPS);
    let half_cells = half_power_point(|f| window_power(&w, f), 2.0);
    // FWHM in cells is 2 half_cells; one cell in metres:
    let cell_m = spec.range_fwhm_m / (2.0 * half_cells);
    let cells_per_bin = bin_m / cell_m;
    let mut one_side = Vec::new();
    for d in 0..=MAX_KERNEL_HALF {
        let v = window_power(&w, d as f64 * cells_per_bin);
        one_side.push(v as f32);
    }
    // Cut where the rest stays below -100 dB.
    let mut half = MAX_KERNEL_HALF;
    while half > 1 && one_side[half..].iter().all(|&v| v < 1e-10) {
        half -= 1;
    }
    one_side.truncate(half + 1);
    let mut kernel: Vec<f32> = one_side.iter().rev().copied().collect();
    kernel.extend(one_side.iter().skip(1));
    kernel
}

/// One-way field of the tapered aperture at `u` (normalised angle, `sin(theta) D /
/// lambda`), over its value at 0.
fn aperture_field(pedestal: f64, u: f64) -> f64 {
    const M: usize = 256;
    let (mut re, mut im, mut sum) = (0.0, 0.0, 0.0);
    for i in 0..M {
        let x = -1.0 + 2.0 * (i as f64 + 0.5) / M as f64;
        let a = pedestal + (1.0 - pedestal) * (std::f64::consts::FRAC_PI_2 * x).cos();
        let ph = std::f64::consts::PI * u * x;
        re += a * ph.cos();
        im += a * ph.sin();
        sum += a;
    }
    (re * re + im * im).sqrt() / sum
}

impl Receiver {
    /// Tabulates the receiver of `spec` for bins of `bin_m` from `first_bin_m`.
    pub fn new(
        spec: &RealismSpec,
        bins: usize,
        bin_m: f64,
        first_bin_m: f64,
    ) -> Result<Receiver, SceneError> {
        spec.validate()?;
        let kernel = range_kernel(spec, bin_m);
        let kernel_half = kernel.len() / 2;
        let mut envelope = vec![0.0f32; kernel_half + 2];
        for l in (0..=kernel_half).rev() {
            envelope[l] = envelope[l + 1].max(kernel[kernel_half + l]);
        }

        // Antenna: find u_half where the two-way power (field^4) is 0.5.
        let p = spec.antenna_pedestal;
        let u_half = half_power_point(|u| aperture_field(p, u).powi(4), 2.0);
        let fwhm_rad = spec.beam_fwhm_deg.to_radians();
        // sin(theta) = u * (sin(fwhm/2) / u_half)
        let sin_per_u = (0.5 * fwhm_rad).sin() / u_half;
        let max_angle = (PATTERN_REACH_WIDTHS * fwhm_rad).min(1.2);
        let pattern_max_tan = max_angle.tan();
        let pattern_per_tan = (PATTERN_ENTRIES - 1) as f64 / pattern_max_tan;
        let pattern: Vec<f32> = (0..PATTERN_ENTRIES)
            .map(|i| {
                let t = i as f64 / pattern_per_tan;
                let u = t.atan().sin() / sin_per_u;
                aperture_field(p, u).powi(4) as f32
            })
            .collect();
        let mut pattern_envelope = vec![0.0f32; PATTERN_ENTRIES + 1];
        for i in (0..PATTERN_ENTRIES).rev() {
            pattern_envelope[i] = pattern_envelope[i + 1].max(pattern[i]);
        }
        pattern_envelope.truncate(PATTERN_ENTRIES);

        let floor_mean: Vec<f32> = (0..bins)
            .map(|b| interpolate(&spec.floor_mean, first_bin_m + b as f64 * bin_m) as f32)
            .collect();
        // A gamma distribution of mean 1 and `shape`.
        let gamma_of_shape = |shape: f64| {
            Gamma::new(shape, shape).map_err(|e| SceneError::Invalid {
                field: "realism.floor_shape".into(),
                reason: e.to_string(),
            })
        };
        let quantiles = |n: usize, shape: f64| -> Result<Vec<f32>, SceneError> {
            let g = gamma_of_shape(shape)?;
            Ok((0..n)
                .map(|i| g.inverse_cdf((i as f64 + 0.5) / n as f64) as f32)
                .collect())
        };
        let floor_quantiles = quantiles(FLOOR_QUANTILES, spec.floor_shape)?;
        let normal = Normal::new(0.0, 1.0).map_err(|e| SceneError::Invalid {
            field: "realism".into(),
            reason: e.to_string(),
        })?;
        let normal_quantiles = (0..FLOOR_QUANTILES)
            .map(|i| normal.inverse_cdf((i as f64 + 0.5) / FLOOR_QUANTILES as f64) as f32)
            .collect();
        let gamma = gamma_of_shape(spec.floor_shape)?;
        let reach = f64::from(COPULA_REACH);
        let floor_of_normal = (0..COPULA_ENTRIES)
            .map(|i| {
                let g = -reach + 2.0 * reach * i as f64 / (COPULA_ENTRIES - 1) as f64;
                let p = normal.cdf(g).clamp(1e-9, 1.0 - 1e-9);
                gamma.inverse_cdf(p) as f32
            })
            .collect();
        let floor_rho = if spec.floor_correlated {
            (-bin_m / (FLOOR_CORRELATION_PER_FWHM * spec.range_fwhm_m)).exp() as f32
        } else {
            0.0
        };
        let exp_quantiles = (0..SPECKLE_QUANTILES)
            .map(|i| -(1.0 - (i as f64 + 0.5) / SPECKLE_QUANTILES as f64).ln() as f32)
            .collect();
        let chi4_quantiles = quantiles(SPECKLE_QUANTILES, 2.0)?;

        let signal_per_m2: Vec<f32> = (0..bins)
            .map(|b| {
                let r = (first_bin_m + b as f64 * bin_m).max(0.5);
                let level_db = spec.signal_gain_db
                    + spec.signal_slope_db_per_decade * (r / 10.0).log10()
                    - 10.0 * (1.0 + (r / spec.rolloff_m).powi(4)).log10()
                    - 10.0 * (1.0 + (spec.highpass_m / r).powi(4)).log10();
                10f64.powf(level_db / (10.0 * spec.log_scale)) as f32
            })
            .collect();
        let gain_envelopes = gain_envelopes(&signal_per_m2);
        let db_of_power: Vec<f64> = (0..DB_TABLE)
            .map(|k| (spec.log_scale * 10.0 * (k.max(1) as f64).log10()).min(spec.saturation_db))
            .collect();
        let wire8_of_power = db_of_power.iter().map(|&d| db_to_bin8(d)).collect();
        let wire16_of_power = db_of_power.iter().map(|&d| db_to_bin16(d)).collect();
        let reach_of = |power: f32| -> usize {
            let limit = NEGLIGIBLE_POWER / power;
            envelope
                .partition_point(|&v| v >= limit)
                .min(kernel_half + 1)
        };
        let reach_by_bits = (0u32..1 << 12)
            .map(|top| {
                // The largest f32 whose top 12 bits are `top`.
                let p = f32::from_bits((top << 20) | 0x000f_ffff);
                if p.is_finite() && p > 0.0 {
                    u16::try_from(reach_of(p)).unwrap_or(u16::MAX)
                } else {
                    0
                }
            })
            .collect();
        Ok(Receiver {
            reach_by_bits,
            kernel,
            kernel_half,
            envelope,
            pattern,
            pattern_envelope,
            pattern_per_tan,
            pattern_max_tan,
            floor_mean,
            floor_quantiles,
            floor_rho,
            normal_quantiles,
            floor_of_normal,
            exp_quantiles,
            chi4_quantiles,
            signal_per_m2,
            gain_envelopes,
            db_of_power,
            wire8_of_power,
            wire16_of_power,
            log_scale: spec.log_scale,
            saturation_db: spec.saturation_db,
            bin_m,
            first_bin_m,
        })
    }

    /// Two-way antenna power at `|tan(offset)|` (0 beyond the table).
    #[inline]
    pub fn pattern_at(&self, abs_tan: f64) -> f32 {
        let i = (abs_tan * self.pattern_per_tan) as usize;
        self.pattern.get(i).copied().unwrap_or(0.0)
    }

    /// The smallest `|tan(offset)|` beyond which a return of `power` (integer units at the
    /// beam's axis) stays below [`NEGLIGIBLE_POWER`] everywhere.
    pub fn pattern_reach_tan(&self, power: f32) -> f64 {
        if power <= NEGLIGIBLE_POWER {
            return 0.0;
        }
        let limit = NEGLIGIBLE_POWER / power;
        let i = self.pattern_envelope.partition_point(|&v| v >= limit);
        (i as f64 + 1.0) / self.pattern_per_tan
    }

    /// The power (integer units on the beam's axis) below which a return stays below
    /// [`NEGLIGIBLE_POWER`] everywhere beyond `|tan(offset)| = max_tan`: `power <
    /// pattern_threshold(t)` implies `pattern_reach_tan(power) <= t`.
    pub fn pattern_threshold(&self, max_tan: f64) -> f32 {
        // pattern_reach_tan(p) = (i + 1) / per_tan with i the first index whose envelope
        // is below NEGLIGIBLE_POWER / p; it is at most max_tan when the envelope at
        // floor(max_tan per_tan) - 1 is below it.
        let i = (max_tan * self.pattern_per_tan).floor() - 1.0;
        if i < 0.0 {
            return NEGLIGIBLE_POWER;
        }
        match self.pattern_envelope.get(i as usize) {
            Some(&e) if e > 0.0 => NEGLIGIBLE_POWER / e * (1.0 - 1e-6),
            Some(_) => f32::INFINITY,
            None => f32::INFINITY,
        }
    }

    /// The largest `signal_per_m2` within `shift_m` metres in range of each bin.
    pub fn gain_envelope(&self, shift_m: f64) -> &[f32] {
        let bins = (shift_m / self.bin_m).ceil().max(0.0) + 1.0;
        let j = self
            .gain_envelopes
            .iter()
            .enumerate()
            .position(|(j, _)| bins <= f64::from(1u32 << j.min(30)))
            .unwrap_or(self.gain_envelopes.len() - 1);
        self.gain_envelopes
            .get(j)
            .map_or(&self.signal_per_m2, |e| e.as_slice())
    }

    /// The kernel half-length beyond which a deposit of `power` stays negligible.
    #[inline]
    pub fn kernel_reach(&self, power: f32) -> usize {
        let top = (power.to_bits() >> 20) as usize;
        self.reach_by_bits
            .get(top)
            .map_or(self.kernel_half, |&r| usize::from(r))
    }

    /// Output dB of integer power `k`.
    #[inline]
    pub fn db_of(&self, k: f64) -> f64 {
        if k < DB_TABLE as f64 {
            self.db_of_power[k as usize]
        } else {
            (self.log_scale * 10.0 * k.log10()).min(self.saturation_db)
        }
    }

    /// Output dB of integer power `k` and its wire value (`db_to_bin8`, or `db_to_bin16`
    /// when `sixteen`), by table below 4096.
    #[inline]
    pub fn quantise(&self, k: u32, sixteen: bool) -> (f64, u16) {
        let i = k as usize;
        match (self.db_of_power.get(i), sixteen) {
            (Some(&db), false) => (db, u16::from(self.wire8_of_power[i])),
            (Some(&db), true) => (db, self.wire16_of_power[i]),
            (None, _) => {
                let db = self.db_of(f64::from(k));
                let wire = if sixteen {
                    db_to_bin16(db)
                } else {
                    u16::from(db_to_bin8(db))
                };
                (db, wire)
            }
        }
    }

    /// The full width at half maximum of the tabulated range kernel, bins (measured on the
    /// table, for tests).
    pub fn kernel_fwhm_bins(&self) -> f64 {
        let h = self.kernel_half;
        let side = &self.kernel[h..];
        let i = side.iter().position(|&v| v < 0.5).unwrap_or(side.len() - 1);
        if i == 0 {
            return 0.0;
        }
        let (a, b) = (f64::from(side[i - 1]), f64::from(side[i]));
        2.0 * ((i - 1) as f64 + (a - 0.5) / (a - b))
    }
}

/// Envelopes of `gain` over `2^j` bins either side, `j = 0..GAIN_ENVELOPES - 1`, then the
/// largest anywhere.
fn gain_envelopes(gain: &[f32]) -> Vec<Vec<f32>> {
    let n = gain.len();
    let at = |v: &[f32], i: isize| -> f32 {
        let i = i.clamp(0, n as isize - 1) as usize;
        v.get(i).copied().unwrap_or(0.0)
    };
    let mut out: Vec<Vec<f32>> = Vec::with_capacity(GAIN_ENVELOPES + 1);
    // Within 1 bin.
    let first: Vec<f32> = (0..n as isize)
        .map(|b| at(gain, b - 1).max(at(gain, b)).max(at(gain, b + 1)))
        .collect();
    out.push(first);
    for j in 0..GAIN_ENVELOPES - 1 {
        let step = 1isize << j;
        let prev = &out[j];
        let next = (0..n as isize)
            .map(|b| at(prev, b - step).max(at(prev, b + step)))
            .collect();
        out.push(next);
    }
    let top = gain.iter().copied().fold(0.0f32, f32::max);
    out.push(vec![top; n]);
    out
}

/// Linear interpolation in `[x, y]` pairs (sorted by x), held flat beyond the ends.
pub fn interpolate(points: &[[f64; 2]], x: f64) -> f64 {
    let Some(first) = points.first() else {
        return 0.0;
    };
    if x <= first[0] {
        return first[1];
    }
    for w in points.windows(2) {
        if x <= w[1][0] {
            let t = (x - w[0][0]) / (w[1][0] - w[0][0]).max(1e-12);
            return w[0][1] + t * (w[1][1] - w[0][1]);
        }
    }
    points.last().map_or(0.0, |p| p[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn receiver(spec: &RealismSpec) -> Receiver {
        Receiver::new(spec, 3768, 0.0438, 0.0).expect("receiver")
    }

    #[test]
    fn the_hann_kernel_has_the_asked_width_and_its_first_sidelobe_near_minus_31_db() {
        let spec = RealismSpec {
            range_window: RangeWindow::Hann,
            range_fwhm_m: 0.3,
            ..RealismSpec::default()
        };
        let r = receiver(&spec);
        let fwhm_m = r.kernel_fwhm_bins() * 0.0438;
        assert!((fwhm_m - 0.3).abs() < 0.03, "FWHM {fwhm_m} m");
        // First sidelobe: the largest local maximum off the main lobe.
        let side = &r.kernel[r.kernel_half..];
        let null = (1..side.len() - 1)
            .find(|&i| side[i] < side[i - 1] && side[i] <= side[i + 1])
            .expect("a null");
        let sidelobe_db =
            10.0 * f64::from(side[null..].iter().copied().fold(0.0, f32::max)).log10();
        assert!((-33.0..=-30.0).contains(&sidelobe_db), "{sidelobe_db} dB");
    }

    #[test]
    fn a_rectangular_window_has_sinc_sidelobes_at_minus_13_db() {
        let spec = RealismSpec {
            range_window: RangeWindow::Rectangular,
            range_fwhm_m: 0.3,
            ..RealismSpec::default()
        };
        let r = receiver(&spec);
        let side = &r.kernel[r.kernel_half..];
        let null = (1..side.len() - 1)
            .find(|&i| side[i] < side[i - 1] && side[i] <= side[i + 1])
            .expect("a null");
        let sidelobe_db =
            10.0 * f64::from(side[null..].iter().copied().fold(0.0, f32::max)).log10();
        assert!((-14.5..=-12.5).contains(&sidelobe_db), "{sidelobe_db} dB");
    }

    #[test]
    fn the_antenna_pattern_has_the_asked_width_and_sidelobes_of_a_uniform_aperture() {
        let spec = RealismSpec {
            beam_fwhm_deg: 2.0,
            antenna_pedestal: 1.0,
            ..RealismSpec::default()
        };
        let r = receiver(&spec);
        let half = 1.0f64.to_radians().tan();
        assert!(
            (r.pattern_at(half) - 0.5).abs() < 0.02,
            "{}",
            r.pattern_at(half)
        );
        // Uniform aperture: one-way first sidelobe -13.3 dB, two-way -26.5 dB.
        let peak_side = (0..r.pattern.len())
            .skip_while(|&i| r.pattern[i] > 1e-4)
            .map(|i| r.pattern[i])
            .fold(0.0f32, f32::max);
        let db = 10.0 * f64::from(peak_side).log10();
        assert!((-27.5..=-25.5).contains(&db), "{db} dB");
    }

    #[test]
    fn the_speckle_tables_have_the_swerling_moments() {
        let r = receiver(&RealismSpec::default());
        let moments = |q: &[f32]| {
            let n = q.len() as f64;
            let m = q.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
            let v = q.iter().map(|&v| (f64::from(v) - m).powi(2)).sum::<f64>() / n;
            (m, v)
        };
        let (m, v) = moments(&r.exp_quantiles);
        assert!(
            (m - 1.0).abs() < 0.01 && (v - 1.0).abs() < 0.05,
            "exp {m} {v}"
        );
        let (m, v) = moments(&r.chi4_quantiles);
        assert!(
            (m - 1.0).abs() < 0.01 && (v - 0.5).abs() < 0.03,
            "chi4 {m} {v}"
        );
    }
}
