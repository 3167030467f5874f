//! Loop-closure verification: is submap `b` a second look at the place submap `a` mapped,
//! and if so, where is `b`'s frame in `a`'s?
//!
//! 1. **Candidate pairs**: each well-observed feature of `b`, placed in `a` by the prior guess
//!    of the transform, against each of `a`'s, gated on position (both features' covariances
//!    and the prior's, chi-square 2 dof) and on material (the reflectivity and absorption
//!    logits `u, v` with both covariances, chi-square 2 dof).
//! 2. **Hypotheses**: a transform from every two candidate pairs whose distances agree
//!    (deterministic sampling with a fixed budget), scored by how many features of `b` then
//!    land on a feature of `a` of the same material (one to one, tight gate without the
//!    prior). The best hypothesis and the best *rival* (a transform clearly different from
//!    the best) are kept.
//! 3. **Verification**: the best hypothesis's matches refined by weighted least squares;
//!    accepted only if there are at least [`AlignSettings::min_matches`], they are jointly
//!    compatible (their joint NIS inside the chi-square bound with `2n - 3` dof), the
//!    transform is compatible with the prior, and no rival explains nearly as much
//!    ([`AlignSettings::max_rival_ratio`]): repeated structure that fits two ways is refused.
//!    One wrong loop closure would bend the whole map; a missed one only costs accuracy.

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use radar_model::geometry::{wrap_angle, Pose2};
use slam_filter::SubmapFeature;
use statrs::distribution::{ChiSquared, ContinuousCDF};

use crate::se2::rotation;

/// The verifier's thresholds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlignSettings {
    /// Features used: at least this many observations.
    pub min_hits: u64,
    /// Fewest matched features to accept a loop closure.
    pub min_matches: usize,
    /// Probability mass inside each gate (position and material).
    pub gate_probability: f64,
    /// Probability for the joint compatibility test.
    pub joint_probability: f64,
    /// Probability for the test of the transform against the prior (loose: the prior is
    /// the chained local filters' covariance, which a long excursion makes optimistic; the
    /// joint compatibility and rival tests guard against wrong closures).
    pub prior_probability: f64,
    /// A rival with at least this share of the best hypothesis's matches refuses the closure.
    pub max_rival_ratio: f64,
    /// Transforms closer than this (m, and a tenth of it in rad) are the same hypothesis.
    pub rival_separation_m: f64,
    /// Hypotheses tried at most.
    pub max_hypotheses: usize,
    /// Two features closer than this (m) give no usable hypothesis.
    pub min_baseline_m: f64,
}

impl Default for AlignSettings {
    fn default() -> Self {
        Self {
            min_hits: 3,
            min_matches: 6,
            gate_probability: 0.99,
            joint_probability: 0.99,
            prior_probability: 0.99999,
            max_rival_ratio: 0.6,
            rival_separation_m: 2.0,
            max_hypotheses: 4000,
            min_baseline_m: 3.0,
        }
    }
}

/// An accepted loop closure between two submaps.
#[derive(Debug, Clone, PartialEq)]
pub struct Alignment {
    /// `b`'s frame in `a`'s.
    pub transform: Pose2,
    /// Its covariance (x, y, theta in `a`'s frame).
    pub covariance: Matrix3<f64>,
    /// Matched `(index in a, index in b)` feature pairs.
    pub matches: Vec<(usize, usize)>,
    /// Their joint NIS, and its degrees of freedom.
    pub nis: f64,
    /// Dof of the joint test.
    pub dof: usize,
    /// Matches of the best rival hypothesis.
    pub rival_matches: usize,
}

/// Why a candidate was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Refusal {
    /// Too few features pass the gates.
    TooFewCandidates(usize),
    /// The best hypothesis matches too few features.
    TooFewMatches(usize),
    /// The matches are not jointly compatible.
    NotJointlyCompatible {
        /// Joint NIS.
        nis: f64,
        /// Its bound.
        bound: f64,
    },
    /// The transform is not compatible with the prior.
    FarFromPrior(f64),
    /// Another transform explains nearly as much: repeated structure.
    Ambiguous {
        /// Best matches.
        best: usize,
        /// Rival matches.
        rival: usize,
    },
    /// The refinement did not give a positive definite covariance.
    Degenerate,
    /// Scans: the registration's residual is too large for a second look at one place.
    PoorFit {
        /// Root-mean-square residual (m).
        rms_m: f64,
    },
    /// Scans: the registration does not pin every direction (a bare corridor).
    Unconstrained {
        /// Standard deviation along the weakest direction (m).
        sigma_m: f64,
        /// And in heading (rad).
        sigma_rad: f64,
    },
    /// A closure from a place descriptor puts the new frame farther from where the chain
    /// of submaps puts it than any drift of the odometry could explain.
    Implausible {
        /// How far from the chain's position (m).
        distance_m: f64,
        /// And heading (rad).
        heading_rad: f64,
    },
    /// Scans: a closure from a place descriptor that puts the new frame elsewhere than the
    /// chain of submaps does, where the earlier place fits itself moved by that
    /// difference: the place repeats (a grid of blocks dressed alike), and the chain's
    /// position fits as well as the descriptor's.
    Repeats {
        /// How far the descriptor's position is from the chain's (m).
        distance_m: f64,
        /// Matches of the earlier scan with itself so moved.
        self_matches: usize,
    },
}

#[derive(Debug, Clone, Copy)]
struct Hypothesis {
    t: Pose2,
    matches: usize,
}

fn chi2_bound(dof: usize, p: f64) -> f64 {
    ChiSquared::new(dof.max(1) as f64)
        .map(|d| d.inverse_cdf(p))
        .unwrap_or(f64::INFINITY)
}

fn mahalanobis2(d: &Vector2<f64>, s: &Matrix2<f64>) -> Option<f64> {
    let ch = s.cholesky()?;
    Some(d.dot(&ch.solve(d)))
}

fn place(t: &Pose2, p: [f64; 2]) -> Vector2<f64> {
    rotation(t.theta) * Vector2::new(p[0], p[1]) + Vector2::new(t.x, t.y)
}

/// The transform taking `b1, b2` onto `a1, a2` (rotation from the direction between them,
/// translation from their midpoints).
fn two_point(a1: Vector2<f64>, a2: Vector2<f64>, b1: Vector2<f64>, b2: Vector2<f64>) -> Pose2 {
    let (da, db) = (a2 - a1, b2 - b1);
    let theta = wrap_angle(da.y.atan2(da.x) - db.y.atan2(db.x));
    let mid_a = 0.5 * (a1 + a2);
    let mid_b = rotation(theta) * (0.5 * (b1 + b2));
    Pose2::new(mid_a.x - mid_b.x, mid_a.y - mid_b.y, theta)
}

struct Problem<'a> {
    a: &'a [SubmapFeature],
    b: &'a [SubmapFeature],
    candidates: Vec<(usize, usize)>,
    gate2: f64,
}

impl Problem<'_> {
    fn same_material(&self, ia: usize, ib: usize) -> bool {
        let (fa, fb) = (&self.a[ia], &self.b[ib]);
        let d = Vector2::new(fa.uv[0] - fb.uv[0], fa.uv[1] - fb.uv[1]);
        mahalanobis2(&d, &(fa.uv_cov + fb.uv_cov)).is_some_and(|m| m <= self.gate2)
    }

    /// `(d, S)` of b's feature placed by `t` against a's, without prior uncertainty.
    fn residual(&self, t: &Pose2, ia: usize, ib: usize) -> (Vector2<f64>, Matrix2<f64>) {
        let (fa, fb) = (&self.a[ia], &self.b[ib]);
        let r = rotation(t.theta);
        let d = Vector2::new(fa.xy[0], fa.xy[1]) - place(t, fb.xy);
        (d, fa.xy_cov + r * fb.xy_cov * r.transpose())
    }

    /// One-to-one matches of `b` onto `a` under `t` among the candidate pairs (every
    /// plausible match passed the looser prior gate), greedy by Mahalanobis distance.
    fn matches(&self, t: &Pose2) -> Vec<(usize, usize)> {
        let mut scored: Vec<(f64, usize, usize)> = Vec::new();
        for &(ia, ib) in &self.candidates {
            let (d, s) = self.residual(t, ia, ib);
            if let Some(m) = mahalanobis2(&d, &s) {
                if m <= self.gate2 {
                    scored.push((m, ia, ib));
                }
            }
        }
        scored.sort_by(|x, y| x.0.total_cmp(&y.0));
        let (mut used_a, mut used_b) = (Vec::new(), Vec::new());
        let mut out = Vec::new();
        for (_, ia, ib) in scored {
            if !used_a.contains(&ia) && !used_b.contains(&ib) {
                used_a.push(ia);
                used_b.push(ib);
                out.push((ia, ib));
            }
        }
        out
    }

    /// Weighted least squares of the transform over `pairs`, from `t`; with its covariance
    /// and the joint NIS.
    fn refine(&self, mut t: Pose2, pairs: &[(usize, usize)]) -> Option<(Pose2, Matrix3<f64>, f64)> {
        let mut info = Matrix3::zeros();
        for _ in 0..10 {
            let mut h = Matrix3::zeros();
            let mut g = Vector3::zeros();
            for &(ia, ib) in pairs {
                let (d, s) = self.residual(&t, ia, ib);
                let w = s.cholesky()?.inverse();
                let fb = &self.b[ib];
                let (sn, cs) = t.theta.sin_cos();
                // d = a - (R b + t): d d / d(tx, ty, theta).
                let dr = Vector2::new(
                    -sn * fb.xy[0] - cs * fb.xy[1],
                    cs * fb.xy[0] - sn * fb.xy[1],
                );
                let j = nalgebra::Matrix2x3::new(-1.0, 0.0, -dr.x, 0.0, -1.0, -dr.y);
                h += j.transpose() * w * j;
                g += j.transpose() * w * d;
            }
            let step = -h.cholesky()?.solve(&g);
            t = Pose2::new(t.x + step.x, t.y + step.y, wrap_angle(t.theta + step.z));
            info = h;
            if step.abs().max() < 1e-10 {
                break;
            }
        }
        let cov = info.cholesky()?.inverse();
        let nis: f64 = pairs
            .iter()
            .filter_map(|&(ia, ib)| {
                let (d, s) = self.residual(&t, ia, ib);
                mahalanobis2(&d, &s)
            })
            .sum();
        Some((t, 0.5 * (cov + cov.transpose()), nis))
    }
}

fn distinct(x: &Pose2, y: &Pose2, sep_m: f64) -> bool {
    (x.x - y.x).hypot(x.y - y.y) > sep_m || wrap_angle(x.theta - y.theta).abs() > 0.1 * sep_m
}

/// Verifies that `b` (features in its own frame) re-observes `a`, given the prior guess
/// `prior` of `b`'s frame in `a`'s with covariance `prior_cov`.
pub fn align(
    a: &[SubmapFeature],
    b: &[SubmapFeature],
    prior: &Pose2,
    prior_cov: &Matrix3<f64>,
    settings: &AlignSettings,
) -> Result<Alignment, Refusal> {
    let gate2 = chi2_bound(2, settings.gate_probability);
    let mut problem = Problem {
        a,
        b,
        candidates: Vec::new(),
        gate2,
    };
    let usable_a: Vec<usize> = (0..a.len())
        .filter(|&i| a[i].hits >= settings.min_hits)
        .collect();
    let usable_b: Vec<usize> = (0..b.len())
        .filter(|&i| b[i].hits >= settings.min_hits)
        .collect();
    // 1. Candidate pairs under the prior.
    let r = rotation(prior.theta);
    let mut candidates: Vec<(usize, usize)> = Vec::new();
    for &ib in &usable_b {
        let fb = &b[ib];
        let p = place(prior, fb.xy);
        let (sn, cs) = prior.theta.sin_cos();
        let j = nalgebra::Matrix2x3::new(
            1.0,
            0.0,
            -sn * fb.xy[0] - cs * fb.xy[1],
            0.0,
            1.0,
            cs * fb.xy[0] - sn * fb.xy[1],
        );
        let s_b = r * fb.xy_cov * r.transpose() + j * prior_cov * j.transpose();
        for &ia in &usable_a {
            let fa = &a[ia];
            let d = Vector2::new(fa.xy[0], fa.xy[1]) - p;
            if mahalanobis2(&d, &(fa.xy_cov + s_b)).is_some_and(|m| m <= gate2)
                && problem.same_material(ia, ib)
            {
                candidates.push((ia, ib));
            }
        }
    }
    if candidates.len() < settings.min_matches {
        return Err(Refusal::TooFewCandidates(candidates.len()));
    }
    problem.candidates = candidates.clone();
    // 2. Hypotheses from pairs of candidate pairs, in a fixed order with a fixed stride so
    // the budget samples the whole list deterministically.
    let m = candidates.len();
    let total = m * (m - 1) / 2;
    let stride = (total / settings.max_hypotheses.max(1)).max(1);
    let mut hypotheses: Vec<Hypothesis> = Vec::new();
    let mut k = 0usize;
    'outer: for i in 0..m {
        for j in (i + 1)..m {
            k += 1;
            if !k.is_multiple_of(stride) {
                continue;
            }
            if hypotheses.len() >= settings.max_hypotheses {
                break 'outer;
            }
            let ((a1, b1), (a2, b2)) = (candidates[i], candidates[j]);
            if a1 == a2 || b1 == b2 {
                continue;
            }
            let pa1 = Vector2::from(a[a1].xy);
            let pa2 = Vector2::from(a[a2].xy);
            let pb1 = Vector2::from(b[b1].xy);
            let pb2 = Vector2::from(b[b2].xy);
            let (la, lb) = ((pa2 - pa1).norm(), (pb2 - pb1).norm());
            if lb < settings.min_baseline_m {
                continue;
            }
            let sigma = (a[a1].xy_cov.trace()
                + a[a2].xy_cov.trace()
                + b[b1].xy_cov.trace()
                + b[b2].xy_cov.trace())
            .sqrt();
            if (la - lb).abs() > 3.0 * sigma + 0.05 {
                continue;
            }
            let t = two_point(pa1, pa2, pb1, pb2);
            if hypotheses.iter().any(|h| !distinct(&h.t, &t, 0.25)) {
                continue;
            }
            let matches = problem.matches(&t).len();
            hypotheses.push(Hypothesis { t, matches });
        }
    }
    hypotheses.sort_by_key(|h| std::cmp::Reverse(h.matches));
    let Some(best) = hypotheses.first().copied() else {
        return Err(Refusal::TooFewMatches(0));
    };
    // 3. Verification.
    let pairs = problem.matches(&best.t);
    let (t, _, _) = problem.refine(best.t, &pairs).ok_or(Refusal::Degenerate)?;
    let pairs = problem.matches(&t);
    if pairs.len() < settings.min_matches {
        return Err(Refusal::TooFewMatches(pairs.len()));
    }
    let (t, cov, nis) = problem.refine(t, &pairs).ok_or(Refusal::Degenerate)?;
    let rival = hypotheses
        .iter()
        .filter(|h| distinct(&h.t, &t, settings.rival_separation_m))
        .map(|h| h.matches)
        .max()
        .unwrap_or(0);
    if rival as f64 >= settings.max_rival_ratio * pairs.len() as f64 {
        return Err(Refusal::Ambiguous {
            best: pairs.len(),
            rival,
        });
    }
    let dof = 2 * pairs.len() - 3;
    let bound = chi2_bound(dof, settings.joint_probability);
    if nis > bound {
        return Err(Refusal::NotJointlyCompatible { nis, bound });
    }
    let d = Vector3::new(
        t.x - prior.x,
        t.y - prior.y,
        wrap_angle(t.theta - prior.theta),
    );
    let prior_m = (prior_cov + cov)
        .cholesky()
        .map(|ch| d.dot(&ch.solve(&d)))
        .ok_or(Refusal::Degenerate)?;
    if prior_m > chi2_bound(3, settings.prior_probability) {
        return Err(Refusal::FarFromPrior(prior_m));
    }
    Ok(Alignment {
        transform: t,
        covariance: cov,
        matches: pairs,
        nis,
        dof,
        rival_matches: rival,
    })
}
