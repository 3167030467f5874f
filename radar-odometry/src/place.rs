//! Place recognition without IO: a polar descriptor of the points around a place (a "scan
//! context", Kim and Kim, IROS 2018), compared under every rotation, with a rotation-invariant
//! ring key for fast retrieval of the nearest earlier places from a k-d tree (kiddo).
//!
//! **Why this descriptor.** A radar place is a 2-D point set: the front end's points or the
//! features a local map holds, in the frame of the place's origin. A polar grid around that
//! origin (rings of range x sectors of bearing) keeps the layout of the place, not only
//! statistics of it, so two streets of a regular city that differ only in where their poles
//! and trees stand still differ; a rotation of the vehicle is a circular shift of the
//! sectors, so comparing under every shift is rotation invariant and gives the relative
//! heading as a by-product, which the loop-closure verifier then starts from. A per-ring
//! summary (the mean over the sectors) does not change under a rotation: it is the key that
//! retrieves candidates in a k-d tree before any full comparison. Radar returns are sparse and
//! their positions jitter by a bin or a beam, and a revisit passes up to metres beside the
//! first visit: each point is therefore spread over the cells near it by a Gaussian kernel
//! ([`PlaceSettings::blur_m`]) and a cell holds the largest kernel value reaching it (a soft
//! occupancy in `[0, 1]`: points seen twice, e.g. by two overlapping local maps, count once).
//! A Radon-based or learned descriptor was not chosen: the first needs dense images the
//! front end does not keep, the second training data we do not have.
//!
//! Memory is bounded by construction: a descriptor is [`RINGS`] x [`SECTORS`] cells whatever
//! the number of points, and building one allocates nothing per point.

use std::f64::consts::TAU;

use kiddo::{ImmutableKdTree, SquaredEuclidean};

/// Rings of range.
pub const RINGS: usize = 20;
/// Sectors of bearing (6 degrees each).
pub const SECTORS: usize = 60;
const CELLS: usize = RINGS * SECTORS;

/// How a descriptor is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaceSettings {
    /// Points further than this from the origin are left out (m); the rings divide it.
    pub max_range_m: f64,
    /// Standard deviation of the kernel each point is spread by (m).
    pub blur_m: f64,
    /// Fewest points (inside the range) for a descriptor.
    pub min_points: usize,
    /// A query is described around origins shifted up to this far (m, each axis) from its
    /// own, on a grid of [`Self::search_step_m`]: a revisit passes metres beside the first
    /// visit, and a polar descriptor is sensitive to where its centre is.
    pub search_reach_m: f64,
    /// Spacing of that grid (m).
    pub search_step_m: f64,
}

/// Shifted origins a query is described around at most.
pub const MAX_SHIFTS: usize = 441;

impl Default for PlaceSettings {
    fn default() -> Self {
        Self {
            max_range_m: 80.0,
            blur_m: 2.0,
            min_points: 12,
            search_reach_m: 8.0,
            search_step_m: 2.0,
        }
    }
}

/// Why no descriptor was made.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PlaceError {
    /// Too few finite points inside the range.
    #[error("{found} points within range, a place needs at least {needed}")]
    TooFewPoints {
        /// Points found.
        found: usize,
        /// Points needed.
        needed: usize,
    },
    /// The settings are not usable: a range, blur or search step not finite and positive,
    /// a negative reach, or more than [`MAX_SHIFTS`] shifted origins.
    #[error("place settings out of bounds: range {max_range_m} m, blur {blur_m} m, search reach {search_reach_m} m every {search_step_m} m (at most {MAX_SHIFTS} shifts)")]
    BadSettings {
        /// The range given.
        max_range_m: f64,
        /// The blur given.
        blur_m: f64,
        /// The search reach given.
        search_reach_m: f64,
        /// The search step given.
        search_step_m: f64,
    },
}

/// A place: the soft occupancy of [`RINGS`] x [`SECTORS`] polar cells around its origin.
#[derive(Clone, PartialEq)]
pub struct PlaceDescriptor {
    /// Row-major: `cells[ring * SECTORS + sector]`; sector 0 starts at bearing 0 (the
    /// origin's x axis), counter-clockwise.
    cells: Box<[f32; CELLS]>,
    ring_key: [f32; RINGS],
    points: usize,
}

impl std::fmt::Debug for PlaceDescriptor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PlaceDescriptor")
            .field("points", &self.points)
            .field("ring_key", &self.ring_key)
            .finish_non_exhaustive()
    }
}

/// Two places compared under every rotation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaceMatch {
    /// Distance at the best rotation: one minus the cosine similarity of the two grids of
    /// cells (the second's sectors shifted), in `[0, 1]` (0: the same place). Scan Context
    /// averages the cosines of single sectors instead; with sparse radar points most sectors
    /// hold one or two points and the whole-grid cosine separated places better.
    pub distance: f64,
    /// The heading of the other place's frame in this one's (rad, in `(-pi, pi]`), to
    /// within a fraction of a sector.
    pub yaw_rad: f64,
    /// Sectors compared (occupied in both at the best rotation).
    pub sectors: usize,
}

impl PlaceSettings {
    /// The shifted origins a query is described around, nearest the centre first.
    pub fn shifts(&self) -> Result<Vec<[f64; 2]>, PlaceError> {
        self.check()?;
        let n = (self.search_reach_m / self.search_step_m).floor() as i64;
        let mut out: Vec<[f64; 2]> = (-n..=n)
            .flat_map(|i| (-n..=n).map(move |j| [i as f64, j as f64]))
            .map(|[i, j]| [i * self.search_step_m, j * self.search_step_m])
            .collect();
        out.sort_by(|a, b| a[0].hypot(a[1]).total_cmp(&b[0].hypot(b[1])));
        Ok(out)
    }

    fn check(&self) -> Result<(), PlaceError> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let ok = positive(self.max_range_m)
            && positive(self.blur_m)
            && positive(self.search_step_m)
            && self.search_reach_m.is_finite()
            && self.search_reach_m >= 0.0
            && {
                let side = 2.0 * (self.search_reach_m / self.search_step_m).floor() + 1.0;
                side * side <= MAX_SHIFTS as f64
            };
        if ok {
            Ok(())
        } else {
            Err(PlaceError::BadSettings {
                max_range_m: self.max_range_m,
                blur_m: self.blur_m,
                search_reach_m: self.search_reach_m,
                search_step_m: self.search_step_m,
            })
        }
    }
}

/// A place to look up: its descriptor around shifted origins ([`PlaceSettings::shifts`]).
#[derive(Debug, Clone)]
pub struct PlaceQuery {
    /// `(shift, descriptor around it)`, the unshifted first.
    pub shifted: Vec<([f64; 2], PlaceDescriptor)>,
}

/// The best match of a query against a place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QueryMatch {
    /// The match at the best shift.
    pub place: PlaceMatch,
    /// That shift (m, in the query's frame).
    pub shift: [f64; 2],
    /// The query's frame in the place's implied by it: the query's shifted origin lies on
    /// the place's origin, turned by the yaw (a guess to within about a search step and a
    /// sector).
    pub transform: [f64; 3],
}

impl PlaceQuery {
    /// Describes `points` (in the query's frame) around every shifted origin; shifts with
    /// too few points are left out (an error when none is left).
    pub fn new(points: &[[f64; 2]], settings: &PlaceSettings) -> Result<Self, PlaceError> {
        let mut shifted = Vec::new();
        let mut last = None;
        for shift in settings.shifts()? {
            match PlaceDescriptor::new_at(points.iter().copied(), shift, settings) {
                Ok(d) => shifted.push((shift, d)),
                Err(e) => last = Some(e),
            }
        }
        match (shifted.is_empty(), last) {
            (true, Some(e)) => Err(e),
            _ => Ok(Self { shifted }),
        }
    }

    /// Compares every shifted descriptor with `place`: the best.
    pub fn compare(&self, place: &PlaceDescriptor) -> Option<QueryMatch> {
        self.shifted
            .iter()
            .map(|(shift, d)| {
                let m = place.compare(d);
                let (s, c) = m.yaw_rad.sin_cos();
                QueryMatch {
                    place: m,
                    shift: *shift,
                    transform: [
                        -(c * shift[0] - s * shift[1]),
                        -(s * shift[0] + c * shift[1]),
                        m.yaw_rad,
                    ],
                }
            })
            .min_by(|a, b| a.place.distance.total_cmp(&b.place.distance))
    }
}

impl PlaceDescriptor {
    /// The descriptor of `points` (x, y in the place's frame, m); non-finite points and
    /// points beyond the range are left out.
    pub fn new(
        points: impl IntoIterator<Item = [f64; 2]>,
        settings: &PlaceSettings,
    ) -> Result<Self, PlaceError> {
        Self::new_at(points, [0.0, 0.0], settings)
    }

    /// The descriptor of the place around `origin` (in the points' frame, axes unchanged).
    pub fn new_at(
        points: impl IntoIterator<Item = [f64; 2]>,
        origin: [f64; 2],
        settings: &PlaceSettings,
    ) -> Result<Self, PlaceError> {
        settings.check()?;
        let (range, blur) = (settings.max_range_m, settings.blur_m);
        let ring_m = range / RINGS as f64;
        let sector_rad = TAU / SECTORS as f64;
        let reach = 3.0 * blur;
        let ring_reach = (reach / ring_m).ceil() as i64;
        let inv_two_var = 1.0 / (2.0 * blur * blur);
        // Each sector's centre bearing, and how many sectors either side of a point's own a
        // ring's cells can lie within the kernel's reach: the same for every point.
        let centre: [(f64, f64); SECTORS] = std::array::from_fn(|si| {
            let b = (si as f64 + 0.5) * sector_rad;
            (b.cos(), b.sin())
        });
        let halves: [i64; RINGS] = std::array::from_fn(|ri| {
            let rc = (ri as f64 + 0.5) * ring_m;
            let half = if rc > reach {
                ((reach / rc).asin() / sector_rad).ceil() as i64 + 1
            } else {
                SECTORS as i64 / 2
            };
            half.min(SECTORS as i64 / 2)
        });
        // The nearest point's squared distance from each cell's centre: the kernel falls
        // with distance, so the largest value reaching a cell is the nearest point's, and it
        // is taken once a cell, not once a point and cell.
        let mut nearest = Box::new([f64::INFINITY; CELLS]);
        let mut n = 0usize;
        for [px, py] in points {
            let (x, y) = (px - origin[0], py - origin[1]);
            let r = x.hypot(y);
            if !(r.is_finite() && r < range) {
                continue;
            }
            n += 1;
            let bearing = y.atan2(x).rem_euclid(TAU);
            let ring = (r / ring_m) as i64;
            let sector = (bearing / sector_rad) as i64;
            for ri in (ring - ring_reach).max(0)..=(ring + ring_reach).min(RINGS as i64 - 1) {
                let rc = (ri as f64 + 0.5) * ring_m;
                let half = halves[ri as usize];
                let row = &mut nearest[ri as usize * SECTORS..(ri as usize + 1) * SECTORS];
                for ds in -half..=half {
                    // `sector` is within [0, SECTORS] (a bearing may round up to a turn) and `half`
                    // at most SECTORS / 2: one wrap is enough.
                    let si = match sector + ds {
                        s if s < 0 => s + SECTORS as i64,
                        s if s >= SECTORS as i64 => s - SECTORS as i64,
                        s => s,
                    } as usize;
                    let (cos, sin) = centre[si];
                    let (cx, cy) = (rc * cos, rc * sin);
                    let d2 = (cx - x) * (cx - x) + (cy - y) * (cy - y);
                    let cell = &mut row[si];
                    if d2 < *cell {
                        *cell = d2;
                    }
                }
            }
        }
        let mut cells = Box::new([0f32; CELLS]);
        for (cell, &d2) in cells.iter_mut().zip(nearest.iter()) {
            if d2.is_finite() {
                *cell = (-d2 * inv_two_var).exp() as f32;
            }
        }
        if n < settings.min_points {
            return Err(PlaceError::TooFewPoints {
                found: n,
                needed: settings.min_points,
            });
        }
        let mut ring_key = [0f32; RINGS];
        for (ring, key) in ring_key.iter_mut().enumerate() {
            let row = &cells[ring * SECTORS..(ring + 1) * SECTORS];
            *key = row.iter().sum::<f32>() / SECTORS as f32;
        }
        Ok(Self {
            cells,
            ring_key,
            points: n,
        })
    }

    /// The rotation-invariant key: each ring's mean occupancy.
    pub fn ring_key(&self) -> &[f32; RINGS] {
        &self.ring_key
    }

    /// Points that went into it.
    pub fn points(&self) -> usize {
        self.points
    }

    /// Bytes held (fixed).
    pub const fn heap_bytes() -> usize {
        CELLS * std::mem::size_of::<f32>()
    }

    fn column(&self, sector: usize) -> impl Iterator<Item = f32> + '_ {
        (0..RINGS).map(move |r| self.cells[r * SECTORS + sector])
    }

    /// Distance under a shift of `shift` sectors (`other`'s sector `j` against this one's
    /// `j + shift`), with the sectors occupied in both.
    fn shifted(
        &self,
        other: &Self,
        norms: &[f32; SECTORS],
        other_norms: &[f32; SECTORS],
        shift: usize,
    ) -> (f64, usize) {
        let (mut dot, mut used) = (0.0f64, 0usize);
        for (j, &nb) in other_norms.iter().enumerate() {
            let i = (j + shift) % SECTORS;
            let na = norms[i];
            if na <= 0.0 || nb <= 0.0 {
                continue;
            }
            let d: f32 = self
                .column(i)
                .zip(other.column(j))
                .map(|(a, b)| a * b)
                .sum();
            dot += f64::from(d);
            used += 1;
        }
        let total = |n: &[f32; SECTORS]| n.iter().map(|v| f64::from(v * v)).sum::<f64>().sqrt();
        let denom = total(norms) * total(other_norms);
        if used == 0 || denom <= 0.0 {
            (1.0, 0)
        } else {
            (1.0 - dot / denom, used)
        }
    }

    fn column_norms(&self) -> [f32; SECTORS] {
        let mut norms = [0f32; SECTORS];
        for (s, n) in norms.iter_mut().enumerate() {
            *n = self.column(s).map(|v| v * v).sum::<f32>().sqrt();
        }
        norms
    }

    /// Compares `other` with this place under every rotation: the best distance and the
    /// heading of `other`'s frame in this one's (refined between sectors by a parabola
    /// through the best shift and its neighbours).
    pub fn compare(&self, other: &Self) -> PlaceMatch {
        let (na, nb) = (self.column_norms(), other.column_norms());
        let scores: Vec<(f64, usize)> = (0..SECTORS)
            .map(|s| self.shifted(other, &na, &nb, s))
            .collect();
        let best = (0..SECTORS)
            .min_by(|&a, &b| scores[a].0.total_cmp(&scores[b].0))
            .unwrap_or(0);
        let (d0, used) = scores[best];
        let dm = scores[(best + SECTORS - 1) % SECTORS].0;
        let dp = scores[(best + 1) % SECTORS].0;
        let curvature = dm - 2.0 * d0 + dp;
        let offset = if curvature > 1e-12 {
            (0.5 * (dm - dp) / curvature).clamp(-0.5, 0.5)
        } else {
            0.0
        };
        let yaw = (best as f64 + offset) * TAU / SECTORS as f64;
        PlaceMatch {
            distance: d0.clamp(0.0, 1.0),
            yaw_rad: radar_model::geometry::wrap_angle(yaw),
            sectors: used,
        }
    }
}

/// Ring keys of many places, for the nearest ones to a query: a k-d tree (kiddo's immutable
/// tree, which takes any number of equal keys) rebuilt on the first query after places were
/// added, O(n log n) over the places indexed.
#[derive(Debug, Clone, Default)]
pub struct PlaceIndex {
    keys: Vec<[f32; RINGS]>,
    ids: Vec<u64>,
    tree: Option<ImmutableKdTree<f32, RINGS>>,
}

impl PlaceIndex {
    /// An empty index.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a place under `id`.
    pub fn insert(&mut self, id: u64, place: &PlaceDescriptor) {
        self.keys.push(place.ring_key);
        self.ids.push(id);
        self.tree = None;
    }

    /// Places indexed.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// No place indexed.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// The ids of the (at most) `k` places whose ring keys are nearest `query`'s, nearest
    /// first, with the squared key distance.
    pub fn nearest(&mut self, query: &PlaceDescriptor, k: usize) -> Vec<(u64, f32)> {
        let Some(k) = std::num::NonZero::new(k.min(self.keys.len())) else {
            return Vec::new();
        };
        let tree = self
            .tree
            .get_or_insert_with(|| ImmutableKdTree::new_from_slice(&self.keys));
        tree.nearest_n::<SquaredEuclidean>(&query.ring_key, k)
            .into_iter()
            .filter_map(|nb| Some((*self.ids.get(nb.item as usize)?, nb.distance)))
            .collect()
    }

    /// The (at most) `k` places whose ring keys come nearest any of the query's shifted
    /// descriptors' (each shift's `k` nearest, merged by the smallest key distance).
    pub fn nearest_to_query(&mut self, query: &PlaceQuery, k: usize) -> Vec<(u64, f32)> {
        let mut best: Vec<(u64, f32)> = Vec::new();
        for (_, d) in &query.shifted {
            for (id, dist) in self.nearest(d, k) {
                match best.iter_mut().find(|(i, _)| *i == id) {
                    Some(b) => b.1 = b.1.min(dist),
                    None => best.push((id, dist)),
                }
            }
        }
        best.sort_by(|a, b| a.1.total_cmp(&b.1));
        best.truncate(k);
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each cell as the descriptor defines it, point by point: the largest kernel value of
    /// the points whose reach (the rings and sectors a point's kernel can touch) covers it.
    fn cells_point_by_point(points: &[[f64; 2]], settings: &PlaceSettings) -> Vec<f32> {
        let ring_m = settings.max_range_m / RINGS as f64;
        let sector_rad = TAU / SECTORS as f64;
        let reach = 3.0 * settings.blur_m;
        let ring_reach = (reach / ring_m).ceil() as i64;
        let mut cells = vec![0f32; CELLS];
        for &[x, y] in points {
            let r = x.hypot(y);
            if r >= settings.max_range_m {
                continue;
            }
            let ring = (r / ring_m) as i64;
            let sector = (y.atan2(x).rem_euclid(TAU) / sector_rad) as i64;
            for ri in (ring - ring_reach).max(0)..=(ring + ring_reach).min(RINGS as i64 - 1) {
                let rc = (ri as f64 + 0.5) * ring_m;
                let half = if rc > reach {
                    ((reach / rc).asin() / sector_rad).ceil() as i64 + 1
                } else {
                    SECTORS as i64 / 2
                }
                .min(SECTORS as i64 / 2);
                for ds in -half..=half {
                    let si = (sector + ds).rem_euclid(SECTORS as i64);
                    let b = (si as f64 + 0.5) * sector_rad;
                    let d2 = (rc * b.cos() - x).powi(2) + (rc * b.sin() - y).powi(2);
                    let w = (-d2 / (2.0 * settings.blur_m * settings.blur_m)).exp() as f32;
                    let cell = &mut cells[ri as usize * SECTORS + si as usize];
                    *cell = cell.max(w);
                }
            }
        }
        cells
    }

    #[test]
    fn each_cell_holds_the_largest_kernel_value_that_reaches_it() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut uniform = move || rng.gen::<f64>();
        let settings = PlaceSettings::default();
        // Near the origin (every sector in reach), along the range's edge, and between.
        let points: Vec<[f64; 2]> = (0..3000)
            .map(|i| {
                let r = match i % 3 {
                    0 => 3.0 * uniform(),
                    1 => settings.max_range_m - 2.0 * uniform(),
                    _ => settings.max_range_m * uniform(),
                };
                let b = TAU * uniform();
                [r * b.cos(), r * b.sin()]
            })
            .collect();
        let d = PlaceDescriptor::new(points.iter().copied(), &settings).unwrap();
        let want = cells_point_by_point(&points, &settings);
        let differ = d
            .cells
            .iter()
            .zip(&want)
            .filter(|(a, b)| (**a - **b).abs() > 1e-6)
            .count();
        assert_eq!(differ, 0, "{differ} of {CELLS} cells differ");
        assert!(want.iter().any(|&w| w > 0.0 && w < 1.0));
    }
}
