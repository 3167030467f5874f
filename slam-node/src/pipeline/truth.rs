//! Ground truth, when the radar is the simulator: the true pose at any time and the true
//! features, behind a small trait so the pipeline can score itself (pose error against its
//! own 3-sigma bounds, association errors, features mapped vs in the scene, rho/alpha
//! convergence) without knowing where the truth comes from.

use radar_model::geometry::{range_bearing, wrap_angle, Pose2};
use serde::Serialize;

use slam_filter::{BeamObservation, BeamReport, FeatureEstimate, RadarEkf};

use super::summary::PipelineSummary;
use crate::output::RotationDiagnostics;
use radar_odometry::PointGrid;

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

pub use super::scores::{MapScore, ObservationErrorStats, PoseErrorStats};

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

/// Truth scoring as an optional observer of the pipeline: it reads the beams, the filter's
/// reports and estimates, and never changes what the pipeline does.
#[derive(Debug)]
pub struct TruthObserver {
    oracle: Box<dyn TruthOracle>,
    pose_errors: PoseErrorStats,
    in_range: Vec<bool>,
    observation_errors: Option<ObservationErrorStats>,
    association_errors: u64,
    clutter_associations: u64,
    /// A grid over the true features' positions: each associated observation is scored with
    /// two nearest-feature queries, and a city has thousands of features.
    grid: PointGrid,
}

/// An observation counts as coming from a true feature within this distance (m).
const SEEN_GATE_M: f64 = 1.5;
/// A mapped feature stands for the true feature within this distance (m).
const MAPPED_GATE_M: f64 = 2.0;

impl TruthObserver {
    /// An observer scoring against `oracle`.
    pub fn new(oracle: Box<dyn TruthOracle>) -> Self {
        let positions: Vec<[f64; 2]> = oracle.features().iter().map(|f| [f.x_m, f.y_m]).collect();
        Self {
            grid: PointGrid::new(&positions, MAPPED_GATE_M),
            in_range: vec![false; oracle.features().len()],
            oracle,
            pose_errors: PoseErrorStats::default(),
            observation_errors: None,
            association_errors: 0,
            clutter_associations: 0,
        }
    }

    /// The index of the true feature nearest to `xy` within `gate_m` ([`nearest_feature`]
    /// through the grid).
    fn nearest(&self, xy: [f64; 2], gate_m: f64) -> Option<usize> {
        self.grid.nearest_within(&xy, gate_m).map(|(i, _)| i)
    }

    /// The true pose at `t_s`.
    pub fn pose_at(&self, t_s: f64) -> Option<Pose2> {
        self.oracle.pose_at(t_s)
    }

    /// Scores one processed beam's associations: the observation's error against the true
    /// geometry, and whether it was paired with the mapped feature of another true feature
    /// (an association error; returned as the count for this beam) or came from no true
    /// feature (clutter).
    /// `frame` places the filter's (submap) frame in the world; `None`: it is the world.
    pub fn on_beam(
        &mut self,
        beam: &BeamObservation,
        report: &BeamReport,
        ekf: &RadarEkf,
        frame: Option<&Pose2>,
    ) -> u32 {
        let Some(true_pose) = self.oracle.pose_at(beam.timestamp_s) else {
            return 0;
        };
        let features = self.oracle.features();
        let mut wrong = 0;
        for &(j, id) in &report.associated {
            let (Some(t), Some(f)) = (beam.targets.get(j), ekf.feature(id)) else {
                continue;
            };
            let xy = true_pose.point_at(t.range_m, t.bearing_rad);
            let seen = self.nearest(xy, SEEN_GATE_M);
            let xy_map = frame.map_or([f.x_m, f.y_m], |fr| {
                slam_graph::se2::transform_point(fr, [f.x_m, f.y_m])
            });
            let mapped = self.nearest(xy_map, MAPPED_GATE_M);
            if let Some(tf) = seen.and_then(|a| features.get(a)) {
                let rb = range_bearing(&true_pose, [tf.x_m, tf.y_m]);
                self.observation_errors
                    .get_or_insert_with(Default::default)
                    .add(
                        t.range_m - rb.range_m,
                        wrap_angle(t.bearing_rad - rb.bearing_rad),
                    );
            }
            match (seen, mapped) {
                (Some(a), Some(b)) if a != b => {
                    self.association_errors += 1;
                    wrong += 1;
                }
                (None, _) => self.clutter_associations += 1,
                _ => {}
            }
        }
        wrong
    }

    /// Scores the pose (in the world, with its covariance) at the end of a rotation at
    /// `time_s` (when the filter has odometry) into `d`, and marks the true features within
    /// `max_range_m` as having come into range.
    #[allow(clippy::too_many_arguments)]
    pub fn on_rotation(
        &mut self,
        time_s: f64,
        pose: Pose2,
        cov: nalgebra::Matrix3<f64>,
        has_odometry: bool,
        max_range_m: f64,
        d: &mut RotationDiagnostics,
    ) {
        let Some(truth) = self.oracle.pose_at(time_s) else {
            return;
        };
        if has_odometry {
            let nees = slam_filter::health::pose_nees(&pose, &cov, &truth).ok();
            d.pose_error_x_m = Some(pose.x - truth.x);
            d.pose_error_y_m = Some(pose.y - truth.y);
            d.pose_error_theta_rad = Some(wrap_angle(pose.theta - truth.theta));
            d.pose_sigma_x_m = Some(cov[(0, 0)].max(0.0).sqrt());
            d.pose_sigma_y_m = Some(cov[(1, 1)].max(0.0).sqrt());
            d.pose_sigma_theta_rad = Some(cov[(2, 2)].max(0.0).sqrt());
            d.pose_nees = nees;
            self.pose_errors
                .add(&pose, [cov[(0, 0)], cov[(1, 1)], cov[(2, 2)]], &truth, nees);
        }
        for (flag, f) in self.in_range.iter_mut().zip(self.oracle.features()) {
            if (f.x_m - truth.x).hypot(f.y_m - truth.y) <= max_range_m {
                *flag = true;
            }
        }
    }

    /// Writes the run's scores into `summary`: pose errors, observation errors, association
    /// errors and the final map against the true features.
    /// `features` is the map in the world; `loss_db` the filter's radar loss.
    pub fn score(
        &self,
        features: &[FeatureEstimate],
        loss_db: f64,
        initial_rho: f64,
        initial_alpha: f64,
        summary: &mut PipelineSummary,
    ) {
        summary.pose = Some(self.pose_errors.clone());
        summary.observation_errors = self.observation_errors;
        summary.association_errors = self.association_errors;
        summary.clutter_associations = self.clutter_associations;
        let in_range = self.in_range.iter().filter(|&&b| b).count();
        let mut score = score_map(
            features,
            self.oracle.features(),
            in_range,
            MAPPED_GATE_M,
            initial_rho,
            initial_alpha,
        );
        score.loss_db = loss_db;
        if let Some(true_loss) = self.oracle.loss_db() {
            score.true_loss_db = Some(true_loss);
            score.mean_rho_error_gauge_fixed = Some(gauge_fixed_rho_error(
                features,
                self.oracle.features(),
                MAPPED_GATE_M,
                score.loss_db - true_loss,
            ));
        }
        summary.map = Some(score);
    }
}
