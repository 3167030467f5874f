//! Feature life cycle before the state: tentative targets waiting to be seen again.
//!
//! A target no feature claims becomes tentative: its world position and that position's
//! covariance from the measurement noise alone (propagated through the inverse of eq. 3,
//! 4) are kept. A later target is another look at the tentative when it comes at least
//! `confirm_min_separation_s` after the previous look (a later rotation, not a neighbouring
//! azimuth of the same sweep) and lies inside the 2-D chi-square gate of the difference of
//! the two positions; the look then refines the tentative's position (a Kalman fusion of the
//! two), and the look that makes `confirm_after` looks confirms it: the filter initialises
//! a feature from that observation. Unconfirmed tentatives expire; their number is bounded.
//!
//! The gate leaves out the pose uncertainty the looks share. Both positions are computed
//! from the pose estimate of their time, and the part of the pose error that has not
//! changed in between moves both the same way; only the pose error's change separates them,
//! and its covariance is the difference of the state's [`SlamState::pose_churn`] between the
//! two looks (the input noise and correction uncertainty added by the predictions in
//! between, plus the covariance of the updates' corrections). Gating with the whole pose
//! covariance instead lets a tentative wander by the pose's sigma from look to look once
//! the pose is uncertain: a point sliding along a wall as the vehicle passes, or the
//! strongest of a tree crown's scatterers, then confirms as a landmark.
//!
//! [`SlamState::pose_churn`]: crate::state::SlamState::pose_churn

use nalgebra::{Matrix2, Matrix2x3, Matrix3, Vector2};
use radar_model::geometry::Pose2;

use super::observation::Target;
use super::state::rotate_pose_block;

/// A target seen once, waiting to be seen again.
#[derive(Debug, Clone, PartialEq)]
pub struct Tentative {
    /// World position (m), fused over its looks.
    pub position: Vector2<f64>,
    /// Its covariance from the measurement noise and the pose error's change between the
    /// looks (m^2), without the pose uncertainty all looks share (see the module docs).
    pub covariance: Matrix2<f64>,
    /// The state's pose churn at the latest look (see the module docs).
    pub churn_mark: Matrix3<f64>,
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
    /// in the current frame): positions move, covariances and churn marks rotate.
    pub fn reframe(&mut self, origin: &Pose2) {
        let (s, c) = origin.theta.sin_cos();
        let rt = Matrix2::new(c, s, -s, c);
        for t in &mut self.items {
            let d = t.position - Vector2::new(origin.x, origin.y);
            t.position = rt * d;
            t.covariance = rt * t.covariance * rt.transpose();
            t.churn_mark = rotate_pose_block(&t.churn_mark, -origin.theta);
        }
    }

    /// Forgets tentatives not seen since `now_s - timeout_s`.
    pub fn expire(&mut self, now_s: f64, timeout_s: f64) {
        self.items.retain(|t| now_s - t.last_seen_s <= timeout_s);
    }

    /// Offers an unclaimed target seen from `pose`, with the state's pose churn `churn` now
    /// (see the module docs) and measurement noise variances `rb_var = [range, bearing]`.
    #[allow(clippy::too_many_arguments)]
    pub fn offer(
        &mut self,
        pose: &Pose2,
        churn: &Matrix3<f64>,
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
        let cov = jz * rz * jz.transpose();
        let cov = 0.5 * (cov + cov.transpose());
        // Each tentative's covariance carried to now: its own plus the pose error's change
        // since its latest look, seen at this target.
        let carried = |tent: &Tentative| {
            let moved = jp * (churn - tent.churn_mark) * jp.transpose();
            let c = tent.covariance + moved;
            0.5 * (c + c.transpose())
        };
        // The nearest tentative inside the gate, with its covariance carried to now.
        let mut best: Option<(usize, f64, Matrix2<f64>)> = None;
        for (idx, tent) in self.items.iter().enumerate() {
            let d = p - tent.position;
            let prior = carried(tent);
            let Some(ch) = (cov + prior).cholesky() else {
                continue;
            };
            let d2 = d.dot(&ch.solve(&d));
            if d2 <= gate_2dof && best.is_none_or(|(_, b, _)| d2 < b) {
                best = Some((idx, d2, prior));
            }
        }
        match best {
            Some((idx, _, prior)) => {
                let Some(tent) = self.items.get_mut(idx) else {
                    return Sighting::Dropped;
                };
                tent.last_seen_s = now_s;
                tent.sightings = tent.sightings.saturating_add(1);
                if now_s - tent.last_look_s < min_separation_s {
                    // A neighbouring azimuth of the same sweep: the same look again.
                    return Sighting::Refreshed;
                }
                if tent.looks.saturating_add(1) >= confirm_after {
                    self.items.swap_remove(idx);
                    return Sighting::Confirmed;
                }
                // A new look: fuse it with the tentative carried to now.
                let Some(s_inv) = (prior + cov).try_inverse() else {
                    return Sighting::Refreshed;
                };
                let gain = prior * s_inv;
                tent.position += gain * (p - tent.position);
                let post = (Matrix2::identity() - gain) * prior;
                tent.covariance = 0.5 * (post + post.transpose());
                tent.churn_mark = *churn;
                tent.power_db = t.power_db;
                tent.looks = tent.looks.saturating_add(1);
                tent.last_look_s = now_s;
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
                    churn_mark: *churn,
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
            &(Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-4, 1e-4, 1e-6)) * now_s),
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

    /// A pole confirms over looks from a moving vehicle; the point of a wall nearest the
    /// radar slides with the vehicle and never does, however uncertain the pose itself is
    /// (the gate holds only the pose error's change between the looks). When the pose error
    /// did change a lot between two looks, the gate widens by that much.
    #[test]
    fn a_point_sliding_along_a_wall_never_confirms_and_a_pole_does() {
        let rb_var = [0.35f64.powi(2), 1.3f64.to_radians().powi(2)];
        let per_look = Matrix3::from_diagonal(&nalgebra::Vector3::new(4e-4, 4e-4, 1e-5));
        let target_at = |pose: &Pose2, p: [f64; 2]| {
            let (dx, dy) = (p[0] - pose.x, p[1] - pose.y);
            Target {
                range_m: dx.hypot(dy),
                bearing_rad: pose.theta - dy.atan2(dx),
                power_db: -45.0,
            }
        };
        let mut poles = TentativeList::default();
        let mut walls = TentativeList::default();
        let mut outcomes = (Vec::new(), Vec::new());
        for k in 0..10 {
            let now = 0.25 * k as f64;
            let pose = Pose2::new(2.25 * k as f64, 0.0, 0.0);
            let churn = per_look * k as f64;
            let pole = target_at(&pose, [30.0, 8.0]);
            let wall = target_at(&pose, [pose.x, 8.0]);
            for (list, t, out) in [
                (&mut poles, pole, &mut outcomes.0),
                (&mut walls, wall, &mut outcomes.1),
            ] {
                out.push(list.offer(&pose, &churn, rb_var, &t, now, 9.21, 0.1, 4, 64));
            }
        }
        assert_eq!(outcomes.0[3], Sighting::Confirmed, "{:?}", outcomes.0);
        assert!(
            outcomes.1.iter().all(|s| *s == Sighting::New),
            "{:?}",
            outcomes.1
        );
        // The same slide of 2.25 m gates when the pose error changed by metres in between
        // (a large correction): the tentative is refreshed, not restarted.
        let mut list = TentativeList::default();
        let pose0 = Pose2::new(0.0, 0.0, 0.0);
        let pose1 = Pose2::new(2.25, 0.0, 0.0);
        let t0 = target_at(&pose0, [0.0, 8.0]);
        let t1 = target_at(&pose1, [2.25, 8.0]);
        let zero = Matrix3::zeros();
        let jumped = Matrix3::from_diagonal(&nalgebra::Vector3::new(4.0, 4.0, 0.0));
        assert_eq!(
            list.offer(&pose0, &zero, rb_var, &t0, 0.0, 9.21, 0.1, 4, 64),
            Sighting::New
        );
        assert_eq!(
            list.offer(&pose1, &jumped, rb_var, &t1, 0.25, 9.21, 0.1, 4, 64),
            Sighting::Refreshed
        );
        assert_eq!(list.items()[0].looks, 2);
    }
}
