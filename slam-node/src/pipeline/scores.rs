//! Scores against ground truth, as the summary reports them: observation errors, pose
//! errors with their 3-sigma consistency, the map against the scene. Plain values (a leaf).

use radar_model::geometry::{wrap_angle, Pose2};
use serde::Serialize;

/// Errors of the associated observations against the true geometry: each observation's
/// range and bearing minus those of the scene feature it came from (the nearest within
/// 1.5 m of where it points), seen from the true pose at its timestamp. Compares what the
/// detector and the grouping really deliver with the noise the filter assumes.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct ObservationErrorStats {
    /// Observations compared.
    pub samples: u64,
    /// Sum of range errors, m.
    pub range_sum_m: f64,
    /// Sum of squared range errors, m^2.
    pub range_sum_sq_m2: f64,
    /// Sum of bearing errors (wrapped), rad.
    pub bearing_sum_rad: f64,
    /// Sum of squared bearing errors, rad^2.
    pub bearing_sum_sq_rad2: f64,
}

impl ObservationErrorStats {
    /// Adds one observation's errors.
    pub fn add(&mut self, range_error_m: f64, bearing_error_rad: f64) {
        if !(range_error_m.is_finite() && bearing_error_rad.is_finite()) {
            return;
        }
        self.samples += 1;
        self.range_sum_m += range_error_m;
        self.range_sum_sq_m2 += range_error_m * range_error_m;
        self.bearing_sum_rad += bearing_error_rad;
        self.bearing_sum_sq_rad2 += bearing_error_rad * bearing_error_rad;
    }

    fn mean_std(&self, sum: f64, sum_sq: f64) -> Option<(f64, f64)> {
        (self.samples > 1).then(|| {
            let n = self.samples as f64;
            let mean = sum / n;
            let var = ((sum_sq - n * mean * mean) / (n - 1.0)).max(0.0);
            (mean, var.sqrt())
        })
    }

    /// Mean and standard deviation of the range errors, m (at least two samples).
    pub fn range_m(&self) -> Option<(f64, f64)> {
        self.mean_std(self.range_sum_m, self.range_sum_sq_m2)
    }

    /// Mean and standard deviation of the bearing errors, rad (at least two samples).
    pub fn bearing_rad(&self) -> Option<(f64, f64)> {
        self.mean_std(self.bearing_sum_rad, self.bearing_sum_sq_rad2)
    }
}

/// Where a series of pose NEES (3 dof) falls against
/// [`slam_filter::health::POSE_NEES_BAND_95`]: the share below says the covariance is too
/// large (conservative), above too small (optimistic). A mean NEES alone hides which: a
/// drive half at 0.5 and half at 5.5 averages 3.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct NeesBand {
    /// Samples below the band.
    pub below: u64,
    /// Samples inside it.
    pub inside: u64,
    /// Samples above it.
    pub above: u64,
}

impl NeesBand {
    /// Counts one NEES against [`slam_filter::health::POSE_NEES_BAND_95`]; a non-finite
    /// value is not counted.
    pub fn add(&mut self, nees: f64) {
        self.add_against(nees, slam_filter::health::POSE_NEES_BAND_95);
    }

    /// `values` counted against the band `(lo, hi)` (another band: an ensemble's, of the
    /// average over runs).
    pub fn of(values: impl IntoIterator<Item = f64>, band: (f64, f64)) -> Self {
        let mut counts = Self::default();
        for v in values {
            counts.add_against(v, band);
        }
        counts
    }

    /// Counts one value against `(lo, hi)`; a non-finite value is not counted.
    fn add_against(&mut self, nees: f64, (lo, hi): (f64, f64)) {
        if !nees.is_finite() {
            return;
        }
        if nees < lo {
            self.below += 1;
        } else if nees > hi {
            self.above += 1;
        } else {
            self.inside += 1;
        }
    }

    /// Samples counted.
    pub fn samples(&self) -> u64 {
        self.below + self.inside + self.above
    }

    /// Shares below, inside and above the band (zeros before any sample).
    pub fn shares(&self) -> [f64; 3] {
        let n = self.samples();
        if n == 0 {
            return [0.0; 3];
        }
        [self.below, self.inside, self.above].map(|c| c as f64 / n as f64)
    }
}

impl std::fmt::Display for NeesBand {
    /// `inside its two-sided 95% band [0.22, 9.35] in 95.0% of N (2.5% below: conservative,
    /// 2.5% above: optimistic)`: a consistent filter's shares.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [below, inside, above] = self.shares().map(|s| 100.0 * s);
        let (lo, hi) = slam_filter::health::POSE_NEES_BAND_95;
        write!(
            f,
            "inside its two-sided 95% band [{lo:.2}, {hi:.2}] in {inside:.1}% of {} ({below:.1}% below: conservative, {above:.1}% above: optimistic)",
            self.samples()
        )
    }
}

/// Pose error statistics against truth, accumulated per rotation.
#[derive(Debug, Clone, Default, Serialize)]
pub struct PoseErrorStats {
    /// Poses compared.
    pub samples: u64,
    /// Sum of squared position errors, m^2.
    pub sum_sq_position_m2: f64,
    /// Largest position error, m.
    pub max_position_m: f64,
    /// Largest heading error, rad.
    pub max_heading_rad: f64,
    /// Comparisons with every pose component inside its 3-sigma bound.
    pub inside_3_sigma: u64,
    /// Sum of pose NEES (3 dof).
    pub nees_sum: f64,
    /// The pose NEES against its two-sided 95 % band.
    pub nees_band: NeesBand,
    /// Final position error, m.
    pub final_position_m: f64,
    /// Final heading error, rad.
    pub final_heading_rad: f64,
}

impl PoseErrorStats {
    /// Adds one comparison of an estimate (with its covariance diagonal and NEES) to truth.
    pub fn add(&mut self, est: &Pose2, var: [f64; 3], truth: &Pose2, nees: Option<f64>) {
        let e = [
            est.x - truth.x,
            est.y - truth.y,
            wrap_angle(est.theta - truth.theta),
        ];
        let pos = e[0].hypot(e[1]);
        self.samples += 1;
        self.sum_sq_position_m2 += pos * pos;
        self.max_position_m = self.max_position_m.max(pos);
        self.max_heading_rad = self.max_heading_rad.max(e[2].abs());
        // A zero variance (the map frame's origin) allows a zero error only, to rounding.
        let inside = e
            .iter()
            .zip(var)
            .all(|(err, v)| err.abs() <= 3.0 * v.max(0.0).sqrt() + 1e-9);
        if inside {
            self.inside_3_sigma += 1;
        }
        self.nees_sum += nees.unwrap_or(0.0);
        if let Some(v) = nees {
            self.nees_band.add(v);
        }
        self.final_position_m = pos;
        self.final_heading_rad = e[2].abs();
    }

    /// Root mean square position error, m.
    pub fn rms_position_m(&self) -> f64 {
        if self.samples == 0 {
            0.0
        } else {
            (self.sum_sq_position_m2 / self.samples as f64).sqrt()
        }
    }

    /// Share of comparisons inside the 3-sigma bounds.
    pub fn inside_fraction(&self) -> f64 {
        if self.samples == 0 {
            0.0
        } else {
            self.inside_3_sigma as f64 / self.samples as f64
        }
    }
}

/// How the map compares with the scene.
#[derive(Debug, Clone, Default, Serialize)]
pub struct MapScore {
    /// Features in the scene.
    pub scene_features: usize,
    /// Scene features the vehicle came within the radar's range of.
    pub scene_features_in_range: usize,
    /// Features in the estimated map.
    pub mapped: usize,
    /// Mapped features within `gate_m` of a scene feature.
    pub matched: usize,
    /// Distinct scene features matched.
    pub distinct_scene_features_matched: usize,
    /// Mean distance of matched features to their scene feature, m.
    pub mean_match_error_m: f64,
    /// Mean |rho - true rho| over matched features: the filter's estimate.
    pub mean_rho_error: f64,
    /// Mean |alpha - true alpha| over matched features.
    pub mean_alpha_error: f64,
    /// The same errors for the filter's initial rho and alpha (what it started from).
    pub initial_rho_error: f64,
    /// Initial alpha error.
    pub initial_alpha_error: f64,
    /// The estimated radar loss L, dB.
    pub loss_db: f64,
    /// The true L, dB, when known.
    pub true_loss_db: Option<f64>,
    /// Mean |rho 10^(-(L - L_true)/10) - true rho|: received power fixes only
    /// `10 log10 rho - L`, so rho and L share one unobservable offset; this removes it.
    pub mean_rho_error_gauge_fixed: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use statrs::distribution::{ChiSquared, ContinuousCDF};

    #[test]
    fn the_nees_band_is_chi_square_3_dof_two_sided_95_percent() {
        let chi2 = ChiSquared::new(3.0).unwrap();
        let (lo, hi) = slam_filter::health::POSE_NEES_BAND_95;
        assert!((chi2.cdf(lo) - 0.025).abs() < 1e-4, "{}", chi2.cdf(lo));
        assert!((chi2.cdf(hi) - 0.975).abs() < 1e-4, "{}", chi2.cdf(hi));
    }

    #[test]
    fn the_nees_band_counts_each_side_and_skips_what_is_not_a_number() {
        let mut band = NeesBand::default();
        for v in [0.1, 0.2158, 3.0, 9.3484, 9.4, 50.0, f64::NAN, f64::INFINITY] {
            band.add(v);
        }
        assert_eq!(
            band,
            NeesBand {
                below: 1,
                inside: 3,
                above: 2
            }
        );
        assert_eq!(band.shares(), [1.0 / 6.0, 0.5, 1.0 / 3.0]);
        assert_eq!(NeesBand::default().shares(), [0.0; 3]);
        let text = band.to_string();
        assert!(text.contains("50.0% of 6"), "{text}");
        assert!(text.contains("16.7% below"), "{text}");
        assert!(text.contains("33.3% above"), "{text}");
    }

    #[test]
    fn pose_errors_count_the_nees_against_its_band() {
        let mut stats = PoseErrorStats::default();
        let truth = Pose2::new(0.0, 0.0, 0.0);
        stats.add(&Pose2::new(0.1, 0.0, 0.0), [0.01; 3], &truth, Some(1.0));
        stats.add(&Pose2::new(3.0, 0.0, 0.0), [0.01; 3], &truth, Some(900.0));
        stats.add(&Pose2::new(0.0, 0.0, 0.0), [0.01; 3], &truth, None);
        assert_eq!(stats.nees_band.inside, 1);
        assert_eq!(stats.nees_band.above, 1);
        assert_eq!(stats.nees_band.samples(), 2);
    }
}
