//! Relocalisation after an odometry gap or a clock resynchronisation (see
//! [`FilterSettings::relocalise_after_gap`](crate::FilterSettings::relocalise_after_gap)).
//!
//! While relocalising, each beam is predicted as usual (the odometry still moves the mean
//! pose) but its targets are only held, as world points placed from the mean pose at the
//! beam's time. Once the held beams have swept a whole turn, the filter looks for the rigid
//! correction `T` (a rotation and a translation of the world) that puts the most distinct
//! mapped features under the held points: every pair of the strongest targets is paired
//! with every pair of features the same distance apart (within the noise), each such
//! pairing gives one `T`, and `T` is scored by how many distinct features have a held point
//! inside their 2-D gate once moved by `T`. The best `T` is accepted only when
//!
//! - at least `relocalise_min_features` distinct features agree on it,
//! - it is plausible under the inflated pose covariance (3-dof exclusion gate), and
//! - no rival, a jointly compatible correction sharing fewer than half of its pairings
//!   with the best's, explains `relocalise_rival_share` as many features (a repetitive map, where a shifted
//!   pose fits almost as well, is not relocalised against);
//!
//! and its pairings are jointly compatible: the stacked range-bearing innovation of every
//! pairing, seen from the corrected pose, passes the chi-square gate of its dimension.
//! Then the pairings are applied as one iterated EKF update (Gauss-Newton on the pose and
//! the paired features, started at the corrected pose, then one ordinary update with the
//! last linearisation), and the filter goes back to beam-by-beam processing. A turn that
//! gives no accepted correction is dropped and the next one tried.
//!
//! A held point `p` was placed from the mean pose `m(t)` at its beam's time; if the true
//! pose is `T m(t)` throughout the turn (the odometry's relative motion over one turn is
//! trusted), the feature is at `T p`, and the target seen from the true pose now is `p` seen
//! from the mean pose now. So the held points are used as range-bearing observations made
//! now, from `m(now)`.

use std::collections::HashMap;
use std::f64::consts::TAU;

use nalgebra::{DMatrix, DVector};
use radar_model::geometry::{range_bearing, range_bearing_with_jacobian, wrap_angle, Pose2};

use super::super::error::FilterError;
use super::super::observation::{BeamObservation, BeamObservationModel};
use super::super::predict::ProcessModel;
use super::super::state::feature_index;
use super::super::update::LinearisedObservation;
use super::{BeamReport, Ekf};

/// Gauss-Newton iterations of the relocalisation update.
const ITERATIONS: usize = 10;
/// Strongest held targets used to make hypotheses (pairs of them).
const ANCHORS: usize = 24;
/// Two anchors closer than this (m) give a poorly determined rotation: not paired.
const MIN_ANCHOR_SEPARATION_M: f64 = 2.0;
/// Hypotheses, in decreasing score, checked for being a rival of the best.
const MAX_RIVAL_CHECKS: usize = 4_096;

/// A target held while relocalising.
#[derive(Debug, Clone, Copy)]
struct HeldTarget {
    /// World position from the mean pose at the beam's time (m).
    xy: [f64; 2],
    /// Range it was seen at (m): its position noise grows with it.
    range_m: f64,
    /// Power (dB): the strongest make the hypotheses.
    power_db: f64,
}

/// The relocalisation in progress.
#[derive(Debug, Clone, Default)]
pub(super) struct Relocalisation {
    /// When it started (state time, s).
    started_s: f64,
    /// Targets of the current turn.
    held: Vec<HeldTarget>,
    /// Bearing swept by the current turn's beams (rad).
    swept_rad: f64,
    /// The previous beam's bearing.
    last_bearing_rad: Option<f64>,
}

impl Relocalisation {
    pub(super) fn new(started_s: f64) -> Self {
        Self {
            started_s,
            ..Self::default()
        }
    }
}

/// A rigid correction of the world: `p -> R(phi) p + t`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Correction {
    phi: f64,
    t: [f64; 2],
}

impl Correction {
    /// The correction taking `a0 -> b0` and the direction of `a1 - a0` to that of
    /// `b1 - b0` (about the midpoints, so both pairs weigh alike).
    fn from_pairs(a: [[f64; 2]; 2], b: [[f64; 2]; 2]) -> Self {
        let da = [a[1][0] - a[0][0], a[1][1] - a[0][1]];
        let db = [b[1][0] - b[0][0], b[1][1] - b[0][1]];
        let phi = wrap_angle(db[1].atan2(db[0]) - da[1].atan2(da[0]));
        let ma = [0.5 * (a[0][0] + a[1][0]), 0.5 * (a[0][1] + a[1][1])];
        let mb = [0.5 * (b[0][0] + b[1][0]), 0.5 * (b[0][1] + b[1][1])];
        let r = rotate(phi, ma);
        Self {
            phi,
            t: [mb[0] - r[0], mb[1] - r[1]],
        }
    }

    fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let r = rotate(self.phi, p);
        [r[0] + self.t[0], r[1] + self.t[1]]
    }

    fn apply_pose(&self, pose: &Pose2) -> Pose2 {
        let p = self.apply([pose.x, pose.y]);
        Pose2::new(p[0], p[1], wrap_angle(pose.theta + self.phi))
    }
}

fn rotate(phi: f64, p: [f64; 2]) -> [f64; 2] {
    let (s, c) = phi.sin_cos();
    [c * p[0] - s * p[1], s * p[0] + c * p[1]]
}

/// A mapped feature considered for relocalisation.
#[derive(Debug, Clone, Copy)]
struct MapPoint {
    slot: usize,
    xy: [f64; 2],
    /// Variance of its position, largest axis (m^2).
    var: f64,
}

/// Features in a grid of square cells, for "which features are near this point".
struct Grid {
    cell_m: f64,
    cells: HashMap<(i64, i64), Vec<usize>>,
}

impl Grid {
    fn new(points: &[MapPoint], cell_m: f64) -> Self {
        let mut cells: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
        for (k, p) in points.iter().enumerate() {
            cells.entry(Self::key(cell_m, p.xy)).or_default().push(k);
        }
        Self { cell_m, cells }
    }

    fn key(cell_m: f64, xy: [f64; 2]) -> (i64, i64) {
        // Saturating float-to-int casts: far points share the edge cells, harmlessly.
        (
            (xy[0] / cell_m).floor() as i64,
            (xy[1] / cell_m).floor() as i64,
        )
    }

    /// Indices of the features in the 3 x 3 cells around `xy`.
    fn near(&self, xy: [f64; 2], out: &mut Vec<usize>) {
        out.clear();
        let (cx, cy) = Self::key(self.cell_m, xy);
        for dx in -1..=1 {
            for dy in -1..=1 {
                if let Some(v) = self
                    .cells
                    .get(&(cx.saturating_add(dx), cy.saturating_add(dy)))
                {
                    out.extend_from_slice(v);
                }
            }
        }
    }
}

/// The outcome of one turn's attempt.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Attempt {
    /// Relocalised: the update was applied.
    Accepted,
    /// No correction was accepted this turn.
    Refused,
}

impl<M: ProcessModel, O: BeamObservationModel> Ekf<M, O> {
    /// Starts relocalising (after a bridged gap or a clock resynchronisation), when it is
    /// switched on and the map has enough features to relocalise against.
    pub(super) fn start_relocalising(&mut self) {
        if self.settings.relocalise_after_gap
            && self.state.feature_count() >= self.settings.relocalise_min_features
        {
            self.relocalising = Some(Relocalisation::new(self.state.time_s()));
            self.tentatives = Default::default();
        }
    }

    /// Whether the filter is relocalising (beams are held, not used).
    pub fn is_relocalising(&self) -> bool {
        self.relocalising.is_some()
    }

    /// One beam while relocalising: predicted and held; once a turn is held, an attempt.
    pub(super) fn relocalise_beam(
        &mut self,
        beam: &BeamObservation,
        far_m: f64,
    ) -> Result<BeamReport, FilterError> {
        if !beam.targets.is_empty() {
            self.predict_to(beam.timestamp_s)?;
        }
        let pose = match self.pose_at(beam.timestamp_s) {
            Some(p) => p,
            None => return Err(FilterError::NoOdometry),
        };
        let (near, far) = (self.settings.min_range_m, far_m);
        let cap = self.settings.relocalise_max_targets;
        let Some(r) = self.relocalising.as_mut() else {
            return Ok(BeamReport::default());
        };
        for t in &beam.targets {
            if t.range_m < near || t.range_m > far {
                continue;
            }
            let held = HeldTarget {
                xy: pose.point_at(t.range_m, t.bearing_rad),
                range_m: t.range_m,
                power_db: t.power_db,
            };
            if r.held.len() < cap {
                r.held.push(held);
            } else if let Some(weakest) = r
                .held
                .iter_mut()
                .min_by(|a, b| a.power_db.total_cmp(&b.power_db))
                .filter(|w| w.power_db < held.power_db)
            {
                *weakest = held;
            }
        }
        if let Some(last) = r.last_bearing_rad {
            r.swept_rad += wrap_angle(beam.bearing_rad - last).abs();
        }
        r.last_bearing_rad = Some(beam.bearing_rad);
        if r.swept_rad < TAU {
            return Ok(BeamReport::default());
        }
        let held = std::mem::take(&mut r.held);
        r.swept_rad = 0.0;
        let started_s = r.started_s;
        self.stats.relocalisation_attempts += 1;
        match self.attempt_relocalisation(&held, far_m)? {
            Attempt::Accepted => {
                self.relocalising = None;
                self.stats.relocalisations += 1;
            }
            Attempt::Refused => {
                if beam.timestamp_s - started_s > self.settings.relocalise_give_up_s {
                    self.relocalising = None;
                    self.stats.relocalisations_abandoned += 1;
                }
            }
        }
        Ok(BeamReport::default())
    }

    /// The mapped features that could be in view: within `far_m` (the radar's range, or the
    /// beam's) of the mean position plus three standard deviations of it.
    fn map_points(&self, far_m: f64) -> Vec<MapPoint> {
        let pose = self.pose();
        let pc = self.pose_covariance();
        let reach = far_m + 3.0 * pc[(0, 0)].max(pc[(1, 1)]).max(0.0).sqrt();
        (0..self.state.feature_count())
            .filter_map(|slot| {
                let p = self.state.params(slot)?;
                let c = self.state.position_covariance(slot)?;
                let d = (p.x_m - pose.x).hypot(p.y_m - pose.y);
                (d <= reach).then(|| MapPoint {
                    slot,
                    xy: [p.x_m, p.y_m],
                    var: c[(0, 0)].max(c[(1, 1)]).max(0.0),
                })
            })
            .collect()
    }

    /// Position variance of a held target (m^2), isotropic bound.
    fn held_var(&self, h: &HeldTarget) -> f64 {
        self.settings.range_std_m.powi(2) + (h.range_m * self.settings.bearing_std_rad).powi(2)
    }

    /// One turn's attempt: hypotheses, scoring, the ambiguity and joint-compatibility
    /// checks, and the update when accepted.
    fn attempt_relocalisation(
        &mut self,
        held: &[HeldTarget],
        far_m: f64,
    ) -> Result<Attempt, FilterError> {
        let map = self.map_points(far_m);
        let need = self.settings.relocalise_min_features;
        if map.len() < need || held.len() < need {
            return Ok(Attempt::Refused);
        }
        let gate2 = self.gates.threshold(2);
        let max_var = held.iter().map(|h| self.held_var(h)).fold(0.0, f64::max)
            + map.iter().map(|m| m.var).fold(0.0, f64::max);
        // Feature pairs by distance apart.
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for a in 0..map.len() {
            for b in a + 1..map.len() {
                let (pa, pb) = (map[a].xy, map[b].xy);
                pairs.push(((pa[0] - pb[0]).hypot(pa[1] - pb[1]), a, b));
            }
        }
        pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
        // The strongest targets, distinct.
        let mut anchors: Vec<usize> = (0..held.len()).collect();
        anchors.sort_by(|&a, &b| held[b].power_db.total_cmp(&held[a].power_db));
        anchors.truncate(ANCHORS);
        let cell = (gate2 * max_var).sqrt().max(0.5);
        let grid = Grid::new(&map, cell);
        let pose = self.pose();
        let pose_cov = self.pose_covariance();
        let Some(pose_info) = pose_cov.try_inverse() else {
            return Ok(Attempt::Refused);
        };
        let prior_gate = self.exclusion.threshold(3);
        let mut scored: Vec<(usize, Correction)> = Vec::new();
        let mut budget = self.settings.relocalise_max_hypotheses;
        let mut near = Vec::new();
        'anchors: for (k, &ia) in anchors.iter().enumerate() {
            for &ib in anchors.iter().skip(k + 1) {
                let (a, b) = (held[ia], held[ib]);
                let d = (a.xy[0] - b.xy[0]).hypot(a.xy[1] - b.xy[1]);
                if d < MIN_ANCHOR_SEPARATION_M {
                    continue;
                }
                let tol = (gate2 * max_var * 2.0).sqrt();
                let lo = pairs.partition_point(|p| p.0 < d - tol);
                for &(df, fa, fb) in pairs.iter().skip(lo) {
                    if df > d + tol {
                        break;
                    }
                    for (f0, f1) in [(fa, fb), (fb, fa)] {
                        if budget == 0 {
                            break 'anchors;
                        }
                        budget -= 1;
                        let c = Correction::from_pairs([a.xy, b.xy], [map[f0].xy, map[f1].xy]);
                        let moved = c.apply_pose(&pose);
                        let dx = nalgebra::Vector3::new(
                            moved.x - pose.x,
                            moved.y - pose.y,
                            wrap_angle(moved.theta - pose.theta),
                        );
                        if dx.dot(&(pose_info * dx)) > prior_gate {
                            continue;
                        }
                        let score = self.score(&c, held, &map, &grid, gate2, &mut near).len();
                        if score >= need {
                            scored.push((score, c));
                        }
                    }
                }
            }
        }
        scored.sort_by_key(|x| std::cmp::Reverse(x.0));
        let Some(&(best, correction)) = scored.first() else {
            return Ok(Attempt::Refused);
        };
        let pairing = self.score(&correction, held, &map, &grid, gate2, &mut near);
        // The best hypothesis of another association: one that shares fewer than half of
        // its pairings with the best's (a slightly different transform that pairs the same
        // way is the same answer, not a rival).
        let mut rival = 0;
        for &(score, c) in scored.iter().skip(1).take(MAX_RIVAL_CHECKS) {
            if (score as f64) < self.settings.relocalise_rival_share * best as f64 {
                break;
            }
            let other = self.score(&c, held, &map, &grid, gate2, &mut near);
            // A pairing is shared when the best's correction also puts its target inside
            // its feature's gate.
            let shared = other
                .iter()
                .filter(|&&(m, j)| {
                    let q = correction.apply(held[j].xy);
                    let d2 = (q[0] - map[m].xy[0]).powi(2) + (q[1] - map[m].xy[1]).powi(2);
                    d2 <= gate2 * (self.held_var(&held[j]) + map[m].var)
                })
                .count();
            // A rival must itself be jointly compatible (a loose isotropic gate lets chance
            // alignments of a few features in).
            if 2 * shared < other.len()
                && self.jointly_compatible(
                    &self.observations(&other, held, &map),
                    &c.apply_pose(&pose),
                )
            {
                rival = score;
                break;
            }
        }
        if rival as f64 >= self.settings.relocalise_rival_share * best as f64 {
            return Ok(Attempt::Refused);
        }
        self.relocalisation_update(&correction, &pairing, held, &map)
    }

    /// The distinct features with a held point inside their gate once moved by `c`, each
    /// with its nearest held point: `(map index, held index)`.
    fn score(
        &self,
        c: &Correction,
        held: &[HeldTarget],
        map: &[MapPoint],
        grid: &Grid,
        gate2: f64,
        near: &mut Vec<usize>,
    ) -> Vec<(usize, usize)> {
        let mut best: HashMap<usize, (f64, usize)> = HashMap::new();
        for (j, h) in held.iter().enumerate() {
            let q = c.apply(h.xy);
            grid.near(q, near);
            let hv = self.held_var(h);
            for &m in near.iter() {
                let f = map[m];
                let d2 = (q[0] - f.xy[0]).powi(2) + (q[1] - f.xy[1]).powi(2);
                let var = hv + f.var;
                if d2 <= gate2 * var {
                    let e = best.entry(m).or_insert((f64::INFINITY, j));
                    if d2 / var < e.0 {
                        *e = (d2 / var, j);
                    }
                }
            }
        }
        let mut out: Vec<(usize, usize)> = best.into_iter().map(|(m, (_, j))| (m, j)).collect();
        out.sort_unstable();
        out
    }

    /// The accepted pairings as one iterated update from the corrected pose, once they are
    /// jointly compatible there: while the stacked innovation fails its chi-square gate, the
    /// pairing with the largest residual is dropped (a clutter point or a phantom that the
    /// coarse isotropic gate let in), down to `relocalise_min_features` pairings.
    fn relocalisation_update(
        &mut self,
        correction: &Correction,
        pairing: &[(usize, usize)],
        held: &[HeldTarget],
        map: &[MapPoint],
    ) -> Result<Attempt, FilterError> {
        let start = correction.apply_pose(&self.pose());
        let mut pairs = self.observations(pairing, held, map);
        while pairs.len() >= self.settings.relocalise_min_features {
            let Some(fit) = self.fit(&pairs, &start) else {
                return Ok(Attempt::Refused);
            };
            if fit.nis <= self.gates.threshold(fit.obs.innovation.len()) {
                let outcome = self.landmark_update(&fit.obs)?;
                self.stats.updates += 1;
                self.stats.nis_sum += outcome.nis;
                self.stats.nis_dof_sum += outcome.dof as u64;
                let now = self.state.time_s();
                for &(slot, _) in &pairs {
                    if let Some(track) = self.state.track_mut(slot) {
                        track.hits += 1;
                        track.consecutive_misses = 0;
                        track.last_seen_s = now;
                    }
                }
                return Ok(Attempt::Accepted);
            }
            let Some(worst) = fit
                .residuals
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1))
                .map(|(k, _)| k)
            else {
                break;
            };
            pairs.remove(worst);
        }
        Ok(Attempt::Refused)
    }

    /// The pairings `(map index, held index)` as `(slot, [R, beta])`: each held point as an
    /// observation made now from the mean pose.
    fn observations(
        &self,
        pairing: &[(usize, usize)],
        held: &[HeldTarget],
        map: &[MapPoint],
    ) -> Vec<(usize, [f64; 2])> {
        let now_pose = self.pose();
        pairing
            .iter()
            .map(|&(m, j)| {
                let rb = range_bearing(&now_pose, held[j].xy);
                (map[m].slot, [rb.range_m, rb.bearing_rad])
            })
            .collect()
    }

    /// Whether `pairs` fitted from `start` pass the chi-square gate of their dimension.
    fn jointly_compatible(&self, pairs: &[(usize, [f64; 2])], start: &Pose2) -> bool {
        self.fit(pairs, start)
            .is_some_and(|fit| fit.nis <= self.gates.threshold(fit.obs.innovation.len()))
    }

    /// Gauss-Newton on the pose and the paired features' positions (the other columns
    /// follow through the covariance), started at `start` with the features at their
    /// means; then the ordinary update's observation at the last linearisation, its NIS,
    /// and each pairing's residual there (squared, in measurement-noise units).
    fn fit(&self, pairs: &[(usize, [f64; 2])], start: &Pose2) -> Option<Fit> {
        let mut columns = vec![0, 1, 2];
        for &(slot, _) in pairs {
            let fi = feature_index(slot);
            columns.extend([fi, fi + 1]);
        }
        let x0: Vec<f64> = columns.iter().map(|&c| self.state.mean()[c]).collect();
        let p_cc = self.state.covariance_block(&columns);
        let var = [
            self.settings.range_std_m.powi(2),
            self.settings.bearing_std_rad.powi(2),
        ];
        let m = 2 * pairs.len();
        let noise = DMatrix::from_diagonal(&DVector::from_iterator(m, (0..m).map(|r| var[r % 2])));
        let mut x = x0.clone();
        x[0] = start.x;
        x[1] = start.y;
        x[2] = start.theta;
        let mut last: Option<(DMatrix<f64>, DVector<f64>, Vec<f64>)> = None;
        for _ in 0..ITERATIONS {
            let pose = Pose2::new(x[0], x[1], x[2]);
            let mut h = DMatrix::zeros(m, columns.len());
            let mut nu = DVector::zeros(m);
            let mut residuals = Vec::with_capacity(pairs.len());
            for (k, (_, zk)) in pairs.iter().enumerate() {
                let f = [x[3 + 2 * k], x[4 + 2 * k]];
                let (rb, jac) = range_bearing_with_jacobian(&pose, f).ok()?;
                for c in 0..3 {
                    h[(2 * k, c)] = jac.range_wrt_pose[c];
                    h[(2 * k + 1, c)] = jac.bearing_wrt_pose[c];
                }
                for c in 0..2 {
                    h[(2 * k, 3 + 2 * k + c)] = jac.range_wrt_feature[c];
                    h[(2 * k + 1, 3 + 2 * k + c)] = jac.bearing_wrt_feature[c];
                }
                nu[2 * k] = zk[0] - rb.range_m;
                nu[2 * k + 1] = wrap_angle(zk[1] - rb.bearing_rad);
                residuals.push(nu[2 * k].powi(2) / var[0] + nu[2 * k + 1].powi(2) / var[1]);
            }
            // The innovation about the prior mean x0, linearised at x (the bearing rows are
            // wrapped where measured; the linear term is not an angle to wrap).
            let mut dx = DVector::from_iterator(x.len(), x0.iter().zip(&x).map(|(a, b)| a - b));
            dx[2] = wrap_angle(dx[2]);
            let nu0 = &nu - &h * &dx;
            let pht = &p_cc * h.transpose();
            let chol = (&h * &pht + &noise).cholesky()?;
            let step = &pht * chol.solve(&nu0);
            let mut moved: f64 = 0.0;
            for (k, xk) in x.iter_mut().enumerate() {
                let next = x0[k] + step[k];
                moved = moved.max((next - *xk).abs());
                *xk = next;
            }
            x[2] = wrap_angle(x[2]);
            last = Some((h, nu0, residuals));
            if moved < 1e-9 {
                break;
            }
        }
        let (h, nu, residuals) = last?;
        let chol = (&h * (&p_cc * h.transpose()) + &noise).cholesky()?;
        let nis = nu.dot(&chol.solve(&nu));
        nis.is_finite().then_some(Fit {
            obs: LinearisedObservation {
                columns,
                jacobian: h,
                innovation: nu,
                noise,
            },
            nis,
            residuals,
        })
    }
}

/// A relocalisation fit: the observation to apply, its NIS, and each pairing's residual.
struct Fit {
    obs: LinearisedObservation,
    nis: f64,
    residuals: Vec<f64>,
}
