//! Shared helpers for the integration tests: central finite differences.

#![allow(dead_code)]

use nalgebra::DMatrix;
use radar_model::wrap_angle;

/// Central-difference Jacobian of `f` at `x` with the absolute step `h`. Outputs whose
/// index is in `angle_rows` have their differences wrapped to (-pi, pi].
pub fn numeric_jacobian<F>(f: F, x: &[f64], h: f64, angle_rows: &[usize]) -> DMatrix<f64>
where
    F: Fn(&[f64]) -> Vec<f64>,
{
    let m = f(x).len();
    let mut jac = DMatrix::zeros(m, x.len());
    let mut xp = x.to_vec();
    for k in 0..x.len() {
        let step = h;
        xp[k] = x[k] + step;
        let fp = f(&xp);
        xp[k] = x[k] - step;
        let fm = f(&xp);
        xp[k] = x[k];
        for r in 0..m {
            let mut d = fp[r] - fm[r];
            if angle_rows.contains(&r) {
                d = wrap_angle(d);
            }
            jac[(r, k)] = d / (2.0 * step);
        }
    }
    jac
}

/// Checks `|a - n| <= rel * max(|a|, |n|) + abs` entry by entry; names the first failure.
pub fn assert_jacobians_agree(
    analytic: &DMatrix<f64>,
    numeric: &DMatrix<f64>,
    rel: f64,
    abs: f64,
) -> Result<(), String> {
    if analytic.shape() != numeric.shape() {
        return Err(format!(
            "shapes differ: analytic {:?}, numeric {:?}",
            analytic.shape(),
            numeric.shape()
        ));
    }
    for r in 0..analytic.nrows() {
        for c in 0..analytic.ncols() {
            let a = analytic[(r, c)];
            let n = numeric[(r, c)];
            if !a.is_finite() || (a - n).abs() > rel * a.abs().max(n.abs()) + abs {
                return Err(format!(
                    "entry ({r}, {c}): analytic {a:e}, numeric {n:e}, difference {:e}",
                    (a - n).abs()
                ));
            }
        }
    }
    Ok(())
}
