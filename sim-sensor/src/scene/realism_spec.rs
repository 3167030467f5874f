//! The realistic renderer's settings as a scene gives them (the scene's `[realism]` table),
//! with the values fitted to the real unit as defaults (`cargo run --release -p sim-sensor
//! --example calibrate` prints them: [`crate::realism::calibrate`] fits, this file keeps the
//! result). IO: none.

use serde::Deserialize;

use crate::error::SceneError;

/// Fitted floor mean per range, `(range_m, mean)` in integer power units.
pub const FITTED_FLOOR_MEAN: &[(f64, f64)] = &[
    (0.25, 29.395),
    (0.75, 64.905),
    (1.25, 11.139),
    (1.75, 11.139),
    (2.50, 4.306),
    (3.50, 2.331),
    (4.50, 2.956),
    (6.25, 3.015),
    (8.75, 3.015),
    (12.50, 3.675),
    (17.50, 3.603),
    (25.00, 3.463),
    (37.50, 3.748),
    (52.50, 3.603),
    (70.00, 3.395),
    (90.00, 3.137),
    (115.00, 2.731),
    (147.50, 2.523),
];
/// Fitted shape of the floor's gamma distribution.
pub const FITTED_FLOOR_SHAPE: f64 = 1.50;
/// Fitted output scale `c` (`dB = c 10 log10 k`).
pub const FITTED_LOG_SCALE: f64 = 0.9860;
/// Largest level observed, dB.
pub const FITTED_SATURATION_DB: f64 = 68.0;
/// Range width (FWHM) of the kernel, metres, fitted so that the simulated street's median
/// peak width matches the real one.
pub const FITTED_RANGE_FWHM_M: f64 = 0.340;
/// Two-way azimuth width (FWHM) of the antenna pattern, degrees, fitted likewise.
pub const FITTED_BEAM_FWHM_DEG: f64 = 1.46;
/// Wire level of a 1 m^2 target at 10 m, dB.
pub const FITTED_SIGNAL_GAIN_DB: f64 = 62.20;
/// Net slope of a fixed target's level with range, dB per decade.
pub const FITTED_SIGNAL_SLOPE_DB_PER_DECADE: f64 = -17.54;

/// Corner of the receiver's near-range high-pass filter, metres.
pub const FITTED_HIGHPASS_M: f64 = 15.0;

/// The window the FMCW range FFT is taken with: decides the range sidelobes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RangeWindow {
    /// No window: sinc sidelobes at -13.3 dB.
    Rectangular,
    /// Hann: first sidelobe -31.5 dB, falling 18 dB an octave.
    Hann,
    /// Hamming: first sidelobe about -43 dB, falling slowly.
    Hamming,
    /// Blackman: first sidelobe -58 dB.
    Blackman,
}

/// The realistic renderer's settings (the scene's `[realism]` table). Every default is the
/// value fitted to the Oxford Radar RobotCar scans by `cargo run --release -p sim-sensor
/// --example calibrate` (see the crate README, "Realistic rendering").
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RealismSpec {
    /// Mean floor power per range, `[range_m, mean]` pairs in the unit's integer power
    /// units (`dB = log_scale x 10 log10 k`), interpolated linearly, held beyond the ends.
    pub floor_mean: Vec<[f64; 2]>,
    /// Shape of the gamma distribution of the floor power (1 = exponential, one look).
    pub floor_shape: f64,
    /// The unit's output scale: `dB = log_scale x 10 log10 k` for integer power `k`.
    pub log_scale: f64,
    /// Largest level the unit outputs, dB.
    pub saturation_db: f64,
    /// Range window of the FMCW FFT.
    pub range_window: RangeWindow,
    /// Full width at half maximum of a point target's range peak, metres.
    pub range_fwhm_m: f64,
    /// Full width at half maximum of the two-way azimuth pattern, degrees.
    pub beam_fwhm_deg: f64,
    /// Pedestal of the aperture's cosine taper in [0, 1] (1 = uniform, first two-way
    /// sidelobe -26.5 dB; 0 = full cosine, -46 dB).
    pub antenna_pedestal: f64,
    /// Wire level of a 1 m^2 target at 10 m, dB.
    pub signal_gain_db: f64,
    /// Net change of a fixed target's wire level per decade of range, dB (0 = the
    /// receiver's compensation cancels the R^-4 exactly).
    pub signal_slope_db_per_decade: f64,
    /// Range beyond which the receiver's low-pass roll-off (second order) sets in, metres.
    pub rolloff_m: f64,
    /// Range below which the receiver's high-pass filter (second order) cuts returns,
    /// metres: the level falls `10 log10(1 + (highpass_m / R)^4)` dB.
    pub highpass_m: f64,
    /// `false`: every scatterer returns its mean power each look (no Swerling draw).
    pub speckle: bool,
    /// `false`: nothing is hidden behind what stands in front.
    pub occlusion: bool,
    /// `false`: no multipath ghosts.
    pub multipath: bool,
    /// Power reflection coefficient of a flat reflector (per bounce) for ghosts.
    pub ghost_reflectance: f64,
    /// Ghost sources are scatterers of at least this cross section (m^2).
    pub ghost_min_rcs_m2: f64,
    /// Ghosts are formed only in reflectors and by sources within this range (m).
    pub ghost_range_m: f64,
    /// `true`: the floor is correlated in range as receiver noise through the range window
    /// is (the real floor's correlation between bins 1 to 4 apart, 131-162 m out: 0.94,
    /// 0.87, 0.77, 0.65); `false`: an independent draw a bin. Either way each bin's level
    /// has the fitted gamma distribution (see `receiver`).
    pub floor_correlated: bool,
}

impl Default for RealismSpec {
    fn default() -> Self {
        // Fitted to the eight Oxford scans (see calibrate.rs and the README).
        Self {
            floor_mean: FITTED_FLOOR_MEAN.iter().map(|&p| [p.0, p.1]).collect(),
            floor_shape: FITTED_FLOOR_SHAPE,
            log_scale: FITTED_LOG_SCALE,
            saturation_db: FITTED_SATURATION_DB,
            range_window: RangeWindow::Hann,
            range_fwhm_m: FITTED_RANGE_FWHM_M,
            beam_fwhm_deg: FITTED_BEAM_FWHM_DEG,
            antenna_pedestal: 0.3,
            signal_gain_db: FITTED_SIGNAL_GAIN_DB,
            signal_slope_db_per_decade: FITTED_SIGNAL_SLOPE_DB_PER_DECADE,
            rolloff_m: 120.0,
            highpass_m: FITTED_HIGHPASS_M,
            speckle: true,
            occlusion: true,
            multipath: true,
            ghost_reflectance: 0.3,
            ghost_min_rcs_m2: 2.0,
            ghost_range_m: 60.0,
            floor_correlated: true,
        }
    }
}

impl RealismSpec {
    /// Checks every value.
    pub fn validate(&self) -> Result<(), SceneError> {
        let bad = |field: &str, reason: String| {
            Err(SceneError::Invalid {
                field: format!("realism.{field}"),
                reason,
            })
        };
        if self.floor_mean.is_empty() || self.floor_mean.len() > 1024 {
            return bad("floor_mean", "needs 1 to 1024 [range_m, mean] pairs".into());
        }
        let mut last = f64::NEG_INFINITY;
        for p in &self.floor_mean {
            if !(p[0].is_finite() && p[0] >= 0.0 && p[0] > last) {
                return bad(
                    "floor_mean",
                    format!("ranges must be finite, >= 0 and increasing, got {}", p[0]),
                );
            }
            if !(p[1].is_finite() && p[1] > 0.0 && p[1] < 1e6) {
                return bad(
                    "floor_mean",
                    format!("means must be in (0, 1e6), got {}", p[1]),
                );
            }
            last = p[0];
        }
        let in_range = |v: f64, lo: f64, hi: f64| v.is_finite() && v >= lo && v <= hi;
        if !in_range(self.floor_shape, 0.05, 100.0) {
            return bad(
                "floor_shape",
                format!("must be in [0.05, 100], got {}", self.floor_shape),
            );
        }
        if !in_range(self.log_scale, 0.5, 2.0) {
            return bad(
                "log_scale",
                format!("must be in [0.5, 2], got {}", self.log_scale),
            );
        }
        if !in_range(self.saturation_db, 1.0, 127.5) {
            return bad(
                "saturation_db",
                format!("must be in [1, 127.5], got {}", self.saturation_db),
            );
        }
        if !in_range(self.range_fwhm_m, 0.001, 10.0) {
            return bad(
                "range_fwhm_m",
                format!("must be in [0.001, 10] m, got {}", self.range_fwhm_m),
            );
        }
        if !in_range(self.beam_fwhm_deg, 0.05, 20.0) {
            return bad(
                "beam_fwhm_deg",
                format!("must be in [0.05, 20], got {}", self.beam_fwhm_deg),
            );
        }
        if !in_range(self.antenna_pedestal, 0.0, 1.0) {
            return bad(
                "antenna_pedestal",
                format!("must be in [0, 1], got {}", self.antenna_pedestal),
            );
        }
        if !in_range(self.signal_gain_db, -100.0, 200.0) {
            return bad(
                "signal_gain_db",
                format!("must be in [-100, 200], got {}", self.signal_gain_db),
            );
        }
        if !in_range(self.signal_slope_db_per_decade, -80.0, 80.0) {
            return bad(
                "signal_slope_db_per_decade",
                format!(
                    "must be in [-80, 80], got {}",
                    self.signal_slope_db_per_decade
                ),
            );
        }
        if !in_range(self.rolloff_m, 1.0, 1e5) {
            return bad(
                "rolloff_m",
                format!("must be in [1, 1e5] m, got {}", self.rolloff_m),
            );
        }
        if !in_range(self.highpass_m, 0.0, 100.0) {
            return bad(
                "highpass_m",
                format!("must be in [0, 100] m, got {}", self.highpass_m),
            );
        }
        if !in_range(self.ghost_reflectance, 0.0, 1.0) {
            return bad(
                "ghost_reflectance",
                format!("must be in [0, 1], got {}", self.ghost_reflectance),
            );
        }
        if !in_range(self.ghost_min_rcs_m2, 0.0, 1e6) {
            return bad(
                "ghost_min_rcs_m2",
                format!("must be in [0, 1e6], got {}", self.ghost_min_rcs_m2),
            );
        }
        if !in_range(self.ghost_range_m, 0.0, 1e4) {
            return bad(
                "ghost_range_m",
                format!("must be in [0, 1e4] m, got {}", self.ghost_range_m),
            );
        }
        Ok(())
    }
}
