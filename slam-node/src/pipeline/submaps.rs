//! Local submaps joined by the global layer, as the pipeline runs them.
//!
//! The filter ([`super::DaemonEkf`]) always holds the current submap, in that submap's frame;
//! this stage owns everything else: the frozen submaps, every submap frame's estimate in the
//! world (the global layer's latest solution, and the chain of switch poses for frames newer
//! than it), the switch rule, and the record of which submap each rotation's pose was
//! estimated in, so that the trajectory can be re-published with the final frames. The
//! global layer runs on its own thread ([`slam_graph::GlobalLayer`]); this stage only
//! `try_send`s frozen submaps and `try_recv`s solutions, once a rotation.

use std::sync::Arc;

use nalgebra::Matrix3;
use radar_model::geometry::Pose2;
use radar_model::material::Material;
use slam_filter::{FeatureEstimate, FrozenSubmap, SubmapFeature};
use slam_graph::se2::{compose, compose_covariance, rotation};
use slam_graph::{GlobalLayer, GlobalMap, GlobalStats, LoopClosure, ScanAccumulator};
use tracing::{info, warn};

use super::ekf::DaemonEkf;
use super::settings::SubmapOptions;
use crate::output::{MapFeature, MapSnapshot, PoseSample};

/// How long a run paced by its pipeline waits for the global layer to join a submap
/// ([`SubmapOptions::wait_for_joins`]) before going on without the solution.
const JOIN_WAIT: std::time::Duration = std::time::Duration::from_secs(60);

/// What the submaps did over a run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SubmapSummary {
    /// Submaps started (the current one included).
    pub submaps: usize,
    /// Loop closures in the global graph at the end.
    pub loop_closures: usize,
    /// The global layer's totals.
    pub global: GlobalStats,
    /// Features held in frozen submaps at the end.
    pub frozen_features: usize,
    /// Bytes the frozen submaps hold.
    pub frozen_bytes: usize,
    /// Solutions received from the global layer during the run.
    pub solutions: u64,
    /// Frozen submaps the layer's queue refused.
    pub refused_sends: u64,
    /// Features in the largest submap when it was closed.
    pub largest_submap_features: usize,
    /// The final (globally optimised) trajectory against the truth, when it is known.
    pub optimised: Option<TrajectoryScore>,
    /// Loop closures whose transform agrees with the truth (within 1 m and 2 degrees), and
    /// those that do not (false loop closures), when the truth is known.
    pub loops_true: usize,
    /// False loop closures.
    pub loops_false: usize,
    /// Closures over every true revisit (within 10 m, at least 300 m of driving apart),
    /// when the truth is known.
    pub revisits: Option<slam_graph::RevisitScore>,
    /// Extending a saved map: the closures from this run's submaps to the saved ones.
    pub loops_to_saved: usize,
    /// The graph's edges against the truth, when it is known: the chain (each submap's
    /// end pose in its own frame), the near links and the loop closures, each as it
    /// entered the graph.
    pub edges_vs_truth: Option<EdgesVsTruth>,
}

/// The global graph's edges against the truth ([`SubmapSummary::edges_vs_truth`]): how
/// far each kind of edge is from the true relative pose of its two frames, against the
/// covariance it was given.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EdgesVsTruth {
    /// Each submap's end pose in its frame, with the filter's covariance of it.
    pub chain: EdgeScore,
    /// Near links ([`slam_graph::GlobalMap::links`]), with the covariance they entered
    /// the graph with (the registration's times `[submaps] near_link_covariance_scale`).
    pub links: EdgeScore,
    /// Loop closures.
    pub loops: EdgeScore,
}

/// One kind of edge against the truth ([`EdgesVsTruth`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EdgeScore {
    /// Edges scored (those whose covariance is positive definite).
    pub count: usize,
    /// Sums of (error / its standard deviation)^2 in x, y and heading, in the earlier
    /// frame.
    pub normalised_sq_sum: [f64; 3],
    /// Sum of heading errors squared (rad^2).
    pub heading_sq_sum: f64,
    /// Sum of the edges' NEES (3 dof, full covariance).
    pub nees_sum: f64,
}

impl EdgeScore {
    /// Scores one edge: `estimate` with covariance `cov` against the true `truth`, both
    /// the later frame in the earlier one's. An edge whose covariance is not positive
    /// definite is not counted.
    pub fn add(&mut self, estimate: &Pose2, cov: &Matrix3<f64>, truth: &Pose2) {
        let Ok(nees) = slam_filter::health::pose_nees(estimate, cov, truth) else {
            return;
        };
        let e = [
            estimate.x - truth.x,
            estimate.y - truth.y,
            radar_model::geometry::wrap_angle(estimate.theta - truth.theta),
        ];
        self.count += 1;
        for (d, err) in e.iter().enumerate() {
            self.normalised_sq_sum[d] += err * err / cov[(d, d)];
        }
        self.heading_sq_sum += e[2] * e[2];
        self.nees_sum += nees;
    }

    /// RMS of each component's error over its standard deviation (x, y, heading); 1 for
    /// an edge as good as its covariance says.
    pub fn normalised_rms(&self) -> Option<[f64; 3]> {
        (self.count > 0).then(|| {
            self.normalised_sq_sum
                .map(|s| (s / self.count as f64).sqrt())
        })
    }

    /// RMS heading error (rad).
    pub fn heading_rms_rad(&self) -> Option<f64> {
        (self.count > 0).then(|| (self.heading_sq_sum / self.count as f64).sqrt())
    }

    /// Mean NEES (3 dof: 3 for a consistent edge).
    pub fn mean_nees(&self) -> Option<f64> {
        (self.count > 0).then(|| self.nees_sum / self.count as f64)
    }
}

/// A whole trajectory against the truth.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TrajectoryScore {
    /// Poses compared.
    pub poses: usize,
    /// RMS position error (m).
    pub rms_m: f64,
    /// Largest position error (m).
    pub max_m: f64,
    /// Final position error (m).
    pub final_m: f64,
    /// RMS heading error (rad).
    pub rms_heading_rad: f64,
    /// Final heading error (rad).
    pub final_heading_rad: f64,
    /// Mean pose NEES (3 dof).
    pub mean_nees: f64,
    /// Share of poses with NEES inside the 3-dof 99 % bound (11.34).
    pub inside_99: f64,
    /// The poses' NEES against its two-sided 95 % band.
    pub nees_band: super::scores::NeesBand,
    /// Mean translational drift over segments of 100, 200, ..., 800 m (% of the segment),
    /// the metric of the radar odometry literature (`slam_filter::drift`, as the KITTI devkit
    /// and the Boreas benchmark define it); `None` when the drive is shorter.
    pub drift_percent: Option<f64>,
    /// Mean rotational drift over the same segments (degrees per 100 m).
    pub drift_deg_per_100m: Option<f64>,
    /// Segments the drift averages.
    pub drift_segments: usize,
    /// Path length of the true trajectory (m).
    pub length_m: f64,
}

/// Scores `estimate` against `truth` (same length, same times).
pub fn score_trajectory(estimate: &[PoseSample], truth: &[Pose2]) -> TrajectoryScore {
    let n = estimate.len().min(truth.len());
    if n == 0 {
        return TrajectoryScore::default();
    }
    let mut s = TrajectoryScore {
        poses: n,
        ..TrajectoryScore::default()
    };
    let (mut se, mut sh, mut nees, mut inside) = (0.0, 0.0, 0.0, 0usize);
    for (e, t) in estimate.iter().zip(truth) {
        let d = (e.x_m - t.x).hypot(e.y_m - t.y);
        let h = radar_model::geometry::wrap_angle(e.theta_rad - t.theta);
        se += d * d;
        sh += h * h;
        s.max_m = s.max_m.max(d);
        s.final_m = d;
        s.final_heading_rad = h;
        let cov = Matrix3::from_fn(|r, c| e.covariance[r][c]);
        if let Ok(v) =
            slam_filter::health::pose_nees(&Pose2::new(e.x_m, e.y_m, e.theta_rad), &cov, t)
        {
            nees += v;
            s.nees_band.add(v);
            if v <= 11.34 {
                inside += 1;
            }
        }
    }
    s.rms_m = (se / n as f64).sqrt();
    s.rms_heading_rad = (sh / n as f64).sqrt();
    s.mean_nees = nees / n as f64;
    s.inside_99 = inside as f64 / n as f64;
    s.length_m = slam_filter::drift::distance_travelled(&truth[..n])
        .last()
        .copied()
        .unwrap_or(0.0);
    let estimate: Vec<Pose2> = estimate[..n]
        .iter()
        .map(|e| Pose2::new(e.x_m, e.y_m, e.theta_rad))
        .collect();
    if let Ok(Some(d)) = slam_filter::drift::odometry_drift(&truth[..n], &estimate) {
        s.drift_percent = Some(d.translation_percent);
        s.drift_deg_per_100m = Some(d.rotation_deg_per_100m);
        s.drift_segments = d.segments;
    }
    s
}

/// The submap stage.
#[derive(Debug)]
pub struct SubmapRun {
    options: SubmapOptions,
    layer: Option<GlobalLayer>,
    frozen: Vec<Arc<FrozenSubmap>>,
    frames: Vec<Pose2>,
    frame_covs: Vec<Matrix3<f64>>,
    version: u64,
    driven_m: f64,
    last_local: Option<Pose2>,
    history: Vec<(f64, u32, Pose2, Matrix3<f64>)>,
    summary: SubmapSummary,
    /// Loop closures and near links the layer reported adding to its graph so far (for a
    /// map saved mid-run: the map keeps both among its loop edges, docs/map-format.md).
    loops: Vec<LoopClosure>,
    /// The current submap's scan (radar odometry's clouds), handed over with it.
    scan: ScanAccumulator,
    /// The first submap of this run: 0, or the saved map's submap count when the run
    /// extends a saved map ([`SubmapRun::resumed`]).
    first_new: usize,
    /// The first submap of every drive after the first (the saved map's, then this run's).
    drive_starts: Vec<usize>,
    /// The joins of later drives to earlier ones (the saved map's, then this run's).
    joins: Vec<LoopClosure>,
    /// Each frozen submap's scan as handed to the global layer (`None`: it kept none), for
    /// the saved map.
    scans: Vec<Option<Arc<Vec<[f64; 2]>>>>,
    /// The saved submaps' paths when the run extends a saved map (this run's are derived
    /// from `history`: [`SubmapRun::paths`]).
    saved_paths: Vec<Vec<[f64; 2]>>,
    /// The current submap's frame chained from this run's first by the switch poses alone,
    /// never by the global layer's solutions: the frame of the run's odometry.
    odometry_frame: Pose2,
}

/// A saved map to go on from, as [`SubmapRun::resumed`] takes it.
#[derive(Debug)]
pub struct Resumed {
    /// The global layer holding the saved graph and the new drive's first frame
    /// ([`slam_graph::GlobalMap::resume`]).
    pub layer: slam_graph::GlobalMap,
    /// The saved submaps.
    pub frozen: Vec<Arc<FrozenSubmap>>,
    /// Their frames and covariances, then the new drive's first frame and its covariance.
    pub frames: Vec<(Pose2, Matrix3<f64>)>,
    /// The saved map's drive starts, then this run's (the saved submap count).
    pub drive_starts: Vec<usize>,
    /// The saved submaps' scans, where the map kept them.
    pub scans: Vec<Option<Arc<Vec<[f64; 2]>>>>,
    /// The saved submaps' paths (empty where the map holds none).
    pub paths: Vec<Vec<[f64; 2]>>,
}

/// `cov` of a pose in a frame, re-expressed with the frame at `frame` (covariance
/// `frame_cov`, independent).
fn world_pose(
    frame: &Pose2,
    frame_cov: &Matrix3<f64>,
    local: &Pose2,
    cov: &Matrix3<f64>,
) -> (Pose2, Matrix3<f64>) {
    (
        compose(frame, local),
        compose_covariance(frame, frame_cov, local, cov),
    )
}

impl SubmapRun {
    /// Starts the stage and the global layer's thread (when loop closure or the layer is
    /// on; the chain of frames is kept either way).
    pub fn new(options: SubmapOptions) -> std::io::Result<Self> {
        Ok(Self {
            layer: Some(GlobalLayer::spawn(options.global)?),
            options,
            frozen: Vec::new(),
            frames: vec![Pose2::new(0.0, 0.0, 0.0)],
            frame_covs: vec![Matrix3::zeros()],
            version: 0,
            driven_m: 0.0,
            last_local: None,
            history: Vec::new(),
            loops: Vec::new(),
            scan: ScanAccumulator::new(&options.global.scans),
            summary: SubmapSummary {
                submaps: 1,
                ..SubmapSummary::default()
            },
            first_new: 0,
            drive_starts: Vec::new(),
            joins: Vec::new(),
            scans: Vec::new(),
            saved_paths: Vec::new(),
            odometry_frame: Pose2::new(0.0, 0.0, 0.0),
        })
    }

    /// The stage going on from a saved map: its submaps frozen, the current submap the new
    /// drive's first, at the frame the join placed; the global layer's thread starts on
    /// the resumed layer.
    pub fn resumed(options: SubmapOptions, r: Resumed) -> std::io::Result<Self> {
        let first_new = r.frozen.len();
        let joins = r.layer.joins().to_vec();
        let loops = r.layer.loops().to_vec();
        let (frames, frame_covs): (Vec<Pose2>, Vec<Matrix3<f64>>) = r.frames.into_iter().unzip();
        let odometry_frame = frames.last().copied().unwrap_or(Pose2::new(0.0, 0.0, 0.0));
        Ok(Self {
            layer: Some(GlobalLayer::spawn_with(r.layer)?),
            options,
            frozen: r.frozen,
            frames,
            frame_covs,
            version: 0,
            driven_m: 0.0,
            last_local: None,
            history: Vec::new(),
            loops,
            scan: ScanAccumulator::new(&options.global.scans),
            summary: SubmapSummary {
                submaps: first_new + 1,
                ..SubmapSummary::default()
            },
            first_new,
            drive_starts: r.drive_starts,
            joins,
            scans: r.scans,
            saved_paths: r.paths,
            odometry_frame,
        })
    }

    /// The first submap of this run (0 unless it extends a saved map).
    pub fn first_new(&self) -> usize {
        self.first_new
    }

    /// The index of the current submap.
    pub fn current(&self) -> usize {
        self.frames.len() - 1
    }

    /// The current submap's frame in the world and its covariance.
    pub fn frame(&self) -> (Pose2, Matrix3<f64>) {
        let k = self.current();
        (self.frames[k], self.frame_covs[k])
    }

    /// A pose of the current submap in the world. While the first submap runs its frame is
    /// the world's and the pose is returned as it is.
    pub fn to_world(&self, local: &Pose2, cov: &Matrix3<f64>) -> (Pose2, Matrix3<f64>) {
        if self.current() == 0 {
            return (*local, *cov);
        }
        let (f, fc) = self.frame();
        world_pose(&f, &fc, local, cov)
    }

    /// A pose of the current submap in the frame of the run's odometry: the submaps'
    /// frames chained by their switch poses only, the global layer's corrections left out
    /// (the pose a radar odometry's drift is measured on; the published pose takes the
    /// corrections as they come).
    pub fn to_odometry(&self, local: &Pose2) -> Pose2 {
        compose(&self.odometry_frame, local)
    }

    /// A point of the current submap in the world.
    pub fn point_to_world(&self, xy: [f64; 2]) -> [f64; 2] {
        if self.current() == 0 {
            return xy;
        }
        slam_graph::se2::transform_point(&self.frames[self.current()], xy)
    }

    /// Takes the global layer's newest solution, if any: the frames it covers are replaced,
    /// newer ones re-chained from them.
    fn poll(&mut self) {
        let Some(layer) = self.layer.as_mut() else {
            return;
        };
        let Some(sol) = layer.poll() else {
            return;
        };
        for r in layer.take_reports() {
            self.loops.extend(r.accepted);
            self.loops.extend(r.links);
        }
        if sol.version <= self.version {
            return;
        }
        self.version = sol.version;
        self.summary.solutions += 1;
        self.summary.loop_closures = sol.loops;
        self.install(&sol.frames, &sol.covariances);
    }

    /// Takes a solution's frames (and covariances) for the frames it covers and re-chains
    /// the newer ones from them.
    fn install(&mut self, frames: &[Pose2], covariances: &[Matrix3<f64>]) {
        let n = frames.len().min(covariances.len()).min(self.frames.len());
        self.frames[..n].copy_from_slice(&frames[..n]);
        self.frame_covs[..n].copy_from_slice(&covariances[..n]);
        self.rechain(n.max(1));
    }

    /// Frames from `from` on, from their predecessors and the switch poses.
    fn rechain(&mut self, from: usize) {
        // A drive's first frame is placed by its join, not chained from the frame before.
        for k in from.max(self.first_new + 1)..self.frames.len() {
            let Some(s) = self.frozen.get(k - 1) else {
                break;
            };
            let (p, c) = world_pose(
                &self.frames[k - 1],
                &self.frame_covs[k - 1],
                &s.end_pose,
                &s.end_cov,
            );
            self.frames[k] = p;
            self.frame_covs[k] = c;
        }
    }

    /// Adds a rotation's registered cloud (in the vehicle's frame at the rotation's end) to
    /// the current submap's scan, placed by `pose`, the filter's pose in the submap then.
    pub fn add_scan(&mut self, pose: &Pose2, cloud: &[[f64; 2]]) {
        let straight = self
            .options
            .scan_max_turn_rad
            .is_none_or(|max| pose.theta.abs() <= max);
        if self.options.global.scans.enabled && straight {
            self.scan.add(pose, cloud);
        }
    }

    /// Once a rotation, after the filter's updates: records the pose, takes a new global
    /// solution, and closes the submap (starting the next) when it is full. Returns whether
    /// a new submap started.
    pub fn end_rotation(&mut self, ekf: &mut DaemonEkf, time_s: f64) -> bool {
        self.poll();
        let local = ekf.pose();
        let local_cov = ekf.pose_covariance();
        self.history
            .push((time_s, self.current() as u32, local, local_cov));
        if let Some(last) = self.last_local {
            self.driven_m += (local.x - last.x).hypot(local.y - last.y);
        }
        self.last_local = Some(local);
        if !self
            .options
            .limits
            .reached(self.driven_m, ekf.feature_count())
        {
            return false;
        }
        self.close_submap(ekf);
        true
    }

    /// Freezes the current submap, hands it to the global layer and starts the next one at
    /// the vehicle.
    fn close_submap(&mut self, ekf: &mut DaemonEkf) {
        let features = ekf.feature_count();
        let frozen = Arc::new(ekf.start_submap());
        self.summary.largest_submap_features = self.summary.largest_submap_features.max(features);
        let k = self.current();
        let (p, c) = world_pose(
            &self.frames[k],
            &self.frame_covs[k],
            &frozen.end_pose,
            &frozen.end_cov,
        );
        self.frames.push(p);
        self.frame_covs.push(c);
        self.odometry_frame = compose(&self.odometry_frame, &frozen.end_pose);
        let scan = self.scan.take();
        let scan_points = scan.len();
        let scan = (self.options.global.scans.enabled && !scan.is_empty()).then_some(scan);
        self.scans.push(scan.clone().map(Arc::new));
        if let Some(layer) = self.layer.as_mut() {
            if layer.submit_with_scan(Arc::clone(&frozen), scan)
                && self.options.wait_for_joins
                && !layer.wait_for_joins(JOIN_WAIT)
            {
                warn!(
                    submap = k,
                    waited_s = JOIN_WAIT.as_secs_f64(),
                    "the global layer has not joined the submap: going on without its solution"
                );
            }
        }
        info!(
            submap = k,
            features,
            scan_points,
            driven_m = self.driven_m,
            end_s = frozen.end_s,
            "submap closed; the next starts at the vehicle"
        );
        self.frozen.push(frozen);
        self.summary.submaps = self.frames.len();
        self.driven_m = 0.0;
        self.last_local = Some(Pose2::new(0.0, 0.0, 0.0));
        if self.options.wait_for_joins {
            // The solution waited for, installed from this rotation on.
            self.poll();
        }
    }

    /// Every feature in the world: the frozen submaps' through their frames, then the
    /// current submap's.
    pub fn world_features(&self, ekf: &DaemonEkf) -> Vec<FeatureEstimate> {
        let mut out = Vec::new();
        for (s, frame) in self.frozen.iter().zip(&self.frames) {
            out.extend(s.features.iter().map(|f| estimate_in(frame, f)));
        }
        let (frame, _) = self.frame();
        out.extend(ekf.features().into_iter().map(|f| placed(&frame, f)));
        out
    }

    /// The map in the world: frozen submaps through their frames, then the current one's.
    pub fn map_snapshot(&self, ekf: &DaemonEkf) -> MapSnapshot {
        let mut snap = MapSnapshot::from_state(ekf.state());
        let (frame, _) = self.frame();
        snap.transform(&frame);
        let mut features: Vec<MapFeature> = Vec::new();
        for (s, f) in self.frozen.iter().zip(&self.frames) {
            features.extend(s.features.iter().map(|x| MapFeature::from_submap(x, f)));
        }
        features.append(&mut snap.features);
        snap.features = features;
        snap.global = Some(crate::output::map::GlobalInfo {
            submaps: self.frames.len(),
            loop_closures: self.summary.loop_closures,
            solution: self.version,
        });
        snap
    }

    /// Scores the final trajectory and the loop closures against the truth
    /// (`truth(t)`: the true pose at time `t`). A frame is the vehicle's body at the moment
    /// its submap started, so a closure's true transform is the true relative pose of the
    /// vehicle at the two switches.
    pub fn score_against(
        &mut self,
        trajectory: &[PoseSample],
        map: Option<&GlobalMap>,
        truth: impl Fn(f64) -> Option<Pose2>,
    ) {
        let pairs: Vec<(PoseSample, Pose2)> = trajectory
            .iter()
            .filter_map(|p| truth(p.timestamp_s).map(|t| (*p, t)))
            .collect();
        let (est, tru): (Vec<PoseSample>, Vec<Pose2>) = pairs.into_iter().unzip();
        if !est.is_empty() {
            self.summary.optimised = Some(score_trajectory(&est, &tru));
        }
        let Some(map) = map else {
            return;
        };
        if self.first_new > 0 {
            // Extending: the saved submaps' times are another run's clock, so only this
            // run's own closures are scored against the truth.
            let n = self.first_new;
            for l in map.loops().iter().filter(|l| l.from >= n) {
                let t = |i: usize| -> Option<Pose2> {
                    if i == n {
                        return trajectory.first().and_then(|p| truth(p.timestamp_s));
                    }
                    truth(map.submaps().get(i - 1)?.end_s)
                };
                if let (Some(a), Some(b)) = (t(l.from), t(l.to)) {
                    let truth = slam_graph::se2::between(&a, &b);
                    if closure_agrees(&truth, l) {
                        self.summary.loops_true += 1;
                    } else {
                        self.summary.loops_false += 1;
                        warn_false_closure(&truth, l);
                    }
                }
            }
            return;
        }
        let frame_truth = |i: usize| -> Option<Pose2> {
            if i == 0 {
                return Some(Pose2::new(0.0, 0.0, 0.0));
            }
            truth(map.submaps().get(i - 1)?.end_s)
        };
        self.summary.revisits = Some(revisit_score(map, &est, &tru, &frame_truth));
        self.summary.edges_vs_truth = Some(edges_vs_truth(map, &frame_truth));
        for l in map.loops() {
            let (Some(a), Some(b)) = (frame_truth(l.from), frame_truth(l.to)) else {
                continue;
            };
            let t = slam_graph::se2::between(&a, &b);
            if closure_agrees(&t, l) {
                self.summary.loops_true += 1;
            } else {
                self.summary.loops_false += 1;
                warn_false_closure(&t, l);
            }
        }
    }

    /// Waits for the global layer to join every submap sent (end of run), installs its
    /// final solution and returns the whole trajectory re-expressed with the final frames
    /// and the run's summary.
    ///
    /// When submaps were closed during the run, the current one is closed too (if it holds
    /// features), so that the end of the drive can close a loop; a run that never filled
    /// its first submap ends as the dense filter would.
    pub fn finish(&mut self, ekf: &mut DaemonEkf) -> (Vec<PoseSample>, Option<GlobalMap>) {
        if self.current() > 0 && ekf.feature_count() > 0 {
            self.close_submap(ekf);
        }
        let map = self.layer.take().and_then(|l| {
            self.summary.refused_sends = l.refused_sends();
            l.finish()
        });
        if let Some(m) = map.as_ref() {
            let sol = m.solution(0.0);
            if sol.version > self.version {
                self.version = sol.version;
                self.summary.solutions += 1;
            }
            self.install(&sol.frames, &sol.covariances);
            self.summary.loop_closures = m.loops().len();
            self.summary.global = *m.stats();
            let n = self.first_new;
            self.summary.loops_to_saved = m
                .loops()
                .iter()
                .filter(|l| n > 0 && l.from < n && l.to >= n)
                .count();
        } else if !self.frozen.is_empty() {
            warn!("the global layer's thread ended early: the trajectory uses the chained frames");
        }
        self.summary.frozen_features = self.frozen.iter().map(|s| s.features.len()).sum();
        self.summary.frozen_bytes = self.frozen.iter().map(|s| s.heap_bytes()).sum();
        let trajectory = self
            .history
            .iter()
            .map(|(t, k, local, cov)| {
                let k = *k as usize;
                let (p, c) = if k == 0 {
                    (*local, *cov)
                } else {
                    world_pose(&self.frames[k], &self.frame_covs[k], local, cov)
                };
                PoseSample {
                    timestamp_s: *t,
                    x_m: p.x,
                    y_m: p.y,
                    theta_rad: p.theta,
                    covariance: [
                        [c[(0, 0)], c[(0, 1)], c[(0, 2)]],
                        [c[(1, 0)], c[(1, 1)], c[(1, 2)]],
                        [c[(2, 0)], c[(2, 1)], c[(2, 2)]],
                    ],
                }
            })
            .collect();
        (trajectory, map)
    }

    /// The run's summary so far.
    pub fn summary(&self) -> &SubmapSummary {
        &self.summary
    }

    /// The frozen submaps, every frame in the world (the current submap's last) with its
    /// covariance, and the loop closures the global layer reported accepting so far.
    pub fn parts(&self) -> SubmapParts<'_> {
        SubmapParts {
            frozen: &self.frozen,
            frames: &self.frames,
            frame_covs: &self.frame_covs,
            loops: &self.loops,
            drive_starts: &self.drive_starts,
            joins: &self.joins,
            scans: &self.scans,
        }
    }

    /// Where the vehicle drove through every submap, in its frame, the current one's last:
    /// a saved map's as it was loaded, this run's from the poses it recorded every rotation,
    /// a position each time the vehicle had moved [`slam_map::PATH_SPACING_M`] from the last,
    /// and a frozen submap's ending where the next one begins.
    pub fn paths(&self) -> Vec<Vec<[f64; 2]>> {
        let mut out = self.saved_paths.clone();
        out.resize(self.frames.len(), Vec::new());
        for (_, k, local, _) in &self.history {
            let Some(path) = out.get_mut(*k as usize) else {
                continue;
            };
            let moved = path
                .last()
                .is_none_or(|p| (local.x - p[0]).hypot(local.y - p[1]) >= slam_map::PATH_SPACING_M);
            if moved && local.x.is_finite() && local.y.is_finite() {
                path.push([local.x, local.y]);
            }
        }
        for (k, frozen) in self.frozen.iter().enumerate().skip(self.first_new) {
            if let Some(path) = out.get_mut(k) {
                path.push([frozen.end_pose.x, frozen.end_pose.y]);
            }
        }
        out
    }
}

/// Every edge of `map`'s graph against the true relative pose of its frames
/// (`frame_truth(i)`: frame `i`'s true pose).
fn edges_vs_truth(map: &GlobalMap, frame_truth: &dyn Fn(usize) -> Option<Pose2>) -> EdgesVsTruth {
    let mut out = EdgesVsTruth::default();
    let between = |i: usize, j: usize| -> Option<Pose2> {
        Some(slam_graph::se2::between(&frame_truth(i)?, &frame_truth(j)?))
    };
    for (i, s) in map.submaps().iter().enumerate() {
        if let Some(t) = between(i, i + 1) {
            out.chain.add(&s.end_pose, &s.end_cov, &t);
        }
    }
    for (score, edges) in [(&mut out.links, map.links()), (&mut out.loops, map.loops())] {
        for l in edges {
            if let Some(t) = between(l.from, l.to) {
                score.add(&l.transform, &l.covariance, &t);
            }
        }
    }
    out
}

/// Logs a closure that disagrees with its true transform `t`.
fn warn_false_closure(t: &Pose2, l: &LoopClosure) {
    warn!(
        from = l.from,
        to = l.to,
        error_m = (t.x - l.transform.x).hypot(t.y - l.transform.y),
        error_deg = radar_model::geometry::wrap_angle(t.theta - l.transform.theta).to_degrees(),
        from_place = l.from_place,
        matches = l.matches,
        "a loop closure disagrees with the truth"
    );
}

/// Whether a closure's transform agrees with the true one `t` (within 1 m and 2 degrees).
fn closure_agrees(t: &Pose2, l: &LoopClosure) -> bool {
    (t.x - l.transform.x).hypot(t.y - l.transform.y) <= 1.0
        && radar_model::geometry::wrap_angle(t.theta - l.transform.theta).abs() <= 2f64.to_radians()
}

/// What [`SubmapRun::parts`] lends.
#[derive(Debug, Clone, Copy)]
pub struct SubmapParts<'a> {
    /// The frozen submaps, in order.
    pub frozen: &'a [Arc<FrozenSubmap>],
    /// Every submap's frame in the world, the current one's last.
    pub frames: &'a [Pose2],
    /// Their covariances.
    pub frame_covs: &'a [Matrix3<f64>],
    /// Loop closures accepted so far.
    pub loops: &'a [LoopClosure],
    /// The first submap of every drive after the first.
    pub drive_starts: &'a [usize],
    /// The joins of later drives to earlier ones.
    pub joins: &'a [LoopClosure],
    /// Each frozen submap's scan, where it kept one.
    pub scans: &'a [Option<Arc<Vec<[f64; 2]>>>],
}

/// The closures over every true revisit: frame `i`'s true origin is the vehicle's true
/// position when it started (frame 0: the first pose), its driving the true path length
/// up to then.
fn revisit_score(
    map: &GlobalMap,
    est: &[PoseSample],
    tru: &[Pose2],
    frame_truth: &dyn Fn(usize) -> Option<Pose2>,
) -> slam_graph::RevisitScore {
    let mut driven = Vec::with_capacity(tru.len());
    let mut total = 0.0;
    for (k, t) in tru.iter().enumerate() {
        if let Some(prev) = k.checked_sub(1).and_then(|p| tru.get(p)) {
            total += (t.x - prev.x).hypot(t.y - prev.y);
        }
        driven.push(total);
    }
    // The last sample at or before `time`.
    let at = |time: f64| {
        est.partition_point(|p| p.timestamp_s <= time)
            .checked_sub(1)
    };
    let frames = map.submaps().len() + 1;
    let start_s = |i: usize| match i {
        0 => est.first().map(|p| p.timestamp_s),
        _ => map.submaps().get(i - 1).map(|s| s.end_s),
    };
    let truth: Vec<Option<Pose2>> = (0..frames).map(frame_truth).collect();
    let (origins, driven_m): (Vec<Option<[f64; 2]>>, Vec<f64>) = (0..frames)
        .map(|i| match start_s(i).and_then(at) {
            Some(k) => (Some([tru[k].x, tru[k].y]), driven[k]),
            None => (None, 0.0),
        })
        .unzip();
    // The true drive, each pose with the submap it was mapped in.
    let ends: Vec<f64> = map.submaps().iter().map(|s| s.end_s).collect();
    let path: Vec<slam_graph::PathSample> = est
        .iter()
        .zip(tru)
        .zip(&driven)
        .map(|((e, t), d)| slam_graph::PathSample {
            xy: [t.x, t.y],
            driven_m: *d,
            submap: ends.partition_point(|end| *end < e.timestamp_s),
        })
        .collect();
    slam_graph::score_path_revisits(
        map.loops(),
        &truth,
        &origins,
        &driven_m,
        &path,
        &slam_graph::RevisitRule::default(),
    )
}

/// A frozen submap's feature in the world through its submap's frame.
fn estimate_in(frame: &Pose2, f: &SubmapFeature) -> FeatureEstimate {
    let shares = Material::new(f.uv[0], f.uv[1]).shares();
    placed(
        frame,
        FeatureEstimate {
            id: f.id,
            x_m: f.xy[0],
            y_m: f.xy[1],
            rho: shares.rho,
            alpha: shares.alpha,
            position_cov: f.xy_cov,
            hits: f.hits,
        },
    )
}

/// A feature estimate moved from a submap's frame into the world by the frame's pose.
fn placed(frame: &Pose2, f: FeatureEstimate) -> FeatureEstimate {
    let r = rotation(frame.theta);
    let [x, y] = slam_graph::se2::transform_point(frame, [f.x_m, f.y_m]);
    FeatureEstimate {
        x_m: x,
        y_m: y,
        position_cov: r * f.position_cov * r.transpose(),
        ..f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(max_turn: Option<f64>) -> SubmapRun {
        SubmapRun::new(SubmapOptions {
            limits: slam_filter::SubmapLimits::UNBOUNDED,
            global: slam_graph::GlobalSettings::default(),
            scan_max_turn_rad: max_turn,
            wait_for_joins: false,
        })
        .expect("the global layer's thread")
    }

    /// Two edges, one as good as its covariance says in heading (error one std) and
    /// one four stds out in x: the normalised RMS, heading RMS and mean NEES are theirs;
    /// an edge with a broken covariance is not counted.
    #[test]
    fn edges_are_scored_against_their_own_covariance() {
        let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.01, 0.04, 1e-6));
        let truth = Pose2::new(50.0, 0.0, 0.0);
        let mut s = EdgeScore::default();
        assert_eq!(s.mean_nees(), None);
        s.add(&Pose2::new(50.0, 0.0, 1e-3), &cov, &truth);
        s.add(&Pose2::new(50.4, 0.0, 0.0), &cov, &truth);
        s.add(&Pose2::new(50.4, 0.0, 0.0), &Matrix3::zeros(), &truth);
        assert_eq!(s.count, 2);
        let [x, y, h] = s.normalised_rms().unwrap();
        assert!((x - (16.0f64 / 2.0).sqrt()).abs() < 1e-9);
        assert!(y.abs() < 1e-12);
        assert!((h - (0.5f64).sqrt()).abs() < 1e-9);
        assert!((s.mean_nees().unwrap() - 8.5).abs() < 1e-9);
        assert!((s.heading_rms_rad().unwrap() - 1e-3 / 2f64.sqrt()).abs() < 1e-12);
    }

    /// A wall 10 m ahead, 2 m wide, sampled every 0.1 m.
    fn wall() -> Vec<[f64; 2]> {
        (0..20).map(|i| [10.0, -1.0 + 0.1 * f64::from(i)]).collect()
    }

    #[test]
    fn the_scan_stops_at_a_turn_when_asked() {
        let straight = Pose2::new(20.0, 0.0, 0.1);
        let turned = Pose2::new(40.0, 5.0, 0.8);
        let mut trimmed = run(Some(0.5));
        trimmed.add_scan(&straight, &wall());
        let before = trimmed.scan.cells();
        assert!(before > 0, "a rotation within the turn limit is kept");
        trimmed.add_scan(&turned, &wall());
        assert_eq!(
            trimmed.scan.cells(),
            before,
            "a rotation past the turn is not"
        );
        let mut whole = run(None);
        whole.add_scan(&straight, &wall());
        whole.add_scan(&turned, &wall());
        assert!(whole.scan.cells() > before, "without a limit both are kept");
    }
}
