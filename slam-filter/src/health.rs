//! Consistency and numerical-health figures: NEES against ground truth, and the state of
//! the covariance (symmetry, definiteness, smallest eigenvalue).

use nalgebra::{DMatrix, Matrix2, Matrix3, Vector2, Vector3};
use radar_model::geometry::{wrap_angle, Pose2};

use super::error::FilterError;

/// Normalised estimation error squared of the pose, `e^T P_vv^{-1} e` with the heading error
/// wrapped; chi-square with 3 dof for a consistent filter.
pub fn pose_nees(estimate: &Pose2, cov: &Matrix3<f64>, truth: &Pose2) -> Result<f64, FilterError> {
    let e = Vector3::new(
        estimate.x - truth.x,
        estimate.y - truth.y,
        wrap_angle(estimate.theta - truth.theta),
    );
    let ch = cov
        .cholesky()
        .ok_or(FilterError::CovarianceNotPositiveDefinite)?;
    Ok(e.dot(&ch.solve(&e)))
}

/// The two-sided 95 % interval of chi-square with 3 dof (its 2.5 % and 97.5 % points): a
/// consistent filter's pose NEES lies below it in 2.5 % of samples, above it in 2.5 %.
pub const POSE_NEES_BAND_95: (f64, f64) = (0.2158, 9.3484);

/// NEES of a feature position (2 dof).
pub fn position_nees(
    estimate: [f64; 2],
    cov: &Matrix2<f64>,
    truth: [f64; 2],
) -> Result<f64, FilterError> {
    let e = Vector2::new(estimate[0] - truth[0], estimate[1] - truth[1]);
    let ch = cov
        .cholesky()
        .ok_or(FilterError::CovarianceNotPositiveDefinite)?;
    Ok(e.dot(&ch.solve(&e)))
}

/// The covariance's numerical health.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CovarianceHealth {
    /// Largest `|P_ij - P_ji|` (0 when kept symmetric by construction).
    pub max_symmetry_error: f64,
    /// Whether a Cholesky factorisation of P succeeded (P positive definite).
    pub cholesky_ok: bool,
    /// Smallest eigenvalue of P; `None` unless asked for (O(n^3)). Its absolute accuracy is
    /// about `n eps max_variance`, so with variances spanning many decades it cannot show
    /// definiteness: see `min_correlation_eigenvalue`.
    pub min_eigenvalue: Option<f64>,
    /// Smallest eigenvalue of the correlation matrix `D^{-1/2} P D^{-1/2}` (D = diag P):
    /// scale-free, in (0, 1] for a positive definite P whatever the spread of variances.
    /// `None` unless asked for, or if a variance is not positive.
    pub min_correlation_eigenvalue: Option<f64>,
    /// Smallest diagonal element (a variance).
    pub min_variance: f64,
    /// Largest diagonal element.
    pub max_variance: f64,
    /// Whether every element is finite.
    pub all_finite: bool,
}

/// Measures `cov`. The Cholesky test is O(n^3 / 3), the eigenvalues O(n^3): diagnostics,
/// not for every beam at hundreds of features.
pub fn covariance_health(cov: &DMatrix<f64>, with_eigenvalues: bool) -> CovarianceHealth {
    let n = cov.nrows();
    let mut max_sym: f64 = 0.0;
    for j in 0..n {
        for i in (j + 1)..n {
            max_sym = max_sym.max((cov[(i, j)] - cov[(j, i)]).abs());
        }
    }
    let diag = cov.diagonal();
    let all_finite = cov.iter().all(|v| v.is_finite());
    let cholesky_ok = all_finite && cov.clone().cholesky().is_some();
    let (min_eigenvalue, min_correlation_eigenvalue) = if with_eigenvalues && all_finite {
        let sym = 0.5 * (cov + cov.transpose());
        let min_eig = sym.symmetric_eigenvalues().iter().copied().reduce(f64::min);
        let min_corr = if diag.iter().all(|&d| d > 0.0) {
            let scale: Vec<f64> = diag.iter().map(|d| 1.0 / d.sqrt()).collect();
            let mut corr = sym;
            for j in 0..n {
                for i in 0..n {
                    corr[(i, j)] *= scale[i] * scale[j];
                }
            }
            corr.symmetric_eigenvalues()
                .iter()
                .copied()
                .reduce(f64::min)
        } else {
            None
        };
        (min_eig, min_corr)
    } else {
        (None, None)
    };
    CovarianceHealth {
        max_symmetry_error: max_sym,
        cholesky_ok,
        min_eigenvalue,
        min_correlation_eigenvalue,
        min_variance: diag.iter().copied().fold(f64::INFINITY, f64::min),
        max_variance: diag.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        all_finite,
    }
}
