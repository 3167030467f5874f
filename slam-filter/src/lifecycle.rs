//! Feature life cycle before the state: tentative targets waiting to be seen again.
//!
//! A target no feature claims becomes tentative: its world position and that position's
//! covariance (pose uncertainty and measurement noise propagated through the inverse of
//! eq. 3, 4) are kept. A later target inside a tentative's 2-D chi-square gate is another
//! look at it when it comes at least `confirm_min_separation_s` after the previous look (a
//! later rotation, not a neighbouring azimuth of the same sweep); the look that makes
//! `confirm_after` looks confirms it, and the filter initialises a feature from that
//! observation. Unconfirmed tentatives expire; their number is bounded.

use nalgebra::{Matrix2, Matrix2x3, Matrix3, Vector2};
use radar_model::geometry::Pose2;

use super::observation::Target;

/// A target seen once, waiting to be seen again.
#[derive(Debug, Clone, PartialEq)]
pub struct Tentative {
    /// World position (m).
    pub position: Vector2<f64>,
    /// Its covariance (m^2).
    pub covariance: Matrix2<f64>,
    /// Power when last seen (dB).
    pub power_db: f64,
    /// First sighting (s).
    pub first_seen_s: f64,
    /// Latest sighting (s).
    pub last_seen_s: f64,
    /// Number of sightings.
    pub sightings: u32,
    /// Looks: sightings at least the confirmation separation apart (the first counts).
    pub looks: u32,
    /// Time of the latest look (s).
    pub last_look_s: f64,
}

/// World position of a target and its Jacobians with respect to the pose and `(R, beta)`
/// (the inverse of eq. 3, 4): `x_f = x + R cos(theta - beta)`, `y_f = y + R sin(theta - beta)`.
pub fn inverse_observation(
    pose: &Pose2,
    t: &Target,
) -> (Vector2<f64>, Matrix2x3<f64>, Matrix2<f64>) {
    let a = pose.theta - t.bearing_rad;
    let (s, c) = a.sin_cos();
    let r = t.range_m;
    let p = Vector2::new(pose.x + r * c, pose.y + r * s);
    let wrt_pose = Matrix2x3::new(1.0, 0.0, -r * s, 0.0, 1.0, r * c);
    let wrt_rb = Matrix2::new(c, r * s, s, -r * c);
    (p, wrt_pose, wrt_rb)
}

/// Outcome of offering an unclaimed target to the tentative list.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sighting {
    /// It started a new tentative.
    New,
    /// It matched a tentative too soon to confirm it (same rotation); the tentative was refreshed.
    Refreshed,
    /// It confirmed a tentative, which was removed: initialise a feature from this target.
    Confirmed,
    /// The list is full and the target was dropped.
    Dropped,
}

/// The tentative targets.
#[derive(Debug, Clone, Default)]
pub struct TentativeList {
    items: Vec<Tentative>,
}

impl TentativeList {
    /// Tentatives currently held.
    pub fn items(&self) -> &[Tentative] {
        &self.items
    }

    /// Re-expresses every tentative in the frame whose origin and axes are `origin` (a pose
    /// in the current frame): positions move, covariances rotate.
    pub fn reframe(&mut self, origin: &Pose2) {
        let (s, c) = origin.theta.sin_cos();
        let rt = Matrix2::new(c, s, -s, c);
        for t in &mut self.items {
            let d = t.position - Vector2::new(origin.x, origin.y);
            t.position = rt * d;
            t.covariance = rt * t.covariance * rt.transpose();
        }
    }

    /// Forgets tentatives not seen since `now_s - timeout_s`.
    pub fn expire(&mut self, now_s: f64, timeout_s: f64) {
        self.items.retain(|t| now_s - t.last_seen_s <= timeout_s);
    }

    /// Offers an unclaimed target seen from `pose` (covariance `pose_cov`, measurement noise
    /// variances `rb_var = [range, bearing]`).
    #[allow(clippy::too_many_arguments)]
    pub fn offer(
        &mut self,
        pose: &Pose2,
        pose_cov: &Matrix3<f64>,
        rb_var: [f64; 2],
        t: &Target,
        now_s: f64,
        gate_2dof: f64,
        min_separation_s: f64,
        confirm_after: u32,
        capacity: usize,
    ) -> Sighting {
        let (p, jp, jz) = inverse_observation(pose, t);
        let rz = Matrix2::new(rb_var[0], 0.0, 0.0, rb_var[1]);
        let cov = jp * pose_cov * jp.transpose() + jz * rz * jz.transpose();
        let cov = 0.5 * (cov + cov.transpose());
        let mut best: Option<(usize, f64)> = None;
        for (idx, tent) in self.items.iter().enumerate() {
            let d = p - tent.position;
            let s = cov + tent.covariance;
            let Some(ch) = s.cholesky() else { continue };
            let d2 = d.dot(&ch.solve(&d));
            if d2 <= gate_2dof && best.map_or(true, |(_, b)| d2 < b) {
                best = Some((idx, d2));
            }
        }
        match best {
            Some((idx, _)) => {
                let Some(tent) = self.items.get_mut(idx) else {
                    return Sighting::Dropped;
                };
                let new_look = now_s - tent.last_look_s >= min_separation_s;
                if new_look && tent.looks.saturating_add(1) >= confirm_after {
                    self.items.swap_remove(idx);
                    return Sighting::Confirmed;
                }
                if new_look {
                    tent.looks = tent.looks.saturating_add(1);
                    tent.last_look_s = now_s;
                }
                tent.position = p;
                tent.covariance = cov;
                tent.power_db = t.power_db;
                tent.last_seen_s = now_s;
                tent.sightings = tent.sightings.saturating_add(1);
                Sighting::Refreshed
            }
            None => {
                if confirm_after <= 1 {
                    return Sighting::Confirmed;
                }
                if self.items.len() >= capacity {
                    return Sighting::Dropped;
                }
                self.items.push(Tentative {
                    position: p,
                    covariance: cov,
                    power_db: t.power_db,
                    first_seen_s: now_s,
                    last_seen_s: now_s,
                    sightings: 1,
                    looks: 1,
                    last_look_s: now_s,
                });
                Sighting::New
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn offer(list: &mut TentativeList, now_s: f64, confirm_after: u32) -> Sighting {
        list.offer(
            &Pose2::new(0.0, 0.0, 0.0),
            &Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-4, 1e-4, 1e-6)),
            [0.01, 1e-4],
            &Target {
                range_m: 20.0,
                bearing_rad: 0.3,
                power_db: -40.0,
            },
            now_s,
            9.21,
            0.1,
            confirm_after,
            16,
        )
    }

    #[test]
    fn confirmation_takes_the_configured_number_of_looks_and_a_sweep_counts_once() {
        let mut list = TentativeList::default();
        assert_eq!(offer(&mut list, 0.0, 3), Sighting::New);
        // A neighbouring azimuth of the same sweep is not another look.
        assert_eq!(offer(&mut list, 0.002, 3), Sighting::Refreshed);
        assert_eq!(offer(&mut list, 0.4, 3), Sighting::Refreshed);
        assert_eq!(list.items()[0].looks, 2);
        assert_eq!(offer(&mut list, 0.8, 3), Sighting::Confirmed);
        assert!(list.items().is_empty());
        // The shipped two looks: confirmed on the next rotation.
        assert_eq!(offer(&mut list, 1.0, 2), Sighting::New);
        assert_eq!(offer(&mut list, 1.4, 2), Sighting::Confirmed);
        // One look: every unclaimed target is mapped at once.
        assert_eq!(offer(&mut list, 2.0, 1), Sighting::Confirmed);
        assert!(list.items().is_empty());
    }
}
