//! Material parameters of a feature: reflected share `rho`, absorbed share `alpha` and
//! transmitted share `tau = 1 - rho - alpha` (the paper's normalised RCS, absorption and
//! transmittance), parameterised without bounds as `(rho, alpha, tau) = softmax(u, v, 0)`.
//!
//! Why: the filter's state holds `u, v`, which may take any real value, and every value
//! gives valid shares, so no update ever needs clamping (clamping after an update biases the
//! estimate and leaves the covariance wrong). Evaluation is in log space through
//! `LSE = log(1 + e^u + e^v)`, computed with the max subtracted, so `ln rho = u - LSE`,
//! `ln alpha = v - LSE`, `ln tau = -LSE` never overflow. Their Jacobians are bounded by 1 in
//! magnitude everywhere:
//!
//! | | d/du | d/dv |
//! |---|---|---|
//! | `ln rho` | `1 - rho` | `-alpha` |
//! | `ln alpha` | `-rho` | `1 - alpha` |
//! | `ln tau` | `-rho` | `-alpha` |
//!
//! Clamping happens in one place only: converting user-supplied `(rho, alpha)` into
//! `(u, v)` ([`Material::from_rho_alpha`]), where each share is raised to at least
//! [`MIN_SHARE`] so the logarithms exist.

use crate::error::{finite, ModelError};

/// Smallest share a user-supplied value is clamped up to (so `|u|, |v| <= ~20.7`).
pub const MIN_SHARE: f64 = 1e-9;

/// Unbounded material parameters, as held in the filter state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Material {
    /// `ln(rho / tau)`.
    pub u: f64,
    /// `ln(alpha / tau)`.
    pub v: f64,
}

/// The three shares; each in [0, 1], summing to 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shares {
    /// Reflected share (normalised RCS).
    pub rho: f64,
    /// Absorbed share.
    pub alpha: f64,
    /// Transmitted share.
    pub tau: f64,
}

/// Natural logarithms of the shares and their gradients with respect to `(u, v)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogShares {
    /// `ln rho`.
    pub ln_rho: f64,
    /// `ln alpha`.
    pub ln_alpha: f64,
    /// `ln tau`.
    pub ln_tau: f64,
    /// `d ln rho / d (u, v)`.
    pub d_ln_rho: [f64; 2],
    /// `d ln alpha / d (u, v)`.
    pub d_ln_alpha: [f64; 2],
    /// `d ln tau / d (u, v)`.
    pub d_ln_tau: [f64; 2],
}

impl Material {
    /// Material from the state's `u, v`.
    pub fn new(u: f64, v: f64) -> Self {
        Self { u, v }
    }

    /// `LSE(0, u, v) = ln(1 + e^u + e^v)`, stable for any finite `u, v`.
    pub fn log_partition(&self) -> f64 {
        let m = 0.0f64.max(self.u).max(self.v);
        m + ((-m).exp() + (self.u - m).exp() + (self.v - m).exp()).ln()
    }

    /// The shares `(rho, alpha, tau) = softmax(u, v, 0)`.
    pub fn shares(&self) -> Shares {
        let lse = self.log_partition();
        Shares {
            rho: (self.u - lse).exp(),
            alpha: (self.v - lse).exp(),
            tau: (-lse).exp(),
        }
    }

    /// Log shares and their bounded gradients (see the module table).
    pub fn log_shares(&self) -> LogShares {
        let lse = self.log_partition();
        let rho = (self.u - lse).exp();
        let alpha = (self.v - lse).exp();
        LogShares {
            ln_rho: self.u - lse,
            ln_alpha: self.v - lse,
            ln_tau: -lse,
            d_ln_rho: [1.0 - rho, -alpha],
            d_ln_alpha: [-rho, 1.0 - alpha],
            d_ln_tau: [-rho, -alpha],
        }
    }

    /// Jacobian of `(rho, alpha)` with respect to `(u, v)`, for reporting a covariance of
    /// the shares (`J P_uv J^T`): `[[rho (1 - rho), -rho alpha], [-alpha rho,
    /// alpha (1 - alpha)]]`. Every entry lies in [-1/4, 1/4].
    pub fn shares_jacobian(&self) -> [[f64; 2]; 2] {
        let s = self.shares();
        [
            [s.rho * (1.0 - s.rho), -s.rho * s.alpha],
            [-s.alpha * s.rho, s.alpha * (1.0 - s.alpha)],
        ]
    }

    /// Converts user-supplied shares into `(u, v)`. Values must be finite, `rho, alpha >= 0`
    /// and `rho + alpha <= 1`; each of `rho`, `alpha`, `tau` is then raised to at least
    /// [`MIN_SHARE`] (the only clamping in the crate) and `u = ln(rho/tau)`,
    /// `v = ln(alpha/tau)`.
    ///
    /// # Errors
    /// [`ModelError::NonFinite`] or [`ModelError::InvalidMaterial`].
    pub fn from_rho_alpha(rho: f64, alpha: f64) -> Result<Self, ModelError> {
        finite(rho, "rho")?;
        finite(alpha, "alpha")?;
        // A few ulps of slack so that shares read back from `shares()` convert again.
        let slack = 1e-12;
        if rho < 0.0 || alpha < 0.0 || rho + alpha > 1.0 + slack {
            return Err(ModelError::InvalidMaterial { rho, alpha });
        }
        let rho_c = rho.max(MIN_SHARE);
        let alpha_c = alpha.max(MIN_SHARE);
        let tau_c = (1.0 - rho - alpha).max(MIN_SHARE);
        Ok(Self {
            u: (rho_c / tau_c).ln(),
            v: (alpha_c / tau_c).ln(),
        })
    }
}
