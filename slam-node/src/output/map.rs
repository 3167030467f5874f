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
}

impl MapSnapshot {
    /// The format tag written in every file.
    pub const FORMAT: &'static str = "slam-node-map v1";

    /// Writes the snapshot as pretty JSON.
    pub fn write_json<W: Write>(&self, sink: W) -> io::Result<()> {
        serde_json::to_writer_pretty(sink, self).map_err(io::Error::other)
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
        };
        let mut buf = Vec::new();
        snap.write_json(&mut buf).unwrap();
        let back: MapSnapshot = serde_json::from_slice(&buf).unwrap();
        assert_eq!(back, snap);
    }
}
