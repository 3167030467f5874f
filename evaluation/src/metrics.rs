//! Small statistics shared by the sections: chi-square bands, RMSE, means, percentiles.

use statrs::distribution::{ChiSquared, ContinuousCDF};

/// The two-sided `confidence` band of the average of `runs` chi-square variables of `dof`
/// degrees of freedom: `[chi2_inv((1-c)/2, runs dof), chi2_inv((1+c)/2, runs dof)] / runs`.
/// For 50 runs, 3 dof and 95 %: [2.36, 3.72].
pub fn average_chi2_band(runs: usize, dof: usize, confidence: f64) -> (f64, f64) {
    let k = (runs.max(1) * dof.max(1)) as f64;
    match ChiSquared::new(k) {
        Ok(d) => {
            let lo = d.inverse_cdf(0.5 * (1.0 - confidence)) / runs.max(1) as f64;
            let hi = d.inverse_cdf(0.5 * (1.0 + confidence)) / runs.max(1) as f64;
            (lo, hi)
        }
        Err(_) => (f64::NAN, f64::NAN),
    }
}

/// The `p` quantile of chi-square with `dof` degrees of freedom.
pub fn chi2_quantile(p: f64, dof: usize) -> f64 {
    match ChiSquared::new(dof.max(1) as f64) {
        Ok(d) => d.inverse_cdf(p),
        Err(_) => f64::NAN,
    }
}

/// Root mean square (NaN for no values).
pub fn rms(values: impl IntoIterator<Item = f64>) -> f64 {
    let (n, s) = values
        .into_iter()
        .fold((0usize, 0.0), |(n, s), v| (n + 1, s + v * v));
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}

/// Arithmetic mean (NaN for no values).
pub fn mean(values: impl IntoIterator<Item = f64>) -> f64 {
    let (n, s) = values
        .into_iter()
        .fold((0usize, 0.0), |(n, s), v| (n + 1, s + v));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

/// The `q` quantile (0..=1) by nearest rank of the finite values (NaN for none).
pub fn quantile(values: &[f64], q: f64) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let rank = (q.clamp(0.0, 1.0) * (v.len() - 1) as f64).round();
    // rank is finite and within [0, len - 1].
    v.get(rank as usize).copied().unwrap_or(f64::NAN)
}

/// Fraction of `(nis, dof)` pairs inside their own `p` chi-square quantile.
pub fn nis_fraction_inside(nis: &[(f64, usize)], p: f64) -> f64 {
    if nis.is_empty() {
        return f64::NAN;
    }
    let mut cache: Vec<f64> = Vec::new();
    let inside = nis
        .iter()
        .filter(|(v, dof)| {
            while cache.len() < *dof {
                cache.push(chi2_quantile(p, cache.len() + 1));
            }
            dof.checked_sub(1)
                .and_then(|i| cache.get(i))
                .is_some_and(|q| v <= q)
        })
        .count();
    inside as f64 / nis.len() as f64
}

/// Mean NIS per degree of freedom over updates (1 when consistent).
pub fn nis_per_dof(nis: &[(f64, usize)]) -> f64 {
    let (s, d) = nis
        .iter()
        .fold((0.0, 0usize), |(s, d), (v, k)| (s + v, d + k));
    if d == 0 {
        f64::NAN
    } else {
        s / d as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fifty_run_three_dof_band_is_the_documented_one() {
        let (lo, hi) = average_chi2_band(50, 3, 0.95);
        assert!(
            (lo - 2.36).abs() < 0.005 && (hi - 3.72).abs() < 0.005,
            "{lo} {hi}"
        );
    }

    #[test]
    fn rms_mean_and_quantile_of_known_values() {
        assert!((rms([3.0, 4.0]) - 12.5f64.sqrt()).abs() < 1e-12);
        assert!((mean([1.0, 2.0, 6.0]) - 3.0).abs() < 1e-12);
        assert_eq!(quantile(&[5.0, 1.0, 3.0], 0.5), 3.0);
        assert!(rms(std::iter::empty()).is_nan());
    }

    #[test]
    fn nis_at_its_own_median_is_inside_the_95_percent_gate() {
        let nis = [(chi2_quantile(0.5, 3), 3), (100.0, 2)];
        assert!((nis_fraction_inside(&nis, 0.95) - 0.5).abs() < 1e-12);
        assert!((nis_per_dof(&[(3.0, 3), (2.0, 2)]) - 1.0).abs() < 1e-12);
    }
}
