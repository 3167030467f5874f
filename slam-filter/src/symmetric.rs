//! Keeping a covariance exactly symmetric. No dependency inside the crate: a leaf.

use nalgebra::DMatrix;

/// `P[i, j]` read from the lower triangle (the only one the per-beam update keeps current).
#[inline]
pub(crate) fn lower_entry(cov: &DMatrix<f64>, i: usize, j: usize) -> f64 {
    if i >= j {
        cov[(i, j)]
    } else {
        cov[(j, i)]
    }
}

/// Copies the lower triangle onto the upper one, in square tiles so that the strided
/// writes stay in cache.
pub(crate) fn mirror_lower(cov: &mut DMatrix<f64>) {
    const TILE: usize = 32;
    let n = cov.nrows();
    let data = cov.as_mut_slice();
    for jb in (0..n).step_by(TILE) {
        let j_end = (jb + TILE).min(n);
        for ib in (jb..n).step_by(TILE) {
            let i_end = (ib + TILE).min(n);
            for j in jb..j_end {
                for i in ib.max(j + 1)..i_end {
                    // (i, j) is at j * n + i (column-major); (j, i) at i * n + j.
                    data[i * n + j] = data[j * n + i];
                }
            }
        }
    }
}
