//! Whole-spectrum prediction and synthesis for one beam (the paper's figures 8 and 9), the
//! comparison of a prediction with a measurement (figure 10), and quantisation to the wire.
//!
//! A [`SpectrumModel`] precomputes, once per geometry and settings, every bin's range, its
//! compensation gain and its target-absent floor distribution. After that:
//!
//! - [`SpectrumModel::predict_into`] writes the predicted spectrum as figure 8 draws it:
//!   the floor's mean power-summed with each target's peak, `P_i + gain(R_b) + k(R_b -
//!   R_i)`, `k(d) = -c d^2` one look's Gaussian shape in dB (0 dB at its centre, so the
//!   peak bin reads `P_i` plus compensation). It is also the noiseless rendering.
//! - [`SpectrumModel::expected_into`] writes the mean in dB over looks: the same with
//!   `k` averaged over the phase-noise jitter,
//!   [`RangeSpread::expected_peak_shape_db`](crate::noise::RangeSpread::expected_peak_shape_db).
//!   The expectation is taken in dB because figure 10's comparison is in dB; power-summing
//!   it with the floor approximates that expectation where the two are within a few dB.
//! - [`SpectrumModel::synthesize_into`] writes one noisy look: a floor draw in every bin,
//!   and for each target a peak of one look's shape, its centre moved by phase noise and its
//!   power by the target-present noise, power-summed in.
//!
//! Both write into a caller-provided buffer and allocate nothing; their cost is one pass
//! over the bins plus, per target, the few bins its peak covers (`KERNEL_SPAN_SIGMAS`
//! sigma each side), never anything that grows with the map. Powers are combined in dB by
//! `max + 10 log10(1 + 10^(-|a - b| / 10))`, so no level overflows linear arithmetic.
//! Real FMCW peaks have windowed-sinc sidelobes; the Gaussian shape leaves them out.

mod compare;

pub use compare::{compare_spectra, difference_into, SpectrumComparison};

use crate::compensation::Compensation;
use crate::error::{finite, ModelError};
use crate::noise::{FloorDistribution, NoiseModel, WeibullQuantiles};
use crate::power::{for_each_power_db, PowerModel, PowerTarget, DB_PER_NEPER_POWER};
use rand::Rng;
use rand_distr::{Distribution, Exp1, StandardNormal};

/// A peak contributes over this many of its sigmas each side of its centre (the Gaussian
/// has fallen 128 dB there, below the 8-bit wire's whole range).
pub const KERNEL_SPAN_SIGMAS: f64 = 7.7;
/// Largest number of bins a spectrum model accepts (bounds the tables it allocates).
pub const MAX_BINS: usize = 1 << 20;
/// Contributions more than this far (dB) below the running sum are skipped.
const NEGLIGIBLE_DB: f64 = 100.0;

/// Where the bins of one spectrum lie in range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpectrumGeometry {
    /// Number of bins.
    pub bins: usize,
    /// Bin size (m), including any range gain.
    pub bin_size_m: f64,
    /// Range of bin 0 (m).
    pub range_offset_m: f64,
}

impl Default for SpectrumGeometry {
    /// The Oxford Radar RobotCar CTS350-X: 3768 bins of 0.0438 m.
    fn default() -> Self {
        Self {
            bins: 3768,
            bin_size_m: 0.0438,
            range_offset_m: 0.0,
        }
    }
}

impl SpectrumGeometry {
    /// The paper's unit: 0.25 m bins out to 200 m.
    pub fn paper_unit() -> Self {
        Self {
            bins: 800,
            bin_size_m: 0.25,
            range_offset_m: 0.0,
        }
    }

    /// Range (m) of bin `b`.
    pub fn bin_range_m(&self, b: usize) -> f64 {
        self.range_offset_m + b as f64 * self.bin_size_m
    }

    /// Validates the geometry.
    ///
    /// # Errors
    /// Zero or more than [`MAX_BINS`] bins, non-positive bin size, non-finite offset.
    pub fn check(&self) -> Result<(), ModelError> {
        if self.bins == 0 || self.bins > MAX_BINS {
            return Err(ModelError::InvalidSetting {
                what: "bins",
                reason: "must be between 1 and MAX_BINS",
            });
        }
        if !(self.bin_size_m.is_finite() && self.bin_size_m > 0.0) {
            return Err(ModelError::InvalidSetting {
                what: "bin_size_m",
                reason: "must be finite and positive",
            });
        }
        finite(self.range_offset_m, "range offset")?;
        Ok(())
    }
}

/// A target as the spectrum sees it: its range and uncompensated power.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpectrumTarget {
    /// Range (m).
    pub range_m: f64,
    /// Uncompensated received power (dBm), eq. 13 minus `L`.
    pub power_db: f64,
}

/// Computes the spectrum targets of one beam (eq. 13 powers) into `out` (cleared first;
/// allocates only if it must grow). `targets` must be sorted by range.
///
/// # Errors
/// As [`for_each_power_db`].
pub fn beam_spectrum_targets(
    model: &PowerModel,
    targets: &[PowerTarget],
    loss_db: f64,
    out: &mut Vec<SpectrumTarget>,
) -> Result<(), ModelError> {
    out.clear();
    out.extend(targets.iter().map(|t| SpectrumTarget {
        range_m: t.range_m,
        power_db: f64::NAN,
    }));
    let result = for_each_power_db(model, targets, loss_db, |i, p| {
        if let Some(slot) = out.get_mut(i) {
            slot.power_db = p;
        }
    });
    if result.is_err() {
        out.clear();
    }
    result
}

/// Power sum of two levels in dB.
#[inline]
pub fn db_power_sum(a_db: f64, b_db: f64) -> f64 {
    let (hi, lo) = if a_db >= b_db {
        (a_db, b_db)
    } else {
        (b_db, a_db)
    };
    let d = lo - hi;
    if d < -NEGLIGIBLE_DB {
        hi
    } else {
        hi + DB_PER_NEPER_POWER * (d / DB_PER_NEPER_POWER).exp().ln_1p()
    }
}

/// Precomputed per-bin tables for one spectrum geometry and set of settings.
#[derive(Debug, Clone)]
pub struct SpectrumModel {
    geometry: SpectrumGeometry,
    noise: NoiseModel,
    gain_db: Vec<f64>,
    floor_mean_db: Vec<f64>,
    /// Per bin `(location, scale)` of the floor draw: `loc + scale E` (`E ~ Exp(1)`)
    /// before `weibull_from_bin`, `offset + scale W` (`W` standard Weibull) from it on.
    floor_draw: Vec<(f64, f64)>,
    /// First bin of the Weibull region (bins increase in range, so it is a suffix).
    weibull_from_bin: usize,
    weibull: WeibullQuantiles,
}

impl SpectrumModel {
    /// Builds the per-bin tables (the only allocation).
    ///
    /// # Errors
    /// Invalid geometry, compensation or noise settings.
    pub fn new(
        geometry: SpectrumGeometry,
        compensation: &Compensation,
        noise: NoiseModel,
    ) -> Result<Self, ModelError> {
        geometry.check()?;
        compensation.check()?;
        noise.absent.check()?;
        let spread_ok = noise.range.resolution_fwhm_m.is_finite()
            && noise.range.resolution_fwhm_m > 0.0
            && noise.range.phase_noise_sigma_m.is_finite()
            && noise.range.phase_noise_sigma_m >= 0.0
            && noise.present.variance_db2.is_finite()
            && noise.present.variance_db2 >= 0.0;
        if !spread_ok {
            return Err(ModelError::InvalidSetting {
                what: "noise",
                reason: "range spread and present variance must be finite and non-negative",
            });
        }
        let ranges = (0..geometry.bins).map(|b| geometry.bin_range_m(b));
        let gain_db: Vec<f64> = ranges.clone().map(|r| compensation.gain_db(r)).collect();
        let floor_mean_db: Vec<f64> = ranges.clone().map(|r| noise.absent.mean_db(r)).collect();
        let floor: Vec<FloorDistribution> =
            ranges.map(|r| noise.absent.distribution_at(r)).collect();
        let weibull_from_bin = floor
            .iter()
            .position(|f| matches!(f, FloorDistribution::Weibull { .. }))
            .unwrap_or(floor.len());
        let floor_draw = floor
            .iter()
            .map(|f| match *f {
                FloorDistribution::ShiftedExponential { loc_db, scale_db } => (loc_db, scale_db),
                FloorDistribution::Weibull {
                    offset_db,
                    scale_db,
                    ..
                } => (offset_db, scale_db),
            })
            .collect();
        let tables_finite = |v: &Vec<f64>| v.iter().all(|x: &f64| x.is_finite());
        if !tables_finite(&gain_db) || !tables_finite(&floor_mean_db) {
            return Err(ModelError::InvalidSetting {
                what: "compensation or noise",
                reason: "gives a non-finite gain or floor inside the spectrum's range",
            });
        }
        Ok(Self {
            geometry,
            noise,
            gain_db,
            floor_mean_db,
            floor_draw,
            weibull_from_bin,
            weibull: WeibullQuantiles::new(noise.absent.weibull_shape),
        })
    }

    /// The geometry.
    pub fn geometry(&self) -> &SpectrumGeometry {
        &self.geometry
    }

    /// The noise settings.
    pub fn noise(&self) -> &NoiseModel {
        &self.noise
    }

    /// Compensation gain (dB) per bin.
    pub fn gain_db(&self) -> &[f64] {
        &self.gain_db
    }

    /// Mean target-absent floor (dB, wire scale) per bin.
    pub fn floor_mean_db(&self) -> &[f64] {
        &self.floor_mean_db
    }

    /// Replaces the compensation gain and the mean floor per bin with tables measured on
    /// the radar (learned from its stream) in place of the configured curves; predictions
    /// use them from now on (the synthesis keeps the configured floor distribution).
    ///
    /// # Errors
    /// A table of the wrong length or with a non-finite value; nothing is changed then.
    pub fn set_tables(&mut self, gain_db: &[f64], floor_mean_db: &[f64]) -> Result<(), ModelError> {
        let bins = self.geometry.bins;
        for table in [gain_db, floor_mean_db] {
            if table.len() != bins {
                return Err(ModelError::BufferTooSmall {
                    needed: bins,
                    got: table.len(),
                });
            }
            if !table.iter().all(|x| x.is_finite()) {
                return Err(ModelError::InvalidSetting {
                    what: "learned tables",
                    reason: "hold a non-finite gain or floor",
                });
            }
        }
        self.gain_db.copy_from_slice(gain_db);
        self.floor_mean_db.copy_from_slice(floor_mean_db);
        Ok(())
    }

    fn check_buffer(&self, out: &[f64]) -> Result<(), ModelError> {
        if out.len() != self.geometry.bins {
            return Err(ModelError::BufferTooSmall {
                needed: self.geometry.bins,
                got: out.len(),
            });
        }
        Ok(())
    }

    /// Bins `[lo, hi)` within the kernel span of `range_m` for a shape of `sigma_m`.
    fn window(&self, range_m: f64, sigma_m: f64) -> Option<(usize, usize)> {
        let g = &self.geometry;
        let centre = (range_m - g.range_offset_m) / g.bin_size_m;
        let half = KERNEL_SPAN_SIGMAS * sigma_m / g.bin_size_m + 1.0;
        let lo = (centre - half).ceil().max(0.0);
        let hi = (centre + half).floor() + 1.0;
        let hi = hi.min(g.bins as f64);
        if lo >= hi {
            return None;
        }
        // Both are finite, non-negative and at most `bins`, so the casts are exact.
        Some((lo as usize, hi as usize))
    }

    /// Power-sums one peak into `out`: at bin range `R_b`, `level_db + gain(R_b) -
    /// c ((R_b - range_m)^2 + jitter_var_m2)`, over the bins where the look's Gaussian
    /// (sigma `sigma_m`) is within [`KERNEL_SPAN_SIGMAS`] sigma.
    fn add_peak(
        &self,
        range_m: f64,
        level_db: f64,
        sigma_m: f64,
        jitter_var_m2: f64,
        out: &mut [f64],
    ) {
        let Some((lo, hi)) = self.window(range_m, sigma_m) else {
            return;
        };
        let coef = -DB_PER_NEPER_POWER / (2.0 * sigma_m * sigma_m);
        for ((b, value), gain) in out[lo..hi]
            .iter_mut()
            .enumerate()
            .zip(&self.gain_db[lo..hi])
        {
            let d = self.geometry.bin_range_m(lo + b) - range_m;
            *value = db_power_sum(*value, level_db + gain + coef * (d * d + jitter_var_m2));
        }
    }

    fn check_targets(targets: &[SpectrumTarget]) -> Result<(), ModelError> {
        for t in targets {
            finite(t.range_m, "spectrum target range")?;
            finite(t.power_db, "spectrum target power")?;
        }
        Ok(())
    }

    /// Predicted measured spectrum (dB per bin) for the targets in one beam, as the paper's
    /// figure 8 draws it: the mean floor, and each target's peak of one look's shape
    /// centred on its predicted range, reaching `P_i` plus compensation there (no noise,
    /// no jitter). This is also the noiseless rendering. `out` must have `bins` elements.
    ///
    /// # Errors
    /// Wrong buffer length or non-finite targets.
    pub fn predict_into(
        &self,
        targets: &[SpectrumTarget],
        out: &mut [f64],
    ) -> Result<(), ModelError> {
        self.peaks_on_floor(targets, 0.0, out)
    }

    /// Expected measured spectrum (dB per bin, the mean in dB over looks): as
    /// [`predict_into`](Self::predict_into) but with each peak's shape averaged in dB over
    /// the phase-noise jitter, which lowers every peak bin by `c sigma_J^2` (1.93 dB with
    /// the defaults; see [`RangeSpread`](crate::noise::RangeSpread)). Bin-by-bin
    /// comparisons (figure 10) against it are unbiased where the synthesis model holds.
    ///
    /// # Errors
    /// Wrong buffer length or non-finite targets.
    pub fn expected_into(
        &self,
        targets: &[SpectrumTarget],
        out: &mut [f64],
    ) -> Result<(), ModelError> {
        let s = self.noise.range.phase_noise_sigma_m;
        self.peaks_on_floor(targets, s * s, out)
    }

    fn peaks_on_floor(
        &self,
        targets: &[SpectrumTarget],
        jitter_var_m2: f64,
        out: &mut [f64],
    ) -> Result<(), ModelError> {
        self.check_buffer(out)?;
        Self::check_targets(targets)?;
        out.copy_from_slice(&self.floor_mean_db);
        let sigma = self.noise.range.look_sigma_m();
        for t in targets {
            self.add_peak(t.range_m, t.power_db, sigma, jitter_var_m2, out);
        }
        Ok(())
    }

    /// One noisy measured spectrum (dB per bin) for the targets in one beam (figure 9).
    /// `out` must have exactly `bins` elements. Deterministic for a seeded `rng`.
    ///
    /// # Errors
    /// Wrong buffer length or non-finite targets.
    pub fn synthesize_into<R: Rng + ?Sized>(
        &self,
        targets: &[SpectrumTarget],
        rng: &mut R,
        out: &mut [f64],
    ) -> Result<(), ModelError> {
        self.check_buffer(out)?;
        Self::check_targets(targets)?;
        let split = self.weibull_from_bin.min(out.len());
        let (near_out, far_out) = out.split_at_mut(split);
        let (near_draw, far_draw) = self.floor_draw.split_at(split);
        for (value, &(loc, scale)) in near_out.iter_mut().zip(near_draw) {
            let e: f64 = Exp1.sample(rng);
            *value = loc + scale * e;
        }
        for (value, &(offset, scale)) in far_out.iter_mut().zip(far_draw) {
            *value = offset + scale * self.weibull.sample(rng);
        }
        let sigma = self.noise.range.look_sigma_m();
        let present_sd = self.noise.present.variance_db2.sqrt();
        for t in targets {
            let jitter = self.noise.range.sample_offset_m(rng);
            let n: f64 = StandardNormal.sample(rng);
            self.add_peak(
                t.range_m + jitter,
                t.power_db + n * present_sd,
                sigma,
                0.0,
                out,
            );
        }
        Ok(())
    }
}
