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

mod correction;
mod fit;

use std::collections::HashMap;
use std::f64::consts::TAU;

use radar_model::geometry::wrap_angle;

use super::{BeamReport, Ekf};
use crate::error::FilterError;
use crate::observation::{BeamObservation, BeamObservationModel};
use crate::predict::ProcessModel;
use correction::{Correction, Grid, MapPoint};

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
}
