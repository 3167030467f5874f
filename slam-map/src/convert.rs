//! From the global layer to a map, and back to what the filter and the global layer use
//! (frozen submaps for the loop-closure verifier, a pose graph to extend).

use nalgebra::Matrix3;
use radar_model::geometry::Pose2;
use slam_filter::{FeatureId, FrozenSubmap, SubmapFeature};
use slam_graph::se2::compose;
use slam_graph::{Edge, EdgeKind, GlobalMap, LoopClosure, PoseGraph};

use crate::error::WriteError;
use crate::model::{
    pack2, pack3, unpack2, unpack3, LoopEdge, Map, MapFeature, MapProfile, MapScan, MapSubmap, Pose,
};
use crate::validate::validate;

/// The covariance of a chain edge whose own is not positive definite (a submap closed, or
/// saved, before the vehicle's pose had any uncertainty in it): unknown, as the global layer
/// takes it (`slam_graph::GlobalMap::add_submap`), x and y in m^2, theta in rad^2.
pub const UNKNOWN_CHAIN_COVARIANCE: [f64; 3] = [1e4, 1e4, 1.0];

/// A chain edge's covariance as the global layer uses it.
fn chain_covariance(c: &crate::model::Sym3) -> Matrix3<f64> {
    let m = unpack3(c);
    if m.cholesky().is_some() {
        m
    } else {
        let [x, y, t] = UNKNOWN_CHAIN_COVARIANCE;
        Matrix3::from_diagonal(&nalgebra::Vector3::new(x, y, t))
    }
}

/// What a map records besides its submaps.
#[derive(Debug, Clone, PartialEq)]
pub struct MapMeta {
    /// The radar it was made with.
    pub profile: MapProfile,
    /// The free note.
    pub source: String,
    /// When it is written (seconds since the Unix epoch): the caller reads the clock.
    pub created_unix_s: u64,
}

/// What was left out building a map (values that would not load back).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BuildReport {
    /// Features with a value that is not finite.
    pub dropped_features: usize,
    /// Loop closures naming a submap not in the map, or not finite.
    pub dropped_loops: usize,
}

fn feature(f: &SubmapFeature) -> MapFeature {
    MapFeature {
        id: f.id.0,
        xy: f.xy,
        xy_cov: pack2(&f.xy_cov),
        uv: f.uv,
        uv_cov: pack2(&f.uv_cov),
        hits: f.hits,
    }
}

fn finite_feature(f: &MapFeature) -> bool {
    f.xy.iter()
        .chain(&f.xy_cov)
        .chain(&f.uv)
        .chain(&f.uv_cov)
        .all(|v| v.is_finite())
}

/// The drives of a map made by more than one run (extend mode): where each later drive's
/// submaps start, and the joins that tie each to the map before it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Drives {
    /// The first submap of every drive after the first.
    pub starts: Vec<usize>,
    /// The joins (`from`: an earlier drive's submap, `to`: a later drive's first).
    pub joins: Vec<LoopClosure>,
}

/// `l` as saved, when it names two submaps of `n` and is finite.
fn edge(l: &LoopClosure, n: usize) -> Option<LoopEdge> {
    let ok = l.from < n
        && l.to < n
        && l.from != l.to
        && [l.transform.x, l.transform.y, l.transform.theta]
            .iter()
            .chain(l.covariance.iter())
            .all(|v| v.is_finite());
    if !ok {
        return None;
    }
    Some(LoopEdge {
        from: u32::try_from(l.from).ok()?,
        to: u32::try_from(l.to).ok()?,
        transform: l.transform.into(),
        covariance: pack3(&l.covariance),
        matches: u32::try_from(l.matches).unwrap_or(u32::MAX),
    })
}

impl Map {
    /// A map of `submaps` (each with its frame in the world and the frame's covariance, in
    /// the order they were closed) and the loop closures between them. Features and loop
    /// closures that would not load back are left out and counted; a frame that is not
    /// finite refuses the map.
    pub fn from_parts<'a>(
        meta: MapMeta,
        submaps: impl IntoIterator<Item = (&'a FrozenSubmap, Pose2, Matrix3<f64>)>,
        loops: &[LoopClosure],
    ) -> Result<(Map, BuildReport), WriteError> {
        Map::from_drives(meta, submaps, loops, &Drives::default())
    }

    /// [`Self::from_parts`] for a map of several drives: `drives` says where each later
    /// drive starts and how it is joined to the earlier ones (a join that does not name two
    /// submaps of the map, or is not finite, is left out and counted with the loops).
    pub fn from_drives<'a>(
        meta: MapMeta,
        submaps: impl IntoIterator<Item = (&'a FrozenSubmap, Pose2, Matrix3<f64>)>,
        loops: &[LoopClosure],
        drives: &Drives,
    ) -> Result<(Map, BuildReport), WriteError> {
        let mut report = BuildReport::default();
        let submaps: Vec<MapSubmap> = submaps
            .into_iter()
            .map(|(s, frame, cov)| {
                let features: Vec<MapFeature> = s.features.iter().map(feature).collect();
                let n = features.len();
                let features: Vec<MapFeature> =
                    features.into_iter().filter(finite_feature).collect();
                report.dropped_features += n - features.len();
                MapSubmap {
                    frame: frame.into(),
                    frame_cov: pack3(&cov),
                    end_pose: s.end_pose.into(),
                    end_cov: pack3(&s.end_cov),
                    end_s: s.end_s,
                    loss_db: s.loss_db,
                    features,
                    descriptor: None,
                }
            })
            .collect();
        let n = submaps.len();
        let mut edges = |ls: &[LoopClosure]| -> Vec<LoopEdge> {
            ls.iter()
                .filter_map(|l| {
                    let e = edge(l, n);
                    if e.is_none() {
                        report.dropped_loops += 1;
                    }
                    e
                })
                .collect()
        };
        let loops = edges(loops);
        let joins = edges(&drives.joins);
        let drive_starts: Vec<u32> = drives
            .starts
            .iter()
            .filter_map(|&s| u32::try_from(s).ok())
            .collect();
        let map = Map {
            created_unix_s: meta.created_unix_s,
            source: meta.source,
            profile: meta.profile,
            submaps,
            loops,
            drive_starts,
            joins,
            scans: Vec::new(),
            paths: Vec::new(),
        };
        validate(&map).map_err(WriteError::Invalid)?;
        Ok((map, report))
    }

    /// The map with the submaps' scans (`(submap, points in its frame)`, in increasing
    /// submap order): stored as 32-bit floats (a millimetre at 10 km); points that are not
    /// finite are left out and a scan beyond [`crate::MAX_SCAN_POINTS`] is thinned evenly
    /// to it. A scan naming a submap the map does not hold, or out of order, refuses the
    /// map.
    pub fn with_scans<'a>(
        mut self,
        scans: impl IntoIterator<Item = (usize, &'a [[f64; 2]])>,
    ) -> Result<Map, WriteError> {
        self.scans = per_submap(scans, crate::MAX_SCAN_POINTS, |submap, points| MapScan {
            submap,
            points,
        });
        validate(&self).map_err(WriteError::Invalid)?;
        Ok(self)
    }

    /// The map with the submaps' paths (`(submap, positions in its frame)`, in increasing
    /// submap order), stored as 32-bit floats; positions that are not finite are left out
    /// and a path beyond [`crate::MAX_PATH_POINTS`] is thinned evenly to it. A path naming
    /// a submap the map does not hold, or out of order, refuses the map.
    pub fn with_paths<'a>(
        mut self,
        paths: impl IntoIterator<Item = (usize, &'a [[f64; 2]])>,
    ) -> Result<Map, WriteError> {
        self.paths = per_submap(paths, crate::MAX_PATH_POINTS, |submap, points| {
            crate::MapPath { submap, points }
        });
        validate(&self).map_err(WriteError::Invalid)?;
        Ok(self)
    }

    /// Submap `k`'s path in 64-bit positions, when it recorded one.
    pub fn path_points(&self, k: usize) -> Option<Vec<[f64; 2]>> {
        self.path_of(k).map(widened)
    }

    /// Submap `k`'s scan in 64-bit points, when it kept one.
    pub fn scan_points(&self, k: usize) -> Option<Vec<[f64; 2]>> {
        self.scan_of(k).map(widened)
    }

    /// The global layer's map: every submap it joined, placed by its current solution, and
    /// its loop closures.
    pub fn from_global(
        meta: MapMeta,
        global: &GlobalMap,
    ) -> Result<(Map, BuildReport), WriteError> {
        let sol = global.solution(0.0);
        let parts = global
            .submaps()
            .iter()
            .zip(sol.frames.iter().zip(&sol.covariances))
            .map(|(s, (f, c))| (s.as_ref(), *f, *c));
        // The near links are edges of the graph like the loop closures (a later frame in an
        // earlier one's, with a covariance) and are saved among them, so that a resumed
        // graph solves to the same frames (docs/map-format.md, `loops`).
        let edges: Vec<LoopClosure> = global.loop_edges().cloned().collect();
        let (map, report) = Map::from_parts(meta, parts, &edges)?;
        let scans = (0..global.submaps().len()).filter_map(|k| global.scan(k).map(|p| (k, p)));
        Ok((map.with_scans(scans)?, report))
    }

    /// The submaps as the filter froze them (for the loop-closure verifier).
    pub fn frozen_submaps(&self) -> Vec<FrozenSubmap> {
        self.submaps.iter().map(MapSubmap::to_frozen).collect()
    }

    /// The global graph: a node per submap frame and one for where the last submap ended,
    /// the chain edges (each submap's end pose, but none into a later drive's first
    /// submap), the loop closures and the joins, as the global layer
    /// built it (a chain edge whose covariance is not positive definite is taken as
    /// unknown, [`UNKNOWN_CHAIN_COVARIANCE`]). Its nodes hold the saved frames; solving it
    /// again reproduces them.
    pub fn pose_graph(&self) -> PoseGraph {
        let mut g = PoseGraph::new();
        for s in &self.submaps {
            g.add_node(s.frame.into());
        }
        if let Some(last) = self.submaps.last() {
            g.add_node(compose(&last.frame.into(), &last.end_pose.into()));
        }
        for (k, s) in self.submaps.iter().enumerate() {
            if k + 1 < self.submaps.len() && !self.chained(k + 1) {
                continue;
            }
            g.add_edge(Edge {
                from: k,
                to: k + 1,
                z: s.end_pose.into(),
                covariance: chain_covariance(&s.end_cov),
                kind: EdgeKind::Chain,
            });
        }
        for l in &self.loops {
            g.add_edge(Edge {
                from: l.from as usize,
                to: l.to as usize,
                z: l.transform.into(),
                covariance: unpack3(&l.covariance),
                kind: EdgeKind::Loop,
            });
        }
        for j in &self.joins {
            g.add_edge(Edge {
                from: j.from as usize,
                to: j.to as usize,
                z: j.transform.into(),
                covariance: unpack3(&j.covariance),
                kind: EdgeKind::Join,
            });
        }
        g
    }

    /// The loop closures as the global layer keeps them.
    pub fn loop_closures(&self) -> Vec<LoopClosure> {
        self.loops.iter().map(closure).collect()
    }

    /// The joins as the global layer keeps them.
    pub fn join_closures(&self) -> Vec<LoopClosure> {
        self.joins.iter().map(closure).collect()
    }
}

fn closure(l: &LoopEdge) -> LoopClosure {
    LoopClosure {
        from: l.from as usize,
        to: l.to as usize,
        transform: l.transform.into(),
        covariance: unpack3(&l.covariance),
        matches: l.matches as usize,
        nis: 0.0,
        dof: 0,
        rival_matches: 0,
        from_place: false,
    }
}

impl MapSubmap {
    /// The submap as the filter froze it.
    pub fn to_frozen(&self) -> FrozenSubmap {
        FrozenSubmap {
            end_pose: self.end_pose.into(),
            end_cov: unpack3(&self.end_cov),
            features: self
                .features
                .iter()
                .map(|f| SubmapFeature {
                    id: FeatureId(f.id),
                    xy: f.xy,
                    xy_cov: unpack2(&f.xy_cov),
                    uv: f.uv,
                    uv_cov: unpack2(&f.uv_cov),
                    hits: f.hits,
                })
                .collect(),
            loss_db: self.loss_db,
            end_s: self.end_s,
        }
    }

    /// The frame in the map's frame.
    pub fn frame_pose(&self) -> Pose2 {
        Pose2::from(self.frame)
    }
}

impl Pose {
    /// The origin.
    pub const ORIGIN: Pose = Pose {
        x: 0.0,
        y: 0.0,
        theta: 0.0,
    };
}

/// `points` as the file stores them: 32-bit floats (a millimetre at 10 km), thinned evenly
/// to at most `max`, those that are not finite left out.
/// A point list per submap (`(submap, points in its frame)`; empty ones left out), each
/// [`stored`] to at most `max` points and made into a record by `make`. A submap index
/// beyond `u32` becomes `u32::MAX`, which validation refuses.
fn per_submap<'a, T>(
    lists: impl IntoIterator<Item = (usize, &'a [[f64; 2]])>,
    max: usize,
    make: impl Fn(u32, Vec<[f32; 2]>) -> T,
) -> Vec<T> {
    lists
        .into_iter()
        .filter(|(_, p)| !p.is_empty())
        .map(|(k, points)| make(u32::try_from(k).unwrap_or(u32::MAX), stored(points, max)))
        .collect()
}

fn stored(points: &[[f64; 2]], max: usize) -> Vec<[f32; 2]> {
    let step = points.len().div_ceil(max.max(1)).max(1);
    points
        .iter()
        .step_by(step)
        .map(|p| [p[0] as f32, p[1] as f32])
        .filter(|p| p[0].is_finite() && p[1].is_finite())
        .collect()
}

/// Stored points back in 64 bits.
fn widened(points: &[[f32; 2]]) -> Vec<[f64; 2]> {
    points
        .iter()
        .map(|q| [f64::from(q[0]), f64::from(q[1])])
        .collect()
}
