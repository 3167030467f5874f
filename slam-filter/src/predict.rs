//! Prediction: the process model (radar-model's `motion`, eq. 2 or the bicycle) applied
//! from the state's time to any requested time with the odometry held since its timestamp.
//!
//! Only the pose rows and columns change: `P_vv <- F P_vv F^T + G Q G^T`, `P_vm <- F P_vm`
//! (mirrored into `P_mv`); with the odometry corrections estimated (state `k`, `b`) the
//! pose also moves with them (see [`propagate_with_bias`]) and they random-walk. L gets no
//! process noise; features' positions none beyond their wander (below). The cost is O(n)
//! per step. The small random-walk variance growth of every u and v, and the positional
//! wander of every x and y with the distance driven ([`FilterSettings::feature_wander_m`]),
//! are applied lazily, per feature, when the feature is next used
//! ([`SlamState::settle_material`], [`SlamState::settle_wander`]): independent
//! additive noise on a state commutes with every update that does not observe that state,
//! so deferring it is exact and keeps an empty beam from touching every feature.
//!
//! Input noise is modelled as white with spectral density `std^2 * correlation_s` (see
//! [`FilterSettings::input_noise_correlation_s`]): over a step of `dt` the inputs'
//! covariance is `Q = diag(speed_std^2, steer_std^2) * correlation_s / dt`, so the pose
//! covariance grows by `G Q G^T`, linear in `dt`, whatever the step size.

use nalgebra::{Matrix2, Matrix3, Matrix3x2, Vector3};
use radar_model::geometry::wrap_angle;

use super::error::FilterError;
use super::settings::FilterSettings;
use super::state::{SlamState, POSE_DIM, SPEED_SCALE_INDEX, STEER_BIAS_INDEX};
use super::symmetric::lower_entry;

pub use super::process::{corrected_input, MotionStep, OdometrySample, ProcessModel};

/// Applies one step of length `dt_s > 0` to the state: O(n).
pub fn predict_step<M: ProcessModel + ?Sized>(
    state: &mut SlamState,
    model: &M,
    input: &OdometrySample,
    dt_s: f64,
    settings: &FilterSettings,
) -> Result<(), FilterError> {
    if !(dt_s > 0.0 && dt_s.is_finite()) {
        return Ok(());
    }
    let [k, b] = state.odometry_bias();
    let with_bias = state.estimates_odometry_bias();
    let (speed, steer) = corrected_input(input, [k, b]);
    let step = model.step(&state.pose(), speed, steer, dt_s)?;
    // The distance driven, for the features' positional wander.
    let travelled = (speed * dt_s).abs();
    if travelled.is_finite() {
        state.odometer_m += travelled;
    }
    let mut f = step.wrt_pose;
    if settings.first_estimate_jacobians {
        // The process models move the vehicle rigidly with its heading, so the heading
        // column of F is (-(y' - y), x' - x, 1). First-estimates Jacobians take the
        // displacement from the pose as last *predicted* (before the updates since), so
        // that the propagation and the measurement Jacobians agree on one linearisation
        // point and global heading stays unobservable.
        let last = state.predicted_pose;
        f[(0, 2)] -= state.mean[1] - last.y;
        f[(1, 2)] += state.mean[0] - last.x;
    }
    let g = step.wrt_input;
    if f.iter().chain(g.iter()).any(|v| !v.is_finite())
        || !(step.pose.x.is_finite() && step.pose.y.is_finite() && step.pose.theta.is_finite())
    {
        return Err(FilterError::NonFiniteInput("process model step"));
    }
    let q = input_noise(settings, dt_s);
    if let Some(tally) = state.tally.as_mut() {
        tally.step(model, input, [k, b], dt_s)?;
    }
    let q_v = g * q * g.transpose();
    if with_bias {
        // The corrections k and b are inputs too: d pose / d k = G_speed * speed,
        // d pose / d b = G_steer.
        let f_b = Matrix3x2::from_columns(&[g.column(0) * input.speed_mps, g.column(1).into()]);
        // What the step adds to the pose error's change (see `SlamState::pose_churn`): the
        // inputs' noise and the corrections' own uncertainty over the step.
        let p_bb = state.odometry_bias_covariance();
        state.pose_churn += q_v + f_b * p_bb * f_b.transpose();
        propagate_with_bias(state, &f, &f_b, &q_v);
        state.walk_odometry_bias([
            settings.speed_scale_walk_per_sqrt_s.powi(2) * dt_s,
            settings.steer_bias_walk_rad_per_sqrt_s.powi(2) * dt_s,
        ]);
    } else {
        state.pose_churn += q_v;
        propagate_pose(state, &f, &q_v);
    }
    state.mean[0] = step.pose.x;
    state.mean[1] = step.pose.y;
    state.mean[2] = wrap_angle(step.pose.theta);
    state.predicted_pose = state.pose();
    Ok(())
}

/// Covariance of the odometry's (speed, steer) over a step of `dt_s`: the configured
/// sigmas, scaled by the inputs' correlation time over the step.
pub(crate) fn input_noise(settings: &FilterSettings, dt_s: f64) -> Matrix2<f64> {
    let q_scale = settings.input_noise_correlation_s / dt_s;
    Matrix2::new(
        settings.speed_std_mps.powi(2) * q_scale,
        0.0,
        0.0,
        settings.steer_std_rad.powi(2) * q_scale,
    )
}

/// `P_vv <- F P_vv F^T + Q_v`, `P_vm <- F P_vm`: the pose rows and columns only.
fn propagate_pose(state: &mut SlamState, f: &Matrix3<f64>, q_v: &Matrix3<f64>) {
    let n = state.dim();
    let p_vv = state.pose_covariance();
    let cov = &mut state.cov;
    let mut new_vv = f * p_vv * f.transpose() + q_v;
    new_vv = 0.5 * (new_vv + new_vv.transpose());
    cov.fixed_view_mut::<3, 3>(0, 0).copy_from(&new_vv);
    // Pose-map cross blocks, read from the pose columns (contiguous in j) and written to both
    // the pose columns and the pose rows (one cache line per column).
    for j in POSE_DIM..n {
        let c = Vector3::new(cov[(j, 0)], cov[(j, 1)], cov[(j, 2)]);
        let fc = f * c;
        for r in 0..POSE_DIM {
            cov[(j, r)] = fc[r];
            cov[(r, j)] = fc[r];
        }
    }
}

/// As [`propagate_pose`] with the odometry corrections `(k, b)` as inputs: the pose moves
/// by `F pose + F_b (k, b)`, the corrections stay, so for every other element `j`
/// `P_vj <- F P_vj + F_b P_bj` and `P_vv <- F P_vv F^T + F P_vb F_b^T + F_b P_bv F^T +
/// F_b P_bb F_b^T + Q_v`, `P_vb <- F P_vb + F_b P_bb`. O(n).
fn propagate_with_bias(
    state: &mut SlamState,
    f: &Matrix3<f64>,
    f_b: &Matrix3x2<f64>,
    q_v: &Matrix3<f64>,
) {
    let n = state.dim();
    let (bk, bb) = (SPEED_SCALE_INDEX, STEER_BIAS_INDEX);
    // Read from the lower triangle (the upper one may be stale, see `SlamState`).
    let p_vv = state.pose_covariance();
    let e = |i: usize, j: usize| state.covariance_entry(i, j);
    let p_vb = Matrix3x2::from_columns(&[
        Vector3::new(e(0, bk), e(1, bk), e(2, bk)),
        Vector3::new(e(0, bb), e(1, bb), e(2, bb)),
    ]);
    let p_bb = Matrix2::new(e(bk, bk), e(bk, bb), e(bb, bk), e(bb, bb));
    let cov = &mut state.cov;
    let fpvb_fbt = f * p_vb * f_b.transpose();
    let mut new_vv = f * p_vv * f.transpose()
        + fpvb_fbt
        + fpvb_fbt.transpose()
        + f_b * p_bb * f_b.transpose()
        + q_v;
    new_vv = 0.5 * (new_vv + new_vv.transpose());
    cov.fixed_view_mut::<3, 3>(0, 0).copy_from(&new_vv);
    for j in POSE_DIM..n {
        let c = Vector3::new(cov[(j, 0)], cov[(j, 1)], cov[(j, 2)]);
        // P[j, b] from the lower triangle (the pose rows written here are not read).
        let fc =
            f * c + f_b * nalgebra::Vector2::new(lower_entry(cov, j, bk), lower_entry(cov, j, bb));
        for r in 0..POSE_DIM {
            cov[(j, r)] = fc[r];
            cov[(r, j)] = fc[r];
        }
    }
}

/// Predicts from the state's time to `to_s` with `input` held, in steps of at most
/// `settings.max_predict_step_s`. Checks the request before touching the state.
pub fn predict_to<M: ProcessModel + ?Sized>(
    state: &mut SlamState,
    model: &M,
    input: &OdometrySample,
    to_s: f64,
    settings: &FilterSettings,
) -> Result<(), FilterError> {
    if !to_s.is_finite() {
        return Err(FilterError::NonFiniteObservation {
            what: "timestamp_s",
            value: to_s,
        });
    }
    let from_s = state.time_s();
    let gap_s = to_s - from_s;
    if gap_s < 0.0 {
        return Err(FilterError::TimeWentBackwards {
            state_s: from_s,
            requested_s: to_s,
        });
    }
    if gap_s > settings.max_predict_gap_s {
        return Err(FilterError::GapTooLong {
            gap_s,
            limit_s: settings.max_predict_gap_s,
        });
    }
    if gap_s == 0.0 {
        return Ok(());
    }
    // gap_s / max_step is bounded by max_predict_gap_s / max_predict_step_s (validated).
    let steps = (gap_s / settings.max_predict_step_s).ceil().max(1.0);
    let dt = gap_s / steps;
    let mut done = 0.0;
    while done < steps {
        predict_step(state, model, input, dt, settings)?;
        done += 1.0;
    }
    state.set_time_s(to_s);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;
    use radar_model::geometry::Pose2;
    use radar_model::motion::MotionModel;

    /// Default settings, a 2.7 m wheelbase and 6 m/s with a slight steer.
    fn car_at_6_mps() -> (FilterSettings, MotionModel, OdometrySample) {
        (
            FilterSettings::default(),
            MotionModel::Bicycle { wheelbase_m: 2.7 },
            OdometrySample {
                timestamp_s: 0.0,
                speed_mps: 6.0,
                steer_rad: 0.05,
            },
        )
    }

    /// Under first-estimates Jacobians the propagation maps the rotation generator at the
    /// pose as last predicted, `(-y, x, 1)`, onto the one at the new prediction, whatever
    /// update moved the estimate in between: the unobservable direction is carried forward
    /// intact. A pose covariance that lies wholly along that direction stays along it.
    #[test]
    fn fej_propagation_carries_the_rotation_generator_forward() {
        let settings = FilterSettings {
            speed_std_mps: 1e-9,
            steer_std_rad: 1e-9,
            ..FilterSettings::default()
        };
        let last_predicted = Pose2::new(3.0, 1.0, 0.3);
        let n0 = Vector3::new(-last_predicted.y, last_predicted.x, 1.0);
        let mut state = SlamState::new(
            Pose2::new(3.2, 0.9, 0.31), // after an update moved it
            Matrix3::zeros(),
            0.0,
            1.0,
            0.0,
        )
        .unwrap();
        state.predicted_pose = last_predicted;
        let s2 = 1e-4;
        let outer = n0 * n0.transpose() * s2;
        for r in 0..3 {
            for c in 0..3 {
                state.cov[(r, c)] = outer[(r, c)];
            }
        }
        let model = MotionModel::Bicycle { wheelbase_m: 2.7 };
        let input = OdometrySample {
            timestamp_s: 0.0,
            speed_mps: 4.0,
            steer_rad: 0.2,
        };
        predict_step(&mut state, &model, &input, 0.05, &settings).unwrap();
        let p = state.pose();
        let n1 = Vector3::new(-p.y, p.x, 1.0);
        let expected = n1 * n1.transpose() * s2;
        let got = state.pose_covariance();
        assert!(
            (got - expected).abs().max() < 1e-9,
            "got {got}, expected {expected}"
        );
        assert_eq!(state.predicted_pose, p);
    }

    /// The per-beam update writes only the lower triangle. Everything after it (a
    /// prediction that moves the pose with the odometry corrections, another update, a new
    /// feature, a removal) reads the lower triangle or mirrors first, so a filter that lets
    /// the upper triangle go stale ends bit for bit where one that mirrors after every
    /// update does.
    #[test]
    fn a_stale_upper_triangle_changes_nothing_downstream() {
        use crate::state::{feature_index, FEATURE_BASE};
        use crate::update::{batched_update, LinearisedObservation};
        use nalgebra::{DMatrix, DVector, Matrix4};

        let features = 5;
        let n = FEATURE_BASE + 4 * features;
        let a = DMatrix::from_fn(n, n, |i, j| ((i * 31 + j * 17) as f64 * 0.37).sin() * 0.1);
        let cov = &a * a.transpose() + DMatrix::identity(n, n) * 0.05;
        let mut mean = DVector::from_fn(n, |i, _| (i as f64 * 0.7).cos() * 5.0);
        mean[SPEED_SCALE_INDEX] = 0.01;
        mean[STEER_BIAS_INDEX] = 0.002;
        let mut stale = SlamState::from_parts(mean, cov, 0.0).unwrap();
        let mut synced = stale.clone();
        let (settings, model, input) = car_at_6_mps();
        for step in 0..6 {
            let slot = step % features;
            let fi = feature_index(slot);
            let obs = LinearisedObservation {
                columns: vec![0, 1, 2, 3, fi, fi + 1, fi + 2],
                jacobian: DMatrix::from_fn(3, 7, |r, c| ((r * 7 + c + step) as f64).sin()),
                innovation: DVector::from_fn(3, |r, _| 0.01 * (r as f64 + 1.0)),
                noise: DMatrix::identity(3, 3) * 0.5,
            };
            batched_update(&mut stale, &obs).unwrap();
            batched_update(&mut synced, &obs).unwrap();
            assert!(stale.upper_stale);
            synced.sync_upper();
            predict_step(&mut stale, &model, &input, 0.01, &settings).unwrap();
            predict_step(&mut synced, &model, &input, 0.01, &settings).unwrap();
            if step == 3 {
                let cross = DMatrix::from_fn(4, stale.dim(), |r, c| {
                    synced.covariance_entry(c, r.min(2)) * 0.1
                });
                let block = Matrix4::identity();
                for s in [&mut stale, &mut synced] {
                    s.augment([1.0, 2.0, 0.0, 0.0], &cross, &block, 0.0, 100)
                        .unwrap();
                }
                assert!(!stale.upper_stale);
            }
            if step == 4 {
                let id = stale.tracks()[1].id;
                stale.remove(id).unwrap();
                synced.remove(id).unwrap();
            }
        }
        assert_eq!(stale.mean(), synced.mean());
        assert_eq!(*stale.covariance(), *synced.covariance());
        let full = stale.covariance();
        assert_eq!(*full, full.transpose());
        assert_eq!(stale.pose_covariance(), full.fixed_view::<3, 3>(0, 0));
        assert_eq!(
            stale.odometry_bias_covariance(),
            full.fixed_view::<2, 2>(SPEED_SCALE_INDEX, SPEED_SCALE_INDEX)
        );
    }

    /// The pose churn (`SlamState::pose_churn`) grows by what each prediction adds beyond
    /// carrying the pose along, and by the covariance of each update's correction: exactly
    /// the pose block's reduction.
    #[test]
    fn the_pose_churn_sums_the_input_noise_and_the_corrections() {
        use crate::update::{batched_update, LinearisedObservation};
        use nalgebra::{DMatrix, DVector};

        let (settings, model, input) = car_at_6_mps();
        let pose_cov = Matrix3::from_diagonal(&Vector3::new(0.5, 0.3, 0.01));
        let mut state = SlamState::new(Pose2::new(1.0, 2.0, 0.3), pose_cov, 0.0, 1.0, 0.0).unwrap();
        assert_eq!(*state.pose_churn(), Matrix3::zeros());
        // Without the corrections in the state: the input noise G Q G^T, whatever P is.
        let dt = 0.05;
        let step = model
            .step(&state.pose(), input.speed_mps, input.steer_rad, dt)
            .unwrap();
        let q = input_noise(&settings, dt);
        let expected = step.wrt_input * q * step.wrt_input.transpose();
        predict_step(&mut state, &model, &input, dt, &settings).unwrap();
        assert!((state.pose_churn() - expected).abs().max() < 1e-15);
        // An update adds its correction's covariance: P_vv before minus P_vv after.
        let before_churn = *state.pose_churn();
        let before = state.pose_covariance();
        let obs = LinearisedObservation {
            columns: vec![0, 1, 2],
            jacobian: DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 0.5, 0.0, 1.0, -2.0]),
            innovation: DVector::from_vec(vec![0.1, -0.2]),
            noise: DMatrix::identity(2, 2) * 0.2,
        };
        batched_update(&mut state, &obs).unwrap();
        let reduction = before - state.pose_covariance();
        let added = state.pose_churn() - before_churn;
        assert!(
            (added - reduction).abs().max() < 1e-12,
            "added {added}, reduction {reduction}"
        );
        assert!(added.symmetric_eigenvalues().min() > -1e-12);
    }

    /// A feature's positional wander follows the distance driven since it was last settled,
    /// `sigma^2 (1 - exp(-d / length))`, added once to its x and y variances and to nothing
    /// else; it saturates at `sigma^2` however far the vehicle drives, and a parked vehicle
    /// adds none.
    #[test]
    fn a_feature_wanders_with_the_distance_driven_not_with_time() {
        use nalgebra::{DMatrix, Matrix4};

        let (settings, model, input) = car_at_6_mps();
        let mut state = SlamState::new(
            Pose2::new(0.0, 0.0, 0.0),
            Matrix3::identity() * 0.01,
            0.0,
            1.0,
            0.0,
        )
        .unwrap();
        let cross = DMatrix::zeros(4, state.dim());
        state
            .augment(
                [10.0, 2.0, 0.0, 0.0],
                &cross,
                &(Matrix4::identity() * 0.04),
                0.0,
                10,
            )
            .unwrap();
        let (sigma, length) = (0.3, 2.0);
        let i = crate::state::FEATURE_BASE;
        let before = state.covariance()[(i, i)];
        // 0.5 s at 6 m/s: 3 m.
        predict_to(&mut state, &model, &input, 0.5, &settings).unwrap();
        assert!(
            (state.odometer_m - 3.0).abs() < 1e-9,
            "{}",
            state.odometer_m
        );
        let predicted = state.covariance().into_owned();
        // The prediction itself leaves the feature's block alone.
        assert_eq!(predicted[(i, i)], before);
        state.settle_wander(0, sigma, length);
        let after = state.covariance().into_owned();
        let added = &after - &predicted;
        let expected = sigma * sigma * (1.0 - (-3.0f64 / length).exp());
        assert!(
            (added[(i, i)] - expected).abs() < 1e-12,
            "{}",
            added[(i, i)]
        );
        assert!((added[(i + 1, i + 1)] - expected).abs() < 1e-12);
        assert_eq!(added.iter().filter(|v| v.abs() > 0.0).count(), 2, "{added}");
        // Settled: nothing more until the vehicle drives again; parked, nothing.
        state.settle_wander(0, sigma, length);
        assert_eq!(state.covariance()[(i, i)], after[(i, i)]);
        let parked = OdometrySample {
            speed_mps: 0.0,
            ..input
        };
        predict_to(&mut state, &model, &parked, 4.0, &settings).unwrap();
        state.settle_wander(0, sigma, length);
        assert_eq!(state.covariance()[(i, i)], after[(i, i)]);
        // A long drive unobserved adds at most sigma^2.
        predict_to(&mut state, &model, &input, 8.5, &settings).unwrap();
        state.settle_wander(0, sigma, length);
        let long = state.covariance()[(i, i)] - after[(i, i)];
        assert!(
            long < sigma * sigma && long > 0.99 * sigma * sigma,
            "{long}"
        );
    }
}
