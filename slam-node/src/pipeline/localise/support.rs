//! How much of the local map a transform explains: the count of local features it puts
//! within [`INLIER_M`] of a map feature, after polishing the transform by a few rounds of
//! nearest-neighbour rigid fitting. The search compares places by it: the winning place must
//! explain clearly more of the local map than any other place of the map
//! ([`super::search::RIVAL_SHARE`]). Unlike the verifier's verdict (which refuses a place
//! where the map holds a street twice, a metre or two apart, as ambiguous), this count is
//! the same for a place that fits twice as for one that fits once, so a place the verifier
//! refuses can still be a rival. No IO.

use std::collections::HashMap;

use radar_model::geometry::{wrap_angle, Pose2};
use slam_graph::se2::transform_point;

/// A local feature this near a map feature (m) under the transform is explained.
pub const INLIER_M: f64 = 1.5;
/// Polishing pairs points this near at first (m), shrinking to [`INLIER_M`].
const POLISH_START_M: f64 = 4.0;
/// Polishing rounds.
const POLISH_ROUNDS: usize = 6;
/// The grid's cell (m): at least the largest search radius.
const CELL_M: f64 = POLISH_START_M;

/// The map's well-seen features on a grid of [`CELL_M`] cells.
#[derive(Debug, Clone, Default)]
pub struct MapGrid {
    cells: HashMap<(i64, i64), Vec<[f64; 2]>>,
}

fn cell(p: [f64; 2]) -> (i64, i64) {
    // Saturating float-to-int casts: a point far outside any map lands in an edge cell.
    (
        (p[0] / CELL_M).floor() as i64,
        (p[1] / CELL_M).floor() as i64,
    )
}

impl MapGrid {
    /// The grid of `points` (the map's frame).
    pub fn new(points: impl IntoIterator<Item = [f64; 2]>) -> Self {
        let mut cells: HashMap<(i64, i64), Vec<[f64; 2]>> = HashMap::new();
        for p in points {
            if p[0].is_finite() && p[1].is_finite() {
                cells.entry(cell(p)).or_default().push(p);
            }
        }
        Self { cells }
    }

    /// The map point nearest `p` within `r` (at most [`CELL_M`]).
    pub fn nearest(&self, p: [f64; 2], r: f64) -> Option<[f64; 2]> {
        let (cx, cy) = cell(p);
        let mut best: Option<([f64; 2], f64)> = None;
        for dx in -1..=1 {
            for dy in -1..=1 {
                let Some(points) = self
                    .cells
                    .get(&(cx.saturating_add(dx), cy.saturating_add(dy)))
                else {
                    continue;
                };
                for q in points {
                    let d = (q[0] - p[0]).hypot(q[1] - p[1]);
                    if d <= r && best.is_none_or(|(_, b)| d < b) {
                        best = Some((*q, d));
                    }
                }
            }
        }
        best.map(|(q, _)| q)
    }

    /// Local points (`local`, in the local frame) that `t` (the local frame in the map's)
    /// puts within [`INLIER_M`] of a map point.
    pub fn inliers(&self, local: &[[f64; 2]], t: &Pose2) -> usize {
        local
            .iter()
            .filter(|p| self.nearest(transform_point(t, **p), INLIER_M).is_some())
            .count()
    }

    /// `guess` polished by nearest-neighbour rigid fits (the pairing radius shrinking from
    /// [`POLISH_START_M`] to [`INLIER_M`]), and the local points it then explains.
    pub fn fit(&self, local: &[[f64; 2]], guess: Pose2) -> (Pose2, usize) {
        let mut t = guess;
        for round in 0..POLISH_ROUNDS {
            let f = round as f64 / (POLISH_ROUNDS - 1) as f64;
            let r = POLISH_START_M + f * (INLIER_M - POLISH_START_M);
            let pairs: Vec<([f64; 2], [f64; 2])> = local
                .iter()
                .filter_map(|p| self.nearest(transform_point(&t, *p), r).map(|q| (*p, q)))
                .collect();
            match rigid_fit(&pairs) {
                Some(next) => t = next,
                None => break,
            }
        }
        (t, self.inliers(local, &t))
    }
}

/// The rigid transform `t` minimising the sum of `|t(b) - a|^2` over pairs `(b, a)`;
/// `None` under three pairs.
pub fn rigid_fit(pairs: &[([f64; 2], [f64; 2])]) -> Option<Pose2> {
    if pairs.len() < 3 {
        return None;
    }
    let n = pairs.len() as f64;
    let (mut cb, mut ca) = ([0.0; 2], [0.0; 2]);
    for (b, a) in pairs {
        cb = [cb[0] + b[0] / n, cb[1] + b[1] / n];
        ca = [ca[0] + a[0] / n, ca[1] + a[1] / n];
    }
    let (mut dot, mut cross) = (0.0, 0.0);
    for (b, a) in pairs {
        let (bx, by) = (b[0] - cb[0], b[1] - cb[1]);
        let (ax, ay) = (a[0] - ca[0], a[1] - ca[1]);
        dot += bx * ax + by * ay;
        cross += bx * ay - by * ax;
    }
    if dot == 0.0 && cross == 0.0 {
        return None;
    }
    let theta = cross.atan2(dot);
    let (s, c) = theta.sin_cos();
    let x = ca[0] - (c * cb[0] - s * cb[1]);
    let y = ca[1] - (s * cb[0] + c * cb[1]);
    Some(Pose2::new(x, y, wrap_angle(theta)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scatter(n: usize) -> Vec<[f64; 2]> {
        (0..n)
            .map(|i| {
                let k = i as f64;
                [(k * 37.3) % 97.0 - 48.0, (k * k * 11.7) % 83.0 - 41.0]
            })
            .collect()
    }

    #[test]
    fn the_fit_recovers_a_transform_from_a_guess_a_few_metres_off() {
        let map = scatter(60);
        let truth = Pose2::new(12.0, -7.0, 0.3);
        let back = slam_graph::se2::inverse(&truth);
        let local: Vec<[f64; 2]> = map.iter().map(|p| transform_point(&back, *p)).collect();
        let grid = MapGrid::new(map.iter().copied());
        let (t, n) = grid.fit(&local, Pose2::new(13.5, -6.0, 0.33));
        assert_eq!(n, 60);
        assert!((t.x - truth.x).hypot(t.y - truth.y) < 1e-6, "{t:?}");
        assert!(wrap_angle(t.theta - truth.theta).abs() < 1e-9);
        // Somewhere else the same points explain little.
        assert!(grid.inliers(&local, &Pose2::new(40.0, 30.0, 1.0)) < 10);
    }

    #[test]
    fn a_map_holding_a_place_twice_explains_it_as_well_as_once() {
        let map = scatter(40);
        let mut twice = map.clone();
        twice.extend(map.iter().map(|p| [p[0] + 1.2, p[1] - 0.8]));
        let grid = MapGrid::new(twice);
        let (_, n) = grid.fit(&map, Pose2::new(0.5, 0.5, 0.0));
        assert_eq!(n, 40);
    }

    #[test]
    fn rigid_fit_needs_three_pairs_and_ignores_non_finite_points() {
        assert!(rigid_fit(&[([0.0, 0.0], [1.0, 1.0]), ([1.0, 0.0], [2.0, 1.0])]).is_none());
        let grid = MapGrid::new([[f64::NAN, 0.0], [1.0, 1.0]]);
        assert_eq!(grid.nearest([1.2, 1.0], 1.0), Some([1.0, 1.0]));
        assert_eq!(grid.nearest([1e300, -1e300], 1.0), None);
    }
}
