//! The global layer: frozen submaps in, optimised submap frames out.
//!
//! [`GlobalMap`] is the layer itself, synchronous and deterministic (tests and offline use
//! call it directly): each frozen submap becomes a node, chained to the previous one by the
//! vehicle's pose at the switch; the earlier submaps its features could overlap (by the
//! current estimate and the uncertainty of the two frames) are offered to the verifier
//! ([`crate::align`]); when none of them verifies, the earlier submaps whose place
//! descriptor matches the new one's ([`crate::places`]) are offered to the same verifier,
//! with the descriptor's transform as the prior; verified closures become loop edges; the
//! graph is solved. If several
//! earlier submaps verify and disagree on where the new one is, none is taken (repeated
//! structure). A solve that fails, does not converge, or leaves a loop edge far outside its
//! own uncertainty is logged and the previous solution stays.
//!
//! [`GlobalLayer`] runs a [`GlobalMap`] on a thread of its own, fed by a bounded channel; the
//! real-time path only ever `try_send`s and `try_recv`s, so it never waits for a solve.

use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Instant;

use crossbeam_channel::{bounded, Receiver, Sender, TrySendError};
use nalgebra::Matrix3;
use radar_model::geometry::Pose2;
use slam_filter::FrozenSubmap;
use statrs::distribution::{ChiSquared, ContinuousCDF};
use tracing::{debug, info, warn};

use crate::align::{align, AlignSettings, Alignment, Refusal};
use crate::graph::{Edge, EdgeKind, PoseGraph, SolveSettings};
use crate::places::{place_points, PlaceSearch, Places};
use crate::scans::{align_scans, reference_scan, ScanAlignSettings, ScanReference};
use crate::se2::{compose, compose_covariance, inverse, transform_point};

/// The global layer's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlobalSettings {
    /// Look for loop closures at all.
    pub loop_closure: bool,
    /// The verifier's thresholds.
    pub align: AlignSettings,
    /// The solver's limits.
    pub solve: SolveSettings,
    /// Earlier submaps are candidates when their feature discs, grown by this many standard
    /// deviations of the relative position, overlap the new one's.
    pub search_sigmas: f64,
    /// The relative uncertainty used for the search is capped at this (m, 1 sigma).
    pub max_search_sigma_m: f64,
    /// The most recent submaps (besides the previous one) not offered to the verifier: they
    /// overlap the new one by construction and share its information.
    pub skip_recent: usize,
    /// An earlier submap is a loop-closure candidate only when the vehicle has moved at
    /// least this far (m, summed over the submaps in between) since it: a loop is a return
    /// after an excursion, not the overlap of neighbouring submaps.
    pub min_loop_travel_m: f64,
    /// Candidates from place descriptors, besides those from the pose uncertainty.
    pub place: PlaceSearch,
    /// Verification by the submaps' scans where both have one ([`crate::scans`]).
    pub scans: ScanAlignSettings,
    /// Closures verified against different earlier places that put the new frame in
    /// different places: when the weaker has at least this share of the stronger's
    /// matches, none is taken. Both passed the verifier, so the scene repeats (a grid city
    /// dressed alike fits one block over with fewer matches only because the blocks'
    /// submaps overlap the new one over different lengths): 0.25, not the verifier's own
    /// rival ratio.
    pub max_conflict_ratio: f64,
    /// A place descriptor's closure that moves the new frame farther than the rival
    /// separation from where the chain of submaps puts it is held until the next submap
    /// of the drive is verified where it implies: a jump a repeated street (a block over,
    /// out of the scan's own reach, where [`crate::scans::fits_itself`] cannot tell) fits
    /// once fits the next submap there only where the repetition goes on.
    pub confirm_place_jumps: bool,
    /// A closure from the pose prior that moves the new frame farther than the rival
    /// separation from where the chain of submaps puts it is held likewise: after a long
    /// stretch the prior's window spans a street's repeats (parked cars every 6 m), and
    /// the verifier may take the one beside the true place.
    pub confirm_prior_slides: bool,
    /// Each new submap's scan is also registered against the scans of the submaps two to
    /// this many before it (the previous one is joined by the chain edge), where the chain
    /// puts their frames within [`Self::near_reach_m`]: a measurement of the chain over
    /// 100-150 m with the lever arm of the whole street, which a junction's few pairs a
    /// rotation do not have. Each verified one that agrees with the chain enters the graph
    /// as an edge ([`GlobalMap::links`]; not a loop closure). 0 or 1: none.
    pub near_links: usize,
    /// See [`Self::near_links`] (m, along the chain between the two frames' origins).
    pub near_reach_m: f64,
    /// A near link needs this many pairs (fewer than a loop closure's
    /// [`ScanAlignSettings::min_pairs`]: two scans 100 m apart along a street share what
    /// lies between them, and the chain's prior is tight).
    pub near_min_pairs: usize,
    /// A near link's covariance is the registration's times this. Its heading errs 2.3
    /// times its own standard deviation on the realistic city, but four times the
    /// covariance made the online pose worse and its NEES no better (slam-node/README.md,
    /// "Near links"): 1.
    pub near_covariance_scale: f64,
    /// An edge from two submaps' scans (a near link, or a loop closure verified by the
    /// scans) registers each scan whole: its submap's rotations placed by the filter, their
    /// placement error growing from nothing at the frame's origin to the submap's end
    /// pose's ([`FrozenSubmap::end_cov`]). Registered whole, a scan errs about as their
    /// mean, which for a random walk has a third of the end's variance. The edge's
    /// covariance adds this share of each of its two submaps' end covariances (the earlier
    /// one's about the earlier frame, with the lever arm of the edge): the error the
    /// registration's own covariance, counting every return independent, does not hold,
    /// and that the chain of end poses between the two frames already carries. 0: the
    /// registration's alone.
    pub scan_smear: f64,
}

/// See [`GlobalSettings::near_covariance_scale`].
const NEAR_SCALE: f64 = 1.0;

/// See [`GlobalSettings::scan_smear`]: the mean of a random walk over its length has a
/// third of the variance of its end. On the realistic city it takes the near links' mean
/// NEES against the truth from 48 to 4.0 and the loop closures' from 34 to 3.7
/// (slam-node/README.md, "Scan edges carry their scans' placement").
const SCAN_SMEAR: f64 = 1.0 / 3.0;

impl Default for GlobalSettings {
    fn default() -> Self {
        Self {
            loop_closure: true,
            align: AlignSettings::default(),
            solve: SolveSettings::default(),
            search_sigmas: 3.0,
            max_search_sigma_m: 50.0,
            skip_recent: 1,
            min_loop_travel_m: 100.0,
            place: PlaceSearch::default(),
            scans: ScanAlignSettings::default(),
            max_conflict_ratio: 0.25,
            confirm_place_jumps: true,
            confirm_prior_slides: true,
            near_links: 3,
            near_reach_m: 120.0,
            near_min_pairs: 100,
            near_covariance_scale: NEAR_SCALE,
            scan_smear: SCAN_SMEAR,
        }
    }
}

/// An edge's covariance from two scans' registration ([`GlobalSettings::scan_smear`]): the registration's
/// (`registration`, of `transform`: the later frame in the earlier one's) with `smear` times
/// the earlier submap's end covariance as an error of the earlier frame and `smear` times
/// the later submap's as one of the later frame.
pub fn scan_edge_covariance(
    transform: &Pose2,
    registration: &Matrix3<f64>,
    earlier_end_cov: &Matrix3<f64>,
    later_end_cov: &Matrix3<f64>,
    smear: f64,
) -> Matrix3<f64> {
    if smear <= 0.0 {
        return *registration;
    }
    crate::se2::compose_covariance(
        &Pose2::new(0.0, 0.0, 0.0),
        &(earlier_end_cov * smear),
        transform,
        &(registration + later_end_cov * smear),
    )
}

/// Whether `found` (a later frame in an earlier one's, from a place descriptor) is within
/// the drift the chain of submaps can have gathered over `driven` metres, the chain putting
/// the later frame at `chain` with covariance `cov` ([`PlaceSearch::drift_floor_m`]); else
/// [`Refusal::Implausible`].
pub fn within_drift(
    p: &PlaceSearch,
    found: &Pose2,
    chain: &Pose2,
    cov: &Matrix3<f64>,
    driven: f64,
) -> Result<(), Refusal> {
    let distance_m = (found.x - chain.x).hypot(found.y - chain.y);
    let heading_rad = radar_model::geometry::wrap_angle(found.theta - chain.theta).abs();
    // A negative or NaN variance gives NaN, and NaN is refused below.
    let sigma_m = (cov[(0, 0)] + cov[(1, 1)]).sqrt();
    let sigma_rad = cov[(2, 2)].sqrt();
    let allowed_m = p.drift_floor_m + p.drift_per_m * driven + 3.0 * sigma_m;
    let allowed_rad = p.heading_drift_floor_rad + p.heading_drift_per_m * driven + 3.0 * sigma_rad;
    if distance_m <= allowed_m && heading_rad <= allowed_rad {
        Ok(())
    } else {
        Err(Refusal::Implausible {
            distance_m,
            heading_rad,
        })
    }
}

/// A loop closure that entered the graph.
#[derive(Debug, Clone, PartialEq)]
pub struct LoopClosure {
    /// The earlier submap.
    pub from: usize,
    /// The later submap.
    pub to: usize,
    /// `to`'s frame in `from`'s.
    pub transform: Pose2,
    /// Its covariance (from the matched features).
    pub covariance: Matrix3<f64>,
    /// Matched features.
    pub matches: usize,
    /// Joint NIS and its dof.
    pub nis: f64,
    /// Dof.
    pub dof: usize,
    /// Matches of the best rival transform.
    pub rival_matches: usize,
    /// The candidate came from a place descriptor (not from the pose uncertainty).
    pub from_place: bool,
}

impl LoopClosure {
    /// The closure of submap `to` to submap `from` that alignment `a` verified.
    fn verified(from: usize, to: usize, a: &Alignment, from_place: bool) -> Self {
        Self {
            from,
            to,
            transform: a.transform,
            covariance: a.covariance,
            matches: a.matches.len(),
            nis: a.nis,
            dof: a.dof,
            rival_matches: a.rival_matches,
            from_place,
        }
    }
}

/// The optimised frames.
#[derive(Debug, Clone, PartialEq)]
pub struct GlobalSolution {
    /// Increases with every accepted solve.
    pub version: u64,
    /// Every submap frame's pose in the world (index = submap number).
    pub frames: Vec<Pose2>,
    /// Their marginal covariances.
    pub covariances: Vec<Matrix3<f64>>,
    /// Loop closures in the graph.
    pub loops: usize,
    /// Time the solve took (ms).
    pub solve_ms: f64,
}

/// What adding one submap did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AddReport {
    /// Candidates offered to the verifier.
    pub candidates: usize,
    /// Of which from place descriptors.
    pub place_candidates: usize,
    /// Closures accepted into the graph.
    pub accepted: Vec<LoopClosure>,
    /// Near links added to the graph, those the solve kept ([`GlobalSettings::near_links`]).
    pub links: Vec<LoopClosure>,
    /// Refusals, by candidate submap.
    pub refused: Vec<(usize, Refusal)>,
    /// Closures verified one by one but dropped because they disagreed with each other.
    pub conflicting: usize,
    /// Closures dropped because the solve left them outside their own uncertainty.
    pub rejected_after_solve: usize,
    /// A closure moving the new frame from the chain (a place jump, a prior slide) was held
    /// for the next submap to confirm.
    pub held: bool,
    /// The held closure of the previous submap was not confirmed by this one: dropped.
    pub unconfirmed: bool,
    /// The solve failed and the previous solution stands.
    pub solve_failed: bool,
    /// Time spent verifying and solving (ms).
    pub elapsed_ms: f64,
}

/// The layer's running totals.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GlobalStats {
    /// Submaps joined.
    pub submaps: usize,
    /// Candidates offered to the verifier.
    pub candidates: u64,
    /// Of which from place descriptors.
    pub place_candidates: u64,
    /// Loop closures in the graph.
    pub loops: u64,
    /// Of which from place descriptors.
    pub place_loops: u64,
    /// Verified closures dropped for disagreeing with another.
    pub conflicting: u64,
    /// Closures dropped after the solve.
    pub rejected_after_solve: u64,
    /// Closures moving the new frame from the chain (place jumps, prior slides) held for
    /// the next submap to confirm.
    pub held: u64,
    /// Of which the next submap did not confirm (dropped).
    pub unconfirmed: u64,
    /// Failed solves.
    pub failed_solves: u64,
    /// Longest add (verification and solve), ms.
    pub max_add_ms: f64,
    /// Submaps whose end pose or covariance was unusable (kept as an unknown chain edge).
    pub bad_submaps: u64,
    /// Links between near submaps' scans tried ([`GlobalSettings::near_links`]).
    pub near_tried: u64,
    /// Of which verified and added to the graph (kept by the solve).
    pub near_links: u64,
    /// Of which verified but dropped after the solve, far outside their covariance.
    pub near_dropped: u64,
}

/// Centre and radius of points (a submap's features, or its scan), in its frame.
pub(crate) fn disc(points: &[[f64; 2]]) -> ([f64; 2], f64) {
    let n = points.len().max(1) as f64;
    let (sx, sy) = points
        .iter()
        .fold((0.0, 0.0), |(x, y), p| (x + p[0], y + p[1]));
    let c = [sx / n, sy / n];
    let r = points
        .iter()
        .map(|p| (p[0] - c[0]).hypot(p[1] - c[1]))
        .fold(0.0, f64::max);
    (c, r)
}

/// The global layer, synchronous.
#[derive(Debug, Clone)]
pub struct GlobalMap {
    pub(crate) settings: GlobalSettings,
    pub(crate) submaps: Vec<Arc<FrozenSubmap>>,
    /// Each submap's scan as the scan verifier pairs against (`None`: verified by features).
    pub(crate) scans: Vec<Option<Arc<ScanReference>>>,
    pub(crate) discs: Vec<([f64; 2], f64)>,
    /// Distance (m) from the first frame to each frame along the chain of switch poses.
    pub(crate) travel: Vec<f64>,
    pub(crate) graph: PoseGraph,
    pub(crate) covariances: Vec<Matrix3<f64>>,
    pub(crate) loops: Vec<LoopClosure>,
    pub(crate) version: u64,
    pub(crate) stats: GlobalStats,
    pub(crate) places: Places,
    /// The drive each frame belongs to (0: the first; later drives come from
    /// [`GlobalMap::resume`]): no chain edge joins two drives, and loop closures between
    /// drives need no travel in between.
    pub(crate) drive: Vec<usize>,
    /// The joins of later drives to earlier ones (see [`crate::resume`]).
    pub(crate) joins: Vec<LoopClosure>,
    /// A closure of the newest submap held for the next one to confirm
    /// ([`GlobalSettings::confirm_place_jumps`], [`GlobalSettings::confirm_prior_slides`]).
    pub(crate) held: Option<LoopClosure>,
    /// The near links in the graph ([`GlobalSettings::near_links`]).
    pub(crate) links: Vec<LoopClosure>,
}

impl GlobalMap {
    /// An empty layer. The first submap's frame is the world.
    pub fn new(settings: GlobalSettings) -> Self {
        Self {
            settings,
            submaps: Vec::new(),
            scans: Vec::new(),
            discs: Vec::new(),
            travel: vec![0.0],
            graph: PoseGraph::new(),
            covariances: Vec::new(),
            loops: Vec::new(),
            version: 0,
            stats: GlobalStats::default(),
            places: Places::default(),
            drive: vec![0],
            joins: Vec::new(),
            held: None,
            links: Vec::new(),
        }
    }

    /// The near links between submaps two or three apart along a drive
    /// ([`GlobalSettings::near_links`]), in the graph beside the loop closures.
    pub fn links(&self) -> &[LoopClosure] {
        &self.links
    }

    /// Every edge of the graph besides the chain and the joins: the loop closures, then
    /// the near links (what a saved map keeps as its loop edges, docs/map-format.md).
    pub fn loop_edges(&self) -> impl Iterator<Item = &LoopClosure> {
        self.loops.iter().chain(&self.links)
    }

    /// The joins of later drives to earlier ones (empty unless resumed).
    pub fn joins(&self) -> &[LoopClosure] {
        &self.joins
    }

    /// The drive each submap frame belongs to (the frame after the last submap included).
    pub fn drives(&self) -> &[usize] {
        &self.drive
    }

    /// The first frame of the drive frame `k` belongs to.
    pub(crate) fn drive_start(&self, k: usize) -> usize {
        let d = self.drive.get(k).copied().unwrap_or(0);
        let mut start = k.min(self.drive.len().saturating_sub(1));
        while start > 0 && self.drive[start - 1] == d {
            start -= 1;
        }
        start
    }

    /// Whether frames `i` and `k` belong to different drives.
    fn other_drive(&self, i: usize, k: usize) -> bool {
        self.drive.get(i) != self.drive.get(k)
    }

    /// The submaps joined so far.
    pub fn submaps(&self) -> &[Arc<FrozenSubmap>] {
        &self.submaps
    }

    /// The loop closures in the graph.
    pub fn loops(&self) -> &[LoopClosure] {
        &self.loops
    }

    /// Running totals.
    pub fn stats(&self) -> &GlobalStats {
        &self.stats
    }

    /// The graph.
    pub fn graph(&self) -> &PoseGraph {
        &self.graph
    }

    /// The current solution.
    pub fn solution(&self, solve_ms: f64) -> GlobalSolution {
        GlobalSolution {
            version: self.version,
            frames: self.graph.nodes().to_vec(),
            covariances: self.covariances.clone(),
            loops: self.loops.len(),
            solve_ms,
        }
    }

    /// Submap `k`'s scan as the scan verifier pairs against, when it has one.
    pub fn scan(&self, k: usize) -> Option<&[[f64; 2]]> {
        self.scans.get(k)?.as_deref().map(ScanReference::points)
    }

    /// Keeps the scan of the submap just added (when scans are on and it has enough
    /// points to verify with) and the disc loop-closure candidates are found by: the scan's,
    /// or the features'.
    pub(crate) fn push_scan(&mut self, submap: &FrozenSubmap, scan: Option<Vec<[f64; 2]>>) {
        let scan = scan
            .filter(|p| self.settings.scans.enabled && p.len() >= self.settings.scans.min_pairs)
            .map(|p| Arc::new(reference_scan(p, &self.settings.scans)));
        let feature_points: Vec<[f64; 2]> = submap.features.iter().map(|f| f.xy).collect();
        self.discs.push(disc(
            scan.as_ref().map_or(&feature_points[..], |c| c.points()),
        ));
        self.scans.push(scan);
    }

    /// Joins a frozen submap: a node for its frame (and one for the frame after it: the
    /// next submap starts where this one ended), its chain edge, verified loop closures,
    /// and a solve.
    pub fn add_submap(&mut self, submap: Arc<FrozenSubmap>) -> AddReport {
        self.add_submap_with_scan(submap, None)
    }

    /// [`Self::add_submap`] with the submap's scan (its registered radar returns in its
    /// frame, see [`crate::scans::ScanAccumulator`]): loop closures between two submaps that
    /// both have one are verified by registering the scans, and the place descriptor is
    /// built from the scan.
    pub fn add_submap_with_scan(
        &mut self,
        submap: Arc<FrozenSubmap>,
        scan: Option<Vec<[f64; 2]>>,
    ) -> AddReport {
        let started = Instant::now();
        let mut report = AddReport::default();
        if self.graph.nodes().is_empty() {
            self.graph.add_node(Pose2::new(0.0, 0.0, 0.0));
            self.covariances.push(Matrix3::zeros());
        }
        let k = self.submaps.len();
        let pose_ok = [submap.end_pose.x, submap.end_pose.y, submap.end_pose.theta]
            .iter()
            .all(|v| v.is_finite());
        let submap = if pose_ok
            && submap.end_cov.iter().all(|v| v.is_finite())
            && submap.end_cov.cholesky().is_some()
        {
            submap
        } else {
            // A chain edge must exist or every later frame floats free: keep the pose with
            // a covariance that says it is unknown.
            warn!(submap = k, "a submap's end covariance is not positive definite: the chain edge is kept as unknown");
            self.stats.bad_submaps += 1;
            let mut fixed = (*submap).clone();
            fixed.end_cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(1e4, 1e4, 1.0));
            if !(fixed.end_pose.x.is_finite()
                && fixed.end_pose.y.is_finite()
                && fixed.end_pose.theta.is_finite())
            {
                fixed.end_pose = Pose2::new(0.0, 0.0, 0.0);
            }
            Arc::new(fixed)
        };
        let frame = self.graph.nodes()[k];
        let next = compose(&frame, &submap.end_pose);
        let next_cov = compose_covariance(
            &frame,
            &self.covariances[k],
            &submap.end_pose,
            &submap.end_cov,
        );
        self.graph.add_node(next);
        self.covariances.push(next_cov);
        self.graph.add_edge(Edge {
            from: k,
            to: k + 1,
            z: submap.end_pose,
            covariance: submap.end_cov,
            kind: EdgeKind::Chain,
        });
        self.push_scan(&submap, scan);
        let last = self.travel.last().copied().unwrap_or(0.0);
        self.travel
            .push(last + submap.end_pose.x.hypot(submap.end_pose.y));
        let d = self.drive.get(k).copied().unwrap_or(0);
        self.drive.push(d);
        self.submaps.push(submap);
        self.stats.submaps = self.submaps.len();
        if self.settings.loop_closure {
            self.link_near(k, &mut report);
            self.close_loops(k, &mut report);
        }
        if !report.accepted.is_empty() || !report.links.is_empty() {
            self.solve_with_loops(&mut report);
        }
        report.elapsed_ms = started.elapsed().as_secs_f64() * 1e3;
        self.stats.max_add_ms = self.stats.max_add_ms.max(report.elapsed_ms);
        report
    }

    /// The relative pose of frame `j` in frame `i` and a conservative covariance (the
    /// marginals propagated as if independent: correlation through the shared chain only
    /// shrinks the true relative uncertainty).
    fn relative(&self, i: usize, j: usize) -> (Pose2, Matrix3<f64>) {
        let nodes = self.graph.nodes();
        let (fi, fj) = (nodes[i], nodes[j]);
        let inv = inverse(&fi);
        let z = compose(&inv, &fj);
        // d z / d fi and d z / d fj through inverse and compose.
        let (ja, jb) = crate::se2::compose_jacobians(&inv, &fj);
        let (c, s) = (fi.theta.cos(), fi.theta.sin());
        let (x, y) = (fi.x, fi.y);
        let jinv = Matrix3::new(-c, -s, s * x - c * y, s, -c, c * x + s * y, 0.0, 0.0, -1.0);
        let ji = ja * jinv;
        let cov =
            ji * self.covariances[i] * ji.transpose() + jb * self.covariances[j] * jb.transpose();
        (z, 0.5 * (cov + cov.transpose()))
    }

    /// Registers submap `k`'s scan against the scans of the submaps two to
    /// [`GlobalSettings::near_links`] before it, from where the chain of submaps puts it,
    /// and puts each verified registration that agrees with the chain in `report.links`, for
    /// the solve to add to the graph as an edge ([`Self::links`]) or drop.
    fn link_near(&mut self, k: usize, report: &mut AddReport) {
        let s = self.settings;
        if s.near_links < 2 || !self.scans.get(k).is_some_and(Option::is_some) {
            return;
        }
        let bound = ChiSquared::new(3.0)
            .map(|d| d.inverse_cdf(0.999))
            .unwrap_or(f64::INFINITY);
        let mut scans = s.scans;
        scans.min_pairs = s.near_min_pairs;
        for back in 2..=s.near_links {
            let Some(i) = k.checked_sub(back) else {
                break;
            };
            // Not across a drive's start: no chain joins two drives.
            if (i + 1..=k).any(|j| self.drive.get(j) != self.drive.get(i)) {
                break;
            }
            let (Some(Some(earlier)), Some(Some(newer))) = (self.scans.get(i), self.scans.get(k))
            else {
                continue;
            };
            // The chain from frame i to frame k: the submaps' own end poses, composed.
            let mut z = Pose2::new(0.0, 0.0, 0.0);
            let mut cov = Matrix3::zeros();
            for e in &self.submaps[i..k] {
                cov = compose_covariance(&z, &cov, &e.end_pose, &e.end_cov);
                z = compose(&z, &e.end_pose);
            }
            if z.x.hypot(z.y) > s.near_reach_m {
                continue;
            }
            self.stats.near_tried += 1;
            // The search window: the chain's uncertainty, at least 1 m and 20 mrad (a
            // junction turns the chain by that: slam-node/README.md, "Near links").
            let mut window = cov;
            for (d, floor) in [(0, 1.0_f64), (1, 1.0), (2, 0.02)] {
                window[(d, d)] = window[(d, d)].max(floor * floor);
            }
            let a = match align_scans(earlier, newer.points(), &z, &window, &s.align, &scans) {
                Ok(a) => a,
                Err(r) => {
                    tracing::debug!(from = i, to = k, refusal = ?r, "near link refused");
                    continue;
                }
            };
            let off = nalgebra::Vector3::new(
                a.transform.x - z.x,
                a.transform.y - z.y,
                radar_model::geometry::wrap_angle(a.transform.theta - z.theta),
            );
            let covariance = scan_edge_covariance(
                &a.transform,
                &(a.covariance * s.near_covariance_scale),
                &self.submaps[i].end_cov,
                &self.submaps[k].end_cov,
                s.scan_smear,
            );
            let agrees = (window + covariance)
                .cholesky()
                .is_some_and(|ch| off.dot(&ch.solve(&off)) <= bound);
            tracing::debug!(
                from = i,
                to = k,
                off_x_m = off.x,
                off_y_m = off.y,
                off_theta_rad = off.z,
                sigma_theta_rad = covariance[(2, 2)].max(0.0).sqrt(),
                agrees,
                "near link"
            );
            if !agrees {
                continue;
            }
            // An edge once the solve keeps it (`solve_with_loops`: a link the solution leaves
            // far outside its covariance is dropped, as a closure is).
            let mut link = LoopClosure::verified(i, k, &a, false);
            link.covariance = covariance;
            report.links.push(link);
        }
    }

    fn close_loops(&mut self, k: usize, report: &mut AddReport) {
        let s = self.settings;
        let Some(newest) = self.submaps.get(k).cloned() else {
            return;
        };
        if let Some(held) = self.held.take() {
            match self.confirm(&held, k, &newest) {
                Some(next) => {
                    info!(
                        from = held.from,
                        to = held.to,
                        next_from = next.from,
                        "a held closure is confirmed by the next submap"
                    );
                    report.accepted.push(held);
                    report.accepted.push(next);
                    // The new submap's place is described for later ones to find, as
                    // after any closure the prior found.
                    if s.place.enabled {
                        let points = self.place_points(k);
                        self.places.skip(points, &s.place);
                    }
                    return;
                }
                None => {
                    info!(
                        from = held.from,
                        to = held.to,
                        "a held closure is not confirmed by the next submap: dropped"
                    );
                    report.unconfirmed = true;
                    self.stats.unconfirmed += 1;
                }
            }
        }
        let (cn, rn) = self.discs[k];
        // (earlier submap, alignment, from a place descriptor)
        let mut verified: Vec<(usize, Alignment, bool)> = Vec::new();
        let by_scan = self.scans.get(k).is_some_and(Option::is_some);
        // (earlier submap, prior, its covariance, how near)
        let mut offered: Vec<(usize, Pose2, Matrix3<f64>, f64)> = Vec::new();
        for i in 0..k {
            // Frame i + 1 is where submap i ended. A submap of an earlier drive is a
            // candidate however recent.
            let too_near = i >= k.saturating_sub(s.skip_recent)
                || self.travel[k] - self.travel[i + 1] < s.min_loop_travel_m;
            if too_near && !self.other_drive(i, k) {
                continue;
            }
            let (z, cov) = self.relative(i, k);
            let sigma = (cov[(0, 0)] + cov[(1, 1)])
                .max(0.0)
                .sqrt()
                .min(s.max_search_sigma_m);
            // A scan reaches as far as the radar sees, so scan discs overlap along whole
            // districts: two submaps with scans are candidates when their frames' origins
            // may be within the scan's reach; features, when their discs may overlap.
            let gap = if by_scan && self.scans.get(i).is_some_and(Option::is_some) {
                z.x.hypot(z.y) - s.scans.origin_reach_m
            } else {
                let (ci, ri) = self.discs[i];
                let c = transform_point(&z, cn);
                (c[0] - ci[0]).hypot(c[1] - ci[1]) - ri - rn
            };
            if gap > s.search_sigmas * sigma {
                continue;
            }
            offered.push((i, z, cov, gap / sigma.max(1e-3)));
        }
        if by_scan {
            // Each scan verification registers from 27 starts: the nearest few only.
            offered.sort_by(|a, b| a.3.total_cmp(&b.3));
            offered.truncate(s.scans.max_prior_candidates);
        }
        for (i, z, cov, _) in offered {
            report.candidates += 1;
            self.stats.candidates += 1;
            let mut search_cov = cov;
            // The cap applies to the gate as well as to the search.
            let cap = s.max_search_sigma_m * s.max_search_sigma_m;
            for d in 0..2 {
                search_cov[(d, d)] = search_cov[(d, d)].min(cap);
            }
            match self.verify(i, k, &newest, &z, &search_cov) {
                Ok(a) => {
                    let off = crate::se2::between(&z, &a.transform);
                    tracing::debug!(
                        candidate = i,
                        submap = k,
                        off_x_m = off.x,
                        off_y_m = off.y,
                        off_theta_rad = off.theta,
                        sigma_x_m = search_cov[(0, 0)].sqrt(),
                        sigma_y_m = search_cov[(1, 1)].sqrt(),
                        matches = a.matches.len(),
                        "loop closure verified from the prior: where it lands from the prior"
                    );
                    verified.push((i, a, false));
                }
                Err(r) => {
                    tracing::debug!(candidate = i, submap = k, refusal = ?r, "loop closure refused");
                    report.refused.push((i, r));
                }
            }
        }
        // The descriptors are for returns the prior does not find: when it found one, the
        // place search is skipped (it costs tens of ms; every verified closure of the prior
        // has been through the same verifier).
        if verified.is_empty() {
            self.place_candidates(k, &newest, &mut verified, report);
        } else if s.place.enabled {
            let points = self.place_points(k);
            self.places.skip(points, &s.place);
        }
        if verified.is_empty() {
            return;
        }
        // Every verified closure implies a pose for frame k: they must all agree with the
        // best (most matches), or none is taken; only the best enters the graph (the others
        // reuse the same features of submap k and would count them twice).
        verified.sort_by_key(|v| std::cmp::Reverse(v.1.matches.len()));
        let implied: Vec<(Pose2, Matrix3<f64>)> = verified
            .iter()
            .map(|(i, a, _)| {
                let fi = self.graph.nodes()[*i];
                (
                    compose(&fi, &a.transform),
                    compose_covariance(&fi, &self.covariances[*i], &a.transform, &a.covariance),
                )
            })
            .collect();
        let bound = ChiSquared::new(3.0)
            .map(|d| d.inverse_cdf(0.999))
            .unwrap_or(f64::INFINITY);
        let (best, best_cov) = implied[0];
        let best_matches = verified[0].1.matches.len();
        let sep = s.align.rival_separation_m;
        // A verified closure that puts frame k elsewhere (outside both the joint uncertainty
        // and the rival separation) is a rival explanation from another place.
        let rival = verified
            .iter()
            .zip(&implied)
            .skip(1)
            .filter(|(_, (q, d))| {
                let e = nalgebra::Vector3::new(
                    best.x - q.x,
                    best.y - q.y,
                    radar_model::geometry::wrap_angle(best.theta - q.theta),
                );
                let far = (best.x - q.x).hypot(best.y - q.y) > sep || e.z.abs() > 0.1 * sep;
                let outside = (best_cov + d)
                    .cholesky()
                    .is_none_or(|ch| e.dot(&ch.solve(&e)) > bound);
                far && outside
            })
            .map(|((_, a, _), _)| a.matches.len())
            .max()
            .unwrap_or(0);
        if rival > 0 && rival as f64 >= s.max_conflict_ratio * best_matches as f64 {
            report.conflicting += verified.len();
            self.stats.conflicting += verified.len() as u64;
            warn!(
                submap = k,
                best = best_matches,
                rival,
                "verified loop closures from different places disagree: none taken (repeated structure)"
            );
            return;
        }
        verified.truncate(1);
        for (i, a, from_place) in verified {
            let closure = LoopClosure::verified(i, k, &a, from_place);
            if self.held_for_confirmation(&closure) {
                info!(
                    from = i,
                    to = k,
                    from_place,
                    "a closure moves the frame from the chain farther than a repeat: held for the next submap to confirm"
                );
                report.held = true;
                self.stats.held += 1;
                self.held = Some(closure);
                return;
            }
            report.accepted.push(closure);
        }
    }

    /// Whether closure `l` is held for the next submap to confirm: within one drive, where
    /// it puts its later frame farther from the chain's than the rival separation and, for
    /// a place descriptor's closure ([`GlobalSettings::confirm_place_jumps`]), three
    /// standard deviations of the chain's relative position: within those the chain's own
    /// uncertainty explains it, and [`Self::not_repeating`] has tried the move on the
    /// earlier scan. A closure from the pose prior ([`GlobalSettings::confirm_prior_slides`])
    /// was searched for within the chain's uncertainty, so only the rival separation, a
    /// street's repeat, is allowed it.
    fn held_for_confirmation(&self, l: &LoopClosure) -> bool {
        let s = &self.settings;
        let asked = if l.from_place {
            s.confirm_place_jumps
        } else {
            s.confirm_prior_slides
        };
        if !asked || self.other_drive(l.from, l.to) {
            return false;
        }
        let (z, cov) = self.relative(l.from, l.to);
        let shift = compose(&z, &inverse(&l.transform));
        let distance_m = shift.x.hypot(shift.y);
        let allowed_m = if l.from_place {
            let sigma_m = (cov[(0, 0)] + cov[(1, 1)]).max(0.0).sqrt();
            s.align.rival_separation_m.max(3.0 * sigma_m)
        } else {
            s.align.rival_separation_m
        };
        // NaN is held.
        distance_m.is_nan() || distance_m > allowed_m
    }

    /// The next submap `k`'s confirmation of `held` (a closure of submap `k - 1` that
    /// [`Self::held_for_confirmation`]): `k` verified against either neighbour of the
    /// held closure's earlier submap, from where the held closure and the chain edge
    /// between `k - 1` and `k` put it, within the place search's prior window, and
    /// implying a frame for `k` within the rival separation of that. The closure with the
    /// most matches, `None` when none is verified there (the held one is then dropped).
    fn confirm(&self, held: &LoopClosure, k: usize, newest: &FrozenSubmap) -> Option<LoopClosure> {
        let s = &self.settings;
        if held.to + 1 != k || self.other_drive(held.to, k) {
            return None;
        }
        let step = self.submaps.get(held.to)?.end_pose;
        let predicted = compose(&held.transform, &step);
        let window = Matrix3::from_diagonal(&nalgebra::Vector3::new(
            s.place.prior_sigma_m.powi(2),
            s.place.prior_sigma_m.powi(2),
            s.place.prior_sigma_rad.powi(2),
        ));
        let sep = s.align.rival_separation_m;
        // Not the held closure's earlier submap itself: its scan overlaps the next
        // submap's too, and a street repeating its pattern aliases both the same way (on
        // the check layout driven on the radar alone, submaps 54 and 55 both verified
        // against submap 12, 222 m from it: the only confirmation over 40 runs).
        [held.from.checked_sub(1), Some(held.from + 1)]
            .into_iter()
            .flatten()
            .filter(|&c| c + 1 < held.to && !self.other_drive(c, k))
            .filter_map(|c| {
                // Frame `held.from` in frame `c`: neighbours along the chain.
                let (rel, _) = self.relative(c, held.from);
                let prior = compose(&rel, &predicted);
                let a = self.verify(c, k, newest, &prior, &window).ok()?;
                let off = crate::se2::between(&prior, &a.transform);
                (off.x.hypot(off.y) <= sep && off.theta.abs() <= 0.1 * sep)
                    .then(|| LoopClosure::verified(c, k, &a, true))
            })
            .max_by_key(|l| l.matches)
    }

    /// Describes the new submap `k` and offers the verifier the earlier submaps its place
    /// descriptor matches (far enough behind, not verified already), each with the
    /// descriptor's transform as the prior (see [`crate::places`]).
    fn place_candidates(
        &mut self,
        k: usize,
        newest: &FrozenSubmap,
        verified: &mut Vec<(usize, Alignment, bool)>,
        report: &mut AddReport,
    ) {
        let s = self.settings;
        if !s.place.enabled {
            return;
        }
        let points = self.place_points(k);
        let Some(query) = self.places.describe(&points, &s.place) else {
            return;
        };
        let travel = &self.travel;
        let last = k.saturating_sub(s.skip_recent);
        let drive = &self.drive;
        let eligible = |i: usize| {
            drive.get(i) != drive.get(k)
                || (i < last && travel[k] - travel[i + 1] >= s.place.min_travel_m)
        };
        let chained = |j: usize| j > 0 && drive.get(j) == drive.get(j - 1);
        let by_scan = self.scans.get(k).is_some_and(Option::is_some);
        let candidates = self.places.candidates(
            &self.submaps,
            &query,
            &crate::places::SubmapOrder {
                eligible: &eligible,
                chained: &chained,
            },
            s.align.min_hits,
            &s.place,
            !by_scan,
        );
        for c in candidates {
            if verified.iter().any(|v| v.0 == c.index) {
                continue;
            }
            report.candidates += 1;
            report.place_candidates += 1;
            self.stats.candidates += 1;
            self.stats.place_candidates += 1;
            let checked = self
                .verify(c.index, k, newest, &c.prior, &c.covariance)
                .and_then(|a| self.plausible(c.index, k, a));
            match checked {
                Ok(a) => verified.push((c.index, a, true)),
                Err(r) => {
                    tracing::debug!(candidate = c.index, submap = k, distance = c.distance, refusal = ?r, "loop closure from a place descriptor refused");
                    report.refused.push((c.index, r));
                }
            }
        }
    }

    /// `a` (submap `k`'s frame in submap `i`'s, from a place descriptor) when it is within
    /// the drift the chain of submaps can have gathered between them ([`within_drift`]).
    fn plausible(&self, i: usize, k: usize, a: Alignment) -> Result<Alignment, Refusal> {
        let (z, cov) = self.relative(i, k);
        let driven = (self.travel[k] - self.travel[i + 1]).max(0.0);
        within_drift(&self.settings.place, &a.transform, &z, &cov, driven)?;
        self.not_repeating(i, &a.transform, &z)?;
        Ok(a)
    }

    /// Where the descriptor's closure (`found`: the new frame in submap `i`'s) and the chain
    /// (`chain`) put the new frame apart by more than the rival separation, the move from
    /// one to the other (`chain * found^-1`, in frame `i`) is tried on submap `i`'s own
    /// scan: if the verifier accepts the scan as a second look at itself so moved, the new
    /// scan, placed where the chain puts it, lies on the same structure as where the
    /// descriptor puts it, and nothing tells the two places apart (a grid of blocks dressed
    /// alike, one block over). Refused ([`crate::scans::fits_itself`], on less evidence than
    /// a closure needs). A place that does not repeat does not fit itself moved, and a
    /// closure after a long drift passes.
    fn not_repeating(&self, i: usize, found: &Pose2, chain: &Pose2) -> Result<(), Refusal> {
        let s = &self.settings;
        let Some(Some(scan)) = self.scans.get(i) else {
            return Ok(());
        };
        let shift = compose(chain, &inverse(found));
        let distance_m = shift.x.hypot(shift.y);
        tracing::debug!(
            submap = i,
            distance_m,
            heading_rad = shift.theta,
            "a place closure against the chain: tried on the earlier scan itself"
        );
        if distance_m <= s.align.rival_separation_m
            && shift.theta.abs() <= 0.1 * s.align.rival_separation_m
        {
            return Ok(());
        }
        let window = [
            s.place.prior_sigma_m,
            s.place.prior_sigma_m,
            s.place.prior_sigma_rad,
        ];
        match crate::scans::fits_itself(scan, &shift, window, &s.scans) {
            Some(self_matches) => Err(Refusal::Repeats {
                distance_m,
                self_matches,
            }),
            None => {
                tracing::debug!(
                    submap = i,
                    distance_m,
                    "the earlier scan does not fit itself moved: the place does not repeat there"
                );
                Ok(())
            }
        }
    }

    /// Place descriptors made so far.
    pub(crate) fn places_described(&self) -> usize {
        self.places.described()
    }

    /// [`Self::place_points`] for the resumed layer.
    pub(crate) fn saved_place_points(&self, k: usize) -> Vec<[f64; 2]> {
        self.place_points(k)
    }

    /// The points submap `k`'s place is described by: its scan when it has one, else its
    /// features and its predecessor's.
    fn place_points(&self, k: usize) -> Vec<[f64; 2]> {
        match self.scans.get(k) {
            Some(Some(scan)) => scan.points().to_vec(),
            _ => {
                // A drive's first submap has no predecessor in its frame.
                let start = self.drive_start(k);
                place_points(
                    &self.submaps[start..],
                    k - start,
                    self.settings.align.min_hits,
                )
            }
        }
    }

    /// Verifies that submap `k` (`newest`) is a second look at submap `i`, `prior` being
    /// `k`'s frame in `i`'s: by their scans when both have one, else by their features.
    fn verify(
        &self,
        i: usize,
        k: usize,
        newest: &FrozenSubmap,
        prior: &Pose2,
        prior_cov: &Matrix3<f64>,
    ) -> Result<Alignment, Refusal> {
        let s = &self.settings;
        match (self.scans.get(i), self.scans.get(k)) {
            (Some(Some(a)), Some(Some(b))) => {
                align_scans(a, b.points(), prior, prior_cov, &s.align, &s.scans).map(|mut a| {
                    a.covariance = scan_edge_covariance(
                        &a.transform,
                        &a.covariance,
                        &self.submaps[i].end_cov,
                        &newest.end_cov,
                        s.scan_smear,
                    );
                    a
                })
            }
            _ => align(
                &self.submaps[i].features,
                &newest.features,
                prior,
                prior_cov,
                &s.align,
            ),
        }
    }

    /// Adds the accepted closures and the near links as edges and solves; drops the closure
    /// or link the solution leaves farthest outside its covariance (0.999 chi-square) and
    /// solves again until none is, and on failure restores the graph as it was.
    fn solve_with_loops(&mut self, report: &mut AddReport) {
        let before = self.graph.clone();
        let bound = ChiSquared::new(3.0)
            .map(|d| d.inverse_cdf(0.999))
            .unwrap_or(f64::INFINITY);
        let mut kept = report.accepted.clone();
        let mut links = std::mem::take(&mut report.links);
        loop {
            self.graph = before.clone();
            for l in kept.iter().chain(&links) {
                self.graph.add_edge(Edge {
                    from: l.from,
                    to: l.to,
                    z: l.transform,
                    covariance: l.covariance,
                    kind: EdgeKind::Loop,
                });
            }
            match self.graph.solve(&self.settings.solve) {
                Ok(sol) => {
                    let first_loop = before.edges().len();
                    let worst = (first_loop..self.graph.edges().len())
                        .filter_map(|e| {
                            self.graph
                                .edge_chi2(e, &sol.nodes)
                                .map(|c| (e - first_loop, c))
                        })
                        .max_by(|a, b| a.1.total_cmp(&b.1));
                    if let Some((idx, chi2)) = worst.filter(|(_, c)| *c > bound) {
                        if idx < kept.len() {
                            warn!(chi2, bound, "a loop closure ends far outside its own uncertainty after the solve: dropped");
                            kept.remove(idx);
                            report.rejected_after_solve += 1;
                            self.stats.rejected_after_solve += 1;
                        } else {
                            let l = links.remove(idx - kept.len());
                            debug!(
                                from = l.from,
                                to = l.to,
                                chi2,
                                bound,
                                "a near link ends far outside its own uncertainty after the solve: dropped"
                            );
                            self.stats.near_dropped += 1;
                        }
                        if kept.is_empty() && links.is_empty() {
                            // Nothing left to add: the report names none (the daemon saves
                            // what it names among the map's loop edges).
                            self.graph = before;
                            report.accepted.clear();
                            return;
                        }
                        continue;
                    }
                    self.graph.set_nodes(&sol.nodes);
                    self.covariances = sol.covariances;
                    self.version += 1;
                    for l in &kept {
                        info!(from = l.from, to = l.to, matches = l.matches, "loop closed");
                    }
                    self.stats.loops += kept.len() as u64;
                    self.stats.place_loops += kept.iter().filter(|l| l.from_place).count() as u64;
                    self.stats.near_links += links.len() as u64;
                    self.loops.extend(kept.iter().cloned());
                    self.links.extend(links.iter().cloned());
                    report.accepted = kept;
                    report.links = links;
                    return;
                }
                Err(e) => {
                    warn!(error = %e, "the global solve failed: the previous solution stays");
                    self.graph = before;
                    report.solve_failed = true;
                    report.accepted.clear();
                    self.stats.failed_solves += 1;
                    return;
                }
            }
        }
    }
}

/// A message to the layer's thread.
#[derive(Debug)]
enum ToLayer {
    Submap(Arc<FrozenSubmap>, Option<Vec<[f64; 2]>>),
}

/// The global layer on a thread of its own.
#[derive(Debug)]
pub struct GlobalLayer {
    to_layer: Option<Sender<ToLayer>>,
    solutions: Receiver<(Arc<GlobalSolution>, AddReport)>,
    thread: Option<JoinHandle<GlobalMap>>,
    latest: Option<Arc<GlobalSolution>>,
    reports: Vec<AddReport>,
    refused_sends: u64,
    /// Submaps handed over, and solutions received for them.
    submitted: u64,
    joined: u64,
}

/// Frozen submaps queued for the layer's thread at most (past it a submap is refused and
/// the chain breaks: the thread is hopelessly behind).
const QUEUE: usize = 256;

impl GlobalLayer {
    /// Starts the layer's thread.
    pub fn spawn(settings: GlobalSettings) -> std::io::Result<Self> {
        Self::spawn_with(GlobalMap::new(settings))
    }

    /// Starts the layer's thread on `map` (a layer resumed from a saved graph,
    /// [`GlobalMap::resume`]: the thread first describes the saved submaps' places).
    pub fn spawn_with(map: GlobalMap) -> std::io::Result<Self> {
        let (tx, rx) = bounded::<ToLayer>(QUEUE);
        let (sol_tx, sol_rx) = bounded(QUEUE);
        let thread = std::thread::Builder::new()
            .name("global-layer".into())
            .spawn(move || {
                let mut map = map;
                map.describe_saved_places();
                while let Ok(ToLayer::Submap(s, scan)) = rx.recv() {
                    let report = map.add_submap_with_scan(s, scan);
                    let solution = Arc::new(map.solution(report.elapsed_ms));
                    if sol_tx.try_send((solution, report)).is_err() {
                        warn!("the real-time path is not reading the global layer's solutions: one dropped");
                    }
                }
                map
            })?;
        Ok(Self {
            to_layer: Some(tx),
            solutions: sol_rx,
            thread: Some(thread),
            latest: None,
            reports: Vec::new(),
            refused_sends: 0,
            submitted: 0,
            joined: 0,
        })
    }

    /// Hands a frozen submap to the layer without waiting. `false` when the queue is full
    /// or the thread is gone (logged; counted in [`Self::refused_sends`]).
    pub fn submit(&mut self, submap: Arc<FrozenSubmap>) -> bool {
        self.submit_with_scan(submap, None)
    }

    /// [`Self::submit`] with the submap's scan ([`GlobalMap::add_submap_with_scan`]).
    pub fn submit_with_scan(
        &mut self,
        submap: Arc<FrozenSubmap>,
        scan: Option<Vec<[f64; 2]>>,
    ) -> bool {
        let Some(tx) = self.to_layer.as_ref() else {
            return false;
        };
        match tx.try_send(ToLayer::Submap(submap, scan)) {
            Ok(()) => {
                self.submitted += 1;
                true
            }
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                self.refused_sends += 1;
                warn!("the global layer's queue is full or its thread is gone: a submap was not joined");
                false
            }
        }
    }

    /// The newest solution, without waiting (`None` until the first arrives).
    pub fn poll(&mut self) -> Option<Arc<GlobalSolution>> {
        while let Ok((s, report)) = self.solutions.try_recv() {
            self.take(s, report);
        }
        self.latest.clone()
    }

    fn take(&mut self, solution: Arc<GlobalSolution>, report: AddReport) {
        self.latest = Some(solution);
        self.reports.push(report);
        self.joined += 1;
    }

    /// Waits, up to `timeout` in all, until the layer has joined every submap handed over
    /// (its solutions then come from [`Self::poll`] at once): for a run paced by its
    /// pipeline (a simulator as fast as possible), where the layer would otherwise fall
    /// submaps behind the simulated time. `false` if the time ran out or the thread is gone.
    pub fn wait_for_joins(&mut self, timeout: std::time::Duration) -> bool {
        let until = Instant::now() + timeout;
        while self.joined < self.submitted {
            let left = until.saturating_duration_since(Instant::now());
            match self.solutions.recv_timeout(left) {
                Ok((s, report)) => self.take(s, report),
                Err(_) => return false,
            }
        }
        true
    }

    /// Reports of every submap joined so far (drained).
    pub fn take_reports(&mut self) -> Vec<AddReport> {
        self.poll();
        std::mem::take(&mut self.reports)
    }

    /// Submaps that could not be handed over.
    pub fn refused_sends(&self) -> u64 {
        self.refused_sends
    }

    /// Closes the queue, waits for the thread to join every submap sent, and returns the
    /// layer (end of run only: this blocks).
    pub fn finish(mut self) -> Option<GlobalMap> {
        self.to_layer.take();
        let map = self.thread.take()?.join().ok();
        self.poll();
        map
    }
}

impl Drop for GlobalLayer {
    fn drop(&mut self) {
        self.to_layer.take();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A link 100 m along x between two submaps whose end headings are 6 mrad uncertain:
    /// with no smear the registration's covariance is the link's; with a third, the heading
    /// gains a third of both ends' variance and the earlier frame's heading swings the later
    /// one sideways over the 100 m lever arm, and the result is symmetric positive definite.
    #[test]
    fn a_scan_edge_carries_its_scans_placement() {
        let t = Pose2::new(100.0, 0.0, 0.0);
        let reg = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.01, 0.01, 9e-6));
        let end = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.04, 0.04, 36e-6));
        assert_eq!(scan_edge_covariance(&t, &reg, &end, &end, 0.0), reg);
        let c = scan_edge_covariance(&t, &reg, &end, &end, 1.0 / 3.0);
        assert!((c[(2, 2)] - (9e-6 + 2.0 * 12e-6)).abs() < 1e-12, "{c}");
        // Sideways: the registration's, both ends' third, and 100 m times the earlier heading.
        let lateral = 0.01 + 2.0 * 0.04 / 3.0 + 100.0 * 100.0 * 12e-6;
        assert!((c[(1, 1)] - lateral).abs() < 1e-9, "{c}");
        assert!((c - c.transpose()).abs().max() < 1e-15);
        assert!(c.cholesky().is_some());
    }

    /// A grid city's look-alike block: the descriptor's match puts the new frame 431 m and
    /// half a turn from where 700 m of odometry put it (seen on the realistic city driven on
    /// the radar alone); a true return after the same drive, 30 m and 10 degrees off the
    /// chain, is kept.
    #[test]
    fn a_place_closure_beyond_any_drift_is_refused() {
        let p = PlaceSearch::default();
        let chain = Pose2::new(400.0, 0.0, 0.0);
        let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(4.0, 4.0, 1e-3));
        let look_alike = Pose2::new(-31.0, 0.0, std::f64::consts::PI);
        match within_drift(&p, &look_alike, &chain, &cov, 700.0) {
            Err(Refusal::Implausible { distance_m, .. }) => {
                assert!((distance_m - 431.0).abs() < 1e-9);
            }
            other => panic!("kept a look-alike: {other:?}"),
        }
        let true_return = Pose2::new(425.0, 15.0, 0.17);
        assert!(within_drift(&p, &true_return, &chain, &cov, 700.0).is_ok());
        // A broken covariance is no licence.
        let nan = Matrix3::from_element(f64::NAN);
        assert!(within_drift(&p, &true_return, &chain, &nan, 700.0).is_err());
    }
}
