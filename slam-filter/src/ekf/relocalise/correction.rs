//! The hypotheses of a relocalisation: rigid corrections of the world, and the mapped
//! features they are scored against, in a grid for "which features are near this point".

use std::collections::HashMap;

use radar_model::geometry::{wrap_angle, Pose2};

/// A rigid correction of the world: `p -> R(phi) p + t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Correction {
    phi: f64,
    t: [f64; 2],
}

impl Correction {
    /// The correction taking `a0 -> b0` and the direction of `a1 - a0` to that of
    /// `b1 - b0` (about the midpoints, so both pairs weigh alike).
    pub(super) fn from_pairs(a: [[f64; 2]; 2], b: [[f64; 2]; 2]) -> Self {
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

    pub(super) fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let r = rotate(self.phi, p);
        [r[0] + self.t[0], r[1] + self.t[1]]
    }

    pub(super) fn apply_pose(&self, pose: &Pose2) -> Pose2 {
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
pub(super) struct MapPoint {
    pub(super) slot: usize,
    pub(super) xy: [f64; 2],
    /// Variance of its position, largest axis (m^2).
    pub(super) var: f64,
}

/// Features in a grid of square cells, for "which features are near this point".
pub(super) struct Grid {
    cell_m: f64,
    cells: HashMap<(i64, i64), Vec<usize>>,
}

impl Grid {
    pub(super) fn new(points: &[MapPoint], cell_m: f64) -> Self {
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
    pub(super) fn near(&self, xy: [f64; 2], out: &mut Vec<usize>) {
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
