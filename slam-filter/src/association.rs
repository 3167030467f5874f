//! Data association inside one beam: a chi-square gate on the whole innovation
//! (range, bearing, power: 3 degrees of freedom; 2 without power), nearest neighbour where
//! every gate holds at most one candidate, and joint compatibility branch and bound (JCBB,
//! Neira and Tardos 2001) with a node budget where gates overlap.
//!
//! All covariances here are small: they involve only the beam's columns
//! `[pose, beam features, L]`, gathered once per beam as `P_cc`.

use nalgebra::{DMatrix, DVector};
use radar_model::geometry::wrap_angle;
use radar_model::layout::{Component, ObservationRow};
use statrs::distribution::{ChiSquared, ContinuousCDF};

use super::observation::{nonzero_columns, row_indices, BeamPrediction, Target};

/// Chi-square thresholds for one gate probability, by degrees of freedom.
#[derive(Debug, Clone)]
pub struct GateTable {
    probability: f64,
    thresholds: Vec<f64>,
}

impl GateTable {
    /// Thresholds for `dof = 1..=max_dof` at `probability` (validated in (0, 1)).
    pub fn new(probability: f64, max_dof: usize) -> Self {
        let thresholds = (1..=max_dof)
            .map(|d| chi2_quantile(probability, d))
            .collect();
        Self {
            probability,
            thresholds,
        }
    }

    /// The gate for `dof` degrees of freedom (computed on demand past the table).
    pub fn threshold(&self, dof: usize) -> f64 {
        match dof.checked_sub(1).and_then(|i| self.thresholds.get(i)) {
            Some(t) => *t,
            None => chi2_quantile(self.probability, dof),
        }
    }
}

/// The `p` quantile of chi-square with `dof` degrees of freedom; +inf if undefined.
pub fn chi2_quantile(p: f64, dof: usize) -> f64 {
    if dof == 0 {
        return 0.0;
    }
    match ChiSquared::new(dof as f64) {
        Ok(d) => d.inverse_cdf(p),
        Err(_) => f64::INFINITY,
    }
}

/// The rows of one feature's observation used in the update: range, bearing, and power
/// when it is used.
pub(crate) fn rows_of(local: usize, with_power: bool) -> Vec<ObservationRow> {
    ObservationRow::of_feature(local, with_power).collect()
}

/// Innovation of target `t` against feature `local`'s prediction on `rows` (bearing wrapped).
pub(crate) fn innovation(
    pred: &BeamPrediction,
    local: usize,
    t: &Target,
    rows: &[ObservationRow],
) -> Vec<f64> {
    let zhat = pred.z.get(local).copied().unwrap_or([0.0; 3]);
    let z = [t.range_m, t.bearing_rad, t.power_db];
    rows.iter()
        .map(|r| {
            let d = r.component.of(&z) - r.component.of(&zhat);
            match r.component {
                Component::Bearing => wrap_angle(d),
                Component::Range | Component::Power => d,
            }
        })
        .collect()
}

/// Everything association needs about one beam.
#[derive(Debug)]
pub struct BeamContext<'a> {
    /// The model's prediction for the beam's features.
    pub prediction: &'a BeamPrediction,
    /// Covariance of the beam's columns (c x c).
    pub p_cc: &'a DMatrix<f64>,
    /// Whether each feature's power row is used.
    pub use_power: &'a [bool],
    /// Per-component noise variances `[range, bearing, power]`.
    pub noise_var: [f64; 3],
}

impl BeamContext<'_> {
    /// Mahalanobis distance squared of a set of (target, feature) pairs, and its dof.
    /// `None` if the joint S is not positive definite.
    pub fn joint_distance(
        &self,
        targets: &[Target],
        pairs: &[(usize, usize)],
    ) -> Option<(f64, usize)> {
        self.distance_with(targets, pairs, true)
    }

    /// As [`Self::joint_distance`] on range and bearing only.
    pub fn geometric_distance(
        &self,
        targets: &[Target],
        pairs: &[(usize, usize)],
    ) -> Option<(f64, usize)> {
        self.distance_with(targets, pairs, false)
    }

    fn distance_with(
        &self,
        targets: &[Target],
        pairs: &[(usize, usize)],
        allow_power: bool,
    ) -> Option<(f64, usize)> {
        let mut rows = Vec::new();
        let mut nu = Vec::new();
        for &(t, f) in pairs {
            let r = rows_of(f, allow_power && *self.use_power.get(f)?);
            nu.extend(innovation(self.prediction, f, targets.get(t)?, &r));
            rows.extend(r);
        }
        let m = rows.len();
        if m == 0 {
            return Some((0.0, 0));
        }
        let h = self
            .prediction
            .jacobian
            .select_rows(row_indices(&rows).iter());
        let mut s = match nonzero_columns(&h) {
            Some(cols) => {
                let h = h.select_columns(cols.iter());
                let p = self
                    .p_cc
                    .select_rows(cols.iter())
                    .select_columns(cols.iter());
                &h * p * h.transpose()
            }
            None => &h * self.p_cc * h.transpose(),
        };
        for (i, r) in rows.iter().enumerate() {
            s[(i, i)] += r.component.of(&self.noise_var);
        }
        let s = 0.5 * (&s + s.transpose());
        let chol = s.cholesky()?;
        let e = chol.l().solve_lower_triangular(&DVector::from_vec(nu))?;
        Some((e.norm_squared(), m))
    }
}

/// The association found for one beam: `pairs[j] = Some(local feature)` for target j.
#[derive(Debug, Clone, PartialEq)]
pub struct Association {
    /// Per target, the beam-local feature it was associated with.
    pub pairs: Vec<Option<usize>>,
    /// Whether JCBB ran (gates overlapped).
    pub used_jcbb: bool,
    /// Whether JCBB ran out of its node budget (the best hypothesis found is used).
    pub budget_exhausted: bool,
    /// Per target, whether some feature's exclusion gate contains its range and bearing (a
    /// chi-square gate wider than the association gate, on the geometry alone, so that a
    /// badly predicted power cannot breed a duplicate): such a target, if left unpaired, is
    /// not evidence of a new feature.
    pub near_feature: Vec<bool>,
}

/// Associates `targets` with the beam's features.
pub fn associate(
    ctx: &BeamContext<'_>,
    targets: &[Target],
    gates: &GateTable,
    exclusion: &GateTable,
    max_nodes: usize,
) -> Association {
    let k = ctx.prediction.z.len();
    // Individual compatibility: d2[j][i] if target j is inside feature i's gate.
    let mut compatible: Vec<Vec<(usize, f64)>> = Vec::with_capacity(targets.len());
    let mut per_feature = vec![0usize; k];
    let mut near_feature = vec![false; targets.len()];
    for (j, near) in near_feature.iter_mut().enumerate() {
        let mut list = Vec::new();
        for (i, count) in per_feature.iter_mut().enumerate() {
            if let Some((d2, dof)) = ctx.geometric_distance(targets, &[(j, i)]) {
                if d2 <= exclusion.threshold(dof) {
                    *near = true;
                }
            }
            if let Some((d2, dof)) = ctx.joint_distance(targets, &[(j, i)]) {
                if d2 <= gates.threshold(dof) {
                    list.push((i, d2));
                    *count += 1;
                }
            }
        }
        list.sort_by(|a, b| a.1.total_cmp(&b.1));
        compatible.push(list);
    }
    let overlap = compatible.iter().any(|l| l.len() > 1) || per_feature.iter().any(|&c| c > 1);
    let nn = greedy_nearest(&compatible, k);
    if !overlap || max_nodes == 0 {
        return Association {
            pairs: nn,
            used_jcbb: false,
            budget_exhausted: false,
            near_feature,
        };
    }
    let mut search = Jcbb {
        ctx,
        targets,
        gates,
        compatible: &compatible,
        nodes_left: max_nodes,
        best: Vec::new(),
        best_d2: f64::INFINITY,
        current: Vec::new(),
    };
    // Seed with nearest neighbour if it is jointly compatible.
    let nn_pairs: Vec<(usize, usize)> = nn
        .iter()
        .enumerate()
        .filter_map(|(j, f)| f.map(|i| (j, i)))
        .collect();
    if let Some((d2, dof)) = ctx.joint_distance(targets, &nn_pairs) {
        if d2 <= gates.threshold(dof) {
            search.best = nn_pairs;
            search.best_d2 = d2;
        }
    }
    search.recurse(0);
    let exhausted = search.nodes_left == 0;
    let mut pairs = vec![None; targets.len()];
    for &(j, i) in &search.best {
        if let Some(p) = pairs.get_mut(j) {
            *p = Some(i);
        }
    }
    Association {
        pairs,
        used_jcbb: true,
        budget_exhausted: exhausted,
        near_feature,
    }
}

/// Global nearest neighbour, greedy: the smallest distances first, each feature once.
fn greedy_nearest(compatible: &[Vec<(usize, f64)>], k: usize) -> Vec<Option<usize>> {
    let mut all: Vec<(f64, usize, usize)> = compatible
        .iter()
        .enumerate()
        .flat_map(|(j, l)| l.iter().map(move |&(i, d2)| (d2, j, i)))
        .collect();
    all.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut used = vec![false; k];
    let mut out = vec![None; compatible.len()];
    for (_, j, i) in all {
        let (Some(u), Some(o)) = (used.get(i), out.get(j)) else {
            continue;
        };
        if !*u && o.is_none() {
            used[i] = true;
            out[j] = Some(i);
        }
    }
    out
}

struct Jcbb<'a, 'b> {
    ctx: &'a BeamContext<'b>,
    targets: &'a [Target],
    gates: &'a GateTable,
    compatible: &'a [Vec<(usize, f64)>],
    nodes_left: usize,
    best: Vec<(usize, usize)>,
    best_d2: f64,
    current: Vec<(usize, usize)>,
}

impl Jcbb<'_, '_> {
    fn better(&self, d2: f64) -> bool {
        self.current.len() > self.best.len()
            || (self.current.len() == self.best.len() && d2 < self.best_d2)
    }

    fn recurse(&mut self, j: usize) {
        if self.nodes_left == 0 {
            return;
        }
        self.nodes_left -= 1;
        if j >= self.targets.len() {
            if let Some((d2, _)) = self.ctx.joint_distance(self.targets, &self.current) {
                if self.better(d2) {
                    self.best = self.current.clone();
                    self.best_d2 = d2;
                }
            }
            return;
        }
        let candidates = self.compatible.get(j).cloned().unwrap_or_default();
        for (i, _) in candidates {
            if self.current.iter().any(|&(_, f)| f == i) {
                continue;
            }
            self.current.push((j, i));
            let ok = match self.ctx.joint_distance(self.targets, &self.current) {
                Some((d2, dof)) => d2 <= self.gates.threshold(dof),
                None => false,
            };
            if ok {
                self.recurse(j + 1);
            }
            self.current.pop();
        }
        // Leave target j unpaired only if that can still beat the best.
        let remaining = self.targets.len() - j - 1;
        if self.current.len() + remaining >= self.best.len() {
            self.recurse(j + 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observation::{BeamObservationModel, RangeBearingModel};
    use crate::state::FeatureParams;
    use radar_model::geometry::Pose2;

    /// Two features 10 m and 11 m ahead on one line, predicted from the origin with a
    /// near-certain state (covariance 1e-6 I over pose, L and both features).
    fn two_features_on_a_line() -> (BeamPrediction, DMatrix<f64>) {
        let feature = |x_m| FeatureParams {
            x_m,
            y_m: 0.0,
            u: 0.0,
            v: 0.0,
        };
        let pred = RangeBearingModel
            .predict_beam(&Pose2::default(), &[feature(10.0), feature(11.0)], 0.0)
            .unwrap();
        (pred, DMatrix::identity(12, 12) * 1e-6)
    }

    /// The fixture's context: no power rows, range sigma 0.5 m.
    fn range_only_context<'a>(pred: &'a BeamPrediction, p_cc: &'a DMatrix<f64>) -> BeamContext<'a> {
        BeamContext {
            prediction: pred,
            p_cc,
            use_power: &[false, false],
            noise_var: [0.25, 1e-4, 1.0],
        }
    }

    fn target(range_m: f64) -> Target {
        Target {
            range_m,
            bearing_rad: 0.0,
            power_db: 0.0,
        }
    }

    #[test]
    fn jcbb_pairs_both_targets_where_greedy_nearest_neighbour_pairs_one() {
        // Two features 10 m and 11 m ahead on one line; range sigma 0.5 m.
        let (pred, p_cc) = two_features_on_a_line();
        let ctx = range_only_context(&pred, &p_cc);
        // T0 at 10.55 m: 1.1 sigma from F0, 0.9 sigma from F1. T1 at 11.6 m: 1.2 sigma from F1,
        // 3.2 sigma from F0 (outside the 99% 2-dof gate of 9.21).
        let targets = [target(10.55), target(11.6)];
        let gates = GateTable::new(0.99, 8);
        let compatible: Vec<Vec<(usize, f64)>> = (0..2)
            .map(|j| {
                (0..2)
                    .filter_map(|i| {
                        let (d2, dof) = ctx.joint_distance(&targets, &[(j, i)])?;
                        (d2 <= gates.threshold(dof)).then_some((i, d2))
                    })
                    .collect()
            })
            .collect();
        assert_eq!(greedy_nearest(&compatible, 2), vec![Some(1), None]);
        let assoc = associate(&ctx, &targets, &gates, &gates, 1000);
        assert!(assoc.used_jcbb && !assoc.budget_exhausted);
        assert_eq!(assoc.pairs, vec![Some(0), Some(1)]);
        // A budget of 0 turns JCBB off: nearest neighbour only.
        let nn = associate(&ctx, &targets, &gates, &gates, 0);
        assert!(!nn.used_jcbb);
        assert_eq!(nn.pairs, vec![Some(1), None]);
    }

    #[test]
    fn a_node_budget_of_one_still_returns_a_consistent_answer() {
        let (pred, p_cc) = two_features_on_a_line();
        let ctx = range_only_context(&pred, &p_cc);
        let targets = [target(10.55), target(11.6)];
        let gates = GateTable::new(0.99, 8);
        let assoc = associate(&ctx, &targets, &gates, &gates, 1);
        assert!(assoc.budget_exhausted);
        // Whatever was found is jointly compatible and uses each feature once.
        let pairs: Vec<(usize, usize)> = assoc
            .pairs
            .iter()
            .enumerate()
            .filter_map(|(j, f)| f.map(|i| (j, i)))
            .collect();
        let (d2, dof) = ctx.joint_distance(&targets, &pairs).unwrap();
        assert!(d2 <= gates.threshold(dof));
    }

    #[test]
    fn the_gate_table_matches_published_chi_square_quantiles() {
        let g = GateTable::new(0.95, 3);
        assert!((g.threshold(3) - 7.8147).abs() < 1e-3);
        assert!((g.threshold(2) - 5.9915).abs() < 1e-3);
        assert!((GateTable::new(0.99, 3).threshold(3) - 11.3449).abs() < 1e-3);
        assert!((g.threshold(30) - 43.773).abs() < 1e-2, "past the table");
    }
}
