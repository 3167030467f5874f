//! The reference cloud a registration pairs against: the previous rotation's points, a k-d
//! tree over them for the widest queries (built at the first), a uniform grid for the registration's gated
//! nearest-neighbour queries, and each point's surface normal where its neighbours lie along a
//! line. Built once a rotation in O(n log n).

use std::sync::OnceLock;

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::grid::PointGrid;

/// The previous rotation's cloud as registrations use it: its points, a k-d tree over them,
/// and each point's surface normal where its neighbours lie along a line (a wall, a fence,
/// a car's side), so that points on a surface pair with the surface, not with whichever
/// sample of it the radar happened to take in the other rotation.
#[derive(Debug)]
pub struct ReferenceCloud {
    pub(crate) points: Vec<[f64; 2]>,
    /// Built at its first query ([`ReferenceCloud::tree`]): a registration whose gates all
    /// stay within the pair grid's reach never needs it.
    tree: OnceLock<ImmutableKdTree<f64, 2>>,
    /// A uniform grid over the points for the registration's gated nearest-neighbour
    /// queries (the k-d tree answers those that would reach too many cells).
    pub(crate) grid: PointGrid,
    /// Unit normal of the local line through each point, `None` where the neighbourhood is
    /// not line-like (an isolated return, a corner, a blob).
    pub(crate) normals: Vec<Option<[f64; 2]>>,
    /// Registrations started from a motion shorter than this (m) pair only with the points
    /// that have a normal ([`ReferenceCloud::surfaces_only_within`]); 0 for none.
    pub(crate) surfaces_only_within_m: f64,
}

/// Neighbours (the point itself included) a normal is fitted to at most.
const NORMAL_NEIGHBOURS: usize = 8;
/// Fewest neighbours (the point itself included) for a normal.
const NORMAL_MIN_NEIGHBOURS: usize = 4;
/// A neighbourhood is a line when its spread across is at most this fraction of its
/// spread along (the ratio of the scatter matrix's eigenvalues).
const LINE_EIGEN_RATIO: f64 = 0.05;

/// A gate reaching more cells than this either side is searched with the k-d tree.
pub(crate) const GRID_MAX_REACH: i64 = 4;

impl ReferenceCloud {
    /// Builds the pair grid (cells half `pair_gate_m` wide; none when that is not positive,
    /// and every pair query goes to the tree) and the normals, once a rotation; the k-d tree
    /// waits for its first query. Neighbours for the normals are taken within `radius_m`.
    pub fn new(points: Vec<[f64; 2]>, radius_m: f64, pair_gate_m: f64) -> Self {
        let grid = PointGrid::new(&points, 0.5 * pair_gate_m);
        let normals = normals(&points, radius_m);
        Self {
            points,
            tree: OnceLock::new(),
            grid,
            normals,
            surfaces_only_within_m: 0.0,
        }
    }

    /// The cloud with the registrations started from a motion shorter than `m` (their
    /// `initial` pose's distance from the cloud's origin) pairing only with its points on
    /// line-like surfaces (walls, fences, cars' sides), not with its isolated returns; 0
    /// for none. For a rotation that moved less than about the pair gate: diffuse returns (the ground's clutter,
    /// one scatterer a square metre) then pair with neighbours a registration cannot tell
    /// from their own, and where something shadows them (a parked car) the shadow's
    /// edges, which are rays from the sensor, turn with it as it moves: on the realistic
    /// city the registrations of a vehicle crawling from the start erred -4 to -8 mrad a
    /// rotation, the same way on eight drives of ten, and the map started turned.
    pub fn surfaces_only_within(mut self, m: f64) -> Self {
        self.surfaces_only_within_m = m;
        self
    }

    /// The points.
    pub fn points(&self) -> &[[f64; 2]] {
        &self.points
    }

    /// The k-d tree over the points, built on the first call.
    pub(crate) fn tree(&self) -> &ImmutableKdTree<f64, 2> {
        self.tree
            .get_or_init(|| ImmutableKdTree::new_from_slice(&self.points))
    }

    /// The point nearest `p` within `max_m`: its index and distance (m); `None` when there
    /// is none that close or the cloud is empty.
    pub fn nearest_within(&self, p: &[f64; 2], max_m: f64) -> Option<(usize, f64)> {
        if self.points.is_empty() {
            return None;
        }
        let nn = self.tree().nearest_one::<SquaredEuclidean>(p);
        let d = nn.distance.max(0.0).sqrt();
        (d <= max_m).then_some((nn.item as usize, d))
    }

    /// The distance from `p` to the surface at its nearest point within `max_m`: along the
    /// point's normal where it lies on a line-like surface, else to the point itself; with
    /// that point's index. `None` when no point is that close.
    pub fn surface_distance(&self, p: &[f64; 2], max_m: f64) -> Option<(usize, f64)> {
        let (i, d) = self.nearest_within(p, max_m)?;
        let q = self.points.get(i)?;
        Some(match self.normal(i) {
            Some(n) => (i, ((p[0] - q[0]) * n[0] + (p[1] - q[1]) * n[1]).abs()),
            None => (i, d),
        })
    }

    /// Point `i`'s normal, `None` when it lies on no line-like surface (or there is no
    /// point `i`).
    pub fn normal(&self, i: usize) -> Option<[f64; 2]> {
        self.normals.get(i).copied().flatten()
    }

    /// Whether point `i` lies on a line-like surface (has a normal).
    pub fn has_normal(&self, i: usize) -> bool {
        self.normal(i).is_some()
    }

    /// How many points have a normal (lie on a line-like surface).
    pub fn with_normals(&self) -> usize {
        self.normals.iter().filter(|n| n.is_some()).count()
    }
}

/// Each point's normal ([`line_normal`]) from its [`NORMAL_NEIGHBOURS`] nearest within
/// `radius_m` (itself included), `None` with fewer than [`NORMAL_MIN_NEIGHBOURS`]. A grid
/// of cells half the radius wide answers the radius queries (25 cells a query): on the
/// realistic city the k-d tree's bounded-heap queries took 2.3 ms a rotation, a seventh of
/// the pipeline's CPU.
pub(crate) fn normals(points: &[[f64; 2]], radius_m: f64) -> Vec<Option<[f64; 2]>> {
    let grid = PointGrid::new(points, 0.5 * radius_m);
    let mut near = Vec::new();
    points
        .iter()
        .map(|p| {
            grid.within(p, radius_m, &mut near);
            if near.len() > NORMAL_NEIGHBOURS {
                near.select_nth_unstable_by(NORMAL_NEIGHBOURS - 1, |a, b| a.1.total_cmp(&b.1));
                near.truncate(NORMAL_NEIGHBOURS);
            }
            if near.len() < NORMAL_MIN_NEIGHBOURS {
                return None;
            }
            line_normal(near.iter().filter_map(|&(i, _)| points.get(i)))
        })
        .collect()
}

/// The unit normal of the line fitted to `points` (principal axes of their scatter), or
/// `None` when they are not line-like.
pub(crate) fn line_normal<'a>(points: impl Iterator<Item = &'a [f64; 2]>) -> Option<[f64; 2]> {
    let (mut n, mut s, mut sxx, mut sxy, mut syy) = (0.0, [0.0; 2], 0.0, 0.0, 0.0);
    for p in points {
        n += 1.0;
        s = [s[0] + p[0], s[1] + p[1]];
        sxx += p[0] * p[0];
        sxy += p[0] * p[1];
        syy += p[1] * p[1];
    }
    if n < 2.0 {
        return None;
    }
    let m = [s[0] / n, s[1] / n];
    let (a, b, c) = (
        sxx / n - m[0] * m[0],
        sxy / n - m[0] * m[1],
        syy / n - m[1] * m[1],
    );
    // Eigenvalues of [[a, b], [b, c]].
    let half_trace = 0.5 * (a + c);
    let root = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let (large, small) = (half_trace + root, half_trace - root);
    if large.is_nan() || large <= 0.0 || small > LINE_EIGEN_RATIO * large {
        return None;
    }
    // The eigenvector of the small eigenvalue: (b, small - a) or (small - c, b).
    let v = if (small - a).abs() + b.abs() > (small - c).abs() + b.abs() {
        [b, small - a]
    } else {
        [small - c, b]
    };
    let norm = v[0].hypot(v[1]);
    (norm > 0.0 && norm.is_finite()).then(|| [v[0] / norm, v[1] / norm])
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A street: two walls and a few posts, seen from the origin.
    pub(crate) fn street() -> Vec<[f64; 2]> {
        let mut pts = Vec::new();
        for i in 0..200 {
            let x = -40.0 + 0.4 * f64::from(i);
            pts.push([x, 8.0 + 0.3 * (0.2 * x).sin()]);
            pts.push([x, -7.5]);
        }
        for k in 0..10 {
            pts.push([-30.0 + 7.0 * f64::from(k), 5.0 + 0.5 * f64::from(k % 3)]);
        }
        pts
    }

    #[test]
    fn a_straight_line_has_a_normal_and_a_blob_has_none() {
        let line: Vec<[f64; 2]> = (0..8).map(|i| [f64::from(i) * 0.2, 1.0]).collect();
        let n = line_normal(line.iter()).expect("a line");
        assert!(
            n[0].abs() < 1e-9 && (n[1].abs() - 1.0).abs() < 1e-9,
            "{n:?}"
        );
        let tilted: Vec<[f64; 2]> = (0..8).map(|i| [f64::from(i), f64::from(i)]).collect();
        let n = line_normal(tilted.iter()).expect("a line");
        assert!((n[0] + n[1]).abs() < 1e-9, "{n:?}");
        let blob = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
        assert!(line_normal(blob.iter()).is_none());
    }

    #[test]
    fn the_pair_grid_finds_the_k_d_trees_nearest_point_within_the_gate() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut uniform = move || rng.gen::<f64>();
        let mut points = street();
        points.extend((0..500).map(|_| [-70.0 + 140.0 * uniform(), -20.0 + 40.0 * uniform()]));
        let gate = 0.6;
        let cloud = ReferenceCloud::new(points.clone(), 1.5, gate);
        assert!(cloud.grid.reach(gate).is_some_and(|r| r <= GRID_MAX_REACH));
        let (mut within, mut beyond) = (0, 0);
        for _ in 0..20_000 {
            let q = [-90.0 + 180.0 * uniform(), -30.0 + 60.0 * uniform()];
            let nn = cloud.tree().nearest_one::<SquaredEuclidean>(&q);
            let grid = cloud.grid.nearest_within(&q, gate);
            if nn.distance <= gate * gate {
                within += 1;
                let (i, d2) = grid.expect("a point within the gate is in a neighbouring cell");
                assert_eq!(d2, nn.distance, "query {q:?}");
                assert_eq!(points[i], points[nn.item as usize]);
            } else {
                beyond += 1;
                assert!(grid.is_none(), "query {q:?}");
            }
        }
        assert!(
            within > 1000 && beyond > 1000,
            "{within} within, {beyond} beyond"
        );
    }
    #[test]
    fn the_grids_normals_are_the_k_d_trees() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        // The street's samples are evenly spaced: jittered, so that no two neighbours tie
        // for the last place (either would do).
        let mut points: Vec<[f64; 2]> = street()
            .into_iter()
            .map(|p| {
                [
                    p[0] + 1e-6 * rng.gen::<f64>(),
                    p[1] + 1e-6 * rng.gen::<f64>(),
                ]
            })
            .collect();
        points.extend((0..800).map(|_| {
            [
                -70.0 + 140.0 * rng.gen::<f64>(),
                -20.0 + 40.0 * rng.gen::<f64>(),
            ]
        }));
        let radius = 1.5;
        let tree = ImmutableKdTree::new_from_slice(&points);
        let k = std::num::NonZero::new(NORMAL_NEIGHBOURS).expect("non-zero");
        let from_tree: Vec<Option<[f64; 2]>> = points
            .iter()
            .map(|p| {
                let near = tree.nearest_n_within::<SquaredEuclidean>(p, radius * radius, k, true);
                (near.len() >= NORMAL_MIN_NEIGHBOURS)
                    .then(|| line_normal(near.iter().map(|nb| &points[nb.item as usize])))
                    .flatten()
            })
            .collect();
        let from_grid = normals(&points, radius);
        assert_eq!(from_grid.len(), points.len());
        // A point that is not finite has no neighbours and no normal.
        assert_eq!(
            normals(&[[f64::NAN, 0.0], [0.0, 0.0]], radius),
            [None, None]
        );
        let mut lines = 0;
        for (i, (g, t)) in from_grid.iter().zip(&from_tree).enumerate() {
            match (g, t) {
                (Some(g), Some(t)) => {
                    lines += 1;
                    assert!(
                        (g[0] * t[1] - g[1] * t[0]).abs() < 1e-9,
                        "point {i}: {g:?} {t:?}"
                    );
                }
                (None, None) => {}
                _ => panic!("point {i} {:?}: grid {g:?}, tree {t:?}", points[i]),
            }
        }
        assert!(lines > 300, "{lines} points on lines");
    }
}
