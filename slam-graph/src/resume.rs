//! A global layer that goes on from a saved graph (slam-node's extend mode): the saved
//! submaps become the first nodes, with their chain edges, loop closures and the joins of
//! their own later drives; a new drive starts at a frame placed by a join (where the new
//! run localised in the saved map), with no chain edge from the saved map's last submap.
//! New submaps then join as during any run, and the loop-closure search offers the saved
//! submaps to the verifier whatever the travel since (they belong to another drive).
//!
//! The saved nodes are free in the solve, held by their saved edges (node 0 stays the
//! world): new loop closures can move them, within what their edges allow. A saved submap
//! whose scan the map kept (format version 3) is verified and described by it as during
//! the run that made it; one without (older maps) by its features.

use std::sync::Arc;

use nalgebra::Matrix3;
use radar_model::geometry::Pose2;
use slam_filter::FrozenSubmap;

use crate::graph::{Edge, EdgeKind};
use crate::layer::{GlobalMap, GlobalSettings, LoopClosure};
use crate::se2::{compose, compose_covariance};

/// A saved graph to go on from.
#[derive(Debug, Clone, Default)]
pub struct SavedGraph {
    /// The submaps, in order (index = node).
    pub submaps: Vec<Arc<FrozenSubmap>>,
    /// Each submap's frame in the world (the saved solution).
    pub frames: Vec<Pose2>,
    /// Their marginal covariances.
    pub covariances: Vec<Matrix3<f64>>,
    /// The drive of each submap (0 for the first drive; non-decreasing).
    pub drives: Vec<usize>,
    /// The loop closures between them.
    pub loops: Vec<LoopClosure>,
    /// The joins of their later drives.
    pub joins: Vec<LoopClosure>,
    /// Each submap's scan in its frame, where the map kept one (missing entries: none).
    pub scans: Vec<Option<Vec<[f64; 2]>>>,
}

/// Why a saved graph cannot be gone on from.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ResumeError {
    /// The saved graph holds no submap.
    #[error("the saved graph holds no submap")]
    Empty,
    /// The per-submap lists differ in length.
    #[error("the saved graph has {submaps} submaps but {frames} frames, {covariances} covariances and {drives} drive numbers")]
    Lengths {
        /// Submaps.
        submaps: usize,
        /// Frames.
        frames: usize,
        /// Covariances.
        covariances: usize,
        /// Drive numbers.
        drives: usize,
    },
    /// An edge names a submap that is not there.
    #[error("an edge joins submaps {from} and {to} of {submaps}")]
    BadEdge {
        /// From.
        from: usize,
        /// To.
        to: usize,
        /// Submaps.
        submaps: usize,
    },
    /// A frame, a covariance or the join is not finite.
    #[error("a value of the saved graph or of the join is not finite")]
    NotFinite,
    /// The drive numbers decrease.
    #[error("the drive numbers of the saved submaps decrease")]
    Drives,
}

fn finite_pose(p: &Pose2) -> bool {
    p.x.is_finite() && p.y.is_finite() && p.theta.is_finite()
}

/// The chain edge covariance the layer uses: the submap's own when positive definite,
/// else unknown (as [`GlobalMap::add_submap`] takes such a submap).
fn chain_covariance(c: &Matrix3<f64>) -> Matrix3<f64> {
    if c.iter().all(|v| v.is_finite()) && c.cholesky().is_some() {
        *c
    } else {
        Matrix3::from_diagonal(&nalgebra::Vector3::new(1e4, 1e4, 1.0))
    }
}

impl SavedGraph {
    fn check(&self, join: &LoopClosure) -> Result<(), ResumeError> {
        let n = self.submaps.len();
        if n == 0 {
            return Err(ResumeError::Empty);
        }
        if self.frames.len() != n || self.covariances.len() != n || self.drives.len() != n {
            return Err(ResumeError::Lengths {
                submaps: n,
                frames: self.frames.len(),
                covariances: self.covariances.len(),
                drives: self.drives.len(),
            });
        }
        if self.drives.windows(2).any(|w| w[1] < w[0]) {
            return Err(ResumeError::Drives);
        }
        for l in self.loops.iter().chain(&self.joins) {
            if l.from >= n || l.to >= n || l.from == l.to {
                return Err(ResumeError::BadEdge {
                    from: l.from,
                    to: l.to,
                    submaps: n,
                });
            }
        }
        if join.from >= n {
            return Err(ResumeError::BadEdge {
                from: join.from,
                to: n,
                submaps: n,
            });
        }
        let finite = self.frames.iter().all(finite_pose)
            && self
                .covariances
                .iter()
                .chain(self.loops.iter().chain(&self.joins).map(|l| &l.covariance))
                .all(|c| c.iter().all(|v| v.is_finite()))
            && self
                .loops
                .iter()
                .chain(&self.joins)
                .all(|l| finite_pose(&l.transform))
            && finite_pose(&join.transform)
            && join.covariance.iter().all(|v| v.is_finite())
            && join.covariance.cholesky().is_some();
        if !finite {
            return Err(ResumeError::NotFinite);
        }
        Ok(())
    }
}

impl GlobalMap {
    /// A layer holding `saved`, and a new drive whose first frame is `join.transform` in
    /// saved submap `join.from`'s frame (with `join.covariance`; `join.to` is set to the new
    /// frame's index, the number of saved submaps). The new drive's submaps are added with
    /// [`GlobalMap::add_submap_with_scan`] as usual. The saved submaps' place descriptors
    /// are made by [`GlobalMap::describe_saved_places`] (they cost time: the layer's thread
    /// makes them).
    pub fn resume(
        settings: GlobalSettings,
        saved: SavedGraph,
        mut join: LoopClosure,
    ) -> Result<Self, ResumeError> {
        saved.check(&join)?;
        let n = saved.submaps.len();
        let mut map = GlobalMap::new(settings);
        let drive = saved.drives[n - 1] + 1;
        for (k, s) in saved.submaps.iter().enumerate() {
            map.graph.add_node(saved.frames[k]);
            map.covariances.push(saved.covariances[k]);
            let scan = saved.scans.get(k).cloned().flatten();
            map.push_scan(s, scan);
            let last = map.travel.last().copied().unwrap_or(0.0);
            map.travel.push(last + s.end_pose.x.hypot(s.end_pose.y));
        }
        map.drive = saved.drives.clone();
        map.drive.push(drive);
        for k in 0..n.saturating_sub(1) {
            if saved.drives[k + 1] != saved.drives[k] {
                continue;
            }
            let s = &saved.submaps[k];
            map.graph.add_edge(Edge {
                from: k,
                to: k + 1,
                z: s.end_pose,
                covariance: chain_covariance(&s.end_cov),
                kind: EdgeKind::Chain,
            });
        }
        for l in &saved.loops {
            map.graph.add_edge(Edge {
                from: l.from,
                to: l.to,
                z: l.transform,
                covariance: l.covariance,
                kind: EdgeKind::Loop,
            });
        }
        join.to = n;
        let anchor = saved.frames[join.from];
        map.graph.add_node(compose(&anchor, &join.transform));
        map.covariances.push(compose_covariance(
            &anchor,
            &saved.covariances[join.from],
            &join.transform,
            &join.covariance,
        ));
        for l in saved.joins.iter().chain(std::iter::once(&join)) {
            map.graph.add_edge(Edge {
                from: l.from,
                to: l.to,
                z: l.transform,
                covariance: l.covariance,
                kind: EdgeKind::Join,
            });
        }
        map.joins = saved.joins;
        map.joins.push(join);
        map.loops = saved.loops;
        map.submaps = saved.submaps;
        map.stats.submaps = n;
        Ok(map)
    }

    /// Describes the saved submaps' places (after [`GlobalMap::resume`]), so that the new
    /// drive's submaps find them by descriptor as they find their own drive's.
    pub fn describe_saved_places(&mut self) {
        if !(self.settings.loop_closure && self.settings.place.enabled) {
            return;
        }
        for k in self.places_described()..self.submaps.len() {
            let points = self.saved_place_points(k);
            self.places.skip(points, &self.settings.place);
        }
    }
}
