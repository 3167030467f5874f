//! Local submaps: the paper's filter, exactly as it is, run on a bounded piece of the drive.
//!
//! A submap is an [`crate::Ekf`] in a frame of its own: the vehicle starts it at the
//! frame's origin with zero covariance, maps the features it meets, and when the vehicle has
//! moved [`SubmapLimits::max_distance_m`] or the map holds [`SubmapLimits::max_features`]
//! features, the submap is frozen and a fresh one starts where the vehicle is
//! ([`crate::Ekf::start_submap`]). The first submap's frame is the world's (its vehicle
//! starts at the configured pose with the configured covariance), so a filter whose limits
//! are never reached is today's dense filter, number for number.
//!
//! A frozen submap keeps what the global layer needs and no more ([`FrozenSubmap`]): the
//! vehicle's pose at the switch relative to the submap's origin with its 3x3 covariance
//! (the edge to the next submap), and each feature's position, material logits and their
//! marginal covariances in the submap's frame. The full covariance (8 n^2 bytes) is dropped:
//! memory grows with the map stored, not with its square.

use nalgebra::{Matrix2, Matrix3};
use radar_model::geometry::Pose2;

use super::state::{FeatureId, SlamState};

/// When a submap is closed. Both limits are checked once a rotation by the caller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubmapLimits {
    /// Close after the vehicle has driven this far (m) in the submap.
    pub max_distance_m: f64,
    /// Close once the submap holds this many features.
    pub max_features: usize,
}

impl SubmapLimits {
    /// Limits never reached: one submap for the whole drive (the dense filter).
    pub const UNBOUNDED: SubmapLimits = SubmapLimits {
        max_distance_m: f64::INFINITY,
        max_features: usize::MAX,
    };

    /// Whether a submap that has driven `distance_m` and holds `features` is full.
    pub fn reached(&self, distance_m: f64, features: usize) -> bool {
        distance_m >= self.max_distance_m || features >= self.max_features
    }
}

/// A feature of a frozen submap, in the submap's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubmapFeature {
    /// The filter's id (unique across the submaps of one filter).
    pub id: FeatureId,
    /// Position (m).
    pub xy: [f64; 2],
    /// Its marginal covariance (m^2).
    pub xy_cov: Matrix2<f64>,
    /// Material logits `u, v` (see radar-model's `material`).
    pub uv: [f64; 2],
    /// Their marginal covariance.
    pub uv_cov: Matrix2<f64>,
    /// Observations used.
    pub hits: u64,
}

/// A closed submap: what the global layer joins.
#[derive(Debug, Clone, PartialEq)]
pub struct FrozenSubmap {
    /// The vehicle's pose when the submap was closed, in the submap's frame (the next
    /// submap's origin).
    pub end_pose: Pose2,
    /// Its covariance (x, y, theta), in the submap's frame.
    pub end_cov: Matrix3<f64>,
    /// The features.
    pub features: Vec<SubmapFeature>,
    /// The radar loss L at closing (dB).
    pub loss_db: f64,
    /// Time the submap was closed (s).
    pub end_s: f64,
}

impl FrozenSubmap {
    /// The compact record of a local map's state (marginals only).
    pub fn from_state(state: &SlamState) -> FrozenSubmap {
        let features = (0..state.feature_count())
            .filter_map(|slot| {
                let p = state.params(slot)?;
                let track = state.tracks().get(slot)?;
                let i = crate::state::FEATURE_BASE + crate::state::FEATURE_DIM * slot;
                Some(SubmapFeature {
                    id: track.id,
                    xy: [p.x_m, p.y_m],
                    xy_cov: state.block2(i),
                    uv: [p.u, p.v],
                    uv_cov: state.block2(i + 2),
                    hits: track.hits,
                })
            })
            .collect();
        FrozenSubmap {
            end_pose: state.pose(),
            end_cov: state.pose_covariance(),
            features,
            loss_db: state.loss_db(),
            end_s: state.time_s(),
        }
    }

    /// Bytes this record holds (for the memory report).
    pub fn heap_bytes(&self) -> usize {
        self.features.capacity() * std::mem::size_of::<SubmapFeature>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unbounded_limits_are_never_reached() {
        assert!(!SubmapLimits::UNBOUNDED.reached(1e12, usize::MAX - 1));
        let l = SubmapLimits {
            max_distance_m: 100.0,
            max_features: 50,
        };
        assert!(l.reached(100.0, 0));
        assert!(l.reached(0.0, 50));
        assert!(!l.reached(99.9, 49));
    }
}
