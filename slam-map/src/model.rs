//! The map's contents: the types the payload is encoded from, field by field.
//!
//! These structs *are* the wire schema of format version [`crate::FORMAT_VERSION`]: postcard
//! encodes their fields in declaration order, without names. Changing a field (its type,
//! its order, adding or removing one) changes the format and must bump the version;
//! `tests/golden.rs` pins the encoding of a fixed map so that such a change cannot go
//! unnoticed. The document `docs/map-format.md` describes every field.
//!
//! Plain arrays rather than nalgebra types, so that the encoding does not depend on another
//! crate's serde representation. Symmetric matrices are stored as their upper triangle,
//! row by row ([`Sym2`], [`Sym3`]).

use nalgebra::{Matrix2, Matrix3};
use radar_model::geometry::Pose2;
use serde::{Deserialize, Serialize};

/// A symmetric 2x2 matrix, upper triangle row by row: `[xx, xy, yy]`.
pub type Sym2 = [f64; 3];

/// A symmetric 3x3 matrix over `(x, y, theta)`, upper triangle row by row:
/// `[xx, xy, xt, yy, yt, tt]`.
pub type Sym3 = [f64; 6];

/// The symmetric part of `m`, packed.
pub fn pack2(m: &Matrix2<f64>) -> Sym2 {
    [m[(0, 0)], 0.5 * (m[(0, 1)] + m[(1, 0)]), m[(1, 1)]]
}

/// The matrix of a packed [`Sym2`].
pub fn unpack2(s: &Sym2) -> Matrix2<f64> {
    Matrix2::new(s[0], s[1], s[1], s[2])
}

/// The symmetric part of `m`, packed.
pub fn pack3(m: &Matrix3<f64>) -> Sym3 {
    let h = |r: usize, c: usize| 0.5 * (m[(r, c)] + m[(c, r)]);
    [m[(0, 0)], h(0, 1), h(0, 2), m[(1, 1)], h(1, 2), m[(2, 2)]]
}

/// The matrix of a packed [`Sym3`].
pub fn unpack3(s: &Sym3) -> Matrix3<f64> {
    Matrix3::new(s[0], s[1], s[2], s[1], s[3], s[4], s[2], s[4], s[5])
}

/// A frame or a relative transform: origin `(x, y)` (m) and heading `theta` (rad,
/// counter-clockwise from +x) in the parent frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// m.
    pub x: f64,
    /// m.
    pub y: f64,
    /// rad.
    pub theta: f64,
}

impl From<Pose2> for Pose {
    fn from(p: Pose2) -> Self {
        Self {
            x: p.x,
            y: p.y,
            theta: p.theta,
        }
    }
}

impl From<Pose> for Pose2 {
    fn from(p: Pose) -> Self {
        Pose2::new(p.x, p.y, p.theta)
    }
}

/// The radar the map was made with: the profile's name and the geometry that decides
/// whether another radar's looks can be matched against the map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapProfile {
    /// The profile's name (`radar_model::profile`, the `[radar] model` key).
    pub name: String,
    /// Azimuths per rotation.
    pub azimuths: u16,
    /// Encoder counts per revolution.
    pub encoder_size: u16,
    /// Range bins per azimuth.
    pub range_bins: u16,
    /// Bin size (m).
    pub bin_size_m: f64,
}

impl From<&radar_model::profile::RadarProfile> for MapProfile {
    fn from(p: &radar_model::profile::RadarProfile) -> Self {
        Self {
            name: p.name.to_owned(),
            azimuths: p.azimuths.value,
            encoder_size: p.encoder_size.value,
            range_bins: p.range_bins.value,
            bin_size_m: p.bin_size_m.value,
        }
    }
}

/// A mapped feature, in its submap's frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MapFeature {
    /// The filter's id (unique across the submaps of one run; ids of different runs may
    /// repeat).
    pub id: u64,
    /// Position in the submap's frame (m).
    pub xy: [f64; 2],
    /// Its marginal covariance (m^2).
    pub xy_cov: Sym2,
    /// Material logits `(u, v)`: reflectivity `rho = e^u / (e^u + e^v + 1)`, absorption
    /// `alpha = e^v / (e^u + e^v + 1)` (radar-model's `material`).
    pub uv: [f64; 2],
    /// Their marginal covariance.
    pub uv_cov: Sym2,
    /// Observations the filter used for it.
    pub hits: u64,
}

impl MapFeature {
    /// Reflectivity, absorption and transmitted share from the logits.
    pub fn shares(&self) -> radar_model::material::Shares {
        radar_model::material::Material::new(self.uv[0], self.uv[1]).shares()
    }
}

/// A place descriptor of a submap: an opaque vector whose meaning its `kind` and `version`
/// name (the place recognition that made it reads it; nothing else does).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaceDescriptor {
    /// Which descriptor (e.g. `"scan-context"`).
    pub kind: String,
    /// The descriptor's own version: a reader refuses versions it does not know.
    pub version: u32,
    /// The values.
    pub values: Vec<f32>,
}

/// A submap: a node of the global graph and the features mapped in its frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapSubmap {
    /// The submap's frame in the map (submap 0's frame is the map's).
    pub frame: Pose,
    /// Its marginal covariance in the global graph (zero for submap 0, which defines the
    /// map's frame).
    pub frame_cov: Sym3,
    /// The vehicle's pose when the submap was closed, in the submap's frame: the next
    /// submap's frame (the chain edge of the graph).
    pub end_pose: Pose,
    /// Its covariance, in the submap's frame.
    pub end_cov: Sym3,
    /// The time the submap was closed (s, the run's clock).
    pub end_s: f64,
    /// The radar loss L when it was closed (dB).
    pub loss_db: f64,
    /// The features.
    pub features: Vec<MapFeature>,
    /// Its place descriptor, when place recognition made one.
    pub descriptor: Option<PlaceDescriptor>,
}

/// A loop closure: submap `to`'s frame measured in submap `from`'s by matched features.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LoopEdge {
    /// The earlier submap (index into [`Map::submaps`]).
    pub from: u32,
    /// The later submap.
    pub to: u32,
    /// `to`'s frame in `from`'s.
    pub transform: Pose,
    /// Its covariance (x, y, theta in `from`'s frame); the information matrix is its inverse.
    pub covariance: Sym3,
    /// Features matched.
    pub matches: u32,
}

/// A submap's scan (format version 3): the radar's returns that the run registered (walls,
/// fences, cars and poles alike), gathered over the submap's rotations in its frame and
/// thinned to one point per cell seen in at least two rotations (slam-graph's
/// `ScanAccumulator`). Loop closure verifies a closure to this submap by registering
/// scans, and describes its place from it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapScan {
    /// The submap (index into [`Map::submaps`]; the scans are in increasing submap order,
    /// one at most per submap).
    pub submap: u32,
    /// The points in the submap's frame (m), at most [`crate::MAX_SCAN_POINTS`].
    pub points: Vec<[f32; 2]>,
}

/// Where the vehicle drove through a submap (format version 4): its positions in the
/// submap's frame, in the order driven, one each time it had moved
/// [`crate::PATH_SPACING_M`] from the last (the first where the submap began: the origin,
/// except for a drive's first submap, whose frame is the map's), at most
/// [`crate::MAX_PATH_POINTS`]. Localisation uses it to know where a vehicle can stand on
/// each of the map's passes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapPath {
    /// The submap (index into [`Map::submaps`]; the paths are in increasing submap order,
    /// one at most per submap).
    pub submap: u32,
    /// The positions `[x, y]` in the submap's frame (m).
    pub points: Vec<[f32; 2]>,
}

/// A saved map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Map {
    /// When the map was written (seconds since the Unix epoch, UTC).
    pub created_unix_s: u64,
    /// A free note: what made the map (program, version, configuration, input).
    pub source: String,
    /// The radar it was made with.
    pub profile: MapProfile,
    /// The submaps, in the order they were closed (index = node of the graph).
    pub submaps: Vec<MapSubmap>,
    /// The loop closures of the graph.
    pub loops: Vec<LoopEdge>,
    /// The first submap of every drive after the first (format version 2; strictly
    /// increasing, each in `1..submaps.len()`): a drive's first submap has no chain edge
    /// from the submap before it (another drive's last), only its joins and loop closures.
    pub drive_starts: Vec<u32>,
    /// Joins (format version 2): where a later drive's first submap was found in the map
    /// when that drive localised in it (extend mode), as an edge from an earlier submap
    /// (`from`) to the drive's first submap (`to`), with the fix's covariance.
    pub joins: Vec<LoopEdge>,
    /// The submaps' scans (format version 3), for the submaps that kept one.
    pub scans: Vec<MapScan>,
    /// The vehicle's path through each submap (format version 4), for the submaps that
    /// recorded one.
    pub paths: Vec<MapPath>,
}

/// A map in format version 3 (no paths): read, never written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct MapV3 {
    pub created_unix_s: u64,
    pub source: String,
    pub profile: MapProfile,
    pub submaps: Vec<MapSubmap>,
    pub loops: Vec<LoopEdge>,
    pub drive_starts: Vec<u32>,
    pub joins: Vec<LoopEdge>,
    pub scans: Vec<MapScan>,
}

impl From<MapV3> for Map {
    fn from(m: MapV3) -> Self {
        Map {
            created_unix_s: m.created_unix_s,
            source: m.source,
            profile: m.profile,
            submaps: m.submaps,
            loops: m.loops,
            drive_starts: m.drive_starts,
            joins: m.joins,
            scans: m.scans,
            paths: Vec::new(),
        }
    }
}

/// A map in format version 2 (no scans): read, never written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct MapV2 {
    pub created_unix_s: u64,
    pub source: String,
    pub profile: MapProfile,
    pub submaps: Vec<MapSubmap>,
    pub loops: Vec<LoopEdge>,
    pub drive_starts: Vec<u32>,
    pub joins: Vec<LoopEdge>,
}

impl From<MapV2> for Map {
    fn from(m: MapV2) -> Self {
        Map::from(MapV3 {
            created_unix_s: m.created_unix_s,
            source: m.source,
            profile: m.profile,
            submaps: m.submaps,
            loops: m.loops,
            drive_starts: m.drive_starts,
            joins: m.joins,
            scans: Vec::new(),
        })
    }
}

/// A map in format version 1 (no drives, no joins): read, never written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct MapV1 {
    pub created_unix_s: u64,
    pub source: String,
    pub profile: MapProfile,
    pub submaps: Vec<MapSubmap>,
    pub loops: Vec<LoopEdge>,
}

impl From<MapV1> for Map {
    fn from(m: MapV1) -> Self {
        Map::from(MapV2 {
            created_unix_s: m.created_unix_s,
            source: m.source,
            profile: m.profile,
            submaps: m.submaps,
            loops: m.loops,
            drive_starts: Vec::new(),
            joins: Vec::new(),
        })
    }
}

impl Map {
    /// Whether submap `k`'s frame is chained from submap `k - 1`'s end (false for submap 0
    /// and for the first submap of every later drive).
    pub fn chained(&self, k: usize) -> bool {
        k > 0 && !self.drive_starts.iter().any(|&s| s as usize == k)
    }

    /// The drive submap `k` belongs to (0: the first drive).
    pub fn drive_of(&self, k: usize) -> usize {
        self.drive_starts
            .iter()
            .filter(|&&s| s as usize <= k)
            .count()
    }

    /// Submap `k`'s scan, when it kept one.
    pub fn scan_of(&self, k: usize) -> Option<&[[f32; 2]]> {
        let k = u32::try_from(k).ok()?;
        self.scans
            .binary_search_by_key(&k, |s| s.submap)
            .ok()
            .map(|i| &self.scans[i].points[..])
    }

    /// Submap `k`'s path, when it recorded one.
    pub fn path_of(&self, k: usize) -> Option<&[[f32; 2]]> {
        let k = u32::try_from(k).ok()?;
        self.paths
            .binary_search_by_key(&k, |s| s.submap)
            .ok()
            .map(|i| &self.paths[i].points[..])
    }

    /// Scan points over all submaps.
    pub fn scan_point_count(&self) -> usize {
        self.scans.iter().map(|s| s.points.len()).sum()
    }

    /// Features over all submaps.
    pub fn feature_count(&self) -> usize {
        self.submaps.iter().map(|s| s.features.len()).sum()
    }

    /// Every feature in the map's frame: `(submap index, position)`.
    pub fn world_positions(&self) -> impl Iterator<Item = (usize, [f64; 2])> + '_ {
        self.submaps.iter().enumerate().flat_map(|(k, s)| {
            let frame = Pose2::from(s.frame);
            s.features
                .iter()
                .map(move |f| (k, slam_graph::se2::transform_point(&frame, f.xy)))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packing_keeps_a_symmetric_matrix_and_symmetrises_an_asymmetric_one() {
        let m = Matrix3::new(4.0, 0.5, 0.1, 0.5, 3.0, -0.2, 0.1, -0.2, 0.01);
        assert_eq!(unpack3(&pack3(&m)), m);
        let m2 = Matrix2::new(2.0, 0.3, 0.3, 1.0);
        assert_eq!(unpack2(&pack2(&m2)), m2);
        let skew = Matrix2::new(2.0, 0.5, 0.25, 1.0);
        assert_eq!(pack2(&skew), [2.0, 0.375, 1.0]);
    }
}
