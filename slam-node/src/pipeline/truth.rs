//! Ground truth, when the radar is the simulator: the true pose at any time and the true
//! features, behind a small trait so the pipeline can score itself (pose error against its
//! own 3-sigma bounds, association errors, features mapped vs in the scene, rho/alpha
//! convergence) without knowing where the truth comes from.

use radar_model::geometry::{wrap_angle, Pose2};
use serde::Serialize;

use slam_filter::FeatureEstimate;

/// A true feature.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TrueFeature {
    /// Scene id.
    pub id: u32,
    /// East, metres.
    pub x_m: f64,
    /// North, metres.
    pub y_m: f64,
    /// True reflectivity.
    pub rho: f64,
    /// True absorption.
    pub alpha: f64,
}

/// Where the truth comes from.
pub trait TruthOracle: Send + std::fmt::Debug {
    /// The true pose at Unix time `t_s`, if known.
    fn pose_at(&self, t_s: f64) -> Option<Pose2>;
    /// Every true feature.
    fn features(&self) -> &[TrueFeature];
    /// The true radar loss L, dB, if known.
    fn loss_db(&self) -> Option<f64> {
        None
    }
}

/// Truth from a simulator scene: its trajectory, integrated exactly as the simulator does,
/// from the simulator's start time.
#[derive(Debug)]
pub struct SceneTruth {
    trajectory: sim_sensor::trajectory::Trajectory,
    start_s: f64,
    features: Vec<TrueFeature>,
    loss_db: f64,
}

impl SceneTruth {
    /// Truth for `scene` started at Unix time `start_s`, valid for `horizon_s` seconds.
    pub fn new(
        scene: &sim_sensor::scene::Scene,
        start_s: f64,
        horizon_s: f64,
    ) -> Result<Self, sim_sensor::SimError> {
        Ok(Self {
            trajectory: sim_sensor::trajectory::Trajectory::new(scene, horizon_s)?,
            start_s,
            loss_db: scene.loss_db,
            features: scene
                .features
                .iter()
                .map(|f| TrueFeature {
                    id: f.id,
                    x_m: f.x_m,
                    y_m: f.y_m,
                    rho: f.rho,
                    alpha: f.alpha,
                })
                .collect(),
        })
    }
}

impl TruthOracle for SceneTruth {
    fn pose_at(&self, t_s: f64) -> Option<Pose2> {
        // Unix seconds in f64 carry about 0.2 us of rounding: a time a hair before the
        // start is the start.
        let dt = t_s - self.start_s;
        if !(-1e-3..1.0e7).contains(&dt) {
            return None;
        }
        let dt = dt.max(0.0);
        // dt is finite, non-negative and below 1e7 s: the nanosecond count fits a u64.
        self.trajectory.pose_at((dt * 1e9).round() as u64).ok()
    }

    fn features(&self) -> &[TrueFeature] {
        &self.features
    }

    fn loss_db(&self) -> Option<f64> {
        Some(self.loss_db)
    }
}

/// The true feature nearest to a point, within `gate_m`.
pub fn nearest_feature(
    features: &[TrueFeature],
    xy: [f64; 2],
    gate_m: f64,
) -> Option<(usize, f64)> {
    features
        .iter()
        .enumerate()
        .map(|(i, f)| (i, (f.x_m - xy[0]).hypot(f.y_m - xy[1])))
        .filter(|&(_, d)| d <= gate_m)
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

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

/// Mean rho error after removing the common rho/L offset `loss_offset_db` (estimated L
/// minus true L): every feature's power depends on `10 log10 rho - L` only.
pub fn gauge_fixed_rho_error(
    map: &[FeatureEstimate],
    truth: &[TrueFeature],
    gate_m: f64,
    loss_offset_db: f64,
) -> f64 {
    let scale = 10f64.powf(-loss_offset_db / 10.0);
    let errors: Vec<f64> = map
        .iter()
        .filter_map(|f| {
            let (i, _) = nearest_feature(truth, [f.x_m, f.y_m], gate_m)?;
            truth.get(i).map(|t| (f.rho * scale - t.rho).abs())
        })
        .collect();
    if errors.is_empty() {
        0.0
    } else {
        errors.iter().sum::<f64>() / errors.len() as f64
    }
}

/// Scores the final map against the scene.
pub fn score_map(
    map: &[FeatureEstimate],
    truth: &[TrueFeature],
    in_range: usize,
    gate_m: f64,
    initial_rho: f64,
    initial_alpha: f64,
) -> MapScore {
    let mut s = MapScore {
        scene_features: truth.len(),
        scene_features_in_range: in_range,
        mapped: map.len(),
        ..MapScore::default()
    };
    let mut seen = vec![false; truth.len()];
    let (mut d_sum, mut r_sum, mut a_sum, mut r0_sum, mut a0_sum) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for f in map {
        if let Some((i, d)) = nearest_feature(truth, [f.x_m, f.y_m], gate_m) {
            if let (Some(t), Some(flag)) = (truth.get(i), seen.get_mut(i)) {
                s.matched += 1;
                *flag = true;
                d_sum += d;
                r_sum += (f.rho - t.rho).abs();
                a_sum += (f.alpha - t.alpha).abs();
                r0_sum += (initial_rho - t.rho).abs();
                a0_sum += (initial_alpha - t.alpha).abs();
            }
        }
    }
    s.distinct_scene_features_matched = seen.iter().filter(|&&x| x).count();
    if s.matched > 0 {
        let n = s.matched as f64;
        s.mean_match_error_m = d_sum / n;
        s.mean_rho_error = r_sum / n;
        s.mean_alpha_error = a_sum / n;
        s.initial_rho_error = r0_sum / n;
        s.initial_alpha_error = a0_sum / n;
    }
    s
}
