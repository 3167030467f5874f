//! Correlative scan matching (after Olson, "Real-time correlative scan matching", 2009):
//! a brute-force search over a window of transforms for the one that lays a scan's points
//! on the most likely cells of a reference's score grid. Unlike ICP it has no basin: it finds
//! the best transform anywhere in the window, and the best *elsewhere* in the window (the
//! rival) says whether the place is ambiguous. Used to start the scan verifier's ICP when
//! the prior is metres off (a place descriptor's, or the chain's after a long drift).

use radar_model::geometry::{wrap_angle, Pose2};

/// A reference scan rasterised: each cell holds the largest Gaussian of the distance to a
/// point of the scan (1 on a point, falling off with `sigma_m`).
#[derive(Debug, Clone)]
pub struct ScoreGrid {
    origin: [f64; 2],
    cell_m: f64,
    width: usize,
    height: usize,
    data: Vec<f32>,
}

/// The grid's reach beyond a point, in standard deviations.
const REACH_SIGMAS: f64 = 3.0;

impl ScoreGrid {
    /// The grid of `points`, with `cell_m` cells and a `sigma_m` kernel; `None` when there
    /// are no finite points or the grid would exceed `max_cells` cells.
    pub fn new(points: &[[f64; 2]], cell_m: f64, sigma_m: f64, max_cells: usize) -> Option<Self> {
        let finite = || {
            points
                .iter()
                .filter(|p| p[0].is_finite() && p[1].is_finite())
        };
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in finite() {
            for d in 0..2 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        if !(lo[0].is_finite() && cell_m > 0.0 && sigma_m > 0.0) {
            return None;
        }
        let margin = REACH_SIGMAS * sigma_m + cell_m;
        let origin = [lo[0] - margin, lo[1] - margin];
        let width = ((hi[0] - lo[0] + 2.0 * margin) / cell_m).ceil() as usize + 1;
        let height = ((hi[1] - lo[1] + 2.0 * margin) / cell_m).ceil() as usize + 1;
        if width.checked_mul(height)? > max_cells {
            return None;
        }
        let mut data = vec![0f32; width * height];
        let reach = (REACH_SIGMAS * sigma_m / cell_m).ceil() as i64;
        let inv2s2 = 1.0 / (2.0 * sigma_m * sigma_m);
        for p in finite() {
            let cx = ((p[0] - origin[0]) / cell_m).floor() as i64;
            let cy = ((p[1] - origin[1]) / cell_m).floor() as i64;
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    let (x, y) = (cx + dx, cy + dy);
                    if x < 0 || y < 0 || x >= width as i64 || y >= height as i64 {
                        continue;
                    }
                    let centre = [
                        origin[0] + (x as f64 + 0.5) * cell_m,
                        origin[1] + (y as f64 + 0.5) * cell_m,
                    ];
                    let d2 = (centre[0] - p[0]).powi(2) + (centre[1] - p[1]).powi(2);
                    let v = (-d2 * inv2s2).exp() as f32;
                    let cell = &mut data[y as usize * width + x as usize];
                    if v > *cell {
                        *cell = v;
                    }
                }
            }
        }
        Some(Self {
            origin,
            cell_m,
            width,
            height,
            data,
        })
    }

    /// The cell of a point, if inside.
    fn cell(&self, p: [f64; 2]) -> Option<(i64, i64)> {
        let x = ((p[0] - self.origin[0]) / self.cell_m).floor();
        let y = ((p[1] - self.origin[1]) / self.cell_m).floor();
        (x.is_finite() && y.is_finite()).then_some((x as i64, y as i64))
    }

    /// Row `y` of the grid (none outside it).
    fn row(&self, y: i64) -> Option<&[f32]> {
        let y = usize::try_from(y).ok().filter(|&y| y < self.height)?;
        Some(&self.data[y * self.width..(y + 1) * self.width])
    }

    /// The shifts `dx` within `-half..=half` that keep column `x + dx` on the grid: the
    /// first and how many (none when no shift does).
    fn span(&self, x: i64, half: i64) -> Option<(i64, usize)> {
        let lo = (-half).max(x.saturating_neg());
        let hi = half.min((self.width as i64 - 1).saturating_sub(x));
        (lo <= hi).then(|| (lo, (hi - lo + 1) as usize))
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.data.len() * std::mem::size_of::<f32>()
    }
}

/// The search window around a prior.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    /// Half-width in x and y (m).
    pub half_m: f64,
    /// Half-width in heading (rad).
    pub half_rad: f64,
    /// Heading step (rad); the translation step is the grid's cell.
    pub step_rad: f64,
}

/// A transform and its score: the mean cell value under the scan's points, in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peak {
    /// The scan's frame in the reference's.
    pub pose: Pose2,
    /// Mean score.
    pub score: f64,
}

/// The best transform of `points` onto `grid` in `window` around `prior`, and the highest
/// other peaks (local maxima), each at least `separation_m` (or a tenth of it in rad) from
/// the best and from each other, at most `rivals` of them, highest first:
/// `(best, rivals)`; `None` for an empty scan. Cost: (window cells)^2 x headings x points
/// lookups.
pub fn correlate(
    grid: &ScoreGrid,
    points: &[[f64; 2]],
    prior: &Pose2,
    window: &Window,
    separation_m: f64,
    rivals: usize,
) -> Option<(Peak, Vec<Peak>)> {
    if points.is_empty() || window.step_rad <= 0.0 {
        return None;
    }
    let n_xy = (window.half_m / grid.cell_m).ceil().max(0.0) as i64;
    let n_t = (window.half_rad / window.step_rad).ceil().max(0.0) as i64;
    let side = (2 * n_xy + 1) as usize;
    let inv_n = 1.0 / points.len() as f64;
    // Every (heading, shift) scored; kept to find the rival.
    let mut scores: Vec<(f64, i64, i64, f64)> =
        Vec::with_capacity(side * side * (2 * n_t + 1) as usize);
    let mut cells: Vec<(i64, i64)> = Vec::with_capacity(points.len());
    let mut sums = vec![0f32; side * side];
    for it in -n_t..=n_t {
        let theta = wrap_angle(prior.theta + it as f64 * window.step_rad);
        let (s, c) = theta.sin_cos();
        cells.clear();
        cells.extend(points.iter().filter_map(|p| {
            grid.cell([prior.x + c * p[0] - s * p[1], prior.y + s * p[0] + c * p[1]])
        }));
        sums.iter_mut().for_each(|v| *v = 0.0);
        for &(x, y) in &cells {
            for (j, dy) in (-n_xy..=n_xy).enumerate() {
                // The window's shifts that land on the grid: the rest score nothing (the
                // grid holds no negative value, so leaving them out adds nothing either).
                let (Some(grid_row), Some(shifts)) =
                    (grid.row(y.saturating_add(dy)), grid.span(x, n_xy))
                else {
                    continue;
                };
                let row = &mut sums[j * side..(j + 1) * side];
                let first = (x + shifts.0) as usize;
                let values = &grid_row[first..first + shifts.1];
                let at = (shifts.0 + n_xy) as usize;
                for (sum, value) in row[at..at + shifts.1].iter_mut().zip(values) {
                    *sum += *value;
                }
            }
        }
        for (j, dy) in (-n_xy..=n_xy).enumerate() {
            for (i, dx) in (-n_xy..=n_xy).enumerate() {
                scores.push((theta, dx, dy, f64::from(sums[j * side + i]) * inv_n));
            }
        }
    }
    let pose_of = |(theta, dx, dy, _): (f64, i64, i64, f64)| {
        Pose2::new(
            prior.x + dx as f64 * grid.cell_m,
            prior.y + dy as f64 * grid.cell_m,
            theta,
        )
    };
    let best = scores.iter().copied().max_by(|a, b| a.3.total_cmp(&b.3))?;
    let best_pose = pose_of(best);
    // The rival is another *peak*: a local maximum of the score over its 26 neighbours in
    // (heading, x, y), far enough from the best. A ridge falling away from the best (a
    // street's walls slid along themselves) is the best's own basin, not a rival; how well
    // the walls pin the slide is the refinement's covariance to say.
    let n_side = side as i64;
    let layers = 2 * n_t + 1;
    let at = |t: i64, j: i64, i: i64| -> f64 {
        if t < 0 || j < 0 || i < 0 || t >= layers || j >= n_side || i >= n_side {
            return f64::NEG_INFINITY;
        }
        scores[((t * n_side + j) * n_side + i) as usize].3
    };
    let far = |p: &Pose2, q: &Pose2| {
        (p.x - q.x).hypot(p.y - q.y) > separation_m
            || wrap_angle(p.theta - q.theta).abs() > 0.1 * separation_m
    };
    let mut peaks: Vec<Peak> = Vec::new();
    for t in 0..layers {
        for j in 0..n_side {
            for i in 0..n_side {
                let r = scores[((t * n_side + j) * n_side + i) as usize];
                let p = pose_of(r);
                if !far(&p, &best_pose) {
                    continue;
                }
                let peak = (-1..=1).all(|dt| {
                    (-1..=1).all(|dj| {
                        (-1..=1).all(|di| {
                            (dt, dj, di) == (0, 0, 0) || at(t + dt, j + dj, i + di) <= r.3
                        })
                    })
                });
                if peak {
                    peaks.push(Peak {
                        pose: p,
                        score: r.3,
                    });
                }
            }
        }
    }
    peaks.sort_by(|a, b| b.score.total_cmp(&a.score));
    let mut kept: Vec<Peak> = Vec::new();
    for p in peaks {
        if kept.len() >= rivals {
            break;
        }
        if kept.iter().all(|k| far(&k.pose, &p.pose)) {
            kept.push(p);
        }
    }
    Some((
        Peak {
            pose: best_pose,
            score: best.3,
        },
        kept,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_search_finds_a_shifted_and_turned_scan_metres_from_the_prior() {
        // An L of walls and a few posts.
        let mut reference = Vec::new();
        for k in 0..80 {
            reference.push([k as f64 * 0.5, 0.0]);
            reference.push([0.0, k as f64 * 0.5]);
        }
        reference.extend([[10.0, 10.0], [25.0, 7.0], [5.0, 30.0]]);
        let truth = Pose2::new(4.0, -3.0, 0.06);
        let inv = crate::se2::inverse(&truth);
        let scan: Vec<[f64; 2]> = reference
            .iter()
            .map(|p| crate::se2::transform_point(&inv, *p))
            .collect();
        let grid = ScoreGrid::new(&reference, 0.5, 0.4, 1 << 20).expect("grid");
        let window = Window {
            half_m: 8.0,
            half_rad: 0.1,
            step_rad: 0.01,
        };
        let (best, rivals) =
            correlate(&grid, &scan, &Pose2::new(0.0, 0.0, 0.0), &window, 3.0, 3).expect("peak");
        let rival = rivals.first();
        assert!((best.pose.x - truth.x).abs() <= 0.5, "{best:?}");
        assert!((best.pose.y - truth.y).abs() <= 0.5, "{best:?}");
        assert!((best.pose.theta - truth.theta).abs() <= 0.011, "{best:?}");
        assert!(best.score > 0.8, "{best:?}");
        assert!(
            rival.expect("a rival").score < 0.7 * best.score,
            "{rival:?}"
        );
    }

    /// The search's best, scored the plain way: every shift of every heading, each point's
    /// cell read one at a time, nothing outside the grid.
    fn best_cell_by_cell(grid: &ScoreGrid, points: &[[f64; 2]], prior: &Pose2, w: &Window) -> Peak {
        let at = |x: i64, y: i64| -> f32 {
            if x < 0 || y < 0 || x >= grid.width as i64 || y >= grid.height as i64 {
                return 0.0;
            }
            grid.data[y as usize * grid.width + x as usize]
        };
        let n_xy = (w.half_m / grid.cell_m).ceil() as i64;
        let n_t = (w.half_rad / w.step_rad).ceil() as i64;
        let mut best = Peak {
            pose: *prior,
            score: f64::NEG_INFINITY,
        };
        for it in -n_t..=n_t {
            let theta = wrap_angle(prior.theta + it as f64 * w.step_rad);
            let (s, c) = theta.sin_cos();
            let cells: Vec<(i64, i64)> = points
                .iter()
                .filter_map(|p| {
                    grid.cell([prior.x + c * p[0] - s * p[1], prior.y + s * p[0] + c * p[1]])
                })
                .collect();
            for dy in -n_xy..=n_xy {
                for dx in -n_xy..=n_xy {
                    let sum: f32 = cells.iter().fold(0.0, |a, &(x, y)| a + at(x + dx, y + dy));
                    let score = f64::from(sum) / points.len() as f64;
                    // The last of equals, as `max_by` keeps.
                    if score >= best.score {
                        best = Peak {
                            pose: Pose2::new(
                                prior.x + dx as f64 * grid.cell_m,
                                prior.y + dy as f64 * grid.cell_m,
                                theta,
                            ),
                            score,
                        };
                    }
                }
            }
        }
        best
    }

    #[test]
    fn a_window_that_overhangs_the_grid_scores_as_cell_by_cell() {
        // A short wall and posts: a small grid, and a window of 6 m around a prior 4 m off
        // its corner, so that most shifts put points off the grid on one side or another.
        let mut reference: Vec<[f64; 2]> = (0..30).map(|k| [k as f64 * 0.3, 0.0]).collect();
        reference.extend([[2.0, 3.0], [7.5, -2.0], [4.0, 5.5]]);
        let grid = ScoreGrid::new(&reference, 0.4, 0.3, 1 << 20).expect("grid");
        let window = Window {
            half_m: 6.0,
            half_rad: 0.05,
            step_rad: 0.01,
        };
        for prior in [
            Pose2::new(-4.0, -4.0, 0.02),
            Pose2::new(12.0, 6.0, -0.03),
            Pose2::new(3.0, 0.5, 0.0),
        ] {
            let want = best_cell_by_cell(&grid, &reference, &prior, &window);
            let (got, _) = correlate(&grid, &reference, &prior, &window, 3.0, 3).expect("peak");
            assert_eq!(got.score, want.score, "{prior:?}");
            assert_eq!(got.pose, want.pose, "{prior:?}");
            assert!(got.score > 0.0, "{prior:?}");
        }
    }

    #[test]
    fn a_grid_too_large_or_without_points_is_refused() {
        assert!(ScoreGrid::new(&[], 1.0, 0.5, 1000).is_none());
        assert!(ScoreGrid::new(&[[f64::NAN, 0.0]], 1.0, 0.5, 1000).is_none());
        assert!(ScoreGrid::new(&[[0.0, 0.0], [1e6, 0.0]], 1.0, 0.5, 1 << 20).is_none());
    }
}
