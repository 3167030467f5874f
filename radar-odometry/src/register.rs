//! Registration of one cloud against a reference: trimmed, robust point-to-line ICP in the
//! plane, and what its information says about the directions the scene constrains.

use kiddo::SquaredEuclidean;
use nalgebra::{Complex, Matrix3, Vector3};
use radar_model::geometry::{wrap_angle, Pose2};

use crate::cloud::{ReferenceCloud, GRID_MAX_REACH};

/// A registration's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Registration {
    /// The current cloud's frame in the reference cloud's frame.
    pub pose: Pose2,
    /// Pairs used at the last iteration.
    pub pairs: usize,
    /// Of those, pairs with a point on a line-like surface (point-to-line).
    pub line_pairs: usize,
    /// Root-mean-square residual of those pairs (m): distance to the line, or to the point.
    pub rms_m: f64,
    /// Iterations run.
    pub iterations: usize,
    /// The Gauss-Newton information `H = sum w J' J` of the last iteration's pairs, in
    /// `[x m, y m, heading rad]`: how strongly the pairs pin each direction of the motion.
    pub information: Matrix3<f64>,
}

/// Trimmed, robust point-to-line ICP in the plane (points on a line-like surface of the
/// reference are pulled onto the surface, the others onto the nearest point): the pose `T`
/// of `current`'s frame in `reference`'s frame such that `T (p) ~ q` for paired points,
/// started at `initial`, by Gauss-Newton with Cauchy weights. Pairs farther apart than the
/// gate are not paired, nor, when `initial` is nearer the reference's origin than its
/// [`ReferenceCloud::surfaces_only_within`], points whose nearest reference point has no
/// normal; the gate narrows from `gate_m` to a
/// fifth of it. `None` when fewer than `min_pairs` pairs survive, the clouds are empty, or
/// the pairs do not constrain all three degrees of freedom.
pub fn register(
    reference: &ReferenceCloud,
    current: &[[f64; 2]],
    initial: Pose2,
    gate_m: f64,
    min_pairs: usize,
) -> Option<Registration> {
    icp(reference, current, None, initial, gate_m, min_pairs, 0)
}

/// [`register`] from `initial` already near (a registration's result, the cloud placed
/// again): the gate starts narrowed to a fifth of `gate_m`, where [`register`]'s ends,
/// and saves the iterations that narrow it (ten of at most forty).
pub fn register_narrowed(
    reference: &ReferenceCloud,
    current: &[[f64; 2]],
    initial: Pose2,
    gate_m: f64,
    min_pairs: usize,
) -> Option<Registration> {
    icp(
        reference,
        current,
        None,
        initial,
        gate_m,
        min_pairs,
        NARROWED_AFTER,
    )
}

/// A registration without hard pairs, from `initial` already near (a registration's
/// result): each return of `current` is drawn towards every reference point within
/// [`SOFT_REACH`] kernel widths of it, each with the weight of a Gaussian kernel of width
/// `kernel_m` on their distance, normalised over the return's neighbours (onto the
/// neighbour's surface where it lies on one, else onto the point), with Cauchy weights of
/// scale `kernel_m` on the residual. Where nearest-neighbour pairs switch all at once as the
/// pose moves, and leave several poses that each pair set holds in place, these weights
/// move continuously with the pose, so the pose found depends much less on where it
/// started. The kernel is fixed: no gate annealing. `None` as [`register`].
pub fn register_soft(
    reference: &ReferenceCloud,
    current: &[[f64; 2]],
    initial: Pose2,
    kernel_m: f64,
    min_pairs: usize,
) -> Option<Registration> {
    if reference.points.is_empty() || current.is_empty() || kernel_m.is_nan() || kernel_m <= 0.0 {
        return None;
    }
    let surfaces_only = initial.x.hypot(initial.y) < reference.surfaces_only_within_m;
    let radius = SOFT_REACH * kernel_m;
    let radius2 = radius * radius;
    let use_grid = reference
        .grid
        .reach(radius + 0.5 * kernel_m)
        .is_some_and(|r| r <= GRID_MAX_REACH);
    let inv_2s2 = 0.5 / (kernel_m * kernel_m);
    let scale2 = kernel_m * kernel_m;
    let mut t = initial;
    let mut last = None;
    let mut near: Vec<(usize, f64)> = Vec::new();
    // Each return's neighbours within the radius and a margin, listed where it was: exact
    // while it has moved less than the margin since (the pose moves millimetres from a
    // registration's result), so most iterations search nothing.
    let margin = 0.5 * kernel_m;
    let listed_r = radius + margin;
    let mut listed: Vec<Option<([f64; 2], Vec<u32>)>> = vec![None; current.len()];
    for it in 0..SOFT_ITERATIONS {
        let (s, c) = t.theta.sin_cos();
        let mut h = Matrix3::<f64>::zeros();
        let mut g = Vector3::<f64>::zeros();
        let (mut n, mut lines, mut sum_r2) = (0usize, 0usize, 0.0);
        for (p, list) in current.iter().zip(listed.iter_mut()) {
            let moved = [t.x + c * p[0] - s * p[1], t.y + s * p[0] + c * p[1]];
            let jt = [-s * p[0] - c * p[1], c * p[0] - s * p[1]];
            let fresh = list.as_ref().is_none_or(|(at, _)| {
                (moved[0] - at[0]).powi(2) + (moved[1] - at[1]).powi(2) > margin * margin
            });
            if fresh {
                if use_grid {
                    reference.grid.within(&moved, listed_r, &mut near);
                } else {
                    near.clear();
                    near.extend(
                        reference
                            .tree()
                            .within_unsorted::<SquaredEuclidean>(&moved, listed_r * listed_r)
                            .iter()
                            .map(|nb| (nb.item as usize, nb.distance)),
                    );
                }
                // At a crawl only the reference's surfaces (points with a normal) are
                // neighbours: kept out of the list, not weighed and then dropped.
                *list = Some((
                    moved,
                    near.iter()
                        .filter(|&&(i, _)| !surfaces_only || reference.has_normal(i))
                        .map(|&(i, _)| i as u32)
                        .collect(),
                ));
            }
            near.clear();
            if let Some((_, indices)) = list.as_ref() {
                for &i in indices {
                    if let Some(q) = reference.points.get(i as usize) {
                        let d2 = (q[0] - moved[0]).powi(2) + (q[1] - moved[1]).powi(2);
                        if d2 <= radius2 {
                            near.push((i as usize, (-d2 * inv_2s2).exp()));
                        }
                    }
                }
            }
            // `near` holds each neighbour's kernel weight.
            let total: f64 = near.iter().map(|&(_, k)| k).sum();
            if near.is_empty() || total <= 0.0 {
                continue;
            }
            n += 1;
            let (mut on_line, mut best) = (false, 0.0);
            for &(i, kernel) in &near {
                let (Some(q), Some(normal)) = (reference.points.get(i), reference.normals.get(i))
                else {
                    continue;
                };
                if kernel > best {
                    best = kernel;
                    on_line = normal.is_some();
                }
                let share = kernel / total;
                let d = [moved[0] - q[0], moved[1] - q[1]];
                match normal {
                    Some(nv) => {
                        let r = nv[0] * d[0] + nv[1] * d[1];
                        let j = Vector3::new(nv[0], nv[1], nv[0] * jt[0] + nv[1] * jt[1]);
                        let w = share / (1.0 + r * r / scale2);
                        h += w * j * j.transpose();
                        g += w * r * j;
                        sum_r2 += share * r * r;
                    }
                    None => {
                        let r2 = d[0] * d[0] + d[1] * d[1];
                        let w = share / (1.0 + r2 / scale2);
                        let jx = Vector3::new(1.0, 0.0, jt[0]);
                        let jy = Vector3::new(0.0, 1.0, jt[1]);
                        h += w * (jx * jx.transpose() + jy * jy.transpose());
                        g += w * (d[0] * jx + d[1] * jy);
                        sum_r2 += share * r2;
                    }
                }
            }
            if on_line {
                lines += 1;
            }
        }
        let delta;
        (t, delta) = gauss_newton_step(&t, &h, &g, n, min_pairs)?;
        last = Some(Registration {
            pose: t,
            pairs: n,
            line_pairs: lines,
            rms_m: (sum_r2 / n.max(1) as f64).sqrt(),
            iterations: it + 1,
            information: h,
        });
        if delta[0].hypot(delta[1]) + delta[2].abs() < SOFT_CONVERGED {
            break;
        }
    }
    last
}

/// The pose `t` moved by the Gauss-Newton step `-H^-1 g` of a registration's normal
/// equations over `pairs` pairs, and the step; `None` with fewer than `min_pairs` (at least
/// 3) pairs, an `H` that is not positive definite (the pairs do not pin all three degrees of
/// freedom), or a step that is not finite.
fn gauss_newton_step(
    t: &Pose2,
    h: &Matrix3<f64>,
    g: &Vector3<f64>,
    pairs: usize,
    min_pairs: usize,
) -> Option<(Pose2, Vector3<f64>)> {
    if pairs < min_pairs.max(3) {
        return None;
    }
    let delta = -h.cholesky()?.solve(g);
    if !delta.iter().all(|v| v.is_finite()) {
        return None;
    }
    let moved = Pose2::new(
        t.x + delta[0],
        t.y + delta[1],
        wrap_angle(t.theta + delta[2]),
    );
    Some((moved, delta))
}

/// [`register_soft`] stops once an iteration moves the pose by less than this (m + rad).
const SOFT_CONVERGED: f64 = 1e-5;

/// [`register_soft`]'s neighbours: within this many kernel widths.
const SOFT_REACH: f64 = 3.0;
/// [`register_soft`]'s largest number of iterations. Its steps shrink slowly (each return's
/// weights are held for a step, as mean shift holds them): on the realistic city's
/// radar-only drive (main seed 1, 474 runs) they took 16.8 on average, 69 % of runs more
/// than 12, 13 % all 30. Capped at 12, the radar alone drifted more (eight drives 0.755 %,
/// against ten at 0.658 % with 30). Followed by the rest of the geometric series two
/// steps the same way start (Aitken's extrapolation, 9.8 steps on average), the
/// registrations' heading errors lost much of their cancelling lag-one correlation (-0.37
/// -> -0.29 on that drive, -0.44 -> -0.22 on the check layout's seed 1) and four drives
/// drifted 0.853 % against 0.735 % without it: not done.
const SOFT_ITERATIONS: usize = 30;

/// ICP's largest number of iterations.
const ITERATIONS: usize = 40;
/// Each iteration narrows the gate by this factor, down to [`GATE_FLOOR`] of the gate.
const GATE_NARROWING: f64 = 0.85;
/// The narrowest gate, as a share of the gate given.
const GATE_FLOOR: f64 = 0.2;
/// The iterations after which the gate is at its narrowest (`0.85^10 < 0.2`).
const NARROWED_AFTER: usize = 10;

/// [`register`] for a cloud swept while the vehicle moved: `current[i]` is a return in the
/// sensor's frame at the moment it was swept, `fractions[i]` how far through the motion
/// that moment was (0 at the reference's frame, 1 at the pose sought). The motion is taken
/// as constant (a constant twist), so the return is moved by the exponential of that
/// fraction of the sought pose's logarithm: every iteration re-places the whole cloud along
/// the motion it is trying, and a turn's onset that the start did not foresee no longer bends
/// the cloud it is fitting. The pose found is the sensor's at fraction 1.
///
/// # Panics
/// Never; `fractions` shorter than `current` leaves the rest at fraction 1.
pub fn register_swept(
    reference: &ReferenceCloud,
    current: &[[f64; 2]],
    fractions: &[f64],
    initial: Pose2,
    gate_m: f64,
    min_pairs: usize,
) -> Option<Registration> {
    icp(
        reference,
        current,
        Some(fractions),
        initial,
        gate_m,
        min_pairs,
        0,
    )
}

/// The ICP of [`register`] and [`register_swept`], from iteration `first` of the gate's
/// narrowing.
fn icp(
    reference: &ReferenceCloud,
    current: &[[f64; 2]],
    fractions: Option<&[f64]>,
    initial: Pose2,
    gate_m: f64,
    min_pairs: usize,
    first: usize,
) -> Option<Registration> {
    if reference.points.is_empty() || current.is_empty() {
        return None;
    }
    let surfaces_only = initial.x.hypot(initial.y) < reference.surfaces_only_within_m;
    let mut t = initial;
    let mut last = None;
    // Each return's last grid search, kept while the pose moves too little to change its
    // answer (see [`Searched`]): the same pairs, far fewer cells read.
    let mut searched: Vec<Option<Searched>> = vec![None; current.len()];
    for it in first..ITERATIONS {
        let gate = gate_m * (GATE_NARROWING.powi(it as i32)).max(GATE_FLOOR);
        let gate2 = gate * gate;
        // Cauchy weights with a scale of half the gate: pairs near the gate count little.
        let scale2 = 0.25 * gate2;
        // The grid while the gate spans a few of its cells; the k-d tree for a gate far
        // wider than the cells it was built for.
        let use_grid = reference
            .grid
            .reach(gate)
            .is_some_and(|r| r <= GRID_MAX_REACH);
        let (s_end, c_end) = t.theta.sin_cos();
        let sweep = fractions.map(|_| Sweep::new(&t));
        let mut h = Matrix3::<f64>::zeros();
        let mut g = Vector3::<f64>::zeros();
        let (mut n, mut lines, mut sum_r2) = (0usize, 0usize, 0.0);
        for ((i, p), last_search) in current.iter().enumerate().zip(searched.iter_mut()) {
            // Where the return lands, and how that moves with the pose's x, y and heading.
            let (moved, jx, jy, jt) = match &sweep {
                Some(sweep) => {
                    let f = fractions.and_then(|f| f.get(i)).copied().unwrap_or(1.0);
                    sweep.place(f, p)
                }
                None => (
                    [
                        t.x + c_end * p[0] - s_end * p[1],
                        t.y + s_end * p[0] + c_end * p[1],
                    ],
                    [1.0, 0.0],
                    [0.0, 1.0],
                    [-s_end * p[0] - c_end * p[1], c_end * p[0] - s_end * p[1]],
                ),
            };
            let nearest = if use_grid {
                match last_search
                    .as_ref()
                    .and_then(|s| s.answer(&reference.points, &moved, gate))
                {
                    Some(kept) => kept,
                    None => {
                        let (nearest, clear2) =
                            reference.grid.nearest_within_and_clear(&moved, gate);
                        *last_search = Some(Searched {
                            at: moved,
                            gate,
                            nearest,
                            clear: clear2.sqrt(),
                        });
                        nearest
                    }
                }
            } else {
                *last_search = None;
                let nn = reference.tree().nearest_one::<SquaredEuclidean>(&moved);
                Some((nn.item as usize, nn.distance))
            };
            let Some((i, distance2)) = nearest else {
                continue;
            };
            if distance2 > gate2 {
                continue;
            }
            let (Some(q), Some(normal)) = (reference.points.get(i), reference.normals.get(i))
            else {
                continue;
            };
            if surfaces_only && normal.is_none() {
                continue;
            }
            let d = [moved[0] - q[0], moved[1] - q[1]];
            n += 1;
            match normal {
                Some(nv) => {
                    lines += 1;
                    let r = nv[0] * d[0] + nv[1] * d[1];
                    let dot = |v: [f64; 2]| nv[0] * v[0] + nv[1] * v[1];
                    let j = Vector3::new(dot(jx), dot(jy), dot(jt));
                    let w = 1.0 / (1.0 + r * r / scale2);
                    h += w * j * j.transpose();
                    g += w * r * j;
                    sum_r2 += r * r;
                }
                None => {
                    let r2 = d[0] * d[0] + d[1] * d[1];
                    let w = 1.0 / (1.0 + r2 / scale2);
                    for (axis, r) in d.iter().enumerate() {
                        let j = Vector3::new(jx[axis], jy[axis], jt[axis]);
                        h += w * j * j.transpose();
                        g += w * r * j;
                    }
                    sum_r2 += r2;
                }
            }
        }
        let delta;
        (t, delta) = gauss_newton_step(&t, &h, &g, n, min_pairs)?;
        let step = delta[0].hypot(delta[1]) + delta[2].abs();
        last = Some(Registration {
            pose: t,
            pairs: n,
            line_pairs: lines,
            rms_m: (sum_r2 / n as f64).sqrt(),
            iterations: it + 1,
            information: h,
        });
        if step < 1e-6 && gate <= GATE_FLOOR * gate_m + 1e-12 {
            break;
        }
    }
    last
}

/// Beyond the distances' rounding (m): a kept answer needs this much room to spare.
const KEPT_MARGIN_M: f64 = 1e-9;

/// A return's last grid search in an ICP: where the return was, the gate, the answer, and
/// the distance within which no other reference point lay
/// ([`crate::grid::PointGrid::nearest_within_and_clear`]).
#[derive(Debug, Clone, Copy)]
struct Searched {
    at: [f64; 2],
    gate: f64,
    nearest: Option<(usize, f64)>,
    clear: f64,
}

impl Searched {
    /// The grid's answer for the return now at `q` with gate `gate` (at most the searched
    /// one), without searching, where the move from `at` cannot have changed it; `None`
    /// where a search is needed. The nearest point stays nearest while its distance plus
    /// the move is below the others' bound minus the move (the triangle inequality, with
    /// [`KEPT_MARGIN_M`] to spare); where nothing lay within the old gate, nothing lies
    /// within a new gate narrower by more than the move.
    fn answer(&self, points: &[[f64; 2]], q: &[f64; 2], gate: f64) -> Option<Option<(usize, f64)>> {
        if gate > self.gate {
            return None;
        }
        // Not `hypot`: its care for overflow costs more than the search it saves.
        let (dx, dy) = (q[0] - self.at[0], q[1] - self.at[1]);
        let moved = (dx * dx + dy * dy).sqrt() + KEPT_MARGIN_M;
        match self.nearest {
            None => (gate + moved < self.clear).then_some(None),
            Some((j, _)) => {
                let p = points.get(j)?;
                // The grid's own arithmetic, so that the distance kept is the bits it gives.
                let d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]);
                if d2.sqrt() + moved >= self.clear - moved {
                    return None;
                }
                Some((d2 <= gate * gate).then_some((j, d2)))
            }
        }
    }
}

/// A constant twist from the identity to a pose `T`, in complex form (the plane as complex
/// numbers: `T`'s translation `t`, heading `theta`): the pose a fraction `f` of the way is
/// `(f V(f theta) / V(theta) t, f theta)` with `V(phi) = (e^{i phi} - 1) / (i phi)`, so its
/// derivatives with `T`'s components are exact, not the first order of a small motion.
struct Sweep {
    t: Complex<f64>,
    theta: f64,
    /// `1 / V(theta)`.
    v_inv: Complex<f64>,
    /// `V'(theta)`.
    dv: Complex<f64>,
}

impl Sweep {
    fn new(pose: &Pose2) -> Self {
        let (v, dv) = v_and_derivative(pose.theta);
        Self {
            t: Complex::new(pose.x, pose.y),
            theta: pose.theta,
            v_inv: v.inv(),
            dv,
        }
    }

    /// The point `p` (in the sensor's frame a fraction `f` of the way) in the frame at the
    /// start, and its derivatives with `T`'s x, y and heading.
    fn place(&self, f: f64, p: &[f64; 2]) -> ([f64; 2], [f64; 2], [f64; 2], [f64; 2]) {
        let (vf, dvf) = v_and_derivative(f * self.theta);
        // d(origin)/d(t) acts on t as multiplication by c.
        let c = f * vf * self.v_inv;
        let origin = c * self.t;
        let d_origin = f * self.t * (f * dvf * self.v_inv - vf * self.v_inv * self.v_inv * self.dv);
        let rotated = Complex::from_polar(1.0, f * self.theta) * Complex::new(p[0], p[1]);
        let moved = origin + rotated;
        let d_theta = d_origin + f * Complex::<f64>::i() * rotated;
        let jy = Complex::<f64>::i() * c;
        (
            [moved.re, moved.im],
            [c.re, c.im],
            [jy.re, jy.im],
            [d_theta.re, d_theta.im],
        )
    }
}

/// `V(phi) = (e^{i phi} - 1) / (i phi)` and its derivative, by their series near zero.
fn v_and_derivative(phi: f64) -> (Complex<f64>, Complex<f64>) {
    if phi.abs() < 1e-3 {
        let p2 = phi * phi;
        (
            Complex::new(1.0 - p2 / 6.0, phi / 2.0 - phi * p2 / 24.0),
            Complex::new(-phi / 3.0 + phi * p2 / 30.0, 0.5 - p2 / 8.0),
        )
    } else {
        let e = Complex::from_polar(1.0, phi);
        let i = Complex::<f64>::i();
        ((e - 1.0) / (i * phi), (phi * e + i * e - i) / (phi * phi))
    }
}

/// SE(2)'s logarithm: the twist `[v_x, v_y, omega]` (per unit of motion) whose exponential
/// is `pose` (the translation is `V(omega) v`, see [`Sweep`]).
pub fn log(pose: &Pose2) -> [f64; 3] {
    let (v, _) = v_and_derivative(pose.theta);
    let u = Complex::new(pose.x, pose.y) / v;
    [u.re, u.im, pose.theta]
}

/// SE(2)'s exponential of the twist `[v_x, v_y, omega]`.
pub fn exp(twist: [f64; 3]) -> Pose2 {
    let (v, _) = v_and_derivative(twist[2]);
    let t = v * Complex::new(twist[0], twist[1]);
    Pose2::new(t.re, t.im, twist[2])
}

/// The pose `fraction` of the way along `motion` at a constant twist.
pub fn along(motion: &Pose2, fraction: f64) -> Pose2 {
    let w = log(motion);
    exp([fraction * w[0], fraction * w[1], fraction * w[2]])
}

/// `points` (in some frame) expressed in the frame of `pose` (a pose in that frame).
pub fn in_frame_of(pose: &Pose2, points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let (s, c) = pose.theta.sin_cos();
    points
        .iter()
        .map(|p| {
            let (dx, dy) = (p[0] - pose.x, p[1] - pose.y);
            [c * dx + s * dy, -s * dx + c * dy]
        })
        .collect()
}

/// Length (m) that puts a heading error on the scale of a translation in [`Constraint`]: a
/// heading error of `1 / L` rad moves a return `L` metres out by a metre's tenth... by
/// `1 / L` of its range; 10 m is a typical range of the returns that pin the heading.
pub const HEADING_LENGTH_M: f64 = 10.0;

/// How well a registration's pairs pin the motion: the eigen-decomposition of its information
/// with the heading scaled by [`HEADING_LENGTH_M`], per pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Constraint {
    /// The smallest eigenvalue of the scaled information per pair: about 0.5 when the pairs'
    /// surfaces face every way (a street with cross walls, cars and posts), 1 for points
    /// paired with points, near 0 along a long featureless wall or in an open field.
    pub weakest: f64,
    /// The direction it belongs to, `[x, y, heading x L]` (unit length).
    pub direction: [f64; 3],
}

impl Constraint {
    /// The analysis of `reg`; `None` without pairs or with a non-finite information.
    pub fn of(reg: &Registration) -> Option<Self> {
        if reg.pairs == 0 || !reg.information.iter().all(|v| v.is_finite()) {
            return None;
        }
        let d = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 1.0 / HEADING_LENGTH_M));
        let scaled = d * reg.information * d / reg.pairs as f64;
        let eig = (0.5 * (scaled + scaled.transpose())).symmetric_eigen();
        let (i, weakest) = eig
            .eigenvalues
            .iter()
            .copied()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        let v = eig.eigenvectors.column(i);
        Some(Self {
            weakest: weakest.max(0.0),
            direction: [v[0], v[1], v[2]],
        })
    }
}

/// The covariance of a registration's motion: the configured floor `floor` (what the
/// registration errs by on a well-constrained scene) plus the pairs' own uncertainty,
/// `c rms^2 H^-1`, where `c` counts how many neighbouring pairs share one error (pairs along
/// one surface are not independent). On a well-constrained scene the second term is a few
/// per cent of the first; along a direction the pairs do not constrain it is large, so the
/// filter leans on its prediction there and the pose's uncertainty grows instead of the
/// pose being confidently wrong. `None` when the information cannot be inverted.
pub fn covariance(
    reg: &Registration,
    floor: &Matrix3<f64>,
    correlated_pairs: f64,
    min_residual_m: f64,
) -> Option<Matrix3<f64>> {
    // A tiny ridge keeps an exactly singular information (one straight wall, no posts)
    // invertible: its inverse is then huge along the wall, which is the point.
    let ridge = 1e-9 * reg.information.trace().abs().max(1e-12);
    let inv = (reg.information + Matrix3::identity() * ridge).try_inverse()?;
    let sigma2 = reg.rms_m.max(min_residual_m).powi(2);
    let cov = floor + inv * (correlated_pairs * sigma2);
    let cov = 0.5 * (cov + cov.transpose());
    cov.iter().all(|v| v.is_finite()).then_some(cov)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::tests::street;

    /// A return's kept answer is the grid's own wherever it is kept: queries near a street's
    /// points (on them, between them, off them), moved by a micrometre to a decimetre, the
    /// gate narrowed or not. And most small moves are answered without a search.
    #[test]
    fn a_kept_pair_is_the_one_a_search_finds() {
        use rand::{Rng, SeedableRng};
        let world = street();
        let cloud = ReferenceCloud::new(world.clone(), 1.5, 0.6);
        let grid = &cloud.grid;
        let (mut kept, mut small) = (0, 0);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(35);
        let mut uniform = move || rng.gen::<f64>();
        for (n, p) in world.iter().enumerate().step_by(3) {
            let q = [
                p[0] + 0.5 * (uniform() - 0.5),
                p[1] + 0.5 * (uniform() - 0.5),
            ];
            let q = if n % 9 == 0 { *p } else { q };
            for gate in [0.6, 0.3, 0.12] {
                let (nearest, clear2) = grid.nearest_within_and_clear(&q, gate);
                assert_eq!(nearest, grid.nearest_within(&q, gate));
                let searched = Searched {
                    at: q,
                    gate,
                    nearest,
                    clear: clear2.sqrt(),
                };
                for moved in [1e-6, 1e-4, 1e-3, 1e-2, 0.1] {
                    let a = std::f64::consts::TAU * uniform();
                    let to = [q[0] + moved * a.cos(), q[1] + moved * a.sin()];
                    for narrowed in [gate, 0.85 * gate] {
                        let Some(answer) = searched.answer(&world, &to, narrowed) else {
                            continue;
                        };
                        kept += 1;
                        if moved <= 1e-4 {
                            small += 1;
                        }
                        assert_eq!(
                            answer,
                            grid.nearest_within(&to, narrowed),
                            "{q:?} moved {moved} gate {gate} -> {narrowed}"
                        );
                    }
                }
            }
        }
        let tried = world.len().div_ceil(3) * 3 * 2 * 2;
        assert!(
            small > tried * 9 / 10,
            "{small} of {tried} micrometre moves kept"
        );
        assert!(kept > small, "{kept} kept");
    }

    #[test]
    fn icp_recovers_a_motion_started_five_per_cent_off() {
        let world = street();
        let a = Pose2::new(0.0, 0.0, 0.0);
        let b = Pose2::new(2.2, 0.05, 0.012);
        let reference = ReferenceCloud::new(in_frame_of(&a, &world), 1.5, 0.6);
        assert!(
            reference.with_normals() > world.len() / 2,
            "walls have normals"
        );
        let current = in_frame_of(&b, &world);
        let reg = register(
            &reference,
            &current,
            Pose2::new(2.2 * 1.05, 0.0, 0.0),
            1.5,
            50,
        )
        .expect("registers");
        assert!((reg.pose.x - b.x).abs() < 1e-3, "{reg:?}");
        assert!((reg.pose.y - b.y).abs() < 1e-3, "{reg:?}");
        assert!((reg.pose.theta - b.theta).abs() < 1e-4, "{reg:?}");
        assert!(reg.line_pairs > 0 && reg.line_pairs < reg.pairs, "{reg:?}");
    }

    /// [`register_soft`] from a start a few centimetres and milliradians off lands on the
    /// motion, with every return paired, on the street's walls (line pairs) and posts; with
    /// no reference point within reach it is no registration, and a kernel that is not
    /// positive is refused.
    #[test]
    fn a_registration_without_hard_pairs_recovers_the_motion() {
        let world = street();
        let reference =
            ReferenceCloud::new(in_frame_of(&Pose2::new(0.0, 0.0, 0.0), &world), 1.5, 0.6);
        let b = Pose2::new(2.2, 0.05, 0.012);
        let current = in_frame_of(&b, &world);
        let reg = register_soft(&reference, &current, Pose2::new(2.23, 0.03, 0.009), 0.1, 50)
            .expect("registers");
        assert!((reg.pose.x - b.x).abs() < 1e-3, "{reg:?}");
        assert!((reg.pose.y - b.y).abs() < 1e-3, "{reg:?}");
        assert!((reg.pose.theta - b.theta).abs() < 1e-4, "{reg:?}");
        assert!(reg.line_pairs > 0 && reg.line_pairs < reg.pairs, "{reg:?}");
        assert!(reg.iterations <= SOFT_ITERATIONS, "{reg:?}");
        let far = Pose2::new(500.0, 0.0, 0.0);
        assert!(register_soft(&reference, &current, far, 0.1, 50).is_none());
        for k in [0.0, -0.1, f64::NAN] {
            assert!(register_soft(&reference, &current, b, k, 50).is_none());
        }
    }

    /// Started near (within the narrowest gate), the narrowed registration lands where the
    /// full one does, and the gate is at its narrowest from its first iteration.
    #[test]
    fn a_registration_started_near_lands_where_the_full_one_does_narrowed() {
        assert!(GATE_NARROWING.powi(NARROWED_AFTER as i32) <= GATE_FLOOR);
        assert!(GATE_NARROWING.powi(NARROWED_AFTER as i32 - 1) > GATE_FLOOR);
        let world = street();
        let reference =
            ReferenceCloud::new(in_frame_of(&Pose2::new(0.0, 0.0, 0.0), &world), 1.5, 0.6);
        let b = Pose2::new(2.2, 0.05, 0.012);
        let current = in_frame_of(&b, &world);
        let start = Pose2::new(2.23, 0.06, 0.011);
        let full = register(&reference, &current, start, 1.5, 50).expect("registers");
        let narrowed = register_narrowed(&reference, &current, start, 1.5, 50).expect("registers");
        for reg in [&full, &narrowed] {
            assert!((reg.pose.x - b.x).abs() < 1e-3, "{reg:?}");
            assert!((reg.pose.y - b.y).abs() < 1e-3, "{reg:?}");
            assert!((reg.pose.theta - b.theta).abs() < 1e-4, "{reg:?}");
        }
        assert_eq!(narrowed.pairs, full.pairs);
    }

    /// Two walls sampled at fixed bearings from each pose (as a radar samples them): the
    /// samples move with the sensor, so pairing points with points pulls the motion along
    /// the walls towards zero; pairing them with the walls' lines does not. A few posts fix
    /// the along-track motion.
    #[test]
    fn walls_sampled_at_fixed_bearings_do_not_shrink_the_motion() {
        let scan = |pose: &Pose2| -> Vec<[f64; 2]> {
            let mut pts = Vec::new();
            for k in 0..400 {
                let bearing = std::f64::consts::TAU * f64::from(k) / 400.0;
                let (s, c) = (pose.theta + bearing).sin_cos();
                // Walls y = 8 and y = -7.5 (world), where the beam meets them within 60 m.
                for wall_y in [8.0, -7.5] {
                    if s.abs() > 1e-9 {
                        let r = (wall_y - pose.y) / s;
                        if r > 4.0 && r < 60.0 {
                            let world = [pose.x + r * c, pose.y + r * s];
                            pts.push(world);
                        }
                    }
                }
            }
            for k in 0..8 {
                pts.push([-20.0 + 6.0 * f64::from(k), 5.0 - 0.7 * f64::from(k % 3)]);
            }
            in_frame_of(pose, &pts)
        };
        let a = Pose2::new(0.0, 0.0, 0.0);
        let b = Pose2::new(2.0, 0.0, 0.0);
        let reference = ReferenceCloud::new(scan(&a), 1.5, 0.6);
        let reg =
            register(&reference, &scan(&b), Pose2::new(2.1, 0.0, 0.0), 0.6, 50).expect("registers");
        assert!((reg.pose.x - b.x).abs() < 0.01, "{reg:?}");
        assert!(
            reg.pose.y.abs() < 0.01 && reg.pose.theta.abs() < 1e-3,
            "{reg:?}"
        );
    }

    /// A vehicle crawling 0.3 m down a street whose ground clutter (a scatterer a square
    /// metre) is seen in a pattern that turns with the sensor, as a parked car's shadow
    /// over it does: paired with everything, the clutter turns the registration after it;
    /// paired with the walls only, the motion is found.
    #[test]
    fn clutter_that_turns_with_the_sensor_does_not_turn_a_surfaces_only_registration() {
        let mut walls = Vec::new();
        for i in 0..267 {
            let x = -40.0 + 0.3 * f64::from(i);
            walls.push([x, 9.0]);
            walls.push([x, -8.5]);
        }
        for i in 0..58 {
            walls.push([36.0, -8.4 + 0.3 * f64::from(i)]);
        }
        // Diffuse clutter in the sensor's frame: a jittered grid, a metre apart.
        let mut seed = 12_345u64;
        let mut uniform = || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut clutter = Vec::new();
        for ix in -30..30 {
            for iy in -7..8 {
                clutter.push([f64::from(ix) + uniform(), f64::from(iy) + uniform() - 0.5]);
            }
        }
        let turned = in_frame_of(&Pose2::new(0.0, 0.0, -0.01), &clutter);
        let b = Pose2::new(0.3, 0.0, 0.0);
        let scan = |pose: &Pose2, clutter: &[[f64; 2]]| {
            let mut pts = in_frame_of(pose, &walls);
            pts.extend_from_slice(clutter);
            pts
        };
        let reference_points = scan(&Pose2::new(0.0, 0.0, 0.0), &clutter);
        let current = scan(&b, &turned);
        let start = Pose2::new(0.25, 0.0, 0.0);
        let all = ReferenceCloud::new(reference_points.clone(), 1.5, 0.6);
        assert!(
            all.with_normals() < walls.len() + clutter.len() / 10,
            "the clutter is not line-like: {} normals",
            all.with_normals()
        );
        let biased = register(&all, &current, start, 0.6, 50).expect("registers");
        let surfaces =
            ReferenceCloud::new(reference_points.clone(), 1.5, 0.6).surfaces_only_within(0.9);
        let farther = ReferenceCloud::new(reference_points, 1.5, 0.6).surfaces_only_within(0.2);
        let unchanged = register(&farther, &current, start, 0.6, 50).expect("registers");
        assert_eq!(unchanged, biased, "started beyond 0.2 m, everything pairs");
        let reg = register(&surfaces, &current, start, 0.6, 50).expect("registers");
        assert!(
            biased.pose.theta.abs() > 0.003,
            "the clutter turns it: {biased:?}"
        );
        assert!((reg.pose.theta - b.theta).abs() < 5e-4, "{reg:?}");
        assert!(
            (reg.pose.x - b.x).abs() < 0.02 && reg.pose.y.abs() < 0.01,
            "{reg:?}"
        );
        assert_eq!(reg.pairs, reg.line_pairs, "only surfaces are paired");
    }

    #[test]
    fn too_few_pairs_is_no_registration() {
        let points = vec![[0.0, 0.0], [1.0, 0.0]];
        let reference = ReferenceCloud::new(points.clone(), 1.5, 1.0);
        assert!(register(&reference, &points, Pose2::new(0.0, 0.0, 0.0), 1.0, 3).is_none());
        assert!(register(&reference, &[], Pose2::new(0.0, 0.0, 0.0), 1.0, 1).is_none());
    }

    /// A single straight wall: the pairs pin the motion across it and the heading, never
    /// along it; the analysis names that direction and the covariance is large along it.
    #[test]
    fn a_lone_wall_is_weak_along_itself_and_its_covariance_says_so() {
        let wall: Vec<[f64; 2]> = (0..300)
            .map(|i| [-30.0 + 0.2 * f64::from(i), 6.0])
            .collect();
        let reference = ReferenceCloud::new(wall.clone(), 1.5, 0.6);
        let moved = in_frame_of(&Pose2::new(0.0, 0.05, 0.0), &wall);
        let reg = register(&reference, &moved, Pose2::new(0.0, 0.0, 0.0), 0.6, 50)
            .expect("a wall still registers across");
        let c = Constraint::of(&reg).expect("pairs");
        assert!(c.weakest < 1e-3, "{c:?}");
        assert!(c.direction[0].abs() > 0.99, "along the wall: {c:?}");
        let floor = Matrix3::from_diagonal(&Vector3::new(
            0.05f64.powi(2),
            0.05f64.powi(2),
            0.003f64.powi(2),
        ));
        let cov = covariance(&reg, &floor, 10.0, 0.02).expect("invertible with the ridge");
        assert!(cov[(0, 0)] > 1.0, "along the wall: {cov}");
        assert!(cov[(1, 1)] < 4.0 * floor[(1, 1)], "across the wall: {cov}");

        let street = street();
        let reference = ReferenceCloud::new(street.clone(), 1.5, 0.6);
        let moved = in_frame_of(&Pose2::new(1.0, 0.0, 0.01), &street);
        let reg =
            register(&reference, &moved, Pose2::new(1.0, 0.0, 0.0), 0.6, 50).expect("registers");
        let c = Constraint::of(&reg).expect("pairs");
        assert!(c.weakest > 0.01, "posts pin the street along: {c:?}");
        let cov = covariance(&reg, &floor, 10.0, 0.02).expect("invertible");
        for i in 0..3 {
            assert!(cov[(i, i)] < 2.0 * floor[(i, i)], "{cov}");
        }
    }

    /// The swept placement's derivatives against central differences, at fractions from
    /// before the start to past the end, for a straight motion, a turn and a near-zero turn.
    #[test]
    fn the_swept_placement_s_jacobian_matches_finite_differences() {
        let p = [23.0, -7.5];
        for pose in [
            Pose2::new(2.5, 0.0, 0.0),
            Pose2::new(2.4, 0.3, 0.12),
            Pose2::new(-1.0, 0.2, -4e-4),
        ] {
            for f in [-0.1, 0.0, 0.3, 0.5, 0.97, 1.0, 1.2] {
                let (moved, jx, jy, jt) = Sweep::new(&pose).place(f, &p);
                // Fraction 1 is the pose itself; the placement is the pose along the twist.
                let at = along(&pose, f);
                let direct = at.point_at(p[0].hypot(p[1]), -p[1].atan2(p[0]));
                assert!((moved[0] - direct[0]).abs() < 1e-9 && (moved[1] - direct[1]).abs() < 1e-9);
                let h = 1e-6;
                for (k, analytic) in [jx, jy, jt].iter().enumerate() {
                    let shifted = |e: f64| {
                        let mut q = [pose.x, pose.y, pose.theta];
                        q[k] += e;
                        Sweep::new(&Pose2::new(q[0], q[1], q[2])).place(f, &p).0
                    };
                    let (a, b) = (shifted(h), shifted(-h));
                    for axis in 0..2 {
                        let numeric = (a[axis] - b[axis]) / (2.0 * h);
                        assert!(
                            (numeric - analytic[axis]).abs() < 1e-5,
                            "pose {pose:?} f {f} column {k} axis {axis}: analytic {} numeric {numeric}",
                            analytic[axis]
                        );
                    }
                }
            }
        }
    }
}
