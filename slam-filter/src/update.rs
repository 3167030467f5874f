//! The batched EKF update with a sparse Jacobian, a Cholesky-factorised innovation
//! covariance, and a symmetric covariance update that costs O(n^2 m).
//!
//! With `H` nonzero only in the columns `c` (pose, the beam's features, L):
//!
//! - `PHt = P[:, c] H^T` (n x m), O(n |c| m): only the columns H touches are read
//! - `S = H P[c, c] H^T + R`, factorised `S = L_S L_S^T` (never inverted)
//! - `W = PHt L_S^{-T}` (n x m), so that `K S K^T = W W^T` and `K nu = W (L_S^{-1} nu)`
//! - `x += W e` with `e = L_S^{-1} nu`, `NIS = e^T e = nu^T S^{-1} nu`
//! - `P -= W W^T`, lower triangle only (blocked matrix products), then mirrored:
//!   O(n^2 m / 2)
//!
//! `P - K S K^T` is the Joseph form `(I - KH) P (I - KH)^T + K R K^T` for the optimal gain,
//! written so that it is symmetric by construction and never forms the n x n `I - KH`.
//! Before anything is written the new diagonal `P_ii - sum_k W_ik^2` is checked: an update
//! that would leave a non-positive variance is refused and the state is left unchanged (an
//! element whose variance is already exactly zero, and which the update does not touch, is
//! left at zero).

use nalgebra::{DMatrix, DVector};
use radar_model::geometry::wrap_angle;

use super::error::FilterError;
use super::state::SlamState;

/// A linearised observation of some state elements, ready for the update.
#[derive(Debug, Clone)]
pub struct LinearisedObservation {
    /// State indices of the Jacobian's columns (distinct).
    pub columns: Vec<usize>,
    /// The Jacobian restricted to `columns`: m x columns.len().
    pub jacobian: DMatrix<f64>,
    /// The innovation `z - h(x)`, m, with angle rows already wrapped.
    pub innovation: DVector<f64>,
    /// Observation noise covariance, m x m, symmetric positive definite.
    pub noise: DMatrix<f64>,
}

/// What one update did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateOutcome {
    /// Normalised innovation squared `nu^T S^{-1} nu`.
    pub nis: f64,
    /// Its degrees of freedom (rows of the observation).
    pub dof: usize,
}

impl LinearisedObservation {
    fn check(&self, n: usize) -> Result<(), FilterError> {
        let m = self.innovation.len();
        if m == 0 {
            return Err(FilterError::Shape("empty observation"));
        }
        if self.jacobian.nrows() != m || self.jacobian.ncols() != self.columns.len() {
            return Err(FilterError::Shape("Jacobian must be m x columns"));
        }
        if self.noise.nrows() != m || self.noise.ncols() != m {
            return Err(FilterError::Shape("noise must be m x m"));
        }
        if self.columns.iter().any(|&c| c >= n) {
            return Err(FilterError::Shape("Jacobian column outside the state"));
        }
        for (what, s) in [
            ("innovation", self.innovation.as_slice()),
            ("Jacobian", self.jacobian.as_slice()),
            ("observation noise", self.noise.as_slice()),
        ] {
            if s.iter().any(|v| !v.is_finite()) {
                return Err(FilterError::NonFiniteInput(what));
            }
        }
        Ok(())
    }
}

/// `P[:, c] H^T`: n x m, reading only the columns of P that H touches (gathered, then one
/// matrix product).
pub(crate) fn p_ht(cov: &DMatrix<f64>, columns: &[usize], h: &DMatrix<f64>) -> DMatrix<f64> {
    cov.select_columns(columns.iter()) * h.transpose()
}

/// `S = H P[c, c] H^T + R` from `PHt`, symmetrised.
pub(crate) fn innovation_covariance(
    pht: &DMatrix<f64>,
    columns: &[usize],
    h: &DMatrix<f64>,
    noise: &DMatrix<f64>,
) -> DMatrix<f64> {
    let m = h.nrows();
    let gathered = pht.select_rows(columns.iter()); // |c| x m = P[c, c] H^T
    let mut s = h * gathered + noise;
    for i in 0..m {
        for j in 0..i {
            let avg = 0.5 * (s[(i, j)] + s[(j, i)]);
            s[(i, j)] = avg;
            s[(j, i)] = avg;
        }
    }
    s
}

/// Applies one batched update to `state`. Rows whose innovation is an angle must already be
/// wrapped. On error the state is unchanged.
pub fn batched_update(
    state: &mut SlamState,
    obs: &LinearisedObservation,
) -> Result<UpdateOutcome, FilterError> {
    let n = state.dim();
    obs.check(n)?;
    let m = obs.innovation.len();
    let pht = p_ht(&state.cov, &obs.columns, &obs.jacobian);
    let s = innovation_covariance(&pht, &obs.columns, &obs.jacobian, &obs.noise);
    let chol = s
        .cholesky()
        .ok_or(FilterError::InnovationNotPositiveDefinite { dim: m })?;
    let l = chol.l();
    // W^T = L_S^{-1} PHt^T (m x n); W = its transpose, stored column-major (n x m).
    let wt = l
        .solve_lower_triangular(&pht.transpose())
        .ok_or(FilterError::InnovationNotPositiveDefinite { dim: m })?;
    let w = wt.transpose();
    let e = l
        .solve_lower_triangular(&obs.innovation)
        .ok_or(FilterError::InnovationNotPositiveDefinite { dim: m })?;
    let nis = e.norm_squared();
    if !nis.is_finite() || w.iter().any(|v| !v.is_finite()) {
        return Err(FilterError::NonFiniteInput("update gain"));
    }
    // Refuse before writing anything if a variance would go non-positive.
    for i in 0..n {
        let mut reduction = 0.0;
        for k in 0..m {
            reduction += w[(i, k)] * w[(i, k)];
        }
        let new_var = state.cov[(i, i)] - reduction;
        // An element with zero variance (a pose started exactly known and not yet moved
        // along that axis) has a zero row, so the update leaves it untouched: allowed.
        // Anything the update does touch must keep a positive variance.
        let untouched_zero = reduction == 0.0 && new_var == 0.0;
        if !((new_var > 0.0 || untouched_zero) && new_var.is_finite()) {
            return Err(FilterError::CovarianceLostDefiniteness {
                index: i,
                value: new_var,
            });
        }
    }
    state.mean += &w * &e;
    state.mean[2] = wrap_angle(state.mean[2]);
    subtract_wwt_lower_and_mirror(&mut state.cov, &w);
    Ok(UpdateOutcome { nis, dof: m })
}

/// Width of the column blocks of the covariance update.
const BLOCK: usize = 64;

/// `P -= W W^T` on the lower triangle, mirrored block by block. Columns are taken in
/// blocks of [`BLOCK`]: for m > 5 rows a block's lower trapezoid (rows `j0..n`) is one
/// matrix product (nalgebra hands it to the cache-blocked `matrixmultiply`), for fewer rows
/// column-slice axpys; each block is mirrored into the upper triangle while it is still in
/// cache. About n^2 m / 2 multiply-adds and one pass over P's memory.
pub(crate) fn subtract_wwt_lower_and_mirror(cov: &mut DMatrix<f64>, w: &DMatrix<f64>) {
    let n = cov.nrows();
    let m = w.ncols();
    let w_t = if m > 5 { Some(w.transpose()) } else { None };
    for j0 in (0..n).step_by(BLOCK) {
        let jb = BLOCK.min(n - j0);
        match &w_t {
            Some(w_t) => {
                let a = w.rows(j0, n - j0);
                let b = w_t.columns(j0, jb);
                let mut c = cov.view_mut((j0, j0), (n - j0, jb));
                c.gemm(-1.0, &a, &b, 1.0);
            }
            None => {
                let w_data = w.as_slice();
                let p_data = cov.as_mut_slice();
                for j in j0..j0 + jb {
                    let p_col = &mut p_data[j * n + j..(j + 1) * n];
                    for k in 0..m {
                        let w_col = &w_data[k * n + j..(k + 1) * n];
                        let wjk = w_col[0];
                        if wjk == 0.0 {
                            continue;
                        }
                        for (p, wi) in p_col.iter_mut().zip(w_col) {
                            *p -= wjk * wi;
                        }
                    }
                }
            }
        }
        mirror_block(cov, j0, jb);
    }
}

/// Copies the lower-triangle part of columns `j0..j0 + jb` onto the upper triangle:
/// `P[r, c] = P[c, r]` for `r` in the block and `c > r`.
fn mirror_block(cov: &mut DMatrix<f64>, j0: usize, jb: usize) {
    let n = cov.nrows();
    let data = cov.as_mut_slice();
    for c in j0..n {
        for r in j0..(j0 + jb).min(c) {
            // (r, c) is at c * n + r (column-major); (c, r) at r * n + c.
            data[c * n + r] = data[r * n + c];
        }
    }
}
