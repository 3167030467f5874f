//! One predict and one update, checked against values worked by hand.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix4};
use radar_model::geometry::Pose2;
use radar_model::motion::MotionModel;
use slam_filter::observation::{state_columns, BeamObservationModel, RangeBearingModel};
use slam_filter::predict::{predict_to, OdometrySample};
use slam_filter::state::{feature_index, SlamState};
use slam_filter::{batched_update, FilterSettings, LinearisedObservation};

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn one_bicycle_prediction_matches_the_hand_computed_mean_and_covariance() {
    // Pose (0, 0, 0), P_vv = diag(0.01, 0.01, 0.001), L variance 100, no features.
    let mut state = SlamState::new(
        Pose2::new(0.0, 0.0, 0.0),
        Matrix3::from_diagonal(&nalgebra::Vector3::new(0.01, 0.01, 0.001)),
        0.0,
        100.0,
        0.0,
    )
    .unwrap();
    let settings = FilterSettings {
        speed_std_mps: 0.1,
        steer_std_rad: 0.1,
        input_noise_correlation_s: 1.0,
        max_predict_step_s: 1.0,
        material_variance_per_s: 0.0,
        ..FilterSettings::default()
    };
    let model = MotionModel::Bicycle { wheelbase_m: 2.0 };
    let input = OdometrySample {
        timestamp_s: 0.0,
        speed_mps: 1.0,
        steer_rad: 0.0,
    };
    predict_to(&mut state, &model, &input, 1.0, &settings).unwrap();
    // v = 1, dt = 1, steer = 0: dtheta = 0, phi = 0, so the pose moves to (1, 0, 0).
    let pose = state.pose();
    assert!(
        close(pose.x, 1.0, 1e-15) && close(pose.y, 0.0, 1e-15) && close(pose.theta, 0.0, 1e-15)
    );
    // F = [[1, 0, -v dt sin phi], [0, 1, v dt cos phi], [0, 0, 1]] = [[1,0,0],[0,1,1],[0,0,1]].
    // F P F^T = [[0.01, 0, 0], [0, 0.01 + 0.001, 0.001], [0, 0.001, 0.001]].
    // G (d/d[v, steer]): x row [dt cos phi, 0] = [1, 0];
    //   dtheta/dsteer = v dt sec^2(0) / wheelbase = 0.5, dtheta/dv = dt tan(0)/wb = 0;
    //   y row [0, v dt cos phi * 1/2 * 0.5] = [0, 0.25]; theta row [0, 0.5].
    // Q = diag(0.1^2, 0.1^2) * correlation (1 s) / dt (1 s) = diag(0.01, 0.01).
    // G Q G^T = 0.01 * [[1, 0, 0], [0, 0.0625, 0.125], [0, 0.125, 0.25]].
    // Sum: [[0.02, 0, 0], [0, 0.011625, 0.00225], [0, 0.00225, 0.0035]].
    let expected = Matrix3::new(0.02, 0.0, 0.0, 0.0, 0.011625, 0.00225, 0.0, 0.00225, 0.0035);
    let got = state.pose_covariance();
    for i in 0..3 {
        for j in 0..3 {
            assert!(
                close(got[(i, j)], expected[(i, j)], 1e-15),
                "P[{i},{j}] = {}",
                got[(i, j)]
            );
        }
    }
    // L is untouched and uncorrelated.
    let p = state.covariance();
    assert_eq!(p[(3, 3)], 100.0);
    assert_eq!((p[(0, 3)], p[(1, 3)], p[(2, 3)]), (0.0, 0.0, 0.0));
    assert_eq!(state.time_s(), 1.0);
}

#[test]
fn one_range_bearing_update_matches_the_hand_computed_kalman_update() {
    // Pose (0, 0, 0) with P_vv = diag(0.5, 0.5, 0.01); a feature at (10, 0) with position
    // variance 0.5 each, u, v variance 1, no correlations; L variance 100.
    let mut state = SlamState::new(
        Pose2::new(0.0, 0.0, 0.0),
        Matrix3::from_diagonal(&nalgebra::Vector3::new(0.5, 0.5, 0.01)),
        0.0,
        100.0,
        0.0,
    )
    .unwrap();
    let n = state.dim();
    let block = Matrix4::from_diagonal(&nalgebra::Vector4::new(0.5, 0.5, 1.0, 1.0));
    state
        .augment(
            [10.0, 0.0, 0.0, 0.0],
            &DMatrix::zeros(4, n),
            &block,
            0.0,
            10,
        )
        .unwrap();
    let params = [state.params(0).unwrap()];
    let pred = RangeBearingModel
        .predict_beam(&state.pose(), &params, state.loss_db())
        .unwrap();
    // h = [R, beta] = [10, 0].
    assert!(close(pred.z[0][0], 10.0, 1e-12) && close(pred.z[0][1], 0.0, 1e-12));
    // Observe R = 10.5, beta = 0 with sigma_R = 1, sigma_beta = 0.01 rad.
    // H_R = [-1, 0, 0 | 1, 0, 0, 0 | 0]; H_beta = [0, 1/10, 1 | 0, -1/10, 0, 0 | 0].
    // S = diag(0.5 + 0.5 + 1, 0.5/100 + 0.01 + 0.5/100 + 1e-4) = diag(2, 0.0201); S_Rb = 0.
    // nu = [0.5, 0]: NIS = 0.25 / 2 = 0.125.
    // K_R column = P H_R^T / 2: x_v: -0.5/2 = -0.25, x_f: 0.5/2 = 0.25.
    // Mean: x_v = -0.25 * 0.5 = -0.125, x_f = 10 + 0.125 = 10.125; y, theta unchanged.
    // P_xx = 0.5 - 0.5^2 / 2 = 0.375, P_(x, x_f) = 0 - (-0.5)(0.5)/2 = 0.125,
    // P_(x_f, x_f) = 0.375.
    let rows = [0usize, 1];
    let obs = LinearisedObservation {
        columns: state_columns(&[0]),
        jacobian: pred.jacobian.select_rows(rows.iter()),
        innovation: DVector::from_vec(vec![0.5, 0.0]),
        noise: DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 1e-4])),
    };
    let out = batched_update(&mut state, &obs).unwrap();
    assert_eq!(out.dof, 2);
    assert!(close(out.nis, 0.125, 1e-14), "NIS {}", out.nis);
    let x = state.mean();
    assert!(close(x[0], -0.125, 1e-14));
    assert!(close(x[1], 0.0, 1e-14) && close(x[2], 0.0, 1e-14));
    let f = feature_index(0);
    assert!(close(x[f], 10.125, 1e-14) && close(x[f + 1], 0.0, 1e-14));
    let p = state.covariance();
    assert!(close(p[(0, 0)], 0.375, 1e-14));
    assert!(close(p[(0, f)], 0.125, 1e-14) && p[(0, f)] == p[(f, 0)]);
    assert!(close(p[(f, f)], 0.375, 1e-14));
    // The bearing row: S_beta = 0.0201, P_theta,beta = 0.01: P_theta = 0.01 - 0.01^2/0.0201.
    assert!(close(p[(2, 2)], 0.01 - 1e-4 / 0.0201, 1e-14));
    // u, v and L are not observed by range-bearing: untouched.
    assert_eq!(
        (p[(f + 2, f + 2)], p[(f + 3, f + 3)], p[(3, 3)]),
        (1.0, 1.0, 100.0)
    );
}
