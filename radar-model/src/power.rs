//! Received power of several targets down one beam: the paper's eq. 13, and the textbook
//! two-way radar equation beside it, both evaluated in dB as sums of logarithms so that
//! any number of targets neither underflows nor overflows, with analytic Jacobians.
//!
//! Targets are given sorted by range, nearest first (`R_1 <= R_2 <= ...`, `R_0 = 0`). The
//! power returned is the **uncompensated observed power** of `docs/contracts.md`:
//! `h_P = eq. 13 in dB - L` (dBm), before the receiver's range compensation.
//!
//! # The two spreading forms
//!
//! [`SpreadingForm::Paper`], eq. 13 exactly:
//! `P_i = 10 log K + (2i-1) 10 log A_I - 20 i log(4 pi) + 10 log rho_i
//!        + 20 sum_{j<i} log tau_j - 40 sum_{j=1..i} log s_j - L`.
//!
//! [`SpreadingForm::Textbook`]: the radar equation over the whole path with two passes
//! through every target in front:
//! `P_i = 10 log K + 10 log A_I - 20 log(4 pi) + 10 log rho_i + 20 sum_{j<i} log tau_j
//!        - 40 log s'_i - L`.
//!
//! Both agree for the first target. `K = P_t G A_e`, `A_e = G lambda^2 / (4 pi)`.
//!
//! They part for the targets behind: for the second, paper over textbook is
//! `A_I^2 R_2^4 / ((4 pi)^2 R_1^4 (R_2 - R_1)^4)`, +3.1 dB in the paper's penetration scene
//! (8.5 m and 14 m) with `A_I = 200 m^2`, and growing as the separation shrinks: the paper's
//! form can predict a target just behind another brighter than it would be alone, which
//! the textbook form never does. Which one fits measured spectra better is for the
//! evaluation to say; both are here, exact, selectable.
//!
//! # Regularisation of coincident targets
//!
//! The paper's `(R_j - R_{j-1})^4` sends the power of a target just behind another one to
//! infinity. Every separation is replaced by `s_j = sqrt((R_j - R_{j-1})^2 + dr^2)` with
//! `dr` the range resolution (and in the textbook form `s'_i = sqrt(R_i^2 + dr^2)`): the
//! radar cannot tell distances shorter than `dr` apart, so the model should not either. The
//! change, `20 log10(1 + (dr/dR)^2)`, is 1.9 dB at `dR = 2 dr`, below 0.1 dB beyond
//! `10 dr` (2.5 m) and 0.005 dB for a lone target at 10 m; `d ln s / dR` is bounded by
//! `1 / (2 dr)`, and a target at the sensor stays finite. Two neighbours closer than `dr`
//! are flagged [`unresolvable`](BeamPowers::unresolvable): their order may flip between
//! looks, so a filter should drop or inflate their power observation.
//!
//! # Calibration of the constants
//!
//! `P_t = 15 dBm` and `lambda = 3.89 mm` are the paper's. `G = 38.5 dBi` is the directivity
//! `4 pi / (dtheta_az dtheta_el)` of a 1.8 x 1.8 degree pencil beam (41.0 dBi) at 55 %
//! aperture efficiency. `A_I = 200 m^2` is the illuminated area: since `rho <= 1`, `rho A_I`
//! is the largest radar cross section the model can represent, and 200 m^2 lets the paper's
//! 177 m^2 reflector be `rho = 0.885` while a 1 m^2 pole is `rho = 0.005`. With these, the
//! first-target level is `10 log K + 10 log A_I - 20 log(4 pi) = 33.8 dBm` at 1 m (so
//! -6.2 dBm for `rho = 1` at 10 m); `compensation` maps that to 80 dB on the wire.

use crate::error::{finite, ModelError};
use crate::material::Material;
use nalgebra::DMatrix;
use std::f64::consts::{LN_10, PI};

/// `10 / ln 10`: converts a natural log to dB of power.
pub const DB_PER_NEPER_POWER: f64 = 10.0 / LN_10;

/// How power spreads between targets down one beam.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SpreadingForm {
    /// The paper's eq. 13: spreading over each separation `R_j - R_{j-1}`.
    #[default]
    Paper,
    /// The textbook radar equation: spreading over the whole path `R_i`.
    Textbook,
}

/// The radar's constants in eq. 13 (see the module doc for the calibration).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RadarConstants {
    /// Transmit power `P_t` (dBm).
    pub tx_power_dbm: f64,
    /// Wavelength `lambda` (m).
    pub wavelength_m: f64,
    /// Antenna gain `G` (dBi).
    pub antenna_gain_dbi: f64,
    /// Illuminated area `A_I` (m^2).
    pub illuminated_area_m2: f64,
}

impl Default for RadarConstants {
    fn default() -> Self {
        Self {
            tx_power_dbm: 15.0,
            wavelength_m: 3.89e-3,
            antenna_gain_dbi: 38.5,
            illuminated_area_m2: 200.0,
        }
    }
}

impl RadarConstants {
    /// `10 log10 K`, `K = P_t G A_e`, `A_e = G lambda^2 / (4 pi)` (eq. 13, 7), in dBm m^2.
    pub fn k_db(&self) -> f64 {
        self.tx_power_dbm + 2.0 * self.antenna_gain_dbi + 20.0 * self.wavelength_m.log10()
            - 10.0 * (4.0 * PI).log10()
    }

    /// `10 log10 A_I` (dB m^2).
    pub fn area_db(&self) -> f64 {
        10.0 * self.illuminated_area_m2.log10()
    }

    /// Level (dBm) of a lone target with `rho = 1` at 1 m, before regularisation and loss:
    /// `10 log K + 10 log A_I - 20 log(4 pi)` (eq. 7).
    pub fn unit_level_dbm(&self) -> f64 {
        self.k_db() + self.area_db() - 20.0 * (4.0 * PI).log10()
    }

    fn check(&self) -> Result<(), ModelError> {
        finite(self.tx_power_dbm, "tx power")?;
        finite(self.antenna_gain_dbi, "antenna gain")?;
        if !(self.wavelength_m.is_finite() && self.wavelength_m > 0.0) {
            return Err(ModelError::InvalidSetting {
                what: "wavelength_m",
                reason: "must be finite and positive",
            });
        }
        if !(self.illuminated_area_m2.is_finite() && self.illuminated_area_m2 > 0.0) {
            return Err(ModelError::InvalidSetting {
                what: "illuminated_area_m2",
                reason: "must be finite and positive",
            });
        }
        Ok(())
    }
}

/// Settings of the multi-target power model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerModel {
    /// Paper or textbook spreading.
    pub form: SpreadingForm,
    /// Radar constants.
    pub constants: RadarConstants,
    /// Range resolution `dr` (m): regularises separations and decides resolvability.
    /// The paper's unit: `c / 2B = 0.25 m` for a 600 MHz sweep.
    pub range_resolution_m: f64,
}

impl Default for PowerModel {
    fn default() -> Self {
        Self {
            form: SpreadingForm::Paper,
            constants: RadarConstants::default(),
            range_resolution_m: 0.25,
        }
    }
}

impl PowerModel {
    /// Validates the settings.
    ///
    /// # Errors
    /// Non-finite or non-positive constants or range resolution.
    pub fn check(&self) -> Result<(), ModelError> {
        self.constants.check()?;
        if !(self.range_resolution_m.is_finite() && self.range_resolution_m > 0.0) {
            return Err(ModelError::InvalidSetting {
                what: "range_resolution_m",
                reason: "must be finite and positive",
            });
        }
        Ok(())
    }
}

/// One target down a beam, as the power model sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerTarget {
    /// Range `R_i` (m), eq. 3.
    pub range_m: f64,
    /// Material `(u, v)`.
    pub material: Material,
}

/// Regularised separation `s = sqrt(dR^2 + dr^2)` and `d ln s / d dR = dR / s^2`.
pub fn regularised_separation(delta_range_m: f64, range_resolution_m: f64) -> (f64, f64) {
    let s2 = delta_range_m * delta_range_m + range_resolution_m * range_resolution_m;
    (s2.sqrt(), delta_range_m / s2)
}

fn check_targets(targets: &[PowerTarget], loss_db: f64) -> Result<(), ModelError> {
    finite(loss_db, "loss L")?;
    let mut previous = f64::NEG_INFINITY;
    for (index, t) in targets.iter().enumerate() {
        finite(t.range_m, "target range")?;
        finite(t.material.u, "material u")?;
        finite(t.material.v, "material v")?;
        if t.range_m < 0.0 {
            return Err(ModelError::InvalidSetting {
                what: "target range",
                reason: "must not be negative",
            });
        }
        if t.range_m < previous {
            return Err(ModelError::TargetsNotSorted { index });
        }
        previous = t.range_m;
    }
    Ok(())
}

/// Flags neighbours closer than the range resolution (both of each such pair).
pub fn flag_unresolvable(targets: &[PowerTarget], range_resolution_m: f64, out: &mut [bool]) {
    for flag in out.iter_mut() {
        *flag = false;
    }
    for i in 1..targets.len().min(out.len()) {
        if targets[i].range_m - targets[i - 1].range_m < range_resolution_m {
            out[i - 1] = true;
            out[i] = true;
        }
    }
}

/// Received power (dBm) of every target down one beam, eq. 13 (or the textbook form) minus
/// `L`, written into `out` (allocation-free). `targets` must be sorted by range.
///
/// # Errors
/// Non-finite input, unsorted targets, invalid model, or `out` shorter than `targets`.
pub fn beam_powers_db(
    model: &PowerModel,
    targets: &[PowerTarget],
    loss_db: f64,
    out: &mut [f64],
) -> Result<(), ModelError> {
    if out.len() < targets.len() {
        return Err(ModelError::BufferTooSmall {
            needed: targets.len(),
            got: out.len(),
        });
    }
    for_each_power_db(model, targets, loss_db, |i, p| {
        if let Some(slot) = out.get_mut(i) {
            *slot = p;
        }
    })
}

/// Eq. 13 (or the textbook form) minus `L` for every target down one beam, handing
/// `(index, power_db)` to `sink` in range order. `targets` must be sorted by range.
///
/// # Errors
/// Non-finite input, unsorted targets or an invalid model (checked before any call).
pub fn for_each_power_db<F: FnMut(usize, f64)>(
    model: &PowerModel,
    targets: &[PowerTarget],
    loss_db: f64,
    mut sink: F,
) -> Result<(), ModelError> {
    model.check()?;
    check_targets(targets, loss_db)?;
    let c = &model.constants;
    let four_pi_db = 20.0 * (4.0 * PI).log10();
    let k_db = c.k_db();
    let area_db = c.area_db();
    let unit_db = c.unit_level_dbm();
    let dr = model.range_resolution_m;
    // Running sums over the targets in front, in dB: 20 sum_{j<i} log tau_j, and the paper's
    // -40 sum_{j<=i} log s_j.
    let mut tau_db = 0.0;
    let mut spread_db = 0.0;
    let mut previous_range = 0.0;
    for (i0, t) in targets.iter().enumerate() {
        let i = (i0 + 1) as f64;
        let ls = t.material.log_shares();
        let (s, _) = regularised_separation(t.range_m - previous_range, dr);
        spread_db -= 4.0 * DB_PER_NEPER_POWER * s.ln();
        let p = match model.form {
            SpreadingForm::Paper => {
                k_db + (2.0 * i - 1.0) * area_db - i * four_pi_db
                    + DB_PER_NEPER_POWER * ls.ln_rho
                    + tau_db
                    + spread_db
                    - loss_db
            }
            SpreadingForm::Textbook => {
                let (s_path, _) = regularised_separation(t.range_m, dr);
                unit_db + DB_PER_NEPER_POWER * ls.ln_rho + tau_db
                    - 4.0 * DB_PER_NEPER_POWER * s_path.ln()
                    - loss_db
            }
        };
        sink(i0, p);
        tau_db += 2.0 * DB_PER_NEPER_POWER * ls.ln_tau;
        previous_range = t.range_m;
    }
    Ok(())
}

/// Powers of one beam with their Jacobian. Matrices are `n x n`, lower triangular (a
/// target depends only on itself and the targets in front); `d P_i / d L = -1` for all `i`.
#[derive(Debug, Clone, PartialEq)]
pub struct BeamPowers {
    /// `P_i` (dBm), uncompensated, loss included.
    pub power_db: Vec<f64>,
    /// Target closer than the range resolution to a neighbour.
    pub unresolvable: Vec<bool>,
    /// `d P_i / d R_k`.
    pub wrt_range: DMatrix<f64>,
    /// `d P_i / d u_k`.
    pub wrt_u: DMatrix<f64>,
    /// `d P_i / d v_k`.
    pub wrt_v: DMatrix<f64>,
}

/// Powers of one beam (as [`beam_powers_db`]) and their analytic Jacobian.
///
/// Paper form: `d P_i / d R_k = -40/ln10 * sum_{j<=i} d ln s_j / d R_k` with
/// `d ln s_j / d R_j = (R_j - R_{j-1}) / s_j^2 = -d ln s_j / d R_{j-1}`. Textbook form:
/// `d P_i / d R_i = -40/ln10 * R_i / (R_i^2 + dr^2)`. Material: `d P_i / d(u_i, v_i) =
/// 10/ln10 * d ln rho_i`, `d P_i / d(u_k, v_k) = 20/ln10 * d ln tau_k` for `k < i`.
///
/// # Errors
/// As [`beam_powers_db`].
pub fn beam_powers_with_jacobian(
    model: &PowerModel,
    targets: &[PowerTarget],
    loss_db: f64,
) -> Result<BeamPowers, ModelError> {
    let n = targets.len();
    let mut power_db = vec![0.0; n];
    beam_powers_db(model, targets, loss_db, &mut power_db)?;
    let mut unresolvable = vec![false; n];
    flag_unresolvable(targets, model.range_resolution_m, &mut unresolvable);
    let dr = model.range_resolution_m;
    let mut wrt_range = DMatrix::zeros(n, n);
    let mut wrt_u = DMatrix::zeros(n, n);
    let mut wrt_v = DMatrix::zeros(n, n);
    let logs: Vec<_> = targets.iter().map(|t| t.material.log_shares()).collect();
    // g[j] = d ln s_j / d (R_j - R_{j-1}) for the separation ending at target j.
    let mut previous_range = 0.0;
    let mut g = vec![0.0; n];
    for (j, t) in targets.iter().enumerate() {
        g[j] = regularised_separation(t.range_m - previous_range, dr).1;
        previous_range = t.range_m;
    }
    let k4 = 4.0 * DB_PER_NEPER_POWER;
    for i in 0..n {
        match model.form {
            SpreadingForm::Paper => {
                for j in 0..=i {
                    wrt_range[(i, j)] -= k4 * g[j];
                    if j > 0 {
                        wrt_range[(i, j - 1)] += k4 * g[j];
                    }
                }
            }
            SpreadingForm::Textbook => {
                wrt_range[(i, i)] = -k4 * regularised_separation(targets[i].range_m, dr).1;
            }
        }
        wrt_u[(i, i)] = DB_PER_NEPER_POWER * logs[i].d_ln_rho[0];
        wrt_v[(i, i)] = DB_PER_NEPER_POWER * logs[i].d_ln_rho[1];
        for k in 0..i {
            wrt_u[(i, k)] = 2.0 * DB_PER_NEPER_POWER * logs[k].d_ln_tau[0];
            wrt_v[(i, k)] = 2.0 * DB_PER_NEPER_POWER * logs[k].d_ln_tau[1];
        }
    }
    Ok(BeamPowers {
        power_db,
        unresolvable,
        wrt_range,
        wrt_u,
        wrt_v,
    })
}
