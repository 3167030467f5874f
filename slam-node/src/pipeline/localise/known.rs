//! The saved map's features in the map's frame, and the few near the vehicle that the
//! filter holds as known landmarks, swapped in and out as the vehicle moves. No IO.

use std::collections::{HashMap, HashSet};

use nalgebra::{Matrix2, Matrix3};
use radar_model::geometry::Pose2;
use slam_filter::{FeatureId, SubmapFeature};
use slam_graph::se2::{compose_covariance, inverse, rotation, transform_point};
use slam_map::model::unpack2;
use slam_map::Map;

use crate::pipeline::DaemonEkf;

/// A saved feature in the map's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldFeature {
    /// The submap it was mapped in.
    pub submap: usize,
    /// Position in the map's frame (m).
    pub xy: [f64; 2],
    /// Its covariance in the submap's frame turned into the map's (m^2): the submap
    /// frame's own uncertainty is not in it (see [`MapFeatures::frame_covariance_at`]).
    pub xy_cov: Matrix2<f64>,
    /// Material logits.
    pub uv: [f64; 2],
    /// Their covariance.
    pub uv_cov: Matrix2<f64>,
    /// Observations the mapping run used.
    pub hits: u64,
}

impl WorldFeature {
    /// As the loop-closure verifier takes features (in the map's frame).
    pub fn as_submap_feature(&self, id: u64) -> SubmapFeature {
        SubmapFeature {
            id: FeatureId(id),
            xy: self.xy,
            xy_cov: self.xy_cov,
            uv: self.uv,
            uv_cov: self.uv_cov,
            hits: self.hits,
        }
    }
}

/// Every feature of a map in its frame, and the submap frames.
#[derive(Debug, Clone)]
pub struct MapFeatures {
    /// The features.
    pub features: Vec<WorldFeature>,
    /// Each submap's frame in the map's frame and its covariance.
    pub frames: Vec<(Pose2, Matrix3<f64>)>,
    /// Where each submap ended (the next one's frame; the last one's end pose).
    pub ends: Vec<Pose2>,
    /// Each submap's end pose in its own frame and its covariance there (the mapping
    /// vehicle's uncertainty relative to the frame when the submap closed).
    pub end_local: Vec<(Pose2, Matrix3<f64>)>,
    /// Where the vehicle drove through each submap, in the map's frame (the map's paths,
    /// format version 4); empty where the map holds none ([`MapFeatures::path_of`] then
    /// takes the line from the frame to the end).
    pub paths: Vec<Vec<[f64; 2]>>,
}

/// A covariance made symmetric positive definite enough to enter the filter: at least
/// `floor` on the diagonal (the saved marginal of a feature seen many times can be tiny).
fn floored(m: Matrix2<f64>, floor: f64) -> Matrix2<f64> {
    let s = 0.5 * (m + m.transpose());
    let e = s.symmetric_eigen();
    let mut vals = e.eigenvalues;
    for v in vals.iter_mut() {
        *v = v.max(floor);
    }
    e.eigenvectors * Matrix2::from_diagonal(&vals) * e.eigenvectors.transpose()
}

impl MapFeatures {
    /// The map's features placed by their submaps' frames.
    pub fn new(map: &Map) -> Self {
        let mut features = Vec::with_capacity(map.feature_count());
        let mut frames = Vec::with_capacity(map.submaps.len());
        let mut ends = Vec::with_capacity(map.submaps.len());
        let mut end_local = Vec::with_capacity(map.submaps.len());
        let mut paths = Vec::with_capacity(map.submaps.len());
        for (k, s) in map.submaps.iter().enumerate() {
            let frame = Pose2::from(s.frame);
            paths.push(map.path_points(k).map_or_else(Vec::new, |path| {
                path.iter().map(|q| transform_point(&frame, *q)).collect()
            }));
            let r = rotation(frame.theta);
            frames.push((frame, slam_map::model::unpack3(&s.frame_cov)));
            ends.push(slam_graph::se2::compose(&frame, &Pose2::from(s.end_pose)));
            end_local.push((
                Pose2::from(s.end_pose),
                slam_map::model::unpack3(&s.end_cov),
            ));
            for f in &s.features {
                features.push(WorldFeature {
                    submap: k,
                    xy: transform_point(&frame, f.xy),
                    xy_cov: floored(r * unpack2(&f.xy_cov) * r.transpose(), 1e-6),
                    uv: f.uv,
                    uv_cov: floored(unpack2(&f.uv_cov), 1e-6),
                    hits: f.hits,
                });
            }
        }
        Self {
            features,
            frames,
            ends,
            end_local,
            paths,
        }
    }

    /// Where the vehicle drove through submap `k` in the map's frame: the saved path, or
    /// without one (a map before format version 4) the line from its frame to its end. A
    /// drive's first submap's frame is the map's origin, not where the vehicle started,
    /// so that line can miss its drive by far.
    pub fn path_of(&self, k: usize) -> std::borrow::Cow<'_, [[f64; 2]]> {
        match self.paths.get(k).filter(|p| !p.is_empty()) {
            Some(p) => std::borrow::Cow::Borrowed(p),
            None => std::borrow::Cow::Owned(match (self.frames.get(k), self.ends.get(k)) {
                (Some((a, _)), Some(b)) => vec![[a.x, a.y], [b.x, b.y]],
                _ => Vec::new(),
            }),
        }
    }

    /// The submap whose stretch of drive ([`MapFeatures::path_of`]) passes nearest `xy`.
    pub fn nearest_submap(&self, xy: [f64; 2]) -> Option<usize> {
        let dist = |k: usize| polyline_distance(xy, &self.path_of(k));
        (0..self.frames.len()).min_by(|&i, &j| dist(i).total_cmp(&dist(j)))
    }

    /// The uncertainty the map adds to a pose estimated against its features near `pose`:
    /// errors the features share, which matching many of them does not average away. The
    /// mapping vehicle's pose where it passed nearest (its frame's covariance in the map,
    /// composed with its covariance in the frame, grown linearly along the submap's
    /// stretch from zero at the frame to the saved end covariance) is carried to `pose`:
    /// the features it mapped there are off by its error, rigidly.
    pub fn frame_covariance_at(&self, pose: &Pose2) -> Matrix3<f64> {
        let Some(k) = self.nearest_submap([pose.x, pose.y]) else {
            return Matrix3::zeros();
        };
        self.shared_covariance(k, pose, &self.frames[k].1)
    }

    /// Where `pose` (in the map's frame, with the filter's covariance `cov` against the
    /// map's features near it) is in the nearest submap's frame: `(submap, pose in its
    /// frame, covariance there)`. The covariance adds the mapping vehicle's uncertainty
    /// along the submap's stretch (shared by the features there), not the frame's own.
    pub fn in_nearest_submap(
        &self,
        pose: &Pose2,
        cov: &Matrix3<f64>,
    ) -> Option<(usize, Pose2, Matrix3<f64>)> {
        let k = self.nearest_submap([pose.x, pose.y])?;
        let frame = self.frames[k].0;
        let world = cov + self.shared_covariance(k, pose, &Matrix3::zeros());
        let back = inverse(&frame);
        let rel = slam_graph::se2::compose(&back, pose);
        let rel_cov = compose_covariance(&back, &Matrix3::zeros(), pose, &world);
        Some((k, rel, 0.5 * (rel_cov + rel_cov.transpose())))
    }

    /// The error the features near `pose` in submap `k` share: the frame's (`frame_cov`)
    /// and the mapping vehicle's along the stretch, carried to `pose`.
    fn shared_covariance(&self, k: usize, pose: &Pose2, frame_cov: &Matrix3<f64>) -> Matrix3<f64> {
        let frame = self.frames[k].0;
        let frame_cov = *frame_cov;
        let (end, end_cov) = self.end_local[k];
        let local = slam_graph::se2::compose(&inverse(&frame), pose);
        // Where along the stretch (0 at the frame, 1 at the end) the vehicle is.
        let len2 = end.x * end.x + end.y * end.y;
        let s = if len2 > 0.0 {
            ((local.x * end.x + local.y * end.y) / len2).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let mapper = Pose2::new(s * end.x, s * end.y, s * end.theta);
        let mapper_cov = s * 0.5 * (end_cov + end_cov.transpose());
        let mapper_world = slam_graph::se2::compose(&frame, &mapper);
        let mapper_world_cov = compose_covariance(&frame, &frame_cov, &mapper, &mapper_cov);
        let rel = slam_graph::se2::compose(&inverse(&mapper_world), pose);
        compose_covariance(&mapper_world, &mapper_world_cov, &rel, &Matrix3::zeros())
    }
}

/// The distance from `p` to the segment `a`-`b`.
/// Distance (m) from `p` to the polyline `path` (infinite for an empty one).
pub(crate) fn polyline_distance(p: [f64; 2], path: &[[f64; 2]]) -> f64 {
    match path {
        [] => f64::INFINITY,
        [a] => (p[0] - a[0]).hypot(p[1] - a[1]),
        _ => path
            .windows(2)
            .map(|w| segment_distance(w[0], w[1], p))
            .fold(f64::INFINITY, f64::min),
    }
}

/// Points `spacing` (m) apart by distance travelled along the polyline `path`, from its
/// first vertex up to, not including, its last: the spacing runs on across vertices, so a
/// saved path's vertices every [`slam_map::PATH_SPACING_M`] give a point every `spacing`,
/// not one per vertex. At most [`MAX_PATH_SAMPLES`] points: a longer path (a map file's
/// far-flung but finite vertices) is sampled more coarsely, at no unbounded cost.
pub(crate) fn path_samples(path: &[[f64; 2]], spacing: f64) -> Vec<[f64; 2]> {
    let finite_len = |w: &[[f64; 2]]| {
        let len = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
        if len.is_finite() {
            len
        } else {
            0.0
        }
    };
    let total: f64 = path.windows(2).map(finite_len).sum();
    let step = if spacing.is_finite() && spacing > 0.0 {
        spacing.max(total / MAX_PATH_SAMPLES as f64)
    } else {
        f64::INFINITY
    };
    let mut out = Vec::new();
    // Distance along the current segment at which the next point falls.
    let mut next = 0.0;
    for w in path.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        if !len.is_finite() || !step.is_finite() {
            // No distance to run along: the vertex itself.
            out.push(a);
            next = 0.0;
            continue;
        }
        while next < len && out.len() < 2 * MAX_PATH_SAMPLES {
            let t = next / len;
            out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            next += step;
        }
        next = (next - len).max(0.0);
    }
    out
}

/// The most points [`path_samples`] gives along a path, one more for rounding, plus the
/// vertices it cannot run along (a non-finite segment); a safety net stops it at twice this.
/// A saved path holds at most [`slam_map::MAX_PATH_POINTS`] vertices 2 m apart: 8.2 km,
/// 820 places at 10 m.
pub(crate) const MAX_PATH_SAMPLES: usize = 8192;

/// Distance (m) from `p` to the segment from `a` to `b`.
pub(crate) fn segment_distance(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * d[0]).hypot(p[1] - a[1] - t * d[1])
}

/// The map's features the filter holds now.
#[derive(Debug, Clone, Default)]
pub struct Loaded {
    /// Map feature index -> the filter's id.
    ids: HashMap<usize, FeatureId>,
    /// Features the filter retired (not seen where they should be): not put back until
    /// the vehicle has left them behind.
    gone: HashSet<usize>,
    /// Where the last swap was made.
    last_swap: Option<Pose2>,
    /// Features put in and taken out over the run.
    pub inserted: u64,
    /// Taken out.
    pub removed: u64,
    /// Refused by the filter (a covariance not positive definite).
    pub refused: u64,
}

/// How the swap chooses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwapRule {
    /// Features held at most (the nearest).
    pub max_loaded: usize,
    /// Features further than this from the vehicle are not held (m).
    pub radius_m: f64,
    /// A feature held stays until it is not among the nearest `max_loaded * keep_factor`.
    pub keep_factor: f64,
    /// Swap after the vehicle moved this far (m) or turned a tenth of it (rad).
    pub every_m: f64,
}

impl Loaded {
    /// How many the filter holds.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// Whether none is held.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// Forgets every feature (the filter was replaced).
    pub fn clear(&mut self) {
        self.ids.clear();
        self.gone.clear();
        self.last_swap = None;
    }

    /// Puts the nearest features into the filter and takes out those left behind, when
    /// the vehicle moved far enough since the last swap (or `force`).
    pub fn swap(
        &mut self,
        ekf: &mut DaemonEkf,
        map: &MapFeatures,
        rule: &SwapRule,
        time_s: f64,
        force: bool,
    ) {
        let pose = ekf.pose();
        let moved = self.last_swap.is_none_or(|p| {
            (p.x - pose.x).hypot(p.y - pose.y) >= rule.every_m
                || radar_model::geometry::wrap_angle(p.theta - pose.theta).abs()
                    >= 0.1 * rule.every_m
        });
        if !(force || moved) {
            return;
        }
        self.last_swap = Some(pose);
        // Retired by the filter: remembered as gone.
        let state = ekf.state();
        let retired: Vec<usize> = self
            .ids
            .iter()
            .filter(|(_, id)| state.slot_of(**id).is_none())
            .map(|(k, _)| *k)
            .collect();
        for k in retired {
            self.ids.remove(&k);
            self.gone.insert(k);
        }
        let mut near: Vec<(f64, usize)> = map
            .features
            .iter()
            .enumerate()
            .filter_map(|(k, f)| {
                let d = (f.xy[0] - pose.x).hypot(f.xy[1] - pose.y);
                (d <= rule.radius_m).then_some((d, k))
            })
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0));
        let keep_n = ((rule.max_loaded as f64) * rule.keep_factor).ceil() as usize;
        let keep: HashSet<usize> = near.iter().take(keep_n).map(|(_, k)| *k).collect();
        self.gone.retain(|k| keep.contains(k));
        let out: Vec<(usize, FeatureId)> = self
            .ids
            .iter()
            .filter(|(k, _)| !keep.contains(k))
            .map(|(k, id)| (*k, *id))
            .collect();
        for (k, id) in out {
            if ekf.remove_feature(id).is_ok() {
                self.removed += 1;
            }
            self.ids.remove(&k);
        }
        for (_, k) in near {
            if self.ids.len() >= rule.max_loaded {
                break;
            }
            if self.ids.contains_key(&k) || self.gone.contains(&k) {
                continue;
            }
            let f = &map.features[k];
            match ekf.insert_known_feature(f.xy, &f.xy_cov, f.uv, &f.uv_cov, time_s) {
                Ok(id) => {
                    self.ids.insert(k, id);
                    self.inserted += 1;
                }
                Err(_) => self.refused += 1,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_segment_distance_clamps_to_the_ends() {
        assert!((segment_distance([0.0, 0.0], [10.0, 0.0], [5.0, 3.0]) - 3.0).abs() < 1e-12);
        assert!((segment_distance([0.0, 0.0], [10.0, 0.0], [13.0, 4.0]) - 5.0).abs() < 1e-12);
        assert!((segment_distance([1.0, 1.0], [1.0, 1.0], [4.0, 5.0]) - 5.0).abs() < 1e-12);
    }

    /// Two submaps along +x, the second's frame turned by `turn`; `end_cov` on each.
    fn two_submaps(turn: f64, end_var: f64) -> Map {
        let feature = |x: f64| slam_map::MapFeature {
            id: x as u64,
            xy: [x, 5.0],
            xy_cov: [0.01, 0.0, 0.01],
            uv: [0.0, 0.0],
            uv_cov: [0.1, 0.0, 0.1],
            hits: 5,
        };
        let submap = |frame: slam_map::Pose| slam_map::MapSubmap {
            frame,
            frame_cov: [0.04, 0.0, 0.0, 0.04, 0.0, 1e-4],
            end_pose: slam_map::Pose {
                x: 50.0,
                y: 0.0,
                theta: 0.0,
            },
            end_cov: [end_var, 0.0, 0.0, end_var, 0.0, end_var * 1e-2],
            end_s: 1.0,
            loss_db: 0.0,
            features: (0..5).map(|i| feature(10.0 * f64::from(i))).collect(),
            descriptor: None,
        };
        Map {
            created_unix_s: 0,
            source: String::new(),
            profile: slam_map::MapProfile::from(&radar_model::profile::CTS350X),
            submaps: vec![
                submap(slam_map::Pose::ORIGIN),
                submap(slam_map::Pose {
                    x: 50.0,
                    y: 0.0,
                    theta: turn,
                }),
            ],
            loops: Vec::new(),
            drive_starts: Vec::new(),
            joins: Vec::new(),
            scans: Vec::new(),
            paths: Vec::new(),
        }
    }

    #[test]
    fn a_pose_in_the_nearest_submap_is_the_pose_seen_from_its_frame_with_its_covariance() {
        let cov = Matrix3::new(0.09, 0.02, 0.001, 0.02, 0.04, -0.002, 0.001, -0.002, 4e-4);
        let pose = Pose2::new(70.0, 8.0, 0.3);
        for (turn, end_var) in [(0.0, 0.0), (0.4, 0.0), (0.4, 0.25)] {
            let features = MapFeatures::new(&two_submaps(turn, end_var));
            let (k, rel, rel_cov) = features.in_nearest_submap(&pose, &cov).unwrap();
            assert_eq!(k, 1);
            let frame = features.frames[1].0;
            let back = slam_graph::se2::compose(&frame, &rel);
            assert!((back.x - pose.x).hypot(back.y - pose.y) < 1e-9);
            assert!((back.theta - pose.theta).abs() < 1e-12);
            assert!((rel_cov - rel_cov.transpose()).norm() < 1e-15);
            assert!(rel_cov.cholesky().is_some());
            // The filter's covariance turned into the frame, checked against the numeric
            // Jacobian of the pose seen from the frame; the mapper's stretch only adds.
            let h = 1e-6;
            let mut j = Matrix3::zeros();
            for c in 0..3 {
                let mut d = [0.0; 3];
                d[c] = h;
                let moved = Pose2::new(pose.x + d[0], pose.y + d[1], pose.theta + d[2]);
                let r = slam_graph::se2::compose(&inverse(&frame), &moved);
                j[(0, c)] = (r.x - rel.x) / h;
                j[(1, c)] = (r.y - rel.y) / h;
                j[(2, c)] = (r.theta - rel.theta) / h;
            }
            let turned = j * cov * j.transpose();
            let extra = rel_cov - turned;
            if end_var == 0.0 {
                assert!(extra.norm() < 1e-8, "{extra}");
            } else {
                let e = nalgebra::SymmetricEigen::new(0.5 * (extra + extra.transpose()));
                assert!(
                    e.eigenvalues.min() > -1e-9 && e.eigenvalues.max() > 1e-3,
                    "{extra}"
                );
            }
        }
    }

    #[test]
    fn a_floored_covariance_is_positive_definite_and_keeps_a_large_one() {
        let tiny = Matrix2::new(1e-12, 0.0, 0.0, 0.0);
        assert!(floored(tiny, 1e-6).cholesky().is_some());
        let big = Matrix2::new(2.0, 0.5, 0.5, 1.0);
        assert!((floored(big, 1e-6) - big).norm() < 1e-12);
    }
}
