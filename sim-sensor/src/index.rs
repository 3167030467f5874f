//! A uniform grid over the scene's features, answering "which features lie within `r` of
//! this point" at a cost that grows with the features near the point, not with the scene.

/// Most cells the grid may hold; coarser cells are used for very large scenes.
const MAX_CELLS: usize = 1 << 20;

/// A uniform grid of feature indices.
#[derive(Debug, Clone)]
pub struct GridIndex {
    origin: [f64; 2],
    cell_m: f64,
    cols: usize,
    rows: usize,
    /// `starts[c]..starts[c + 1]` are the entries of cell `c` in `entries`.
    starts: Vec<u32>,
    entries: Vec<u32>,
}

impl GridIndex {
    /// Builds the grid over `points` (finite coordinates) with cells of about `cell_m`.
    pub fn new(points: &[[f64; 2]], cell_m: f64) -> GridIndex {
        let mut min = [f64::INFINITY; 2];
        let mut max = [f64::NEG_INFINITY; 2];
        for p in points {
            for axis in 0..2 {
                min[axis] = min[axis].min(p[axis]);
                max[axis] = max[axis].max(p[axis]);
            }
        }
        if points.is_empty() {
            min = [0.0; 2];
            max = [0.0; 2];
        }
        let span = [(max[0] - min[0]).max(1e-9), (max[1] - min[1]).max(1e-9)];
        let mut cell_m = if cell_m.is_finite() && cell_m > 0.0 {
            cell_m
        } else {
            10.0
        };
        // Coarsen until the grid fits.
        while (span[0] / cell_m + 1.0) * (span[1] / cell_m + 1.0) > MAX_CELLS as f64 {
            cell_m *= 2.0;
        }
        let cols = (span[0] / cell_m).floor() as usize + 1;
        let rows = (span[1] / cell_m).floor() as usize + 1;
        let mut counts = vec![0u32; cols * rows + 1];
        let cell_of = |p: &[f64; 2]| -> usize {
            let c = (((p[0] - min[0]) / cell_m).floor() as usize).min(cols - 1);
            let r = (((p[1] - min[1]) / cell_m).floor() as usize).min(rows - 1);
            r * cols + c
        };
        for p in points {
            if let Some(n) = counts.get_mut(cell_of(p) + 1) {
                *n += 1;
            }
        }
        for i in 1..counts.len() {
            counts[i] += counts[i - 1];
        }
        let starts = counts.clone();
        let mut fill = counts;
        let mut entries = vec![0u32; points.len()];
        for (i, p) in points.iter().enumerate() {
            let cell = cell_of(p);
            if let Some(slot) = fill.get_mut(cell) {
                let at = *slot as usize;
                if let Some(e) = entries.get_mut(at) {
                    *e = i as u32;
                }
                *slot += 1;
            }
        }
        GridIndex {
            origin: min,
            cell_m,
            cols,
            rows,
            starts,
            entries,
        }
    }

    /// Every point's index, cell by cell (cells row by row, a cell's points in their
    /// order): the order [`Self::for_each_near`] visits them in.
    pub fn cell_order(&self) -> &[u32] {
        &self.entries
    }

    /// The cell size actually used, metres.
    pub fn cell_m(&self) -> f64 {
        self.cell_m
    }

    /// Calls `visit` with the index of every point in a cell that overlaps the disk of
    /// `radius_m` about `centre` (a superset of the points inside the disk; the caller
    /// checks distances exactly).
    pub fn for_each_near(&self, centre: [f64; 2], radius_m: f64, mut visit: impl FnMut(usize)) {
        if self.entries.is_empty() || !(radius_m.is_finite() && radius_m >= 0.0) {
            return;
        }
        let to_cell = |v: f64, origin: f64, n: usize| -> Option<usize> {
            let c = ((v - origin) / self.cell_m).floor();
            if c < 0.0 {
                Some(0)
            } else if c >= n as f64 {
                Some(n - 1)
            } else if c.is_finite() {
                Some(c as usize)
            } else {
                None
            }
        };
        // Empty intersection with the grid's box: nothing to visit.
        let span_x = self.cols as f64 * self.cell_m;
        let span_y = self.rows as f64 * self.cell_m;
        if centre[0] + radius_m < self.origin[0]
            || centre[1] + radius_m < self.origin[1]
            || centre[0] - radius_m > self.origin[0] + span_x
            || centre[1] - radius_m > self.origin[1] + span_y
        {
            return;
        }
        let (Some(c0), Some(c1), Some(r0), Some(r1)) = (
            to_cell(centre[0] - radius_m, self.origin[0], self.cols),
            to_cell(centre[0] + radius_m, self.origin[0], self.cols),
            to_cell(centre[1] - radius_m, self.origin[1], self.rows),
            to_cell(centre[1] + radius_m, self.origin[1], self.rows),
        ) else {
            return;
        };
        let half_diag = self.cell_m * std::f64::consts::FRAC_1_SQRT_2;
        for r in r0..=r1 {
            let cy = self.origin[1] + (r as f64 + 0.5) * self.cell_m;
            for c in c0..=c1 {
                let cx = self.origin[0] + (c as f64 + 0.5) * self.cell_m;
                if (cx - centre[0]).hypot(cy - centre[1]) > radius_m + half_diag {
                    continue;
                }
                let cell = r * self.cols + c;
                let (Some(&lo), Some(&hi)) = (self.starts.get(cell), self.starts.get(cell + 1))
                else {
                    continue;
                };
                if let Some(ids) = self.entries.get(lo as usize..hi as usize) {
                    for &i in ids {
                        visit(i as usize);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn a_disk_query_finds_every_point_inside_the_disk(
            points in proptest::collection::vec((-500.0..500.0f64, -500.0..500.0f64), 0..300),
            centre in (-600.0..600.0f64, -600.0..600.0f64),
            radius in 0.0..300.0f64,
            cell in 1.0..50.0f64,
        ) {
            let pts: Vec<[f64; 2]> = points.iter().map(|&(x, y)| [x, y]).collect();
            let grid = GridIndex::new(&pts, cell);
            let mut found = vec![false; pts.len()];
            grid.for_each_near([centre.0, centre.1], radius, |i| found[i] = true);
            for (i, p) in pts.iter().enumerate() {
                if (p[0] - centre.0).hypot(p[1] - centre.1) <= radius {
                    prop_assert!(found[i], "point {i} at {p:?} missed");
                }
            }
        }
    }

    #[test]
    fn a_query_far_from_every_point_visits_nothing() {
        let pts: Vec<[f64; 2]> = (0..100).map(|i| [f64::from(i), 0.0]).collect();
        let grid = GridIndex::new(&pts, 5.0);
        let mut n = 0;
        grid.for_each_near([1e5, 1e5], 200.0, |_| n += 1);
        assert_eq!(n, 0);
    }

    #[test]
    fn a_huge_sparse_scene_gets_coarser_cells_instead_of_a_huge_grid() {
        let pts = vec![[0.0, 0.0], [1e6, 1e6]];
        let grid = GridIndex::new(&pts, 1.0);
        assert!(grid.cell_m() >= 1000.0, "{}", grid.cell_m());
    }
}
