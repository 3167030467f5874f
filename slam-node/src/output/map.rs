//! The map file: JSON, one document per snapshot (the daemon rewrites `map.json` at the
//! end of the run and every `map_every_rotations`).
//!
//! ```json
//! { "format": "slam-node-map v1", "timestamp_s": 1.7e9, "loss_db": 3.1, "loss_var_db2": 0.4,
//!   "features": [ { "id": 7, "x_m": 12.0, "y_m": -3.5, "rho": 0.25, "alpha": 0.45,
//!     "tau": 0.30, "covariance": [[..4 x 4 over x, y, rho, alpha..]], "observations": 31 } ] }
//! ```
//! `covariance` is over `(x_m, y_m, rho, alpha)`: the filter keeps `(u, v)` with
//! `(rho, alpha, tau) = softmax(u, v, 0)`, and the rho/alpha block is its first-order
//! transform through that map.

use std::io::{self, Write};

use serde::{Deserialize, Serialize};
use slam_filter::state::{feature_index, SlamState, LOSS_INDEX};

/// One mapped feature.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapFeature {
    /// Stable id given when the feature was initialised.
    pub id: u64,
    /// East, metres.
    pub x_m: f64,
    /// North, metres.
    pub y_m: f64,
    /// Normalised reflectivity.
    pub rho: f64,
    /// Normalised absorption.
    pub alpha: f64,
    /// Transmitted share, 1 - rho - alpha.
    pub tau: f64,
    /// Covariance over (x_m, y_m, rho, alpha), row-major.
    pub covariance: [[f64; 4]; 4],
    /// Updates the feature has taken part in.
    pub observations: u64,
}

/// The whole map at one time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapSnapshot {
    /// Always `slam-node-map v1`.
    pub format: String,
    /// Time of the state the snapshot was taken from.
    pub timestamp_s: f64,
    /// The radar loss L, dB.
    pub loss_db: f64,
    /// Variance of L, dB^2.
    pub loss_var_db2: f64,
    /// Every feature in the state.
    pub features: Vec<MapFeature>,
    /// With submaps: the map is the union of the submaps' features placed by the global
    /// layer's optimised frames (absent for one dense map).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub global: Option<GlobalInfo>,
}

/// How a map made of submaps was put together.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct GlobalInfo {
    /// Submaps (the current one included).
    pub submaps: usize,
    /// Loop closures in the global graph.
    pub loop_closures: usize,
    /// The global solution the frames come from (0: chained switch poses, not optimised).
    pub solution: u64,
}

impl MapSnapshot {
    /// The format tag written in every file.
    pub const FORMAT: &'static str = "slam-node-map v1";

    /// The filter's map: positions, rho and alpha with their covariance (the (u, v) block
    /// mapped through the softmax's Jacobian), and L. The material variances are as the
    /// state holds them: call `Ekf::settle_material_noise` first so that they include the
    /// random walk of features not seen lately.
    pub fn from_state(state: &SlamState) -> MapSnapshot {
        let mut features = Vec::with_capacity(state.feature_count());
        for slot in 0..state.feature_count() {
            let (Some(params), Some(track)) = (state.params(slot), state.tracks().get(slot)) else {
                continue;
            };
            let material = radar_model::material::Material::new(params.u, params.v);
            let shares = material.shares();
            let j = material.shares_jacobian();
            let base = feature_index(slot);
            // Covariance of (x, y, u, v) from the state.
            let c = |r: usize, k: usize| state.covariance_entry(base + r, base + k);
            // Transform T = diag(I2, J): cov' = T C T^T.
            let t = |r: usize, k: usize| -> f64 {
                match (r, k) {
                    (0, 0) | (1, 1) => 1.0,
                    (2, 2) => j[0][0],
                    (2, 3) => j[0][1],
                    (3, 2) => j[1][0],
                    (3, 3) => j[1][1],
                    _ => 0.0,
                }
            };
            let mut cov = [[0.0; 4]; 4];
            for (r, row) in cov.iter_mut().enumerate() {
                for (k, out) in row.iter_mut().enumerate() {
                    let mut acc = 0.0;
                    for a in 0..4 {
                        for b in 0..4 {
                            acc += t(r, a) * c(a, b) * t(k, b);
                        }
                    }
                    *out = acc;
                }
            }
            features.push(MapFeature {
                id: track.id.0,
                x_m: params.x_m,
                y_m: params.y_m,
                rho: shares.rho,
                alpha: shares.alpha,
                tau: shares.tau,
                covariance: cov,
                observations: track.hits,
            });
        }
        let loss_var = state.covariance_entry(LOSS_INDEX, LOSS_INDEX);
        MapSnapshot {
            format: MapSnapshot::FORMAT.into(),
            timestamp_s: state.time_s(),
            loss_db: state.loss_db(),
            loss_var_db2: loss_var,
            features,
            global: None,
        }
    }

    /// Moves every feature from a submap's frame into the world: `frame` is the submap's
    /// frame in the world (positions move, position covariances rotate).
    pub fn transform(&mut self, frame: &radar_model::geometry::Pose2) {
        for f in &mut self.features {
            f.transform(frame);
        }
    }

    /// Writes the snapshot as pretty JSON.
    pub fn write_json<W: Write>(&self, sink: W) -> io::Result<()> {
        serde_json::to_writer_pretty(sink, self).map_err(io::Error::other)
    }
}

impl MapFeature {
    /// A frozen submap's feature, placed in the world by its submap's `frame`.
    pub fn from_submap(
        f: &slam_filter::SubmapFeature,
        frame: &radar_model::geometry::Pose2,
    ) -> Self {
        let material = radar_model::material::Material::new(f.uv[0], f.uv[1]);
        let shares = material.shares();
        let j = material.shares_jacobian();
        let mut cov = [[0.0; 4]; 4];
        for r in 0..2 {
            for c in 0..2 {
                cov[r][c] = f.xy_cov[(r, c)];
                let mut acc = 0.0;
                for a in 0..2 {
                    for b in 0..2 {
                        acc += j[r][a] * f.uv_cov[(a, b)] * j[c][b];
                    }
                }
                cov[2 + r][2 + c] = acc;
            }
        }
        let mut out = MapFeature {
            id: f.id.0,
            x_m: f.xy[0],
            y_m: f.xy[1],
            rho: shares.rho,
            alpha: shares.alpha,
            tau: shares.tau,
            covariance: cov,
            observations: f.hits,
        };
        out.transform(frame);
        out
    }

    /// Moves the feature from a frame into its parent (`frame` is the frame's pose there).
    pub fn transform(&mut self, frame: &radar_model::geometry::Pose2) {
        let (s, c) = frame.theta.sin_cos();
        let (x, y) = (self.x_m, self.y_m);
        self.x_m = frame.x + c * x - s * y;
        self.y_m = frame.y + s * x + c * y;
        let r = nalgebra::Matrix2::new(c, -s, s, c);
        let p = nalgebra::Matrix2::new(
            self.covariance[0][0],
            self.covariance[0][1],
            self.covariance[1][0],
            self.covariance[1][1],
        );
        let q = r * p * r.transpose();
        self.covariance[0][0] = q[(0, 0)];
        self.covariance[0][1] = q[(0, 1)];
        self.covariance[1][0] = q[(1, 0)];
        self.covariance[1][1] = q[(1, 1)];
        // Cross terms position x material rotate with the position.
        for m in 2..4 {
            let (a, b) = (self.covariance[0][m], self.covariance[1][m]);
            self.covariance[0][m] = c * a - s * b;
            self.covariance[1][m] = s * a + c * b;
            self.covariance[m][0] = self.covariance[0][m];
            self.covariance[m][1] = self.covariance[1][m];
        }
    }
}

/// The 2x2 position block of a feature's covariance.
pub fn position_covariance(f: &MapFeature) -> [[f64; 2]; 2] {
    let c = &f.covariance;
    [[c[0][0], c[0][1]], [c[1][0], c[1][1]]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_snapshot_round_trips_through_json() {
        let snap = MapSnapshot {
            format: MapSnapshot::FORMAT.into(),
            timestamp_s: 1.0,
            loss_db: 2.0,
            loss_var_db2: 0.5,
            features: vec![MapFeature {
                id: 3,
                x_m: 1.0,
                y_m: 2.0,
                rho: 0.2,
                alpha: 0.3,
                tau: 0.5,
                covariance: [
                    [1.0, 0.1, 0.0, 0.0],
                    [0.1, 2.0, 0.0, 0.0],
                    [0.0; 4],
                    [0.0; 4],
                ],
                observations: 9,
            }],
            global: None,
        };
        let mut buf = Vec::new();
        snap.write_json(&mut buf).unwrap();
        let back: MapSnapshot = serde_json::from_slice(&buf).unwrap();
        assert_eq!(back, snap);
    }
}
