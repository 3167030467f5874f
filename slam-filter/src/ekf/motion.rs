//! The motion since a mark, measured (for example by registering two radar rotations) and
//! used as an update by stochastic cloning: the pose at the mark is copied into the state's
//! clone, and the measurement holds the pose's change since.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use radar_model::geometry::{wrap_angle, Pose2};

use super::{Ekf, MotionOutcome};
use crate::error::FilterError;
use crate::motion_tally::{relative_pose, MotionTally};
use crate::observation::BeamObservationModel;
use crate::predict::ProcessModel;
use crate::state::{CLONE_INDEX, PLACEMENT_INDEX, PREVIOUS_PLACEMENT_INDEX};
use crate::update::{batched_update, LinearisedObservation};

impl<M: ProcessModel, O: BeamObservationModel> Ekf<M, O> {
    /// Marks the state's time as the reference for the next
    /// [`Self::observe_motion_since_mark`]: the pose is copied into the state's clone (see
    /// [`crate::state`]) and the odometry's tally of the motion starts (see
    /// [`crate::motion_tally`]). Any earlier mark is dropped.
    pub fn mark_motion(&mut self) {
        self.state.clone_pose();
        self.state.tally = Some(MotionTally::start(self.state.time_s()));
    }

    /// The tally since the last mark, up to the state's time; `None` without a mark (none
    /// was set, or a gap, a clock jump or a new submap dropped it).
    pub fn motion_tally(&self) -> Option<&MotionTally> {
        self.state.tally.as_ref()
    }

    /// The estimated pose in the frame of the estimated pose at the last mark (the clone),
    /// every update since included: the motion the filter holds since the mark. `None`
    /// without a mark.
    pub fn pose_since_mark(&self) -> Option<Pose2> {
        self.state.tally.as_ref()?;
        Some(relative_pose(&self.state.clone_pose_mean(), &self.pose()).0)
    }

    /// The pose at `time_s` in the frame of the pose at the last mark, as the odometry
    /// drives it (the tally extrapolated with the held odometry, mean only; updates since
    /// the mark do not move it). `None` without a mark or odometry.
    pub fn motion_since_mark(&self, time_s: f64) -> Option<Pose2> {
        let tally = self.state.tally.as_ref()?;
        let held = self.odometry?;
        self.extrapolate_from(tally.rel, &held, time_s).ok()
    }

    /// Updates the state with a measurement of the motion since the last mark: `measured`
    /// is the pose at the state's time in the frame of the pose at the mark (for example
    /// from registering two radar rotations), `cov` its covariance. The prediction is the
    /// estimated pose in the frame of the estimated clone (the pose at the mark, corrected
    /// since by every update through its correlations): stochastic cloning, so the
    /// measurement holds the pose's change itself, and through their correlations the
    /// odometry corrections `k`, `b`, the pose at the mark and the map. The odometry's input
    /// noise since the mark is in the pose's covariance and not in the clone's, so it is
    /// counted once. A measurement whose normalised innovation exceeds `gate_chi2` (3 dof) is
    /// refused and changes nothing; so does one without a mark. The mark stays: call
    /// [`Self::mark_motion`] to start the next interval.
    pub fn observe_motion_since_mark(
        &mut self,
        measured: Pose2,
        cov: &Matrix3<f64>,
        gate_chi2: f64,
    ) -> Result<MotionOutcome, FilterError> {
        let share = self.settings.registration_placement_share;
        if share > 0.0 {
            return self.observe_motion_with_placement(measured, cov, gate_chi2, share);
        }
        let Some(MotionInnovation {
            columns,
            h,
            nu,
            nis,
        }) = self.motion_innovation(&measured, cov)?
        else {
            return Ok(MotionOutcome::NoMark);
        };
        // The gate first, on S = H P H^T + R (3 x 3); then the filter's one batched update.
        let nis = nis.ok_or(FilterError::InnovationNotPositiveDefinite { dim: 3 })?;
        if !nis.is_finite() || nis > gate_chi2 {
            return Ok(MotionOutcome::Gated { nis });
        }
        batched_update(
            &mut self.state,
            &LinearisedObservation {
                columns: columns.to_vec(),
                jacobian: h,
                innovation: nu,
                noise: DMatrix::from_fn(3, 3, |r, c| 0.5 * (cov[(r, c)] + cov[(c, r)])),
            },
        )?;
        self.stats.motion_updates += 1;
        Ok(MotionOutcome::Applied { nis })
    }

    /// [`Self::observe_motion_since_mark`] when a share `share` of the measurement's
    /// covariance is its clouds' placement ([`crate::FilterSettings::registration_placement_share`]):
    /// the measurement is `h(x) + d_k - d_{k-1} + w`, with `d_{k-1}` the reference cloud's
    /// placement error (held in the state since the last measurement, or a fresh prior of
    /// `share cov` when the state does not hold it), `d_k` the measured cloud's (prior
    /// `share cov`, kept in the state for the next measurement) and `w` white noise of
    /// `(1 - 2 share) cov`. Each measurement alone has the covariance `cov`; consecutive
    /// ones are correlated `-share` (the placement errors cancel when chained). Gated on the
    /// innovation before the state changes.
    fn observe_motion_with_placement(
        &mut self,
        measured: Pose2,
        cov: &Matrix3<f64>,
        gate_chi2: f64,
        share: f64,
    ) -> Result<MotionOutcome, FilterError> {
        let Some(MotionInnovation {
            columns, h, mut nu, ..
        }) = self.motion_innovation(&measured, cov)?
        else {
            return Ok(MotionOutcome::NoMark);
        };
        let sym = 0.5 * (cov + cov.transpose());
        let placement = sym * share;
        let white = sym * (1.0 - 2.0 * share);
        let held = self.state.has_placement();
        // The reference's placement error is predicted into the measurement with a minus.
        if held {
            for r in 0..3 {
                nu[r] += self.state.mean[PLACEMENT_INDEX + r];
            }
        }
        // The gate on S = H P H^T + R over the pose, the clone and (held) the reference's
        // placement, with the measured cloud's placement and the white noise in R (and the
        // reference's prior when not held).
        let mut gate_columns: Vec<usize> = columns.to_vec();
        let mut gate_h = DMatrix::zeros(3, if held { 9 } else { 6 });
        gate_h.view_mut((0, 0), (3, 6)).copy_from(&h);
        let mut r_gate = placement + white;
        if held {
            gate_columns.extend(PLACEMENT_INDEX..PLACEMENT_INDEX + 3);
            for r in 0..3 {
                gate_h[(r, 6 + r)] = -1.0;
            }
        } else {
            r_gate += placement;
        }
        let s = &gate_h * self.state.covariance_block(&gate_columns) * gate_h.transpose()
            + DMatrix::from_fn(3, 3, |r, c| r_gate[(r, c)]);
        let nis = (0.5 * (&s + s.transpose()))
            .cholesky()
            .map(|ch| nu.dot(&ch.solve(&nu)))
            .ok_or(FilterError::InnovationNotPositiveDefinite { dim: 3 })?;
        if !nis.is_finite() || nis > gate_chi2 {
            return Ok(MotionOutcome::Gated { nis });
        }
        // The reference's placement to the previous slot, the measured cloud's in the newest.
        self.state.shift_placement(&placement);
        let mut all_columns: Vec<usize> = columns.to_vec();
        all_columns.extend(PLACEMENT_INDEX..PLACEMENT_INDEX + 3);
        all_columns.extend(PREVIOUS_PLACEMENT_INDEX..PREVIOUS_PLACEMENT_INDEX + 3);
        let mut jacobian = DMatrix::zeros(3, 12);
        jacobian.view_mut((0, 0), (3, 6)).copy_from(&h);
        for r in 0..3 {
            jacobian[(r, 6 + r)] = 1.0;
            jacobian[(r, 9 + r)] = -1.0;
        }
        batched_update(
            &mut self.state,
            &LinearisedObservation {
                columns: all_columns,
                jacobian,
                innovation: nu,
                noise: DMatrix::from_fn(3, 3, |r, c| white[(r, c)]),
            },
        )?;
        self.stats.motion_updates += 1;
        Ok(MotionOutcome::Applied { nis })
    }

    /// Forgets the newest registered cloud's placement error (see
    /// [`crate::FilterSettings::registration_placement_share`]): for a caller whose next
    /// motion measurement registers against a cloud the last measurement did not (it failed,
    /// was refused or was not made), so that the reference's placement is taken from its
    /// prior, independent of the state. Nothing when the share is zero.
    pub fn forget_placement(&mut self) {
        self.state.forget_placement();
    }

    /// Adds `variances` (x m^2, y m^2, heading rad^2) to the pose's covariance: process noise
    /// over the interval since the mark that the motion model did not hold, for a caller that
    /// has found it missed a manoeuvre (a turn's onset a constant-velocity prediction could
    /// not foresee). The pose's covariance with the clone is unchanged, so a measurement of
    /// the motion since the mark then weighs against the prediction by the larger variance.
    /// Non-finite or negative entries are ignored.
    pub fn add_process_noise_since_mark(&mut self, variances: [f64; 3]) {
        self.state.inflate_pose_covariance(variances);
    }

    /// Raises the steering offset's variance back to its prior's
    /// ([`crate::FilterSettings::steer_bias_std_rad`]) where it is below: for a caller that
    /// has found the measurements it learned the offset from were not independent of the
    /// prediction (registrations that stayed at the heading they started from), so what they
    /// taught is not known. The mean and the correlations are kept; the variance is added
    /// to, so the covariance stays positive definite. Nothing without an estimated offset.
    pub fn forget_steer_bias(&mut self) {
        let prior = self.settings.steer_bias_std_rad.powi(2);
        let now = self.state.odometry_bias_covariance()[(1, 1)];
        if self.state.estimates_odometry_bias() && prior > now {
            self.state.walk_odometry_bias([0.0, prior - now]);
        }
    }

    /// Sets the pose to the pose at the last mark composed with `measured` (the pose at
    /// the state's time in the mark's frame, with covariance `cov`), as odometry drives a
    /// pose: for when the measurement *is* the odometry (radar odometry on the radar alone),
    /// not a second opinion of it. The pose's covariance becomes the mark's, carried through
    /// the composition, plus the measurement's; its correlations with the rest of the state
    /// are the mark's, carried the same way. What the pose learned since the mark from the
    /// map is kept only as far as it reached the mark through their correlation.
    ///
    /// Unlike [`Self::observe_motion_since_mark`] it cannot move the mark or the map: a
    /// measurement of the motion since the mark says nothing about where the mark is. (Fed
    /// as an update against a prediction that only repeats the last rotation's motion, the
    /// innovation of a slowing vehicle moved the whole trajectory sideways through the
    /// prediction's correlations: metres in a rotation on the realistic city.)
    ///
    /// Returns [`MotionOutcome::NoMark`] without a mark, and an error for a non-finite
    /// measurement, changing nothing either way.
    pub fn compose_motion_since_mark(
        &mut self,
        measured: Pose2,
        cov: &Matrix3<f64>,
    ) -> Result<MotionOutcome, FilterError> {
        // The measurement against the filter's own motion since the mark (reported only).
        let Some(innovation) = self.motion_innovation(&measured, cov)? else {
            return Ok(MotionOutcome::NoMark);
        };
        let nis = innovation.nis.unwrap_or(f64::NAN);
        let mark = self.state.clone_pose_mean();
        // d(mark + measured) / d(mark) and / d(measured).
        let (j_mark, j_measured) = mark.compose_jacobians(&measured);
        let n = self.state.dim();
        let st = &mut self.state;
        // Every column but the pose's own: P[pose, j] = J_mark P[mark, j].
        for j in 3..n {
            let column = Vector3::from_fn(|r, _| st.covariance_entry(CLONE_INDEX + r, j));
            let carried = j_mark * column;
            for r in 0..3 {
                st.cov[(r, j)] = carried[r];
                st.cov[(j, r)] = carried[r];
            }
        }
        let p_mark = Matrix3::from_fn(|r, k| st.covariance_entry(CLONE_INDEX + r, CLONE_INDEX + k));
        let sym = 0.5 * (cov + cov.transpose());
        let p_pose =
            j_mark * p_mark * j_mark.transpose() + j_measured * sym * j_measured.transpose();
        for r in 0..3 {
            for k in 0..3 {
                st.cov[(r, k)] = 0.5 * (p_pose[(r, k)] + p_pose[(k, r)]);
            }
        }
        let pose = mark.compose(&measured);
        st.mean[0] = pose.x;
        st.mean[1] = pose.y;
        st.mean[2] = pose.theta;
        self.stats.motion_updates += 1;
        Ok(MotionOutcome::Applied { nis })
    }

    /// A measurement of the motion since the mark against the filter's own: `None` without
    /// a mark; an error for a non-finite measurement.
    fn motion_innovation(
        &self,
        measured: &Pose2,
        cov: &Matrix3<f64>,
    ) -> Result<Option<MotionInnovation>, FilterError> {
        if ![measured.x, measured.y, measured.theta]
            .iter()
            .chain(cov.iter())
            .all(|v| v.is_finite())
        {
            return Err(FilterError::NonFiniteInput("measured motion"));
        }
        if self.state.tally.is_none() {
            return Ok(None);
        }
        let (predicted, jacobian) = relative_pose(&self.state.clone_pose_mean(), &self.pose());
        // First-estimates Jacobians: the pose and the clone linearised where they were
        // predicted, as the propagation between them was (see `crate::predict`); at the
        // updated estimates the two disagree, and the motion measurement's translation then
        // tells the filter its global heading, which no motion measurement can (30 simulated
        // drives with wheels and registrations, `tests/placement_error.rs`: final NEES 40.4
        // at the updated estimates, 3.1 here).
        let jacobian = if self.settings.first_estimate_jacobians {
            relative_pose(&self.state.clone_first, &self.state.predicted_pose).1
        } else {
            jacobian
        };
        let nu = DVector::from_vec(vec![
            measured.x - predicted.x,
            measured.y - predicted.y,
            wrap_angle(measured.theta - predicted.theta),
        ]);
        let columns = [0, 1, 2, CLONE_INDEX, CLONE_INDEX + 1, CLONE_INDEX + 2];
        let h = DMatrix::from_fn(3, 6, |r, c| jacobian[(r, c)]);
        let s = &h * self.state.covariance_block(&columns) * h.transpose()
            + DMatrix::from_fn(3, 3, |r, c| cov[(r, c)]);
        let nis = (0.5 * (&s + s.transpose()))
            .cholesky()
            .map(|ch| nu.dot(&ch.solve(&nu)));
        Ok(Some(MotionInnovation {
            columns,
            h,
            nu,
            nis,
        }))
    }
}

/// A motion measurement against the filter's motion since the mark.
struct MotionInnovation {
    /// The pose's and the clone's elements of the state.
    columns: [usize; 6],
    /// The measurement's Jacobian in those columns.
    h: DMatrix<f64>,
    /// The innovation `[x, y, heading]`.
    nu: DVector<f64>,
    /// Its normalised square; `None` when its covariance is not positive definite.
    nis: Option<f64>,
}
