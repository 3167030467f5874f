//! The batched EKF update with a sparse Jacobian, a Cholesky-factorised innovation
//! covariance, and a symmetric covariance update that costs O(n^2 m).
//!
//! With `H` nonzero only in the columns `c` (pose, the beam's features, L):
//!
//! - `PHt = P[:, c] H^T` (n x m), O(n |c| m): only the columns H touches are read
//! - `S = H P[c, c] H^T + R`, factorised `S = L_S L_S^T` (never inverted)
//! - `W = PHt L_S^{-T}` (n x m), so that `K S K^T = W W^T` and `K nu = W (L_S^{-1} nu)`
//! - `x += W e` with `e = L_S^{-1} nu`, `NIS = e^T e = nu^T S^{-1} nu`
//! - `P -= W W^T` on the lower triangle only, O(n^2 m / 2): for a beam's few rows fused
//!   contiguous passes down each column from the diagonal; for big batches blocked matrix
//!   products. The upper triangle is left stale and mirrored only when something needs the
//!   whole matrix (a new feature, [`SlamState::covariance`]); everything on the per-beam
//!   path reads the lower triangle.
//!
//! `P - K S K^T` is the Joseph form `(I - KH) P (I - KH)^T + K R K^T` for the optimal gain,
//! written so that it is symmetric by construction and never forms the n x n `I - KH`.
//! Before anything is written the new diagonal `P_ii - sum_k W_ik^2` is checked: an update
//! that would leave a non-positive variance is refused and the state is left unchanged (an
//! element whose variance is already exactly zero, and which the update does not touch, is
//! left at zero).

use multiversion::multiversion;
use nalgebra::{DMatrix, DVector};
use radar_model::geometry::wrap_angle;

use super::error::FilterError;
use super::observation::nonzero_columns;
use super::state::{SlamState, POSE_DIM};

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

/// `P[:, c] H^T`: n x m, reading only the columns of P that H touches. Only `P`'s lower
/// triangle is read (the upper one may be stale, see [`SlamState::covariance`]): column `c`
/// from row `c` down is contiguous, the entries above it are row `c`'s (`P[i, c] = P[c, i]`).
pub(crate) fn p_ht(state: &SlamState, columns: &[usize], h: &DMatrix<f64>) -> DMatrix<f64> {
    let cov = &state.cov;
    let n = cov.nrows();
    let mut gathered = DMatrix::zeros(n, columns.len());
    for (k, &c) in columns.iter().enumerate() {
        let mut dst = gathered.column_mut(k);
        dst.rows_mut(c, n - c)
            .copy_from(&cov.view((c, c), (n - c, 1)));
        for i in 0..c {
            dst[i] = cov[(c, i)];
        }
    }
    gathered * h.transpose()
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
    batched_update_considering(state, obs, &[])
}

/// [`batched_update`] with the elements at `consider` held as consider parameters (the
/// Schmidt-Kalman update): their gain rows are zero, so their means and their own block of
/// the covariance stay as they were, while their cross-covariances with the rest take the
/// ordinary update. With `K` the optimal gain and `D` zeroing the consider rows, the update
/// `P - D K H P - P H^T K^T D + D K S K^T D` is, entry by entry, the ordinary `P - W W^T`
/// except where both indices are consider ones: the covariance stays that of the
/// estimator's actual error (positive definite), for a gain that is not the optimal one.
/// Indices outside the state are ignored.
pub fn batched_update_considering(
    state: &mut SlamState,
    obs: &LinearisedObservation,
    consider: &[usize],
) -> Result<UpdateOutcome, FilterError> {
    let n = state.dim();
    obs.check(n)?;
    let m = obs.innovation.len();
    // Columns the Jacobian does not touch (a beam's candidates that were not observed)
    // contribute exact zeros: leave them out of `P H^T`.
    let pruned = nonzero_columns(&obs.jacobian).map(|keep| {
        let columns: Vec<usize> = keep.iter().map(|&k| obs.columns[k]).collect();
        (columns, obs.jacobian.select_columns(keep.iter()))
    });
    let (columns, jacobian) = match &pruned {
        Some((c, h)) => (c.as_slice(), h),
        None => (obs.columns.as_slice(), &obs.jacobian),
    };
    let pht = p_ht(state, columns, jacobian);
    let s = innovation_covariance(&pht, columns, jacobian, &obs.noise);
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
    let consider: Vec<usize> = consider.iter().copied().filter(|&c| c < n).collect();
    // Refuse before writing anything if a variance would go non-positive.
    for i in (0..n).filter(|i| !consider.contains(i)) {
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
    // The consider elements' means and their own covariance block (lower triangle), put
    // back after the ordinary update.
    let kept_mean: Vec<f64> = consider.iter().map(|&c| state.mean[c]).collect();
    let kept_cov: Vec<(usize, usize, f64)> = consider
        .iter()
        .flat_map(|&a| consider.iter().map(move |&b| (a.max(b), a.min(b))))
        .map(|(a, b)| (a, b, state.cov[(a, b)]))
        .collect();
    state.mean += &w * &e;
    for (&c, &m) in consider.iter().zip(&kept_mean) {
        state.mean[c] = m;
    }
    state.mean[2] = wrap_angle(state.mean[2]);
    // The correction's covariance in the pose block, `W_v W_v^T` (see
    // `SlamState::pose_churn`).
    for i in 0..POSE_DIM {
        for j in 0..POSE_DIM {
            let mut sum = 0.0;
            for k in 0..m {
                sum += w[(i, k)] * w[(j, k)];
            }
            state.pose_churn[(i, j)] += sum;
        }
    }
    subtract_wwt(&mut state.cov, &w);
    for &(a, b, v) in &kept_cov {
        state.cov[(a, b)] = v;
    }
    state.upper_stale = true;
    Ok(UpdateOutcome { nis, dof: m })
}

/// Width of the column blocks of the covariance update.
const BLOCK: usize = 64;

/// Up to this many columns of `W` the update is done with fused column passes; above it
/// one blocked matrix product per column block.
const FUSED_MAX_ROWS: usize = 8;

/// `P -= W W^T` on the lower triangle (`i >= j`); the upper triangle is not brought up to
/// date (the big-batch path writes the upper part of its diagonal blocks too).
///
/// For the per-beam updates (m at most [`FUSED_MAX_ROWS`], typically 3: range, bearing,
/// power of one target) every column `j` of `P` is updated from its diagonal down in one
/// contiguous pass with up to four columns of `W` fused, at n^2 m / 2 multiply-adds in
/// vectorisable streams. For bigger batches the lower triangle is a blocked matrix product
/// per column block of [`BLOCK`] (nalgebra hands it to the cache-blocked `matrixmultiply`).
/// Each lower entry gets the same products summed in the same order as a full symmetric
/// update would give it, so mirroring the result gives that update bit for bit.
pub(crate) fn subtract_wwt(cov: &mut DMatrix<f64>, w: &DMatrix<f64>) {
    let n = cov.nrows();
    let m = w.ncols();
    if m <= FUSED_MAX_ROWS {
        subtract_wwt_fused(cov.as_mut_slice(), w.as_slice(), n, m);
        return;
    }
    let w_t = w.transpose();
    for j0 in (0..n).step_by(BLOCK) {
        let jb = BLOCK.min(n - j0);
        let a = w.rows(j0, n - j0);
        let b = w_t.columns(j0, jb);
        let mut c = cov.view_mut((j0, j0), (n - j0, jb));
        c.gemm(-1.0, &a, &b, 1.0);
    }
}

/// `P -= W W^T` on the lower triangle of the column-major `p` (n x n), `w` column-major
/// n x m: for each column `j` of `P`, rows `j..n`, the columns of `W` in groups of up to
/// four, each group one pass.
///
/// Compiled twice and chosen at run time: with AVX (four doubles a vector) where the CPU
/// has it, else the baseline (two). The arithmetic is the same element-wise products and
/// sums in the same order, without fused multiply-adds, so both give the same bits.
#[multiversion(targets("x86_64+avx"))]
fn subtract_wwt_fused(p: &mut [f64], w: &[f64], n: usize, m: usize) {
    let cols: Vec<&[f64]> = (0..m).map(|k| &w[k * n..(k + 1) * n]).collect();
    for (j, p_col) in p.chunks_exact_mut(n).enumerate() {
        let p_low = &mut p_col[j..];
        let mut k = 0;
        while k < m {
            match m - k {
                1 => axpy1(p_low, &cols[k][j..], cols[k][j]),
                2 => axpy2(
                    p_low,
                    [&cols[k][j..], &cols[k + 1][j..]],
                    [cols[k][j], cols[k + 1][j]],
                ),
                3 => axpy3(
                    p_low,
                    [&cols[k][j..], &cols[k + 1][j..], &cols[k + 2][j..]],
                    [cols[k][j], cols[k + 1][j], cols[k + 2][j]],
                ),
                _ => axpy4(
                    p_low,
                    [
                        &cols[k][j..],
                        &cols[k + 1][j..],
                        &cols[k + 2][j..],
                        &cols[k + 3][j..],
                    ],
                    [cols[k][j], cols[k + 1][j], cols[k + 2][j], cols[k + 3][j]],
                ),
            }
            k += (m - k).min(4);
        }
    }
}

#[inline(always)]
fn axpy1(p: &mut [f64], w: &[f64], a: f64) {
    if a == 0.0 {
        return;
    }
    for (p, w) in p.iter_mut().zip(w) {
        *p -= a * w;
    }
}

#[inline(always)]
fn axpy2(p: &mut [f64], w: [&[f64]; 2], a: [f64; 2]) {
    for ((p, w0), w1) in p.iter_mut().zip(w[0]).zip(w[1]) {
        *p -= a[0] * w0 + a[1] * w1;
    }
}

#[inline(always)]
fn axpy3(p: &mut [f64], w: [&[f64]; 3], a: [f64; 3]) {
    for (((p, w0), w1), w2) in p.iter_mut().zip(w[0]).zip(w[1]).zip(w[2]) {
        *p -= a[0] * w0 + a[1] * w1 + a[2] * w2;
    }
}

#[inline(always)]
fn axpy4(p: &mut [f64], w: [&[f64]; 4], a: [f64; 4]) {
    for ((((p, w0), w1), w2), w3) in p.iter_mut().zip(w[0]).zip(w[1]).zip(w[2]).zip(w[3]) {
        *p -= a[0] * w0 + a[1] * w1 + a[2] * w2 + a[3] * w3;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A state of one feature (pose, loss, k, b, clone, placements, the feature) with a
    /// dense, well conditioned covariance, and a 2-row observation of the pose and the
    /// feature.
    fn consider_case() -> (SlamState, LinearisedObservation) {
        let n = crate::state::FEATURE_BASE + crate::state::FEATURE_DIM;
        let a = DMatrix::from_fn(n, n, |i, j| ((i * 5 + j * 3) as f64 * 0.417).sin() * 0.3);
        let cov = &a * a.transpose() + DMatrix::from_diagonal_element(n, n, 0.05);
        let mean = DVector::from_fn(n, |i, _| (i as f64 * 0.3).cos());
        let state = SlamState::from_parts(mean, cov, 0.0).unwrap();
        let f = crate::state::FEATURE_BASE;
        let columns = vec![0, 1, 2, f, f + 1];
        let jacobian = DMatrix::from_fn(2, 5, |r, c| ((r * 5 + c) as f64 * 0.9).cos());
        let obs = LinearisedObservation {
            columns,
            jacobian,
            innovation: DVector::from_vec(vec![0.3, -0.2]),
            noise: DMatrix::from_diagonal(&DVector::from_vec(vec![0.04, 0.02])),
        };
        (state, obs)
    }

    /// The Schmidt-Kalman update holds the consider elements' means and their own block,
    /// updates everything else exactly as the ordinary update does, and equals the explicit
    /// `P - D K H P - P H^T K^T D + D K S K^T D` with `D` zeroing the consider rows; the
    /// result stays symmetric positive definite.
    #[test]
    fn a_consider_update_holds_its_elements_and_gives_the_schmidt_covariance() {
        use crate::state::{SPEED_SCALE_INDEX, STEER_BIAS_INDEX};
        let consider = [SPEED_SCALE_INDEX, STEER_BIAS_INDEX];
        let (before, obs) = consider_case();
        let mut ordinary = before.clone();
        batched_update(&mut ordinary, &obs).unwrap();
        let mut schmidt = before.clone();
        batched_update_considering(&mut schmidt, &obs, &consider).unwrap();
        let (p0, po, ps) = (
            before.covariance().into_owned(),
            ordinary.covariance().into_owned(),
            schmidt.covariance().into_owned(),
        );
        let n = p0.nrows();
        for i in 0..n {
            let held = consider.contains(&i);
            let expected_mean = if held {
                before.mean()[i]
            } else {
                ordinary.mean()[i]
            };
            assert!(
                (schmidt.mean()[i] - expected_mean).abs() < 1e-12,
                "mean {i}"
            );
            for j in 0..n {
                let expected = if held && consider.contains(&j) {
                    p0[(i, j)]
                } else {
                    po[(i, j)]
                };
                assert!((ps[(i, j)] - expected).abs() < 1e-12, "P[{i}, {j}]");
            }
        }
        // The explicit Schmidt form, from the full matrices.
        let mut h = DMatrix::zeros(obs.jacobian.nrows(), n);
        for (k, &c) in obs.columns.iter().enumerate() {
            h.set_column(c, &obs.jacobian.column(k));
        }
        let s = &h * &p0 * h.transpose() + &obs.noise;
        let mut gain = &p0 * h.transpose() * s.clone().try_inverse().unwrap();
        for &c in &consider {
            gain.row_mut(c).fill(0.0);
        }
        let explicit = &p0 - &gain * &h * &p0 - &p0 * h.transpose() * gain.transpose()
            + &gain * &s * gain.transpose();
        assert!(
            (&explicit - &ps).amax() < 1e-10,
            "{}",
            (&explicit - &ps).amax()
        );
        let expected_mean = before.mean() + &gain * &obs.innovation;
        assert!((schmidt.mean() - expected_mean).amax() < 1e-12);
        assert!((&ps - ps.transpose()).amax() < 1e-12);
        assert!(ps.clone().cholesky().is_some(), "positive definite");
    }

    /// The fused update (vectorised, AVX where the CPU has it) gives bit for bit what a
    /// plain scalar loop over the whole matrix gives for the same grouping of `W`'s
    /// columns in the lower triangle, leaves the upper triangle as it was, and mirrored is
    /// exactly symmetric, for every m it handles and for a big batch.
    #[test]
    fn the_fused_update_is_bitwise_the_scalar_one_on_the_lower_triangle() {
        let n = 37;
        for m in (1..=FUSED_MAX_ROWS).chain([FUSED_MAX_ROWS + 3]) {
            let w = DMatrix::from_fn(n, m, |i, k| ((i * 7 + k * 13) as f64 * 0.731).sin());
            let base = DMatrix::from_fn(n, n, |i, j| {
                let (a, b) = (i.min(j) as f64, i.max(j) as f64);
                (a * 0.37 + b * 0.11).cos() + if i == j { 40.0 } else { 0.0 }
            });
            let mut fused = base.clone();
            subtract_wwt(&mut fused, &w);
            let mut scalar = base.clone();
            for j in 0..n {
                for i in 0..n {
                    let mut k = 0;
                    while k < m {
                        let g = (m - k).min(4);
                        let mut sum = w[(j, k)] * w[(i, k)];
                        for q in 1..g {
                            sum += w[(j, k + q)] * w[(i, k + q)];
                        }
                        scalar[(i, j)] -= sum;
                        k += g;
                    }
                }
            }
            for j in 0..n {
                for i in 0..n {
                    if i >= j {
                        if m <= FUSED_MAX_ROWS {
                            assert_eq!(fused[(i, j)], scalar[(i, j)], "m = {m} ({i}, {j})");
                        } else {
                            // The blocked product sums in its own order.
                            let tol = 1e-12 * scalar[(i, j)].abs().max(1.0);
                            assert!((fused[(i, j)] - scalar[(i, j)]).abs() <= tol, "m = {m}");
                        }
                        assert_eq!(scalar[(i, j)], scalar[(j, i)], "m = {m}");
                    } else if m <= FUSED_MAX_ROWS {
                        // (The blocked product also writes the upper part of its diagonal
                        // blocks; the mirror overwrites it.)
                        assert_eq!(fused[(i, j)], base[(i, j)], "m = {m}: upper written");
                    }
                }
            }
            crate::symmetric::mirror_lower(&mut fused);
            assert_eq!(fused, fused.transpose(), "m = {m}");
        }
    }
}
