//! The pose graph: one node per submap frame (node 0, the first submap's frame, is the world
//! and is held fixed), edges for the relative transform from one submap to the next (the
//! vehicle's pose at the switch, with the local filter's covariance) and for verified loop
//! closures. Solved by Levenberg-Marquardt on the normal equations, each step a sparse
//! Cholesky factorisation (faer); marginal covariances from the same factor.
//!
//! Why faer: its sparse `LL^T` returns an error on a matrix that is not positive definite
//! (a failed solve must leave the previous solution in place, not panic), it is pure Rust
//! and maintained, and the SE(2) residual and its Jacobians are a few lines checked against
//! finite differences (`se2`'s tests). factrs, built on faer, was considered: its Cholesky
//! solver panics on a non-positive-definite system and it brings a second nalgebra version.

use std::collections::BTreeMap;

use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};
use nalgebra::{Matrix3, Vector3};
use radar_model::geometry::{wrap_angle, Pose2};

use crate::se2::between_residual;

/// The normal equations' 3x3 blocks (lower triangle), keyed by (row node, column node).
type Blocks = BTreeMap<(usize, usize), Matrix3<f64>>;

/// What an edge stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeKind {
    /// From one submap to the next: the vehicle's pose when the first was closed.
    Chain,
    /// A loop closure: the later submap's frame in the earlier one's, from matched features.
    Loop,
    /// A join: a later drive's first submap frame in an earlier drive's submap, from the
    /// localisation fix that started the drive's mapping (extend mode).
    Join,
}

/// A relative measurement of node `to`'s frame in node `from`'s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    /// The earlier node.
    pub from: usize,
    /// The later node.
    pub to: usize,
    /// `to` in `from`'s frame.
    pub z: Pose2,
    /// Its covariance (x, y, theta in `from`'s frame).
    pub covariance: Matrix3<f64>,
    /// Chain or loop.
    pub kind: EdgeKind,
}

/// Why a solve failed (the previous solution stays in place).
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum GraphError {
    /// An edge names a node that does not exist, or joins a node to itself.
    #[error("edge {index} joins nodes {from} and {to} of a graph of {nodes}")]
    BadEdge {
        /// Edge index.
        index: usize,
        /// Its from node.
        from: usize,
        /// Its to node.
        to: usize,
        /// Nodes in the graph.
        nodes: usize,
    },
    /// An edge's covariance is not positive definite or not finite.
    #[error("edge {0}'s covariance is not positive definite")]
    BadCovariance(usize),
    /// The normal equations are not positive definite (a node not tied to the world).
    #[error("the normal equations are not positive definite")]
    NotPositiveDefinite,
    /// No step reduced the error, or the iteration limit was reached first.
    #[error("the solve did not converge in {0} iterations")]
    NotConverged(usize),
    /// A value went non-finite.
    #[error("the solve produced a non-finite value")]
    NonFinite,
}

/// Iteration limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveSettings {
    /// Most iterations.
    pub max_iterations: usize,
    /// Converged when no state element moves more than this.
    pub step_tolerance: f64,
}

impl Default for SolveSettings {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            step_tolerance: 1e-9,
        }
    }
}

/// A converged solution.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Every node's pose in the world.
    pub nodes: Vec<Pose2>,
    /// Marginal covariance of every node (node 0's is zero: it defines the world).
    pub covariances: Vec<Matrix3<f64>>,
    /// The weighted squared error before and after.
    pub chi2_before: f64,
    /// After.
    pub chi2: f64,
    /// Iterations taken.
    pub iterations: usize,
}

/// The graph: nodes (initial guesses) and edges.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PoseGraph {
    nodes: Vec<Pose2>,
    edges: Vec<Edge>,
}

/// `Omega = Sigma^-1`, checked.
fn information(cov: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    if !cov.iter().all(|v| v.is_finite()) {
        return None;
    }
    let sym = 0.5 * (cov + cov.transpose());
    let inv = sym.cholesky()?.inverse();
    Some(0.5 * (inv + inv.transpose()))
}

impl PoseGraph {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a node at `guess`; returns its index.
    pub fn add_node(&mut self, guess: Pose2) -> usize {
        self.nodes.push(guess);
        self.nodes.len() - 1
    }

    /// Adds an edge.
    pub fn add_edge(&mut self, edge: Edge) {
        self.edges.push(edge);
    }

    /// Removes the last edge (a loop closure the solve did not keep).
    pub fn pop_edge(&mut self) -> Option<Edge> {
        self.edges.pop()
    }

    /// The nodes' current values.
    pub fn nodes(&self) -> &[Pose2] {
        &self.nodes
    }

    /// The edges.
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }

    /// Replaces the nodes' values (after a solve was accepted).
    pub fn set_nodes(&mut self, nodes: &[Pose2]) {
        for (n, v) in self.nodes.iter_mut().zip(nodes) {
            *n = *v;
        }
    }

    /// One edge's weighted squared error at `nodes`.
    pub fn edge_chi2(&self, index: usize, nodes: &[Pose2]) -> Option<f64> {
        let e = self.edges.get(index)?;
        let (a, b) = (nodes.get(e.from)?, nodes.get(e.to)?);
        let (r, _, _) = between_residual(a, b, &e.z);
        let omega = information(&e.covariance)?;
        Some(r.dot(&(omega * r)))
    }

    fn check(&self) -> Result<Vec<Matrix3<f64>>, GraphError> {
        let n = self.nodes.len();
        self.edges
            .iter()
            .enumerate()
            .map(|(index, e)| {
                if e.from >= n || e.to >= n || e.from == e.to {
                    return Err(GraphError::BadEdge {
                        index,
                        from: e.from,
                        to: e.to,
                        nodes: n,
                    });
                }
                information(&e.covariance).ok_or(GraphError::BadCovariance(index))
            })
            .collect()
    }

    fn chi2(&self, nodes: &[Pose2], omegas: &[Matrix3<f64>]) -> f64 {
        self.edges
            .iter()
            .zip(omegas)
            .map(|(e, w)| {
                let (r, _, _) = between_residual(&nodes[e.from], &nodes[e.to], &e.z);
                r.dot(&(w * r))
            })
            .sum()
    }

    /// The normal equations at `nodes` (node 0 fixed): `H` as 3x3 blocks of the lower
    /// triangle keyed by (row node, column node), and `b = J^T Omega r`.
    fn normal_equations(&self, nodes: &[Pose2], omegas: &[Matrix3<f64>]) -> (Blocks, Vec<f64>) {
        let dim = 3 * (nodes.len() - 1);
        let mut blocks: BTreeMap<(usize, usize), Matrix3<f64>> = BTreeMap::new();
        let mut b = vec![0.0; dim];
        for (e, w) in self.edges.iter().zip(omegas) {
            let (r, ja, jb) = between_residual(&nodes[e.from], &nodes[e.to], &e.z);
            let parts = [(e.from, ja), (e.to, jb)];
            for &(i, ji) in &parts {
                if i == 0 {
                    continue;
                }
                let g: Vector3<f64> = ji.transpose() * w * r;
                for k in 0..3 {
                    b[3 * (i - 1) + k] += g[k];
                }
                for &(j, jj) in &parts {
                    if j == 0 || j > i {
                        continue;
                    }
                    *blocks.entry((i, j)).or_insert_with(Matrix3::zeros) += ji.transpose() * w * jj;
                }
            }
        }
        (blocks, b)
    }

    /// Factorises `H + lambda diag(H)` (lower triangle).
    fn factor(
        blocks: &BTreeMap<(usize, usize), Matrix3<f64>>,
        dim: usize,
        lambda: f64,
    ) -> Result<faer::sparse::linalg::solvers::Llt<usize, f64>, GraphError> {
        let mut triplets = Vec::with_capacity(blocks.len() * 9);
        for (&(i, j), m) in blocks {
            for r in 0..3 {
                for c in 0..3 {
                    let (row, col) = (3 * (i - 1) + r, 3 * (j - 1) + c);
                    if row < col {
                        continue;
                    }
                    let mut v = m[(r, c)];
                    if row == col {
                        v *= 1.0 + lambda;
                    }
                    triplets.push(Triplet::new(row, col, v));
                }
            }
        }
        let h = SparseColMat::<usize, f64>::try_new_from_triplets(dim, dim, &triplets)
            .map_err(|_| GraphError::NotPositiveDefinite)?;
        h.sp_cholesky(Side::Lower)
            .map_err(|_| GraphError::NotPositiveDefinite)
    }

    /// Solves from the current node values. On success returns the solution (the graph's
    /// own values are not changed: install them with [`Self::set_nodes`]); on failure the
    /// caller keeps what it had.
    pub fn solve(&self, settings: &SolveSettings) -> Result<Solution, GraphError> {
        let omegas = self.check()?;
        let n = self.nodes.len();
        let mut nodes = self.nodes.clone();
        let chi2_before = self.chi2(&nodes, &omegas);
        if n <= 1 {
            return Ok(Solution {
                covariances: vec![Matrix3::zeros(); n],
                nodes,
                chi2_before,
                chi2: chi2_before,
                iterations: 0,
            });
        }
        let dim = 3 * (n - 1);
        let mut chi2 = chi2_before;
        let mut lambda = 0.0;
        let mut iterations = 0;
        let mut converged = false;
        while iterations < settings.max_iterations {
            iterations += 1;
            let (blocks, b) = self.normal_equations(&nodes, &omegas);
            let llt = Self::factor(&blocks, dim, lambda)?;
            let mut step = Mat::<f64>::from_fn(dim, 1, |i, _| -b[i]);
            llt.solve_in_place(step.as_mut());
            let mut trial = nodes.clone();
            let mut largest: f64 = 0.0;
            for k in 1..n {
                let d = [
                    step[(3 * (k - 1), 0)],
                    step[(3 * (k - 1) + 1, 0)],
                    step[(3 * (k - 1) + 2, 0)],
                ];
                if !d.iter().all(|v| v.is_finite()) {
                    return Err(GraphError::NonFinite);
                }
                largest = d.iter().fold(largest, |m, v| m.max(v.abs()));
                let p = &nodes[k];
                trial[k] = Pose2::new(p.x + d[0], p.y + d[1], wrap_angle(p.theta + d[2]));
            }
            let trial_chi2 = self.chi2(&trial, &omegas);
            if !trial_chi2.is_finite() {
                return Err(GraphError::NonFinite);
            }
            if trial_chi2 <= chi2 * (1.0 + 1e-12) + 1e-12 {
                nodes = trial;
                chi2 = trial_chi2;
                lambda *= 0.1;
                if largest < settings.step_tolerance {
                    converged = true;
                    break;
                }
            } else {
                lambda = if lambda == 0.0 { 1e-4 } else { lambda * 10.0 };
                if lambda > 1e8 {
                    // No step reduces the error: at a minimum to machine precision, or stuck.
                    converged = largest < 1e-6;
                    break;
                }
            }
        }
        if !converged {
            return Err(GraphError::NotConverged(iterations));
        }
        let covariances = Self::marginals(&self.normal_equations(&nodes, &omegas).0, n)?;
        Ok(Solution {
            nodes,
            covariances,
            chi2_before,
            chi2,
            iterations,
        })
    }

    /// Every node's marginal covariance from the normal equations at the solution.
    fn marginals(
        blocks: &BTreeMap<(usize, usize), Matrix3<f64>>,
        n: usize,
    ) -> Result<Vec<Matrix3<f64>>, GraphError> {
        let dim = 3 * (n - 1);
        let llt = Self::factor(blocks, dim, 0.0)?;
        let mut out = vec![Matrix3::zeros(); n];
        // Column blocks in batches, so a long chain stays O(n) memory per batch.
        const BATCH: usize = 64;
        let mut first = 1;
        while first < n {
            let last = (first + BATCH).min(n);
            let cols = 3 * (last - first);
            let mut rhs = Mat::<f64>::zeros(dim, cols);
            for c in 0..cols {
                rhs[(3 * (first - 1) + c, c)] = 1.0;
            }
            llt.solve_in_place(rhs.as_mut());
            for (k, slot) in out.iter_mut().enumerate().take(last).skip(first) {
                let (o, c0) = (3 * (k - 1), 3 * (k - first));
                let m = Matrix3::from_fn(|r, c| rhs[(o + r, c0 + c)]);
                if !m.iter().all(|v| v.is_finite()) {
                    return Err(GraphError::NonFinite);
                }
                *slot = 0.5 * (m + m.transpose());
            }
            first = last;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::se2::{between, compose};

    fn cov(sxy: f64, st: f64) -> Matrix3<f64> {
        Matrix3::from_diagonal(&Vector3::new(sxy * sxy, sxy * sxy, st * st))
    }

    #[test]
    fn a_chain_alone_solves_to_its_own_composition_with_composed_covariances() {
        let steps = [
            Pose2::new(10.0, 0.0, 0.3),
            Pose2::new(8.0, 1.0, -0.2),
            Pose2::new(12.0, -2.0, 1.0),
        ];
        let mut g = PoseGraph::new();
        let mut at = Pose2::new(0.0, 0.0, 0.0);
        g.add_node(at);
        let mut expected_cov = Matrix3::zeros();
        for (k, s) in steps.iter().enumerate() {
            let c = cov(0.1, 0.01);
            expected_cov = crate::se2::compose_covariance(&at, &expected_cov, s, &c);
            at = compose(&at, s);
            // A poor initial guess.
            g.add_node(Pose2::new(at.x + 1.0, at.y - 1.0, at.theta + 0.1));
            g.add_edge(Edge {
                from: k,
                to: k + 1,
                z: *s,
                covariance: c,
                kind: EdgeKind::Chain,
            });
        }
        let sol = g.solve(&SolveSettings::default()).unwrap();
        let last = sol.nodes[3];
        assert!((last.x - at.x).abs() < 1e-9 && (last.y - at.y).abs() < 1e-9);
        assert!(sol.chi2 < 1e-18);
        let d = sol.covariances[3] - expected_cov;
        assert!(d.abs().max() < 1e-9, "{d}");
    }

    #[test]
    fn a_loop_closure_pulls_a_drifted_square_back() {
        // A square of four 50 m sides whose odometry turns a little too much.
        let truth: Vec<Pose2> = (0..4)
            .map(|k| {
                let a = k as f64 * std::f64::consts::FRAC_PI_2;
                let p = [[0.0, 0.0], [50.0, 0.0], [50.0, 50.0], [0.0, 50.0]][k];
                Pose2::new(p[0], p[1], a)
            })
            .collect();
        let mut g = PoseGraph::new();
        let mut at = truth[0];
        g.add_node(at);
        for k in 0..4 {
            let next = truth[(k + 1) % 4];
            let mut z = between(&truth[k], &next);
            if k == 3 {
                z = between(&truth[3], &Pose2::new(0.0, 0.0, 0.0));
            }
            z.theta += 0.02;
            at = compose(&at, &z);
            g.add_node(at);
            g.add_edge(Edge {
                from: k,
                to: k + 1,
                z,
                covariance: cov(0.2, 0.02),
                kind: EdgeKind::Chain,
            });
        }
        let before = g.nodes()[4];
        // Node 4 is node 0 seen again: a loop closure says so exactly.
        g.add_edge(Edge {
            from: 0,
            to: 4,
            z: Pose2::new(0.0, 0.0, 0.0),
            covariance: cov(0.05, 0.005),
            kind: EdgeKind::Loop,
        });
        let sol = g.solve(&SolveSettings::default()).unwrap();
        let after = sol.nodes[4];
        assert!(
            before.x.hypot(before.y) > 2.5,
            "the drift to undo: {before:?}"
        );
        assert!(after.x.hypot(after.y) < 0.1, "{after:?}");
        assert!(sol.covariances[4][(0, 0)] < 0.05 * 0.05 * 1.01);
    }

    #[test]
    fn a_node_tied_to_nothing_fails_and_says_so() {
        let mut g = PoseGraph::new();
        g.add_node(Pose2::new(0.0, 0.0, 0.0));
        g.add_node(Pose2::new(1.0, 0.0, 0.0));
        g.add_node(Pose2::new(2.0, 0.0, 0.0));
        g.add_edge(Edge {
            from: 0,
            to: 1,
            z: Pose2::new(1.0, 0.0, 0.0),
            covariance: cov(0.1, 0.01),
            kind: EdgeKind::Chain,
        });
        assert_eq!(
            g.solve(&SolveSettings::default()),
            Err(GraphError::NotPositiveDefinite)
        );
    }

    #[test]
    fn bad_edges_are_refused_before_any_arithmetic() {
        let mut g = PoseGraph::new();
        g.add_node(Pose2::new(0.0, 0.0, 0.0));
        g.add_node(Pose2::new(1.0, 0.0, 0.0));
        g.add_edge(Edge {
            from: 0,
            to: 5,
            z: Pose2::new(1.0, 0.0, 0.0),
            covariance: cov(0.1, 0.01),
            kind: EdgeKind::Chain,
        });
        assert!(matches!(
            g.solve(&SolveSettings::default()),
            Err(GraphError::BadEdge { .. })
        ));
        g.pop_edge();
        let mut c = cov(0.1, 0.01);
        c[(2, 2)] = f64::NAN;
        g.add_edge(Edge {
            from: 0,
            to: 1,
            z: Pose2::new(1.0, 0.0, 0.0),
            covariance: c,
            kind: EdgeKind::Chain,
        });
        assert_eq!(
            g.solve(&SolveSettings::default()),
            Err(GraphError::BadCovariance(0))
        );
    }
}
