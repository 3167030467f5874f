//! A saved map's radar scans as localisation uses them: every submap's scan placed by its
//! frame in the map's, one reference cloud over all of them for tracking, a bucket grid
//! for "the map's points around here", and place descriptors of the scans every
//! [`PLACE_SPACING_M`] along the mapping drive for the search without a prior.
//!
//! **Why scans and not the map's point features.** In a city of fronts, fences and parked
//! cars the filter's point features are mostly returns the next drive does not see again
//! (21 of the realistic city map's 385 features match a scene feature), while the scans
//! hold every wall the radar saw in at least two rotations: what the next drive sees again.
//! No IO.

use std::collections::HashMap;

use nalgebra::{Matrix3, Vector3};
use radar_model::geometry::Pose2;
use radar_odometry::{PlaceDescriptor, PlaceIndex, PlaceSettings, ReferenceCloud};
use slam_graph::correlate::ScoreGrid;
use slam_graph::scans::SCAN_NORMAL_RADIUS_M;
use slam_graph::se2::transform_point;
use slam_map::Map;

use super::known::{path_samples, polyline_distance, MapFeatures};
use super::search::{drive_points, PLACE_SPACING_M};

/// The tracking reference's pair gate (m): its grid's cells are half of it.
pub const TRACK_PAIR_GATE_M: f64 = 2.0;
/// Buckets of the "points around here" grid (m).
const BUCKET_M: f64 = 20.0;

/// A saved map's scans in the map's frame.
#[derive(Debug)]
pub struct ScanMap {
    /// Every scan point in the map's frame (the tracking reference's points).
    pub cloud: ReferenceCloud,
    buckets: HashMap<(i64, i64), Vec<u32>>,
    /// Places along the mapping drive: the place's origin (axes of the map's frame) and the
    /// descriptor of the map's points around it.
    pub places: Vec<(Pose2, PlaceDescriptor)>,
    /// The descriptors' settings.
    pub settings: PlaceSettings,
    /// The whole map's correlative score grid for tracking ([`TRACK_GRID_CELL_M`] cells, a
    /// [`TRACK_GRID_SIGMA_M`] kernel; twice as coarse when the map spans too large an area,
    /// `None` when even that exceeds [`TRACK_GRID_MAX_CELLS`]).
    pub grid: Option<ScoreGrid>,
    /// Where the mapping drive passed more than once, how far apart its passes put the
    /// same walls ([`Disagreement::measure`]).
    pub disagreement: Disagreement,
}

/// Submaps this close in the drive's order are one pass (their scans overlap by the
/// radar's reach): not compared.
const SAME_PASS_SUBMAPS: usize = 2;
/// A point of one pass has a point of the other within this (m) where they overlap.
const OVERLAP_M: f64 = 5.0;
/// Two submaps are compared when this share of one's points (a subsample) overlaps the
/// other's.
const MIN_OVERLAP_SHARE: f64 = 0.2;
/// The offsets between passes searched for (m, one sigma: the verifier's window is three).
const PASS_OFFSET_SIGMA_M: f64 = 4.0;
/// Points of a submap looked at for the overlap share.
const OVERLAP_SAMPLE: usize = 400;

/// Where the map disagrees with itself: each pair of submaps of different passes over the
/// same streets aligned scan to scan (the loop-closure verifier's `align_scans`, from no
/// offset), and the offset between them, at the middle of their overlap, kept over the
/// overlap's buckets. The map's frame is the mapping drive's estimate; where its passes
/// put the same wall metres apart a localiser matches one or the other (or both), and how
/// far it can be from "the truth in the map's frame" is that offset: the published
/// covariance adds it there (by scans; by features the submap frame's covariance plays
/// that part).
#[derive(Debug, Default)]
pub struct Disagreement {
    /// Per bucket of [`BUCKET_M`]: the largest offset's covariance `[x, y, heading]` (its
    /// outer product).
    buckets: HashMap<(i64, i64), Matrix3<f64>>,
    /// Pairs of submaps of different passes that overlap, and of those the ones aligned.
    pub pairs_compared: usize,
    /// See `pairs_compared`.
    pub pairs_aligned: usize,
    /// The offsets (m) of the aligned pairs, at the middle of their overlap.
    pub offsets_m: Vec<f64>,
    /// Wall time the comparison took at load (ms).
    pub wall_ms: f64,
}

impl Disagreement {
    /// Compares the submaps' scans `scans` (each in the map's frame, in the drive's
    /// order) pass against pass. `paths[k]` is where the vehicle drove through submap `k`
    /// in the map's frame (a polyline): an offset is kept where both passes' paths run
    /// within [`PASSES_NEAR_M`] of each other (where a vehicle can be on either pass), not
    /// over every wall both scans saw (a street crossing theirs, seen down its length, is
    /// not where their disagreement puts a localiser).
    pub fn measure(scans: &[Vec<[f64; 2]>], paths: &[Vec<[f64; 2]>]) -> Self {
        let started = std::time::Instant::now();
        let settings = slam_graph::scans::ScanAlignSettings::default();
        let align = slam_graph::align::AlignSettings::default();
        let boxes: Vec<Option<[f64; 4]>> = scans.iter().map(|s| bounds(s)).collect();
        let mut out = Self::default();
        // Each submap's scan as the verifier pairs against, built once (its k-d tree also
        // answers the overlap queries).
        let mut references: HashMap<usize, slam_graph::scans::ScanReference> = HashMap::new();
        let prior = Pose2::new(0.0, 0.0, 0.0);
        let prior_cov = Matrix3::from_diagonal(&Vector3::new(
            PASS_OFFSET_SIGMA_M.powi(2),
            PASS_OFFSET_SIGMA_M.powi(2),
            0.05f64.powi(2),
        ));
        for k in 0..scans.len() {
            for j in k + SAME_PASS_SUBMAPS + 1..scans.len() {
                let (Some(a), Some(b)) = (boxes[k], boxes[j]) else {
                    continue;
                };
                if a[0] > b[2] + OVERLAP_M
                    || b[0] > a[2] + OVERLAP_M
                    || a[1] > b[3] + OVERLAP_M
                    || b[1] > a[3] + OVERLAP_M
                {
                    continue;
                }
                let reference = references.entry(j).or_insert_with(|| {
                    slam_graph::scans::reference_scan(scans[j].clone(), &settings)
                });
                let rj = &reference.cloud;
                let stride = scans[k].len().div_ceil(OVERLAP_SAMPLE).max(1);
                let sampled = scans[k].iter().step_by(stride);
                let n = scans[k].len().div_ceil(stride);
                let near = sampled
                    .filter(|p| rj.nearest_within(p, OVERLAP_M).is_some())
                    .count();
                if n == 0 || (near as f64) < MIN_OVERLAP_SHARE * n as f64 {
                    continue;
                }
                out.pairs_compared += 1;
                let overlap: Vec<[f64; 2]> = scans[k]
                    .iter()
                    .filter(|p| rj.nearest_within(p, OVERLAP_M).is_some())
                    .copied()
                    .collect();
                let Ok(al) = slam_graph::scans::align_scans(
                    reference, &overlap, &prior, &prior_cov, &align, &settings,
                ) else {
                    continue;
                };
                out.pairs_aligned += 1;
                let n = overlap.len() as f64;
                let c = overlap
                    .iter()
                    .fold([0.0, 0.0], |m, p| [m[0] + p[0] / n, m[1] + p[1] / n]);
                let moved = transform_point(&al.transform, c);
                let d = Vector3::new(
                    moved[0] - c[0],
                    moved[1] - c[1],
                    radar_model::geometry::wrap_angle(al.transform.theta),
                );
                out.offsets_m.push(d[0].hypot(d[1]));
                let cov = d * d.transpose();
                let (Some(pk), Some(pj)) = (paths.get(k), paths.get(j)) else {
                    continue;
                };
                let shared = along(pk)
                    .filter(|p| polyline_distance(*p, pj) <= PASSES_NEAR_M)
                    .chain(along(pj).filter(|p| polyline_distance(*p, pk) <= PASSES_NEAR_M));
                for p in shared {
                    let slot = out
                        .buckets
                        .entry(bucket_of(p))
                        .or_insert_with(Matrix3::zeros);
                    if cov.trace() > slot.trace() {
                        *slot = cov;
                    }
                }
            }
        }
        out.wall_ms = started.elapsed().as_secs_f64() * 1e3;
        out
    }

    /// The map's disagreement with itself at `p` (the covariance of the largest offset
    /// between its passes there; zero where it was driven once).
    pub fn at(&self, p: [f64; 2]) -> Matrix3<f64> {
        self.buckets
            .get(&bucket_of(p))
            .copied()
            .unwrap_or_else(Matrix3::zeros)
    }
}

/// Points at most [`PATH_SAMPLE_M`] apart along `path`, both ends included.
fn along(path: &[[f64; 2]]) -> impl Iterator<Item = [f64; 2]> + '_ {
    path_samples(path, PATH_SAMPLE_M)
        .into_iter()
        .chain(path.last().copied())
}

/// Two passes share a street where their paths run this close (m): the street's width
/// and a lane or two more (a map without paths, before format version 4, gives each submap
/// the line from where it began to where it ended).
const PASSES_NEAR_M: f64 = 15.0;
/// Spacing of the samples along a submap's path (m).
const PATH_SAMPLE_M: f64 = 2.0;

/// `[min x, min y, max x, max y]` of `points`; `None` when empty.
fn bounds(points: &[[f64; 2]]) -> Option<[f64; 4]> {
    points.iter().fold(None, |b, p| {
        Some(match b {
            None => [p[0], p[1], p[0], p[1]],
            Some(b) => [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ],
        })
    })
}

/// The tracking score grid's cells (m), kernel (m) and bound (cells, 4 bytes each).
pub const TRACK_GRID_CELL_M: f64 = 0.5;
/// See [`TRACK_GRID_CELL_M`].
pub const TRACK_GRID_SIGMA_M: f64 = 0.5;
/// See [`TRACK_GRID_CELL_M`].
pub const TRACK_GRID_MAX_CELLS: usize = 8 << 20;

fn bucket_of(p: [f64; 2]) -> (i64, i64) {
    (
        (p[0] / BUCKET_M).floor() as i64,
        (p[1] / BUCKET_M).floor() as i64,
    )
}

impl ScanMap {
    /// The map's scans placed by their frames (`frames` from [`MapFeatures`]); `None` when
    /// the map holds no scan point.
    pub fn new(map: &Map, frames: &MapFeatures) -> Option<Self> {
        let scans: Vec<Vec<[f64; 2]>> = frames
            .frames
            .iter()
            .enumerate()
            .map(|(k, (frame, _))| {
                map.scan_of(k).map_or_else(Vec::new, |scan| {
                    scan.iter()
                        .map(|q| transform_point(frame, [f64::from(q[0]), f64::from(q[1])]))
                        .filter(|p| p[0].is_finite() && p[1].is_finite())
                        .collect()
                })
            })
            .collect();
        // Where the vehicle drove through each submap, in the map's frame.
        let paths: Vec<Vec<[f64; 2]>> = (0..frames.frames.len())
            .map(|k| frames.path_of(k).into_owned())
            .collect();
        let disagreement = Disagreement::measure(&scans, &paths);
        let mut out = Self::from_points(scans.concat(), frames)?;
        out.disagreement = disagreement;
        Some(out)
    }

    /// The map of `points` (already in the map's frame), with places along the drive of
    /// `frames`; `None` without points.
    pub fn from_points(points: Vec<[f64; 2]>, frames: &MapFeatures) -> Option<Self> {
        if points.is_empty() {
            return None;
        }
        let mut buckets: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
        for (i, p) in points.iter().enumerate() {
            // The map's scans are bounded when read (slam-map): the index fits a u32.
            if let Ok(i) = u32::try_from(i) {
                buckets.entry(bucket_of(*p)).or_default().push(i);
            }
        }
        let grid = ScoreGrid::new(
            &points,
            TRACK_GRID_CELL_M,
            TRACK_GRID_SIGMA_M,
            TRACK_GRID_MAX_CELLS,
        )
        .or_else(|| {
            ScoreGrid::new(
                &points,
                2.0 * TRACK_GRID_CELL_M,
                TRACK_GRID_SIGMA_M,
                TRACK_GRID_MAX_CELLS,
            )
        });
        let cloud = ReferenceCloud::new(points, SCAN_NORMAL_RADIUS_M, TRACK_PAIR_GATE_M);
        let mut out = Self {
            cloud,
            buckets,
            places: Vec::new(),
            settings: PlaceSettings::default(),
            grid,
            disagreement: Disagreement::default(),
        };
        let r = out.settings.max_range_m;
        for p in drive_points(frames, PLACE_SPACING_M) {
            let around: Vec<[f64; 2]> = out
                .near(p, r)
                .into_iter()
                .map(|q| [q[0] - p[0], q[1] - p[1]])
                .collect();
            if let Ok(d) = PlaceDescriptor::new(around, &out.settings) {
                out.places.push((Pose2::new(p[0], p[1], 0.0), d));
            }
        }
        Some(out)
    }

    /// Scan points in the map.
    pub fn len(&self) -> usize {
        self.cloud.points().len()
    }

    /// Whether the map holds none (never, once built).
    pub fn is_empty(&self) -> bool {
        self.cloud.points().is_empty()
    }

    /// The map's scan points within `radius_m` of `centre`.
    pub fn near(&self, centre: [f64; 2], radius_m: f64) -> Vec<[f64; 2]> {
        let pts = self.cloud.points();
        let (lo, hi) = (
            bucket_of([centre[0] - radius_m, centre[1] - radius_m]),
            bucket_of([centre[0] + radius_m, centre[1] + radius_m]),
        );
        let r2 = radius_m * radius_m;
        let mut out = Vec::new();
        for bx in lo.0..=hi.0 {
            for by in lo.1..=hi.1 {
                let Some(ids) = self.buckets.get(&(bx, by)) else {
                    continue;
                };
                out.extend(
                    ids.iter()
                        .filter_map(|&i| pts.get(i as usize))
                        .filter(|p| {
                            let (dx, dy) = (p[0] - centre[0], p[1] - centre[1]);
                            dx * dx + dy * dy <= r2
                        })
                        .copied(),
                );
            }
        }
        out
    }

    /// The map's points within the descriptors' range of `pose`, in `pose`'s frame: what a
    /// vehicle there would see of the map, to look up look-alike places.
    pub fn around(&self, pose: &Pose2) -> Vec<[f64; 2]> {
        let inv = slam_graph::se2::inverse(pose);
        self.near([pose.x, pose.y], self.settings.max_range_m)
            .into_iter()
            .map(|q| transform_point(&inv, q))
            .collect()
    }

    /// The places' ring keys indexed.
    pub fn index(&self) -> PlaceIndex {
        let mut index = PlaceIndex::new();
        for (i, (_, d)) in self.places.iter().enumerate() {
            index.insert(i as u64, d);
        }
        index
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::localise::repeated_tests::Lcg;
    use crate::pipeline::localise::scan_search::tests::street;

    /// The street's points in `[from, to)` along it, each moved by `offset`: one submap's
    /// scan in the map's frame.
    fn submap(world: &[[f64; 2]], from: f64, to: f64, offset: [f64; 2]) -> Vec<[f64; 2]> {
        world
            .iter()
            .filter(|p| p[0] >= from && p[0] < to)
            .map(|p| [p[0] + offset[0], p[1] + offset[1]])
            .collect()
    }

    #[test]
    fn a_second_pass_placed_apart_is_measured_where_it_overlaps_and_nowhere_else() {
        let world = street(&mut Lcg(11), 0.0);
        let there: Vec<Vec<[f64; 2]>> = (0..4)
            .map(|k| {
                let x = 100.0 * f64::from(k);
                submap(&world, x, x + 100.0, [0.0, 0.0])
            })
            .collect();
        // Each submap's path: down the middle of the street (y = 0), the way it drove.
        let path = |x: f64, back: bool, offset: [f64; 2]| {
            let (a, b) = (
                [x + offset[0], offset[1]],
                [x + 100.0 + offset[0], offset[1]],
            );
            if back {
                vec![b, a]
            } else {
                vec![a, b]
            }
        };
        let paths: Vec<Vec<[f64; 2]>> = (0..4)
            .map(|k| path(100.0 * f64::from(k), false, [0.0; 2]))
            .collect();
        // One pass: nothing to compare, no disagreement anywhere.
        let once = Disagreement::measure(&there, &paths);
        assert_eq!((once.pairs_compared, once.pairs_aligned), (0, 0));
        assert_eq!(once.at([50.0, 8.0]), Matrix3::zeros());

        // The way back over the first 300 m, the map's estimate 1.5 m further along and
        // 0.4 m to the side.
        let offset = [1.5, 0.4];
        let mut both = there.clone();
        both.extend((0..3).rev().map(|k| {
            let x = 100.0 * f64::from(k);
            submap(&world, x, x + 100.0, offset)
        }));
        let mut both_paths = paths.clone();
        both_paths.extend(
            (0..3)
                .rev()
                .map(|k| path(100.0 * f64::from(k), true, offset)),
        );
        let twice = Disagreement::measure(&both, &both_paths);
        // Submaps 1 and 5, 0 and 6; not 2 and 4, two submaps apart in the drive's order
        // (taken for one pass: the radar's reach spans them).
        assert_eq!(
            (
                twice.pairs_compared,
                twice.pairs_aligned,
                twice.offsets_m.len()
            ),
            (2, 2, 2),
            "{:?}",
            twice.offsets_m
        );
        let apart = offset[0].hypot(offset[1]);
        for d in &twice.offsets_m {
            assert!((d - apart).abs() < 0.1, "{d} m, not {apart} m");
        }
        let here = twice.at([150.0, 8.0]);
        assert!(
            (here[(0, 0)].sqrt() - 1.5).abs() < 0.1 && (here[(1, 1)].sqrt() - 0.4).abs() < 0.1,
            "{here}"
        );
        // The last 100 m were driven once.
        assert_eq!(twice.at([350.0, 8.0]), Matrix3::zeros());
        // 50 m down the street across at 100 m, whose fronts both passes saw: the offset
        // is kept where the passes drove, not wherever their scans overlap.
        assert_eq!(twice.at([105.0, 50.0]), Matrix3::zeros());
    }
}
