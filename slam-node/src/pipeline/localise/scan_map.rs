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

use radar_model::geometry::Pose2;
use radar_odometry::{PlaceDescriptor, PlaceIndex, PlaceSettings, ReferenceCloud};
use slam_graph::correlate::ScoreGrid;
use slam_graph::scans::SCAN_NORMAL_RADIUS_M;
use slam_graph::se2::transform_point;
use slam_map::Map;

use super::known::MapFeatures;
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
        let mut points = Vec::with_capacity(map.scan_point_count());
        for (k, (frame, _)) in frames.frames.iter().enumerate() {
            if let Some(scan) = map.scan_of(k) {
                points.extend(
                    scan.iter()
                        .map(|q| transform_point(frame, [f64::from(q[0]), f64::from(q[1])]))
                        .filter(|p| p[0].is_finite() && p[1].is_finite()),
                );
            }
        }
        Self::from_points(points, frames)
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
