//! The augmented state: mean, covariance, and which feature lives where.
//!
//! # Layout
//!
//! | index            | element                                   |
//! |------------------|-------------------------------------------|
//! | 0, 1, 2          | vehicle pose `x`, `y` (m), `theta` (rad)  |
//! | 3                | radar loss `L` (dB)                       |
//! | 4                | odometry speed correction `k` (ratio)     |
//! | 5                | odometry steering offset `b` (rad)        |
//! | 6, 7, 8          | the pose at the last motion mark (a clone)|
//! | 9, 10, 11        | the newest registered cloud's placement error (x, y, heading) |
//! | 12, 13, 14       | the one before it (scratch of the motion update) |
//! | 15 + 4 s + 0, 1  | feature in slot `s`: `x_s`, `y_s` (m)     |
//! | 15 + 4 s + 2, 3  | feature in slot `s`: `u_s`, `v_s`         |
//!
//! `L` is stored right after the pose (the paper puts it last) so that appending a feature
//! is a resize that leaves every existing index in place, and removing one shifts only the
//! features after it. `k` and `b` are the odometry's systematic errors (not in the paper):
//! the motion model is driven by `speed (1 + k)` and `steer + b` (see
//! [`super::FilterSettings::speed_scale_std`]). When they are not estimated they stay at
//! zero with zero variance and nothing couples to them, so the filter is the paper's. The
//! clone (not in the paper either) is a copy of the pose taken at
//! [`crate::Ekf::mark_motion`], so that a measurement of the motion since then (radar
//! odometry) can be an update on the pose at the mark and the pose now together
//! (stochastic cloning); the prediction never moves it, the updates correct it through its
//! correlations like any other element. Before the first mark it is zero with zero variance
//! and, like unestimated corrections, changes nothing. The placement errors (not in the
//! paper either) are how far each radar cloud a motion measurement registers is bent by the
//! motion it was placed along: a registration of cloud `k` against cloud `k - 1` errs by
//! `d_k - d_{k-1}` plus white noise, so consecutive errors cancel when chained (see
//! [`crate::FilterSettings::registration_placement_share`]); zero with zero variance, and
//! unused, unless that share is set. `(rho, alpha, tau) = softmax(u, v, 0)` (radar-model's `material`), so
//! every value of `u, v` is a valid material and no clamping is ever needed.
//!
//! The covariance `P` is symmetric by construction: its lower triangle is always current,
//! and every operation but the per-beam update writes both triangles. The per-beam update
//! writes only the lower one (half the work of the filter's dominant cost) and marks the
//! upper one stale; it is mirrored when something needs the whole matrix (a new feature,
//! [`SlamState::covariance`]), and every accessor reads the lower triangle. Feature ids are stable for the life of the filter; slots are not.

use std::borrow::Cow;

use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, Matrix4};
use radar_model::geometry::{wrap_angle, Pose2};

use super::error::FilterError;
use super::motion_tally::MotionTally;

/// Number of pose elements.
pub const POSE_DIM: usize = 3;
/// Index of the radar loss L.
pub const LOSS_INDEX: usize = 3;
/// Index of the odometry speed correction `k` (the model's speed is `speed (1 + k)`).
pub const SPEED_SCALE_INDEX: usize = 4;
/// Index of the odometry steering offset `b` (the model's steering is `steer + b`).
pub const STEER_BIAS_INDEX: usize = 5;
/// Index of the clone's first element: the pose (x, y, heading) at the last motion mark.
pub const CLONE_INDEX: usize = 6;
/// Index of the newest registered cloud's placement error (x, y, heading; see the module
/// docs).
pub const PLACEMENT_INDEX: usize = 9;
/// Index of the placement error of the cloud before it: scratch of
/// [`crate::Ekf::observe_motion_since_mark`].
pub const PREVIOUS_PLACEMENT_INDEX: usize = 12;
/// Index of the first feature's first element.
pub const FEATURE_BASE: usize = 15;
/// Elements per feature: x, y, u, v.
pub const FEATURE_DIM: usize = 4;

pub use super::id::FeatureId;

/// Book-keeping for one feature in the state (not part of the estimate).
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureTrack {
    /// Stable id.
    pub id: FeatureId,
    /// Consecutive beams in which it was expected to be seen and was not.
    pub consecutive_misses: u32,
    /// Number of observations used in updates.
    pub hits: u64,
    /// Time it entered the state (s).
    pub created_s: f64,
    /// Time it was last associated (s).
    pub last_seen_s: f64,
    /// Time up to which the material random walk has been added to its u, v variances.
    pub material_settled_s: f64,
    /// The position estimate it entered the state with (m): the linearisation point of its
    /// range and bearing Jacobians under first-estimates Jacobians.
    pub first_xy_m: [f64; 2],
    /// Predicted `(range, bearing)` in the radar's frame at the first of the current run of
    /// looks from an unchanged viewpoint (see [`super::FilterSettings::repeat_look_range_m`]).
    pub look_anchor: Option<[f64; 2]>,
    /// Time of the run's latest counted look (s).
    pub last_look_s: f64,
    /// Looks in the current run from within one range-bearing cell of `look_anchor`.
    pub repeat_looks: u32,
    /// The odometer reading up to which its positional wander has been added (m).
    pub wander_settled_m: f64,
    /// Rotations it was in the radar's view for, whole (counted by
    /// [`crate::Ekf::score_rotation`]).
    pub rotations_in_view: u32,
    /// Of those, the rotations in which a target was associated with it.
    pub rotations_reobserved: u32,
}

/// A feature's estimated state elements.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureParams {
    /// World x (m).
    pub x_m: f64,
    /// World y (m).
    pub y_m: f64,
    /// Softmax logit of rho.
    pub u: f64,
    /// Softmax logit of alpha.
    pub v: f64,
}

/// The mean and covariance of the augmented state, with its feature book-keeping.
#[derive(Debug, Clone)]
pub struct SlamState {
    pub(crate) mean: DVector<f64>,
    /// The covariance. Its lower triangle (`i >= j`) is always current; the upper one is
    /// stale while `upper_stale` (the per-beam updates write only the lower triangle).
    pub(crate) cov: DMatrix<f64>,
    /// Whether `cov`'s upper triangle lags its lower one (see [`Self::covariance`]).
    pub(crate) upper_stale: bool,
    tracks: Vec<FeatureTrack>,
    next_id: u64,
    time_s: f64,
    /// The pose as last predicted, before any update since (the propagation's linearisation
    /// point under first-estimates Jacobians).
    pub(crate) predicted_pose: Pose2,
    /// The motion since the last mark, advanced by every prediction step (book-keeping, not
    /// part of the estimate): see [`crate::motion_tally`].
    pub(crate) tally: Option<MotionTally>,
    /// The pose as predicted (before the updates) at the last mark: the clone's
    /// linearisation point under first-estimates Jacobians (see
    /// [`crate::Ekf::observe_motion_since_mark`]).
    pub(crate) clone_first: Pose2,
    /// How much the pose estimate may have moved relative to the truth since the start
    /// (book-keeping, not part of the estimate): the sum of what every prediction step added
    /// to the pose covariance beyond carrying it along (the inputs' noise and the odometry
    /// corrections' uncertainty over the step), what every update took out of it (the
    /// covariance of its correction) and every inflation. Between two times, the difference
    /// is the covariance of the pose error's change, which is what separates two looks at a
    /// landmark; the error both looks share cancels (see [`crate::lifecycle`]).
    pub(crate) pose_churn: Matrix3<f64>,
    /// Distance the vehicle has driven (m), for the features' positional wander.
    pub(crate) odometer_m: f64,
}

/// A pose-block matrix (x, y, heading) expressed in axes turned by `angle_rad`: the x-y
/// block rotates, the heading stays.
pub(crate) fn rotate_pose_block(m: &Matrix3<f64>, angle_rad: f64) -> Matrix3<f64> {
    let (s, c) = angle_rad.sin_cos();
    let r = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
    let out = r * m * r.transpose();
    0.5 * (out + out.transpose())
}

/// Index of slot `s`'s first element.
pub const fn feature_index(slot: usize) -> usize {
    FEATURE_BASE + FEATURE_DIM * slot
}

fn check_finite(values: &[f64], what: &'static str) -> Result<(), FilterError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(FilterError::NonFiniteInput(what))
    }
}

impl SlamState {
    /// A state with no features: pose and loss with their (independent) covariances.
    pub fn new(
        pose: Pose2,
        pose_cov: Matrix3<f64>,
        loss_db: f64,
        loss_var_db2: f64,
        time_s: f64,
    ) -> Result<Self, FilterError> {
        check_finite(
            &[pose.x, pose.y, pose.theta, loss_db, loss_var_db2, time_s],
            "initial state",
        )?;
        check_finite(pose_cov.as_slice(), "initial pose covariance")?;
        if pose_cov.cholesky().is_none() && pose_cov != Matrix3::zeros() {
            return Err(FilterError::CovarianceNotPositiveDefinite);
        }
        if loss_var_db2 <= 0.0 {
            return Err(FilterError::CovarianceNotPositiveDefinite);
        }
        let mut mean = DVector::zeros(FEATURE_BASE);
        mean[0] = pose.x;
        mean[1] = pose.y;
        mean[2] = wrap_angle(pose.theta);
        mean[LOSS_INDEX] = loss_db;
        let mut cov = DMatrix::zeros(FEATURE_BASE, FEATURE_BASE);
        for r in 0..3 {
            for c in 0..3 {
                // Mirror the lower triangle so the stored matrix is exactly symmetric.
                let (i, j) = if r >= c { (r, c) } else { (c, r) };
                cov[(r, c)] = pose_cov[(i, j)];
            }
        }
        cov[(LOSS_INDEX, LOSS_INDEX)] = loss_var_db2;
        Ok(Self {
            mean,
            cov,
            upper_stale: false,
            tracks: Vec::new(),
            next_id: 0,
            time_s,
            predicted_pose: Pose2::new(pose.x, pose.y, wrap_angle(pose.theta)),
            tally: None,
            clone_first: Pose2::new(pose.x, pose.y, wrap_angle(pose.theta)),
            pose_churn: Matrix3::zeros(),
            odometer_m: 0.0,
        })
    }

    /// A state from a whole mean and covariance (layout in the module docs), for restoring a
    /// saved estimate or building test and benchmark states. The covariance's lower triangle
    /// is used (mirrored); features get fresh ids in slot order. Checks shape and finiteness,
    /// not definiteness (O(n^3)): see [`super::health::covariance_health`].
    pub fn from_parts(
        mean: DVector<f64>,
        mut cov: DMatrix<f64>,
        time_s: f64,
    ) -> Result<Self, FilterError> {
        let n = mean.len();
        if n < FEATURE_BASE || !(n - FEATURE_BASE).is_multiple_of(FEATURE_DIM) {
            return Err(FilterError::Shape("state length must be 15 + 4 N"));
        }
        if cov.nrows() != n || cov.ncols() != n {
            return Err(FilterError::Shape("covariance must be n x n"));
        }
        check_finite(mean.as_slice(), "state mean")?;
        check_finite(cov.as_slice(), "state covariance")?;
        check_finite(&[time_s], "state time")?;
        super::symmetric::mirror_lower(&mut cov);
        let features = (n - FEATURE_BASE) / FEATURE_DIM;
        let tracks = (0..features)
            .map(|k| FeatureTrack {
                id: FeatureId(k as u64),
                consecutive_misses: 0,
                hits: 0,
                created_s: time_s,
                last_seen_s: time_s,
                material_settled_s: time_s,
                first_xy_m: [mean[feature_index(k)], mean[feature_index(k) + 1]],
                look_anchor: None,
                repeat_looks: 0,
                last_look_s: time_s,
                wander_settled_m: 0.0,
                rotations_in_view: 0,
                rotations_reobserved: 0,
            })
            .collect();
        let mut mean = mean;
        mean[2] = wrap_angle(mean[2]);
        Ok(Self {
            predicted_pose: Pose2::new(mean[0], mean[1], mean[2]),
            tally: None,
            clone_first: Pose2::new(mean[0], mean[1], mean[2]),
            pose_churn: Matrix3::zeros(),
            odometer_m: 0.0,
            mean,
            cov,
            upper_stale: false,
            tracks,
            next_id: features as u64,
            time_s,
        })
    }

    /// Starts a new local map in place: the vehicle at the origin of its own frame with zero
    /// covariance, no features, the radar loss L and the odometry corrections kept with their
    /// joint covariance, no clone, the time and the id counter kept (ids stay unique across
    /// local maps). Returns the state as it was.
    pub(crate) fn restart_at_origin(&mut self) -> SlamState {
        let mut mean = DVector::zeros(FEATURE_BASE);
        let mut cov = DMatrix::zeros(FEATURE_BASE, FEATURE_BASE);
        for r in LOSS_INDEX..CLONE_INDEX {
            mean[r] = self.mean[r];
            for c in LOSS_INDEX..CLONE_INDEX {
                cov[(r, c)] = self.covariance_entry(r, c);
            }
        }
        let fresh = SlamState {
            mean,
            cov,
            upper_stale: false,
            tracks: Vec::new(),
            next_id: self.next_id,
            time_s: self.time_s,
            predicted_pose: Pose2::new(0.0, 0.0, 0.0),
            // A new local frame: the motion since a mark in the old one is not carried.
            tally: None,
            clone_first: Pose2::new(0.0, 0.0, 0.0),
            // The same book-keeping, turned into the new frame's axes (as the tentative
            // targets' marks are, see `TentativeList::reframe`).
            pose_churn: rotate_pose_block(&self.pose_churn, -self.mean[2]),
            odometer_m: self.odometer_m,
        };
        std::mem::replace(self, fresh)
    }

    /// State dimension n = 15 + 4 N.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Number of features N.
    pub fn feature_count(&self) -> usize {
        self.tracks.len()
    }

    /// Time the estimate refers to (s).
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    pub(crate) fn set_time_s(&mut self, t: f64) {
        self.time_s = t;
    }

    /// The mean vector (layout in the module docs).
    pub fn mean(&self) -> &DVector<f64> {
        &self.mean
    }

    /// The covariance matrix, exactly symmetric. The per-beam updates write only the lower
    /// triangle, so after one this is a mirrored copy (O(n^2)); otherwise it is borrowed.
    /// For single entries and blocks use [`Self::covariance_entry`] and
    /// [`Self::covariance_block`], which never copy the matrix.
    pub fn covariance(&self) -> Cow<'_, DMatrix<f64>> {
        if self.upper_stale {
            let mut full = self.cov.clone();
            super::symmetric::mirror_lower(&mut full);
            Cow::Owned(full)
        } else {
            Cow::Borrowed(&self.cov)
        }
    }

    /// `P[i, j]` (read from the lower triangle). Panics outside the state, like indexing.
    #[inline]
    pub fn covariance_entry(&self, i: usize, j: usize) -> f64 {
        super::symmetric::lower_entry(&self.cov, i, j)
    }

    /// Brings the upper triangle up to date with the lower one (O(n^2) when stale).
    pub(crate) fn sync_upper(&mut self) {
        if self.upper_stale {
            super::symmetric::mirror_lower(&mut self.cov);
            self.upper_stale = false;
        }
    }

    /// The covariance of the elements `indices` (in that order): `P[indices, indices]`,
    /// read entry by entry from the lower triangle (a beam's block, without copying whole
    /// rows of `P`).
    pub fn covariance_block(&self, indices: &[usize]) -> DMatrix<f64> {
        let k = indices.len();
        DMatrix::from_fn(k, k, |i, j| self.covariance_entry(indices[i], indices[j]))
    }

    /// The vehicle pose.
    pub fn pose(&self) -> Pose2 {
        Pose2::new(self.mean[0], self.mean[1], self.mean[2])
    }

    /// The pose's 3x3 covariance block.
    pub fn pose_covariance(&self) -> Matrix3<f64> {
        Matrix3::from_fn(|i, j| self.covariance_entry(i, j))
    }

    /// The radar loss L (dB).
    pub fn loss_db(&self) -> f64 {
        self.mean[LOSS_INDEX]
    }

    /// The odometry corrections `[k, b]`: the motion model is driven by `speed (1 + k)` and
    /// `steer + b`. Zero when they are not estimated.
    pub fn odometry_bias(&self) -> [f64; 2] {
        [self.mean[SPEED_SCALE_INDEX], self.mean[STEER_BIAS_INDEX]]
    }

    /// The odometry corrections' 2x2 covariance.
    pub fn odometry_bias_covariance(&self) -> Matrix2<f64> {
        self.block2(SPEED_SCALE_INDEX)
    }

    /// `P[i..i + 2, i..i + 2]` from the lower triangle.
    pub(crate) fn block2(&self, i: usize) -> Matrix2<f64> {
        Matrix2::from_fn(|r, c| self.covariance_entry(i + r, i + c))
    }

    /// Whether the odometry corrections are estimated (either has a variance).
    pub fn estimates_odometry_bias(&self) -> bool {
        self.cov[(SPEED_SCALE_INDEX, SPEED_SCALE_INDEX)] > 0.0
            || self.cov[(STEER_BIAS_INDEX, STEER_BIAS_INDEX)] > 0.0
    }

    /// Gives the odometry corrections the prior variances `[k, b]` (zero: not estimated), with
    /// no correlation to the rest of the state: set at the start, before any prediction.
    pub(crate) fn set_odometry_bias_prior(&mut self, variances: [f64; 2]) {
        for (i, v) in [SPEED_SCALE_INDEX, STEER_BIAS_INDEX]
            .into_iter()
            .zip(variances)
        {
            self.mean[i] = 0.0;
            for j in 0..self.dim() {
                self.cov[(i, j)] = 0.0;
                self.cov[(j, i)] = 0.0;
            }
            self.cov[(i, i)] = if v.is_finite() && v > 0.0 { v } else { 0.0 };
        }
    }

    /// Adds random-walk variances `[k, b]` to the odometry corrections (non-negative, finite
    /// entries only).
    pub(crate) fn walk_odometry_bias(&mut self, variances: [f64; 2]) {
        for (i, v) in [SPEED_SCALE_INDEX, STEER_BIAS_INDEX]
            .into_iter()
            .zip(variances)
        {
            if v.is_finite() && v > 0.0 {
                self.cov[(i, i)] += v;
            }
        }
    }

    /// Copies the pose into the clone (mean, and its rows and columns of P): afterwards the
    /// clone is the pose at this time, jointly distributed with the rest of the state as the
    /// pose is. O(n).
    pub(crate) fn clone_pose(&mut self) {
        let n = self.dim();
        self.clone_first = self.predicted_pose;
        for r in 0..POSE_DIM {
            self.mean[CLONE_INDEX + r] = self.mean[r];
        }
        // Every column but the clone's own: P[c, j] = P[pose, j], read from the lower
        // triangle, written to both.
        for j in (0..n).filter(|j| !(CLONE_INDEX..CLONE_INDEX + POSE_DIM).contains(j)) {
            for r in 0..POSE_DIM {
                let v = self.covariance_entry(r, j);
                self.cov[(CLONE_INDEX + r, j)] = v;
                self.cov[(j, CLONE_INDEX + r)] = v;
            }
        }
        for r in 0..POSE_DIM {
            for c in 0..POSE_DIM {
                self.cov[(CLONE_INDEX + r, CLONE_INDEX + c)] = self.covariance_entry(r, c);
            }
        }
    }

    /// Whether the newest cloud's placement error is in the state (its variance is set:
    /// see [`Self::shift_placement`]).
    pub(crate) fn has_placement(&self) -> bool {
        (0..POSE_DIM).any(|r| self.cov[(PLACEMENT_INDEX + r, PLACEMENT_INDEX + r)] > 0.0)
    }

    /// Zeroes the block at `index` (3 elements): mean, and rows and columns of P. O(n).
    fn clear_block(&mut self, index: usize) {
        let n = self.dim();
        for r in index..index + POSE_DIM {
            self.mean[r] = 0.0;
            for j in 0..n {
                self.cov[(r, j)] = 0.0;
                self.cov[(j, r)] = 0.0;
            }
        }
    }

    /// Forgets the newest cloud's placement error: the next motion measurement registers
    /// against a cloud whose placement the state does not hold (a registration failed or
    /// was refused, the mark was dropped), so its prior is taken fresh there.
    pub(crate) fn forget_placement(&mut self) {
        self.clear_block(PLACEMENT_INDEX);
    }

    /// Before a motion measurement that models its clouds' placement: the newest cloud's
    /// placement error (mean, rows and columns of P) moves to the previous one's slot, as
    /// the reference the measurement registers against; if the state did not hold it, the
    /// previous slot gets `prior` instead, independent of the rest. The newest slot then
    /// holds the measured cloud's own placement error, `prior`, independent of everything.
    /// O(n).
    pub(crate) fn shift_placement(&mut self, prior: &Matrix3<f64>) {
        let n = self.dim();
        let held = self.has_placement();
        self.clear_block(PREVIOUS_PLACEMENT_INDEX);
        if held {
            for r in 0..POSE_DIM {
                let (a, b) = (PLACEMENT_INDEX + r, PREVIOUS_PLACEMENT_INDEX + r);
                self.mean[b] = self.mean[a];
                for j in (0..n).filter(|j| !(PLACEMENT_INDEX..FEATURE_BASE).contains(j)) {
                    let v = self.covariance_entry(a, j);
                    self.cov[(b, j)] = v;
                    self.cov[(j, b)] = v;
                }
            }
            for r in 0..POSE_DIM {
                for c in 0..POSE_DIM {
                    let v = self.covariance_entry(PLACEMENT_INDEX + r, PLACEMENT_INDEX + c);
                    self.cov[(PREVIOUS_PLACEMENT_INDEX + r, PREVIOUS_PLACEMENT_INDEX + c)] = v;
                }
            }
        }
        self.clear_block(PLACEMENT_INDEX);
        for r in 0..POSE_DIM {
            for c in 0..POSE_DIM {
                let v = 0.5 * (prior[(r, c)] + prior[(c, r)]);
                self.cov[(PLACEMENT_INDEX + r, PLACEMENT_INDEX + c)] = v;
                if !held {
                    self.cov[(PREVIOUS_PLACEMENT_INDEX + r, PREVIOUS_PLACEMENT_INDEX + c)] = v;
                }
            }
        }
    }

    /// The clone: the pose at the last motion mark as now estimated (see the module docs).
    pub fn clone_pose_mean(&self) -> Pose2 {
        Pose2::new(
            self.mean[CLONE_INDEX],
            self.mean[CLONE_INDEX + 1],
            self.mean[CLONE_INDEX + 2],
        )
    }

    /// Feature book-keeping in slot order.
    pub fn tracks(&self) -> &[FeatureTrack] {
        &self.tracks
    }

    pub(crate) fn track_mut(&mut self, slot: usize) -> Option<&mut FeatureTrack> {
        self.tracks.get_mut(slot)
    }

    /// The slot of a feature id (linear in N; N is bounded by the settings).
    pub fn slot_of(&self, id: FeatureId) -> Option<usize> {
        self.tracks.iter().position(|t| t.id == id)
    }

    /// Adds the material random walk `rate_per_s * (now - settled)` to slot `slot`'s u and v
    /// variances (see `predict`'s module docs: deferring it is exact).
    pub fn settle_material(&mut self, slot: usize, rate_per_s: f64) {
        let now = self.time_s;
        let Some(track) = self.tracks.get_mut(slot) else {
            return;
        };
        let dt = now - track.material_settled_s;
        track.material_settled_s = now;
        let q = rate_per_s * dt;
        if q > 0.0 && q.is_finite() {
            let i = feature_index(slot);
            self.cov[(i + 2, i + 2)] += q;
            self.cov[(i + 3, i + 3)] += q;
        }
    }

    /// Adds the positional wander since it was last settled to slot `slot`'s x and y
    /// variances: `sigma_m^2 (1 - exp(-d / length_m))` for `d` metres driven since. The
    /// apparent position of a return that is not a true point moves as the viewpoint does,
    /// by up to about `sigma_m` (the object's scale), over about `length_m` of travel; a
    /// parked vehicle adds nothing. Deferred like [`Self::settle_material`] (additive noise
    /// on states no update in between observes).
    pub fn settle_wander(&mut self, slot: usize, sigma_m: f64, length_m: f64) {
        let now = self.odometer_m;
        let Some(track) = self.tracks.get_mut(slot) else {
            return;
        };
        let d = now - track.wander_settled_m;
        track.wander_settled_m = now;
        if !(sigma_m > 0.0 && length_m > 0.0 && d > 0.0) {
            return;
        }
        let q = sigma_m * sigma_m * -(-d / length_m).exp_m1();
        if q > 0.0 && q.is_finite() {
            let i = feature_index(slot);
            self.cov[(i, i)] += q;
            self.cov[(i + 1, i + 1)] += q;
        }
    }

    /// [`Self::settle_material`] for every feature: O(N).
    pub fn settle_all_material(&mut self, rate_per_s: f64) {
        for slot in 0..self.tracks.len() {
            self.settle_material(slot, rate_per_s);
        }
    }

    /// Adds `variances` to the pose's x, y and heading variances (the covariance stays
    /// positive definite: a diagonal, non-negative addition). Negative or non-finite entries
    /// are ignored.
    pub fn inflate_pose_covariance(&mut self, variances: [f64; 3]) {
        for (i, v) in variances.into_iter().enumerate() {
            if v.is_finite() && v > 0.0 {
                self.cov[(i, i)] += v;
                self.pose_churn[(i, i)] += v;
            }
        }
    }

    /// The pose error's accumulated change since the start (see the field's docs): the
    /// difference between two readings is the covariance of the pose error's change
    /// between them.
    pub fn pose_churn(&self) -> &Matrix3<f64> {
        &self.pose_churn
    }

    /// A feature's parameters by slot.
    pub fn params(&self, slot: usize) -> Option<FeatureParams> {
        if slot >= self.tracks.len() {
            return None;
        }
        let i = feature_index(slot);
        Some(FeatureParams {
            x_m: self.mean[i],
            y_m: self.mean[i + 1],
            u: self.mean[i + 2],
            v: self.mean[i + 3],
        })
    }

    /// A feature's 2x2 position covariance by slot.
    pub fn position_covariance(&self, slot: usize) -> Option<Matrix2<f64>> {
        if slot >= self.tracks.len() {
            return None;
        }
        Some(self.block2(feature_index(slot)))
    }

    /// Numbers the features added from now on from `first` at least (never backwards).
    pub fn number_features_from(&mut self, first: u64) {
        self.next_id = self.next_id.max(first);
    }

    /// Appends a feature. `mean` is `[x, y, u, v]`, `cross` its 4 x n covariance with the
    /// existing state, `block` its own 4x4 covariance (its lower triangle is used). Existing
    /// indices are unchanged; the cost is one O(n^2) copy into the larger matrix.
    pub fn augment(
        &mut self,
        mean: [f64; 4],
        cross: &DMatrix<f64>,
        block: &Matrix4<f64>,
        time_s: f64,
        max_features: usize,
    ) -> Result<FeatureId, FilterError> {
        let n = self.dim();
        if self.tracks.len() >= max_features {
            return Err(FilterError::TooManyFeatures(max_features));
        }
        if cross.nrows() != FEATURE_DIM || cross.ncols() != n {
            return Err(FilterError::Shape("augment cross-covariance must be 4 x n"));
        }
        check_finite(&mean, "new feature mean")?;
        check_finite(cross.as_slice(), "new feature cross-covariance")?;
        check_finite(block.as_slice(), "new feature covariance")?;
        // The enlarged matrix is written whole: bring the upper triangle up to date first.
        self.sync_upper();
        let old = std::mem::replace(&mut self.cov, DMatrix::zeros(0, 0));
        let mut cov = old.resize(n + FEATURE_DIM, n + FEATURE_DIM, 0.0);
        for r in 0..FEATURE_DIM {
            for c in 0..n {
                cov[(n + r, c)] = cross[(r, c)];
                cov[(c, n + r)] = cross[(r, c)];
            }
            for c in 0..FEATURE_DIM {
                let (i, j) = if r >= c { (r, c) } else { (c, r) };
                cov[(n + r, n + c)] = block[(i, j)];
            }
        }
        self.cov = cov;
        let old_mean = std::mem::replace(&mut self.mean, DVector::zeros(0));
        let mut m = old_mean.resize_vertically(n + FEATURE_DIM, 0.0);
        for (k, v) in mean.iter().enumerate() {
            m[n + k] = *v;
        }
        self.mean = m;
        let id = FeatureId(self.next_id);
        self.next_id += 1;
        self.tracks.push(FeatureTrack {
            id,
            consecutive_misses: 0,
            hits: 1,
            created_s: time_s,
            last_seen_s: time_s,
            material_settled_s: time_s,
            first_xy_m: [mean[0], mean[1]],
            look_anchor: None,
            repeat_looks: 0,
            last_look_s: time_s,
            wander_settled_m: self.odometer_m,
            rotations_in_view: 0,
            rotations_reobserved: 0,
        });
        Ok(id)
    }

    /// Removes a feature's rows and columns; the features after it move down one slot (the
    /// lower triangle stays the lower triangle, so a stale upper one stays merely stale).
    pub fn remove(&mut self, id: FeatureId) -> Result<(), FilterError> {
        let slot = self.slot_of(id).ok_or(FilterError::UnknownFeature(id))?;
        let i = feature_index(slot);
        let cov = std::mem::replace(&mut self.cov, DMatrix::zeros(0, 0));
        self.cov = cov
            .remove_rows(i, FEATURE_DIM)
            .remove_columns(i, FEATURE_DIM);
        let mean = std::mem::replace(&mut self.mean, DVector::zeros(0));
        self.mean = mean.remove_rows(i, FEATURE_DIM);
        self.tracks.remove(slot);
        Ok(())
    }
}
