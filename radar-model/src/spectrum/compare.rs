//! Bin-by-bin comparison of a predicted with a measured spectrum (the paper's figure 10):
//! the difference, the fraction of bins inside the 99 % bound, and the mean bias.

use crate::error::ModelError;

/// Summary of predicted minus measured over the bins both spectra have.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpectrumComparison {
    /// Bins compared (both values finite).
    pub bins: usize,
    /// Bins skipped because either value was not finite.
    pub skipped: usize,
    /// Mean of predicted minus measured (dB): the bias.
    pub mean_bias_db: f64,
    /// Root mean square of the difference (dB).
    pub rms_db: f64,
    /// Fraction of compared bins with `|difference| <= bound_db`.
    pub fraction_inside: f64,
    /// The bound used (dB).
    pub bound_db: f64,
}

fn check_lengths(predicted: &[f64], measured: &[f64]) -> Result<(), ModelError> {
    if predicted.len() != measured.len() {
        return Err(ModelError::BufferTooSmall {
            needed: predicted.len(),
            got: measured.len(),
        });
    }
    Ok(())
}

/// Writes `predicted - measured` per bin into `out` (NaN where either is not finite).
///
/// # Errors
/// Lengths differ.
pub fn difference_into(
    predicted: &[f64],
    measured: &[f64],
    out: &mut [f64],
) -> Result<(), ModelError> {
    check_lengths(predicted, measured)?;
    check_lengths(predicted, out)?;
    for ((o, p), m) in out.iter_mut().zip(predicted).zip(measured) {
        *o = if p.is_finite() && m.is_finite() {
            p - m
        } else {
            f64::NAN
        };
    }
    Ok(())
}

/// Compares two spectra against a symmetric bound (the paper's is
/// [`PAPER_BOUND_99_DB`](crate::noise::PAPER_BOUND_99_DB) = 16.35 dB). Non-finite bins are
/// skipped and counted. With no comparable bins, the bias and RMS are 0 and the fraction 0.
///
/// # Errors
/// Lengths differ, or the bound is not finite and positive.
pub fn compare_spectra(
    predicted: &[f64],
    measured: &[f64],
    bound_db: f64,
) -> Result<SpectrumComparison, ModelError> {
    check_lengths(predicted, measured)?;
    if !(bound_db.is_finite() && bound_db > 0.0) {
        return Err(ModelError::InvalidSetting {
            what: "bound_db",
            reason: "must be finite and positive",
        });
    }
    let mut bins = 0usize;
    let mut inside = 0usize;
    let mut sum = 0.0;
    let mut sum_sq = 0.0;
    for (p, m) in predicted.iter().zip(measured) {
        if !(p.is_finite() && m.is_finite()) {
            continue;
        }
        let d = p - m;
        bins += 1;
        sum += d;
        sum_sq += d * d;
        if d.abs() <= bound_db {
            inside += 1;
        }
    }
    let n = bins.max(1) as f64;
    Ok(SpectrumComparison {
        bins,
        skipped: predicted.len() - bins,
        mean_bias_db: sum / n,
        rms_db: (sum_sq / n).sqrt(),
        fraction_inside: if bins == 0 { 0.0 } else { inside as f64 / n },
        bound_db,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comparison_reports_bias_fraction_inside_and_skipped_bins() {
        let predicted = [10.0, 10.0, 10.0, 10.0, f64::NAN];
        let measured = [12.0, 8.0, 30.0, 10.0, 1.0];
        let c = compare_spectra(&predicted, &measured, 16.35).unwrap();
        assert_eq!(c.bins, 4);
        assert_eq!(c.skipped, 1);
        assert!((c.mean_bias_db - -5.0).abs() < 1e-12);
        assert!((c.fraction_inside - 0.75).abs() < 1e-12);
        assert!((c.rms_db - (408.0f64 / 4.0).sqrt()).abs() < 1e-12);
        let mut d = [0.0; 5];
        difference_into(&predicted, &measured, &mut d).unwrap();
        assert_eq!(d[2], -20.0);
        assert!(d[4].is_nan());
        assert!(compare_spectra(&predicted, &measured[..2], 16.35).is_err());
        assert!(compare_spectra(&predicted, &measured, 0.0).is_err());
    }
}
