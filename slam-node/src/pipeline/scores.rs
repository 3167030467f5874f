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
