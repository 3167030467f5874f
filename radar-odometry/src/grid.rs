//! Nearest-point queries within a gate over a fixed set of 2-D points, in bounded memory.

/// Cells a [`PointGrid`] holds at most (a larger cloud or a smaller gate gets larger cells).
const MAX_GRID_CELLS: usize = 1 << 18;

/// A uniform grid over a set of points, sorted by cell (a counting sort): every point within
/// a gate of a query lies within `ceil(gate / cell)` cells of the query's, so the nearest
/// point there is the nearest in the set whenever that one is within the gate. Radar
/// odometry builds one a rotation with cells half its pair gate wide; truth scoring one per
/// run over the scene's features. A few contiguous
/// row slices and distances a query, against a k-d tree's descent; memory 4 bytes a cell
/// (at most [`MAX_GRID_CELLS`]) and 20 a point: the grid keeps its own copy of the points in
/// cell order, so that a row of cells is read from contiguous memory rather than gathered
/// point by point from the caller's order (the same distances, in the same order).
#[derive(Debug, Default)]
pub struct PointGrid {
    origin: [f64; 2],
    cell_m: f64,
    nx: usize,
    ny: usize,
    /// `starts[c]..starts[c + 1]` are cell c's entries in `order` (row-major, y outer).
    starts: Vec<u32>,
    /// Point indices sorted by cell.
    order: Vec<u32>,
    /// The points in `order`'s order: `sorted[k] == points[order[k]]`.
    sorted: Vec<[f64; 2]>,
}

impl PointGrid {
    /// A grid of cells at least `cell_m` wide over the finite points of `points` (wider when
    /// the cloud is too large for [`MAX_GRID_CELLS`] of them).
    pub fn new(points: &[[f64; 2]], cell_m: f64) -> Self {
        let finite = |p: &&[f64; 2]| p[0].is_finite() && p[1].is_finite();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points.iter().filter(finite) {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        if !(lo[0] <= hi[0] && cell_m.is_finite() && cell_m > 0.0) {
            return Self::default();
        }
        let (w, h) = (hi[0] - lo[0], hi[1] - lo[1]);
        // Cells no smaller than asked, and few enough for the bound with every finite point
        // inside the grid (the cloud's far edges included).
        let cell_count =
            |cell: f64| ((w / cell) as usize + 1).saturating_mul((h / cell) as usize + 1);
        let mut cell_m = cell_m.max((w * h / MAX_GRID_CELLS as f64).sqrt());
        while cell_count(cell_m) > MAX_GRID_CELLS {
            cell_m *= 1.0625;
        }
        let nx = (w / cell_m) as usize + 1;
        let ny = (h / cell_m) as usize + 1;
        let mut grid = Self {
            origin: lo,
            cell_m,
            nx,
            ny,
            starts: vec![0; nx * ny + 1],
            order: Vec::new(),
            sorted: Vec::new(),
        };
        // A counting sort in place: each cell's count, then its end (a running sum), then,
        // the points taken last to first, each cell's end moved back over its points to its
        // start, so that a cell keeps its points in their given order.
        let cells: Vec<Option<usize>> = points.iter().map(|p| grid.cell_of(p)).collect();
        for c in cells.iter().flatten() {
            grid.starts[*c] += 1;
        }
        let mut end = 0;
        for s in &mut grid.starts[..nx * ny] {
            end += *s;
            *s = end;
        }
        grid.starts[nx * ny] = end;
        grid.order = vec![0; end as usize];
        for (i, c) in cells.iter().enumerate().rev() {
            if let Some(c) = *c {
                grid.starts[c] -= 1;
                grid.order[grid.starts[c] as usize] = i as u32;
            }
        }
        grid.sorted = grid.order.iter().map(|&i| points[i as usize]).collect();
        grid
    }

    /// The cell holding `p`, `None` outside the grid or for a non-finite point.
    fn cell_of(&self, p: &[f64; 2]) -> Option<usize> {
        let (ix, iy) = self.cell_coords(p)?;
        (ix >= 0 && iy >= 0 && (ix as usize) < self.nx && (iy as usize) < self.ny)
            .then(|| iy as usize * self.nx + ix as usize)
    }

    fn cell_coords(&self, p: &[f64; 2]) -> Option<(i64, i64)> {
        if self.nx == 0 || !(p[0].is_finite() && p[1].is_finite()) {
            return None;
        }
        let fx = ((p[0] - self.origin[0]) / self.cell_m).floor();
        let fy = ((p[1] - self.origin[1]) / self.cell_m).floor();
        // Far outside the grid (beyond any i64 cell): nothing near.
        if fx.abs() > 1e15 || fy.abs() > 1e15 {
            return None;
        }
        Some((fx as i64, fy as i64))
    }

    /// Cells either side of a query's cell that hold every point within `gate_m` of it;
    /// `None` for an empty grid.
    pub fn reach(&self, gate_m: f64) -> Option<i64> {
        (self.nx > 0 && gate_m.is_finite() && gate_m >= 0.0)
            .then(|| (gate_m / self.cell_m).ceil().clamp(1.0, 1e6) as i64)
    }

    /// The point nearest to `q` if it is within `gate_m`: its index in the points the grid
    /// was built over, and its squared distance. Rows of cells are searched outwards from the query's and
    /// skipped once they are farther than the best found; a row's cells are contiguous.
    pub fn nearest_within(&self, q: &[f64; 2], gate_m: f64) -> Option<(usize, f64)> {
        self.search::<false>(q, gate_m).0
    }

    /// [`PointGrid::nearest_within`]'s answer, and a squared distance within which no other
    /// point of the grid lies: the second nearest's within the gate, the gate's where there
    /// is none, 0 where nothing can be said (an empty grid, a non-finite query). A query
    /// moved by `d` since keeps the same answer while the nearest's distance plus `d` stays
    /// below that distance's root minus `d` (an iterative registration's next iteration).
    /// Rows are skipped only once farther than the second nearest, so a query reads more
    /// cells than [`PointGrid::nearest_within`].
    pub fn nearest_within_and_clear(
        &self,
        q: &[f64; 2],
        gate_m: f64,
    ) -> (Option<(usize, f64)>, f64) {
        self.search::<true>(q, gate_m)
    }

    /// The point indices of row `iy`'s cells `x0..=x1` and the points themselves (both
    /// contiguous, in cell order); the caller keeps the row and columns inside the grid.
    fn row(&self, iy: i64, x0: i64, x1: i64) -> (&[u32], &[[f64; 2]]) {
        let row = iy as usize * self.nx;
        let from = self.starts[row + x0 as usize] as usize;
        let to = self.starts[row + x1 as usize + 1] as usize;
        (&self.order[from..to], &self.sorted[from..to])
    }

    /// Every point of the grid within `radius_m` of `q` (its index in the points the grid was
    /// built over), with its squared distance, into
    /// `out` (cleared first), in the grid's order; nothing for an empty grid or a
    /// non-finite query.
    pub fn within(&self, q: &[f64; 2], radius_m: f64, out: &mut Vec<(usize, f64)>) {
        out.clear();
        let (Some(reach), Some((cx, cy))) = (self.reach(radius_m), self.cell_coords(q)) else {
            return;
        };
        let r2 = radius_m * radius_m;
        let x0 = (cx - reach).max(0);
        let x1 = (cx + reach).min(self.nx as i64 - 1);
        let y0 = (cy - reach).max(0);
        let y1 = (cy + reach).min(self.ny as i64 - 1);
        if x0 > x1 || y0 > y1 {
            return;
        }
        for iy in y0..=y1 {
            let (indices, points) = self.row(iy, x0, x1);
            for (&i, p) in indices.iter().zip(points) {
                let d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]);
                if d2 <= r2 {
                    out.push((i as usize, d2));
                }
            }
        }
    }

    /// The search of both: with `CLEAR`, the bound that skips rows is the second nearest's
    /// distance, kept as the second value; without, the nearest's (the second value is 0).
    fn search<const CLEAR: bool>(&self, q: &[f64; 2], gate_m: f64) -> (Option<(usize, f64)>, f64) {
        let (Some(reach), Some((cx, cy))) = (self.reach(gate_m), self.cell_coords(q)) else {
            return (None, 0.0);
        };
        let mut bound = gate_m * gate_m;
        let clear = |bound: f64| if CLEAR { bound } else { 0.0 };
        let x0 = (cx - reach).max(0);
        let x1 = (cx + reach).min(self.nx as i64 - 1);
        if x0 > x1 {
            return (None, clear(bound));
        }
        let mut best: Option<(usize, f64)> = None;
        for k in 0..=2 * reach {
            // cy, cy + 1, cy - 1, cy + 2, ...
            let iy = if k % 2 == 1 {
                cy + (k + 1) / 2
            } else {
                cy - k / 2
            };
            if iy < 0 || iy >= self.ny as i64 {
                continue;
            }
            // The row's nearest edge to the query.
            let y_lo = self.origin[1] + iy as f64 * self.cell_m;
            let dy = (y_lo - q[1]).max(q[1] - (y_lo + self.cell_m)).max(0.0);
            if dy * dy > bound {
                continue;
            }
            let (indices, points) = self.row(iy, x0, x1);
            for (&i, p) in indices.iter().zip(points) {
                let d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]);
                if d2 > bound {
                    continue;
                }
                match best {
                    // The first point at the least distance is the answer, ties included.
                    Some((_, b)) if d2 >= b => {
                        if CLEAR {
                            bound = d2;
                        }
                    }
                    _ => {
                        if !CLEAR {
                            bound = d2;
                        } else if let Some((_, b)) = best {
                            bound = b;
                        }
                        best = Some((i as usize, d2));
                    }
                }
            }
        }
        (best, clear(bound))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cloud 160 m across (a radar's 80 m either side) needs more than the bound's cells
    /// at a 0.3 m cell: the cells grow, and every point, the far edges' too, is in the grid.
    #[test]
    fn a_wide_cloud_gets_wider_cells_and_keeps_every_point() {
        let mut points: Vec<[f64; 2]> = (0..=160)
            .flat_map(|i| [[-80.0 + f64::from(i), -80.0], [-80.0 + f64::from(i), 80.0]])
            .collect();
        points.extend((0..=160).map(|i| [80.0, -80.0 + f64::from(i)]));
        let grid = PointGrid::new(&points, 0.3);
        assert!(grid.nx * grid.ny <= MAX_GRID_CELLS);
        assert!(grid.cell_m > 0.3);
        assert_eq!(grid.order.len(), points.len(), "every point is in a cell");
        for (i, p) in points.iter().enumerate() {
            let (j, d2) = grid.nearest_within(p, 0.3).expect("itself");
            assert_eq!((points[j], d2), (points[i], 0.0));
        }
    }

    #[test]
    fn the_grid_stays_bounded_for_a_huge_or_damaged_cloud() {
        let points = vec![
            [-1e9, 0.0],
            [1e9, 3.0],
            [f64::NAN, 1.0],
            [0.0, f64::INFINITY],
            [2.0, 2.0],
        ];
        let grid = PointGrid::new(&points, 0.6);
        assert!(grid.nx * grid.ny <= MAX_GRID_CELLS);
        assert_eq!(
            grid.order.len(),
            3,
            "the three finite points are in the grid"
        );
        let near = |g: &PointGrid, q: [f64; 2]| g.nearest_within(&q, 2.0);
        assert_eq!(near(&grid, [1e9, 2.0]).map(|n| n.0), Some(1));
        assert!(near(&grid, [f64::NAN, 0.0]).is_none());
        assert!(near(&grid, [1e300, 0.0]).is_none());
        assert!(near(&PointGrid::new(&[], 0.6), [0.0, 0.0]).is_none());
    }

    /// Against a linear scan over scattered points, queries anywhere (inside, at the edges,
    /// outside the grid) and gates smaller and larger than the cells: the same nearest point.
    #[test]
    fn the_grid_finds_what_a_linear_scan_finds() {
        let points: Vec<[f64; 2]> = (0..400)
            .map(|i| {
                let t = f64::from(i);
                [
                    60.0 * (t * 0.618).fract() - 30.0,
                    40.0 * (t * 0.382).fract() - 20.0,
                ]
            })
            .collect();
        let grid = PointGrid::new(&points, 2.0);
        for q in 0..500 {
            let t = f64::from(q);
            let query = [
                80.0 * (t * 0.173).fract() - 40.0,
                60.0 * (t * 0.719).fract() - 30.0,
            ];
            for gate in [0.7, 1.5, 2.0, 5.0] {
                let linear = points
                    .iter()
                    .enumerate()
                    .map(|(i, p)| (i, (p[0] - query[0]).powi(2) + (p[1] - query[1]).powi(2)))
                    .filter(|&(_, d2)| d2 <= gate * gate)
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                // Every point within the gate, as the scan finds them.
                let mut within = Vec::new();
                grid.within(&query, gate, &mut within);
                within.sort_by_key(|w| w.0);
                let all: Vec<(usize, f64)> = points
                    .iter()
                    .enumerate()
                    .map(|(i, p)| (i, (p[0] - query[0]).powi(2) + (p[1] - query[1]).powi(2)))
                    .filter(|&(_, d2)| d2 <= gate * gate)
                    .collect();
                assert_eq!(within, all, "{query:?} gate {gate}");
                let found = grid.nearest_within(&query, gate);
                assert_eq!(
                    found.map(|f| f.0),
                    linear.map(|l| l.0),
                    "{query:?} gate {gate}"
                );
                // The same answer with the bound on the others: the second nearest within
                // the gate, or the gate.
                let (again, clear2) = grid.nearest_within_and_clear(&query, gate);
                assert_eq!(again, found);
                let second = points
                    .iter()
                    .enumerate()
                    .filter(|&(i, _)| Some(i) != found.map(|f| f.0))
                    .map(|(_, p)| (p[0] - query[0]).powi(2) + (p[1] - query[1]).powi(2))
                    .filter(|&d2| d2 <= gate * gate)
                    .fold(gate * gate, f64::min);
                assert!(
                    (clear2 - second).abs() <= 1e-12,
                    "{query:?} gate {gate}: {clear2} against {second}"
                );
            }
        }
    }
}
