//! Loop closure from the radar's scans, not only its point features.
//!
//! In a city of walls, fences, hedges and parked cars the filter maps few point features (a
//! submap of the realistic city holds about nine), too few for the feature verifier
//! ([`crate::align`]) to tell a return from a coincidence. The radar itself sees thousands
//! of returns from the same street. Each submap therefore also keeps its **scan**: every
//! rotation's registered cloud (radar odometry's, walls included), placed by the filter's
//! pose in the submap's frame and thinned to one point per cell ([`ScanAccumulator`]); only
//! cells seen in at least two rotations are kept, so a passing car or a speckle return does
//! not enter it.
//!
//! A candidate (from the pose uncertainty or a place descriptor) is verified by
//! **registering the two scans** ([`align_scans`]): radar odometry's point-to-line ICP
//! (`radar_odometry::register`) from a small grid of starts around the prior; the best
//! registration must pair a large share of the smaller scan with a small residual, pin all
//! three directions (its covariance, from the registration's information, inside
//! [`ScanAlignSettings::max_sigma_m`] and [`ScanAlignSettings::max_sigma_rad`]), agree with
//! the prior, and no start may converge elsewhere (more than the rival separation away) to
//! nearly as many pairs: a street that fits two ways is refused, as the feature verifier
//! refuses repeated structure. The layer's later checks (closures from different places
//! must agree; a closure left outside its own bound after the solve is dropped) apply as to
//! any closure. No IO, no threads.

use std::collections::HashMap;

use nalgebra::{Matrix3, Vector3};
use radar_model::geometry::{wrap_angle, Pose2};
use radar_odometry::{covariance, register, ReferenceCloud, Registration};
use statrs::distribution::{ChiSquared, ContinuousCDF};

use crate::align::{AlignSettings, Alignment, Refusal};
use crate::correlate::{correlate, ScoreGrid, Window};

/// The scan verifier's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanAlignSettings {
    /// Verify by scans when both submaps have one (otherwise, and when off, by features).
    pub enabled: bool,
    /// A scan keeps one point per square cell this wide (m).
    pub cell_m: f64,
    /// A cell enters the scan when at least this many rotations put a return in it.
    pub min_cell_hits: u32,
    /// Cells a scan keeps at most (a bound on memory: 16 bytes a point).
    pub max_points: usize,
    /// The registration's first pair gate (m); it narrows to a fifth.
    pub gate_m: f64,
    /// The correlative search's score grid: cell (m) and kernel (m, one sigma).
    pub search_cell_m: f64,
    /// The kernel.
    pub search_sigma_m: f64,
    /// The search window: three sigmas of the prior, at most this far either side (m; 40:
    /// a return after two kilometres on the radar alone can find the chain 40-60 m off,
    /// and at 15 m the realistic city's check layout lost its last return, 64 m at the
    /// end; the correlation's cost grows with the square, the slowest join from 0.5 to
    /// 0.9 s)...
    pub max_window_m: f64,
    /// ... and at most this far in heading (rad), in steps of `search_step_rad`.
    pub max_window_rad: f64,
    /// Heading step (rad).
    pub search_step_rad: f64,
    /// The search scores at most this many of the newer scan's points (evenly taken); ICP
    /// then refines its best transform with all of them.
    pub search_points: usize,
    /// The best transform's mean score over the sampled points within the earlier scan's
    /// reach (`coverage_m`) must reach this (1: every point on a point).
    pub min_score: f64,
    /// The search's other peaks (farther than `rival_separation_m` from the best, or a
    /// tenth of it in rad) refined by ICP as well, at most this many.
    pub rival_peaks: usize,
    /// A refinement that ends elsewhere with this share of the best's inliers refuses the
    /// closure (repeated structure).
    pub max_rival_ratio: f64,
    /// See `rival_peaks` (m).
    pub rival_separation_m: f64,
    /// Fewest pairs for a closure.
    pub min_pairs: usize,
    /// A point of the newer scan is an inlier when it lies this close to the earlier
    /// scan's surface (m): the registrations from the starts are ranked by inliers, and a
    /// start that converges elsewhere to nearly as many is a rival.
    pub inlier_m: f64,
    /// Share of the newer scan's points in the earlier scan's reach (see `coverage_m`)
    /// that must be inliers.
    pub min_overlap: f64,
    /// A point of the newer scan, placed by the registration, is within the earlier scan's
    /// reach when an earlier point lies this close (m). Two submaps of a street driven the
    /// other way overlap over part of their length only, and the rest of the newer scan
    /// (streets, fronts the earlier drive never saw) says nothing for or against the
    /// closure: the share of inliers counts the points the earlier scan could have seen.
    pub coverage_m: f64,
    /// Candidates from the pose uncertainty: two submaps with scans are candidates when
    /// their frames' origins may lie within this distance (m) of each other.
    pub origin_reach_m: f64,
    /// And the nearest this many at most (each verification registers from 27 starts).
    pub max_prior_candidates: usize,
    /// Largest residual (m, root mean square over the pairs).
    pub max_rms_m: f64,
    /// The closure's standard deviation along its weakest direction, at most (m).
    pub max_sigma_m: f64,
    /// And in heading (rad).
    pub max_sigma_rad: f64,
    /// A return's noise for the joint test of the pairs (m).
    pub point_sigma_m: f64,
    /// Pairs counted as one independent measurement (neighbouring points of one surface
    /// are not independent): the covariance is scaled by it.
    pub correlated_pairs: f64,
}

impl Default for ScanAlignSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            cell_m: 1.0,
            min_cell_hits: 2,
            max_points: 40_000,
            gate_m: 4.0,
            search_cell_m: 1.0,
            search_sigma_m: 0.7,
            max_window_m: 40.0,
            max_window_rad: 0.15,
            search_step_rad: 0.01,
            search_points: 600,
            min_score: 0.3,
            rival_peaks: 3,
            max_rival_ratio: 0.8,
            rival_separation_m: 5.0,
            min_pairs: 300,
            inlier_m: 0.3,
            min_overlap: 0.3,
            coverage_m: 2.0,
            origin_reach_m: 40.0,
            max_prior_candidates: 4,
            max_rms_m: 0.45,
            max_sigma_m: 0.5,
            max_sigma_rad: 0.01,
            point_sigma_m: 0.3,
            correlated_pairs: 10.0,
        }
    }
}

/// A submap's scan, built one rotation at a time: each registered cloud placed by the pose
/// of the vehicle when it was taken, one point (the mean of the returns) per cell.
#[derive(Debug, Clone, Default)]
pub struct ScanAccumulator {
    cell_m: f64,
    min_hits: u32,
    max_points: usize,
    /// Per cell: rotations that hit it (the last one's number, to count each once), the
    /// returns' sums.
    cells: HashMap<(i64, i64), Cell>,
    rotation: u64,
    /// Returns not kept because the scan was full.
    refused: u64,
}

#[derive(Debug, Clone, Copy, Default)]
struct Cell {
    hits: u32,
    last_rotation: u64,
    n: f64,
    sx: f64,
    sy: f64,
}

impl ScanAccumulator {
    /// An empty scan with `settings`' cell, hit count and bound.
    pub fn new(settings: &ScanAlignSettings) -> Self {
        Self {
            cell_m: if settings.cell_m > 0.0 {
                settings.cell_m
            } else {
                1.0
            },
            min_hits: settings.min_cell_hits.max(1),
            max_points: settings.max_points,
            ..Self::default()
        }
    }

    /// Adds one rotation's `cloud` (in the vehicle's frame) taken at `pose` (the vehicle in
    /// the submap's frame). Non-finite points are skipped; past the bound new cells are
    /// refused (counted).
    pub fn add(&mut self, pose: &Pose2, cloud: &[[f64; 2]]) {
        self.rotation += 1;
        let place = placer(pose);
        for p in cloud {
            let q = place(p);
            if !(q[0].is_finite() && q[1].is_finite()) {
                continue;
            }
            let key = (
                (q[0] / self.cell_m).floor() as i64,
                (q[1] / self.cell_m).floor() as i64,
            );
            let full = self.cells.len() >= self.max_points;
            let cell = match self.cells.get_mut(&key) {
                Some(cell) => cell,
                None if full => {
                    self.refused += 1;
                    continue;
                }
                None => self.cells.entry(key).or_default(),
            };
            if cell.last_rotation != self.rotation {
                cell.hits += 1;
                cell.last_rotation = self.rotation;
            }
            cell.n += 1.0;
            cell.sx += q[0];
            cell.sy += q[1];
        }
    }

    /// Cells so far (kept or not yet).
    pub fn cells(&self) -> usize {
        self.cells.len()
    }

    /// Returns refused because the scan was full.
    pub fn refused(&self) -> u64 {
        self.refused
    }

    /// The scan: one point per cell seen in enough rotations, in a stable order; and starts
    /// the next one empty.
    pub fn take(&mut self) -> Vec<[f64; 2]> {
        let mut kept: Vec<((i64, i64), [f64; 2])> = self
            .cells
            .drain()
            .filter(|(_, c)| c.hits >= self.min_hits && c.n > 0.0)
            .map(|(k, c)| (k, [c.sx / c.n, c.sy / c.n]))
            .collect();
        kept.sort_unstable_by_key(|(k, _)| *k);
        self.rotation = 0;
        kept.into_iter().map(|(_, p)| p).collect()
    }
}

/// The normals of a scan are fitted within this distance (m): two cells' worth.
pub const SCAN_NORMAL_RADIUS_M: f64 = 2.5;

/// Cells a search grid may have at most (4 bytes each).
const MAX_GRID_CELLS: usize = 4 << 20;

/// A submap's scan as the verifier uses it: ICP's reference (tree, pair grid, normals) and
/// the correlative search's score grid.
#[derive(Debug)]
pub struct ScanReference {
    /// ICP's reference.
    pub cloud: ReferenceCloud,
    /// The search's grid (`None` when the scan spans too large an area).
    pub grid: Option<ScoreGrid>,
}

impl ScanReference {
    /// The scan's points.
    pub fn points(&self) -> &[[f64; 2]] {
        self.cloud.points()
    }
}

/// A scan as the verifier pairs against.
pub fn reference_scan(points: Vec<[f64; 2]>, settings: &ScanAlignSettings) -> ScanReference {
    let grid = ScoreGrid::new(
        &points,
        settings.search_cell_m,
        settings.search_sigma_m,
        MAX_GRID_CELLS,
    );
    ScanReference {
        cloud: ReferenceCloud::new(points, SCAN_NORMAL_RADIUS_M, settings.gate_m),
        grid,
    }
}

/// Points of `cloud`, placed by `t`, within `max_m` of `reference`'s surface.
fn inliers(reference: &ReferenceCloud, cloud: &[[f64; 2]], t: &Pose2, max_m: f64) -> usize {
    count_placed(cloud, t, |q| is_inlier(reference, q, max_m))
}

/// Whether each point of `cloud`, moved by `t`, is an inlier (see [`inliers`]).
fn inlier_flags(
    reference: &ReferenceCloud,
    cloud: &[[f64; 2]],
    t: &Pose2,
    max_m: f64,
) -> Vec<bool> {
    let place = placer(t);
    cloud
        .iter()
        .map(|p| is_inlier(reference, &place(p), max_m))
        .collect()
}

/// Whether `q` lies within `max_m` of `reference`'s surface: the nearest point within a
/// cell and a half; the surface distance decides.
fn is_inlier(reference: &ReferenceCloud, q: &[f64; 2], max_m: f64) -> bool {
    reference
        .surface_distance(q, max_m + 1.5)
        .is_some_and(|(_, d)| d <= max_m)
}

/// How many points of `cloud`, moved by `t`, have a point of `reference` within `reach_m`.
fn covered(reference: &ReferenceCloud, cloud: &[[f64; 2]], t: &Pose2, reach_m: f64) -> usize {
    count_placed(cloud, t, |q| reference.nearest_within(q, reach_m).is_some())
}

/// How many points of `cloud`, moved by `t`, satisfy `keep`.
fn count_placed(cloud: &[[f64; 2]], t: &Pose2, keep: impl Fn(&[f64; 2]) -> bool) -> usize {
    let place = placer(t);
    cloud.iter().filter(|p| keep(&place(p))).count()
}

/// A point moved by `t` (its sine and cosine taken once for a whole cloud).
fn placer(t: &Pose2) -> impl Fn(&[f64; 2]) -> [f64; 2] {
    let (sn, cs) = t.theta.sin_cos();
    let (x, y) = (t.x, t.y);
    move |p| [x + cs * p[0] - sn * p[1], y + sn * p[0] + cs * p[1]]
}

/// The correlative search and ICP refinements of [`align_scans`], before its tests.
#[derive(Debug, Clone, Copy)]
struct Searched {
    /// The refinement with the most inliers.
    reg: Registration,
    /// Its inliers.
    inlying: usize,
    /// The most inliers of a refinement that ended elsewhere.
    rival: usize,
    /// That refinement's transform.
    rival_pose: Option<Pose2>,
    /// The points within the reference's reach once placed ([`ScanAlignSettings::coverage_m`]).
    covered: usize,
    /// The search's best score over the sampled points within reach.
    score: f64,
}

fn search_and_refine(
    reference: &ScanReference,
    current: &[[f64; 2]],
    prior: &Pose2,
    prior_cov: &Matrix3<f64>,
    s: &ScanAlignSettings,
) -> Result<Searched, Refusal> {
    let smaller = reference.points().len().min(current.len());
    if smaller < s.min_pairs {
        return Err(Refusal::TooFewCandidates(smaller));
    }
    let Some(grid) = reference.grid.as_ref() else {
        return Err(Refusal::TooFewCandidates(0));
    };
    // The search scores an even subsample over the prior's three-sigma window.
    let stride = current.len().div_ceil(s.search_points.max(1)).max(1);
    let sample: Vec<[f64; 2]> = current.iter().step_by(stride).copied().collect();
    let sigma_xy = prior_cov
        .fixed_view::<2, 2>(0, 0)
        .symmetric_eigenvalues()
        .max()
        .max(0.0)
        .sqrt();
    let window = Window {
        half_m: (3.0 * sigma_xy).clamp(2.0 * s.search_cell_m, s.max_window_m),
        half_rad: (3.0 * prior_cov[(2, 2)].max(0.0).sqrt())
            .clamp(2.0 * s.search_step_rad, s.max_window_rad),
        step_rad: s.search_step_rad,
    };
    let Some((best, peaks)) = correlate(
        grid,
        &sample,
        prior,
        &window,
        s.rival_separation_m,
        s.rival_peaks,
    ) else {
        return Err(Refusal::TooFewMatches(0));
    };
    // The mean score over the sampled points the earlier scan could have seen (see
    // `coverage_m`): a street driven the other way overlaps over part of its length.
    let in_reach = covered(&reference.cloud, &sample, &best.pose, s.coverage_m).max(1);
    let score = best.score * sample.len() as f64 / in_reach as f64;
    if score < s.min_score {
        tracing::debug!(
            score,
            raw = best.score,
            in_reach,
            sampled = sample.len(),
            "scan closure: the search's best score is low"
        );
        return Err(Refusal::TooFewMatches(
            (best.score * current.len() as f64) as usize,
        ));
    }
    // ICP refines the best peak and the highest others with every point, from a gate of two
    // cells; the refinement with the most inliers wins, and one that converged elsewhere
    // (not into the winner's basin) with nearly as many is a rival: repeated structure.
    let refine = |start: Pose2| {
        let reg = register(
            &reference.cloud,
            current,
            start,
            2.0 * s.search_cell_m,
            s.min_pairs,
        )?;
        let n = inliers(&reference.cloud, current, &reg.pose, s.inlier_m);
        Some((reg, n))
    };
    let mut refined: Vec<(Registration, usize)> = std::iter::once(best)
        .chain(peaks)
        .filter_map(|p| refine(p.pose))
        .collect();
    refined.sort_by_key(|r| std::cmp::Reverse(r.1));
    let Some((reg, inlying)) = refined.first().copied() else {
        return Err(Refusal::TooFewMatches(0));
    };
    let (rival, rival_pose) = refined
        .iter()
        .skip(1)
        .filter(|(r, _)| {
            (r.pose.x - reg.pose.x).hypot(r.pose.y - reg.pose.y) > s.rival_separation_m
                || wrap_angle(r.pose.theta - reg.pose.theta).abs() > 0.1 * s.rival_separation_m
        })
        .max_by_key(|(_, n)| *n)
        .map_or((0, None), |(r, n)| (*n, Some(r.pose)));
    let covered = covered(&reference.cloud, current, &reg.pose, s.coverage_m).max(1);
    Ok(Searched {
        reg,
        inlying,
        rival,
        rival_pose,
        covered,
        score,
    })
}

/// Whether `reference` fits itself moved by `shift` (within `window`, its standard
/// deviations `[m, m, rad]`): the inliers of the best refinement when it pairs at least
/// [`ScanAlignSettings::min_pairs`] points, half [`ScanAlignSettings::min_overlap`] of
/// those within reach and within [`ScanAlignSettings::max_rms_m`]; rivals and the
/// covariance are not asked for (several fits, or a slide along a corridor, are fits too).
/// A guard against repeated structure: it finds a repeat on less evidence than a closure
/// needs.
pub fn fits_itself(
    reference: &ScanReference,
    shift: &Pose2,
    window: [f64; 3],
    s: &ScanAlignSettings,
) -> Option<usize> {
    let cov = Matrix3::from_diagonal(&Vector3::new(
        window[0].powi(2),
        window[1].powi(2),
        window[2].powi(2),
    ));
    let f = search_and_refine(reference, reference.points(), shift, &cov, s).ok()?;
    let share = f.inlying as f64 / f.covered as f64;
    (f.inlying >= s.min_pairs && share >= 0.5 * s.min_overlap && f.reg.rms_m <= s.max_rms_m)
        .then_some(f.inlying)
}

/// Verifies that scan `current` (of the newer submap, in its frame) is a second look at
/// `reference` (the earlier submap's scan, in its frame), with `prior` (the newer frame in
/// the earlier one) and its covariance: the transform found, its covariance, and the
/// matched points (index in `reference`, index in `current`). See the module's doc for the
/// tests it must pass.
pub fn align_scans(
    reference: &ScanReference,
    current: &[[f64; 2]],
    prior: &Pose2,
    prior_cov: &Matrix3<f64>,
    align: &AlignSettings,
    s: &ScanAlignSettings,
) -> Result<Alignment, Refusal> {
    let Searched {
        reg,
        inlying,
        rival,
        rival_pose,
        covered,
        score,
    } = search_and_refine(reference, current, prior, prior_cov, s)?;
    if rival as f64 >= s.max_rival_ratio * inlying as f64 {
        // For the log only (two passes over the scan): what each transform alone explains.
        if let Some(r) = rival_pose.filter(|_| tracing::enabled!(tracing::Level::DEBUG)) {
            let on = |t: &Pose2| inlier_flags(&reference.cloud, current, t, s.inlier_m);
            let (a, b) = (on(&reg.pose), on(&r));
            let best_only = a.iter().zip(&b).filter(|(x, y)| **x && !**y).count();
            let rival_only = a.iter().zip(&b).filter(|(x, y)| !**x && **y).count();
            tracing::debug!(
                best_x = reg.pose.x,
                best_y = reg.pose.y,
                best_theta = reg.pose.theta,
                rival_x = r.x,
                rival_y = r.y,
                rival_theta = r.theta,
                best = inlying,
                rival,
                best_only,
                rival_only,
                prior_x = prior.x,
                prior_y = prior.y,
                prior_sigma_m = (prior_cov[(0, 0)] + prior_cov[(1, 1)]).max(0.0).sqrt(),
                "scan closure: a rival"
            );
        }
        return Err(Refusal::Ambiguous {
            best: inlying,
            rival,
        });
    }
    let overlap = inlying as f64 / covered as f64;
    if reg.pairs < s.min_pairs || inlying < s.min_pairs || overlap < s.min_overlap {
        tracing::debug!(
            pairs = reg.pairs,
            inlying,
            covered,
            points = current.len(),
            reference = reference.points().len(),
            rms = reg.rms_m,
            score,
            "scan closure: too few inliers"
        );
        return Err(Refusal::TooFewMatches(inlying));
    }
    if reg.rms_m > s.max_rms_m {
        return Err(Refusal::PoorFit { rms_m: reg.rms_m });
    }
    let floor = Matrix3::from_diagonal(&Vector3::new(1e-4, 1e-4, 1e-6));
    let Some(cov) = covariance(&reg, &floor, s.correlated_pairs, 0.05) else {
        return Err(Refusal::Degenerate);
    };
    let sigma_m = cov
        .fixed_view::<2, 2>(0, 0)
        .symmetric_eigenvalues()
        .max()
        .max(0.0)
        .sqrt();
    let sigma_rad = cov[(2, 2)].max(0.0).sqrt();
    if sigma_m > s.max_sigma_m || sigma_rad > s.max_sigma_rad {
        return Err(Refusal::Unconstrained { sigma_m, sigma_rad });
    }
    let t = reg.pose;
    let e = Vector3::new(
        t.x - prior.x,
        t.y - prior.y,
        wrap_angle(t.theta - prior.theta),
    );
    let bound = ChiSquared::new(3.0)
        .map(|d| d.inverse_cdf(align.prior_probability))
        .unwrap_or(f64::INFINITY);
    let d2 = (prior_cov + cov)
        .cholesky()
        .map(|ch| e.dot(&ch.solve(&e)))
        .unwrap_or(f64::INFINITY);
    if d2 > bound {
        return Err(Refusal::FarFromPrior(d2));
    }
    // The matches: each inlier of `current` with its point of `reference`.
    let place = placer(&t);
    let mut matches = Vec::new();
    let mut nis = 0.0;
    for (j, p) in current.iter().enumerate() {
        let q = place(p);
        if let Some((i, d)) = reference.cloud.surface_distance(&q, s.inlier_m) {
            if d <= s.inlier_m {
                matches.push((i, j));
                nis += (d / s.point_sigma_m).powi(2);
            }
        }
    }
    let dof = (2 * matches.len()).saturating_sub(3).max(1);
    tracing::debug!(
        pairs = reg.pairs,
        inlying,
        covered,
        points = current.len(),
        rms = reg.rms_m,
        score,
        share = overlap,
        "scan closure verified"
    );
    Ok(Alignment {
        transform: t,
        covariance: cov,
        matches,
        nis,
        dof,
        rival_matches: rival,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A street: two building lines with gaps, posts, a cross street; returns every 0.5 m
    /// along the surfaces, with noise.
    fn street(rng: &mut ChaCha8Rng, length: f64) -> Vec<[f64; 2]> {
        let mut pts = Vec::new();
        let mut x = -length;
        while x < length {
            // Fronts with set-backs and gaps, different on each side.
            let gap_l = (x / 17.0).rem_euclid(1.0) < 0.2;
            let gap_r = (x / 23.0).rem_euclid(1.0) < 0.15;
            let set_l = 12.0 + 2.0 * ((x / 31.0).floor() as i64 % 3) as f64;
            let set_r = -10.0 - 1.5 * ((x / 19.0).floor() as i64 % 2) as f64;
            if !gap_l {
                pts.push([
                    x + rng.gen_range(-0.1..0.1),
                    set_l + rng.gen_range(-0.1..0.1),
                ]);
            }
            if !gap_r {
                pts.push([
                    x + rng.gen_range(-0.1..0.1),
                    set_r + rng.gen_range(-0.1..0.1),
                ]);
            }
            x += 0.5;
        }
        // A cross street's fronts and some posts.
        let mut y: f64 = -40.0;
        while y < 40.0 {
            if y.abs() > 12.0 {
                pts.push([30.0, y]);
                pts.push([40.0, y]);
            }
            y += 0.5;
        }
        for k in 0..20 {
            let px = -length + 7.3 * k as f64;
            pts.push([px, 7.0 + (k % 3) as f64]);
        }
        pts
    }

    fn moved(points: &[[f64; 2]], t: &Pose2) -> Vec<[f64; 2]> {
        // `points` in the world; returned in the frame `t` (the newer submap's).
        let inv = crate::se2::inverse(t);
        points
            .iter()
            .map(|p| crate::se2::transform_point(&inv, *p))
            .collect()
    }

    /// The same street looked at twice (`seed`'s noise), the second look from `truth`: the
    /// settings, the first look as a reference and the second in its own frame.
    fn two_looks(seed: u64, truth: &Pose2) -> (ScanAlignSettings, ScanReference, Vec<[f64; 2]>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let s = ScanAlignSettings::default();
        let a = street(&mut rng, 80.0);
        let b = moved(&street(&mut rng, 80.0), truth);
        let reference = reference_scan(a, &s);
        (s, reference, b)
    }

    #[test]
    fn the_scans_of_a_street_seen_twice_give_the_transform_between_the_submaps() {
        let truth = Pose2::new(3.0, -1.5, 0.08);
        let (s, reference, b) = two_looks(7, &truth);
        // The prior 2 m and 0.03 rad off, as a place descriptor leaves it.
        let prior = Pose2::new(4.6, -0.4, 0.05);
        let cov = Matrix3::from_diagonal(&Vector3::new(4.0, 4.0, 0.0025));
        let r = align_scans(&reference, &b, &prior, &cov, &AlignSettings::default(), &s)
            .expect("the street verifies");
        assert!((r.transform.x - truth.x).abs() < 0.1, "{:?}", r.transform);
        assert!((r.transform.y - truth.y).abs() < 0.1, "{:?}", r.transform);
        assert!(
            (r.transform.theta - truth.theta).abs() < 0.005,
            "{:?}",
            r.transform
        );
        assert!(r.matches.len() >= s.min_pairs);
        // The covariance is symmetric, positive definite and covers the error.
        assert!((r.covariance - r.covariance.transpose()).norm() < 1e-12);
        let ch = r.covariance.cholesky().expect("positive definite");
        let e = Vector3::new(
            r.transform.x - truth.x,
            r.transform.y - truth.y,
            r.transform.theta - truth.theta,
        );
        assert!(e.dot(&ch.solve(&e)) < 16.27, "error {e:?} outside 99.9 %");
    }

    #[test]
    fn a_return_the_chain_put_30_m_off_is_searched_for_as_far_as_its_uncertainty_says() {
        // After two kilometres on the radar alone the chain's relative pose may be 30 m
        // off with a 12 m standard deviation: the search reaches three sigmas (up to
        // `max_window_m`), and the street's cross street and posts pin the slide.
        let truth = Pose2::new(3.0, -1.5, 0.02);
        let (s, reference, b) = two_looks(11, &truth);
        let prior = Pose2::new(33.0, 2.0, 0.04);
        let cov = Matrix3::from_diagonal(&Vector3::new(144.0, 144.0, 0.0025));
        let r = align_scans(&reference, &b, &prior, &cov, &AlignSettings::default(), &s)
            .expect("the street verifies from 30 m off");
        assert!((r.transform.x - truth.x).abs() < 0.1, "{:?}", r.transform);
        assert!((r.transform.y - truth.y).abs() < 0.1, "{:?}", r.transform);
        // A window of 15 m, the bound before, does not reach it.
        let narrow = ScanAlignSettings {
            max_window_m: 15.0,
            ..s
        };
        let r = align_scans(
            &reference,
            &b,
            &prior,
            &cov,
            &AlignSettings::default(),
            &narrow,
        );
        assert!(
            r.as_ref()
                .map_or(true, |a| (a.transform.x - truth.x).abs() > 1.0),
            "{r:?}"
        );
    }

    #[test]
    fn two_different_streets_do_not_verify() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let s = ScanAlignSettings::default();
        let a = street(&mut rng, 80.0);
        // Another street: its fronts at other set-backs and rhythms.
        let b: Vec<[f64; 2]> = street(&mut rng, 80.0)
            .into_iter()
            .map(|p| [0.83 * p[0] + 11.0, -1.2 * p[1] + 3.0])
            .collect();
        let reference = reference_scan(a, &s);
        let cov = Matrix3::from_diagonal(&Vector3::new(4.0, 4.0, 0.0025));
        let r = align_scans(
            &reference,
            &b,
            &Pose2::new(0.0, 0.0, 0.0),
            &cov,
            &AlignSettings::default(),
            &s,
        );
        assert!(r.is_err(), "{r:?}");
    }

    #[test]
    fn a_bare_corridor_that_slides_along_itself_is_refused() {
        // Two straight walls, nothing else: the registration cannot pin the motion along
        // them.
        let s = ScanAlignSettings::default();
        let mut a = Vec::new();
        let mut x = -100.0;
        while x < 100.0 {
            a.push([x, 8.0]);
            a.push([x, -8.0]);
            x += 0.5;
        }
        let truth = Pose2::new(5.0, 0.0, 0.0);
        let b = moved(&a, &truth);
        let reference = reference_scan(a, &s);
        let cov = Matrix3::from_diagonal(&Vector3::new(4.0, 4.0, 0.0025));
        let r = align_scans(
            &reference,
            &b,
            &Pose2::new(4.0, 0.0, 0.0),
            &cov,
            &AlignSettings::default(),
            &s,
        );
        // The registration itself refuses a motion its pairs do not pin, or the verifier
        // finds it unconstrained or ambiguous: any way, no closure.
        assert!(r.is_err(), "{r:?}");
    }

    /// A street driven the other way overlaps the earlier one over part of its length: the
    /// newer scan is the earlier street's last 60 m and two other streets beyond it, which
    /// the earlier scan never saw. Scored over all its points the search's best is
    /// under the threshold; over the points within the earlier scan's reach it verifies.
    #[test]
    fn a_scan_that_overlaps_over_part_of_its_length_verifies() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let s = ScanAlignSettings::default();
        let a = street(&mut rng, 80.0);
        let mut seen = street(&mut rng, 80.0);
        seen.retain(|p| p[0] > 20.0);
        // Beyond the earlier scan's end, a street of its own: fronts at other set-backs.
        let beyond: Vec<[f64; 2]> = street(&mut rng, 80.0)
            .into_iter()
            .map(|p| [p[0] + 250.0, 0.8 * p[1] + 1.0])
            .collect();
        seen.extend(beyond);
        let further: Vec<[f64; 2]> = street(&mut rng, 80.0)
            .into_iter()
            .map(|p| [0.9 * p[0] + 420.0, -1.3 * p[1] - 2.0])
            .collect();
        seen.extend(further);
        let truth = Pose2::new(40.0, 0.5, -0.03);
        let b = moved(&seen, &truth);
        let reference = reference_scan(a, &s);
        let prior = Pose2::new(41.5, -0.5, -0.01);
        let cov = Matrix3::from_diagonal(&Vector3::new(4.0, 4.0, 0.0025));
        // Under a third of its points are near the earlier street.
        let near = covered(&reference.cloud, &b, &truth, 2.0);
        assert!(
            (near as f64) < 0.34 * b.len() as f64,
            "{near} of {}",
            b.len()
        );
        let r = align_scans(&reference, &b, &prior, &cov, &AlignSettings::default(), &s)
            .expect("the overlapping part verifies");
        assert!(
            (r.transform.x - truth.x).hypot(r.transform.y - truth.y) < 0.15,
            "{:?}",
            r.transform
        );
        assert!((r.transform.theta - truth.theta).abs() < 0.005);
    }

    /// A street whose every 115 m repeats (a grid of blocks dressed alike) fits itself
    /// moved one block along; a street that does not repeat does not, and neither fits
    /// itself moved where nothing repeats.
    #[test]
    fn a_repeating_street_fits_itself_one_block_over_and_another_does_not() {
        let s = ScanAlignSettings::default();
        let mut rng = ChaCha8Rng::seed_from_u64(10);
        // One block's street, 115 m, repeated four times along x.
        let block: Vec<[f64; 2]> = street(&mut rng, 57.5)
            .into_iter()
            .filter(|p| p[0] >= -57.5 && p[0] < 57.5 && p[1].abs() < 20.0)
            .collect();
        let repeated: Vec<[f64; 2]> = (0..4)
            .flat_map(|k| {
                let noise = &mut rng;
                block
                    .iter()
                    .map(|p| {
                        [
                            p[0] + 115.0 * k as f64 + noise.gen_range(-0.05..0.05),
                            p[1] + noise.gen_range(-0.05..0.05),
                        ]
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        let reference = reference_scan(repeated, &s);
        let window = [2.0, 2.0, 0.05];
        let block_over = Pose2::new(114.0, 0.6, 0.01);
        assert!(
            fits_itself(&reference, &block_over, window, &s).is_some(),
            "one block over"
        );
        assert!(
            fits_itself(&reference, &Pose2::new(57.0, 0.0, 0.0), window, &s).is_none(),
            "half a block over"
        );
        // A street that does not repeat, 460 m long.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let long: Vec<[f64; 2]> = (0..4)
            .flat_map(|k| {
                street(&mut rng, 57.5)
                    .into_iter()
                    .filter(|p| p[0] >= -57.5 && p[0] < 57.5 && p[1].abs() < 20.0)
                    .map(move |p| {
                        // Each block its own rhythm and fronts: stretched, set back
                        // differently, every other one mirrored across the street.
                        let f = 0.7 + 0.13 * k as f64;
                        let side = if k % 2 == 0 { 1.0 } else { -1.0 };
                        [
                            115.0 * k as f64 + f * p[0],
                            side * (1.0 + 0.45 * k as f64) * p[1],
                        ]
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        let reference = reference_scan(long, &s);
        assert!(
            fits_itself(&reference, &block_over, window, &s).is_none(),
            "a street that does not repeat"
        );
    }

    #[test]
    fn the_accumulator_keeps_cells_seen_twice_and_respects_its_bound() {
        let s = ScanAlignSettings {
            max_points: 3,
            ..ScanAlignSettings::default()
        };
        let mut acc = ScanAccumulator::new(&s);
        let pose = Pose2::new(10.0, 0.0, std::f64::consts::FRAC_PI_2);
        acc.add(&pose, &[[1.2, 0.3], [5.5, 0.5], [f64::NAN, 0.0]]);
        acc.add(&pose, &[[1.4, 0.3], [7.5, 0.5], [9.5, 0.5], [11.5, 0.5]]);
        assert_eq!(acc.cells(), 3);
        assert_eq!(acc.refused(), 2);
        let scan = acc.take();
        // Only the first return's cell was hit twice; placed by the pose (x' = 10 - y).
        assert_eq!(scan.len(), 1);
        assert!((scan[0][0] - 9.7).abs() < 1e-9 && (scan[0][1] - 1.3).abs() < 1e-9);
        assert_eq!(acc.cells(), 0);
    }
}
