//! Every analytic Jacobian against central finite differences over random scenes
//! (relative tolerance 1e-6 with an absolute floor of 1e-6), and the material
//! parameterisation's invariants.

mod common;

use common::{assert_jacobians_agree, numeric_jacobian};
use nalgebra::DMatrix;
use proptest::prelude::*;
use radar_model::material::Material;
use radar_model::power::{beam_powers_db, beam_powers_with_jacobian, PowerModel, PowerTarget};
use radar_model::{
    observe_beam, range_bearing_with_jacobian, BeamFeature, BeamObservation, ControlInput,
    MotionModel, Pose2, SpreadingForm,
};

const REL: f64 = 1e-6;
const ABS: f64 = 1e-6;
const H: f64 = 1e-5;

fn form() -> impl Strategy<Value = SpreadingForm> {
    prop_oneof![Just(SpreadingForm::Paper), Just(SpreadingForm::Textbook)]
}

/// 1 to 8 targets, sorted, separated by at least 5 mm (so a finite-difference step never
/// swaps two of them), from 0.5 m to about 200 m.
fn sorted_targets() -> impl Strategy<Value = Vec<(f64, f64, f64)>> {
    prop::collection::vec((0.005f64..25.0, -8.0f64..8.0, -8.0f64..8.0), 1..=8).prop_map(|v| {
        let mut range = 0.5;
        v.into_iter()
            .map(|(gap, u, vv)| {
                range += gap;
                (range, u, vv)
            })
            .collect()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn range_and_bearing_jacobians_match_finite_differences(
        x in -500.0f64..500.0, y in -500.0f64..500.0, theta in -3.2f64..3.2,
        range in 0.5f64..300.0, dir in -3.2f64..3.2,
    ) {
        let pose = Pose2::new(x, y, theta);
        let f = [x + range * dir.cos(), y + range * dir.sin()];
        let (_, j) = range_bearing_with_jacobian(&pose, f).unwrap();
        let analytic = DMatrix::from_row_slice(2, 5, &[
            j.range_wrt_pose[0], j.range_wrt_pose[1], j.range_wrt_pose[2],
            j.range_wrt_feature[0], j.range_wrt_feature[1],
            j.bearing_wrt_pose[0], j.bearing_wrt_pose[1], j.bearing_wrt_pose[2],
            j.bearing_wrt_feature[0], j.bearing_wrt_feature[1],
        ]);
        let numeric = numeric_jacobian(|s| {
            let (rb, _) = range_bearing_with_jacobian(&Pose2::new(s[0], s[1], s[2]), [s[3], s[4]]).unwrap();
            vec![rb.range_m, rb.bearing_rad]
        }, &[x, y, theta, f[0], f[1]], H, &[1]);
        assert_jacobians_agree(&analytic, &numeric, REL, ABS).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn motion_jacobians_match_finite_differences(
        x in -1000.0f64..1000.0, y in -1000.0f64..1000.0, theta in -3.2f64..3.2,
        speed in -5.0f64..30.0, steer in -1.2f64..1.2, dt in 0.0f64..1.0,
        bicycle in any::<bool>(), param in 0.1f64..5.0,
    ) {
        let model = if bicycle {
            MotionModel::Bicycle { wheelbase_m: param }
        } else {
            MotionModel::Paper { step_s: param }
        };
        // Stay in the model's operating domain: at most one radian of turn per step (a
        // 0.1 m wheelbase at 26 m/s can turn 327 rad in one step, where central differences
        // themselves lose their accuracy). The steering is scaled down to get there.
        let steer = match model {
            MotionModel::Bicycle { wheelbase_m } => {
                let limit = wheelbase_m / (speed.abs() * dt).max(1e-9);
                steer.tan().clamp(-limit, limit).atan()
            }
            MotionModel::Paper { step_s } => steer.clamp(-step_s / dt.max(1e-9), step_s / dt.max(1e-9)),
        };
        let pose = Pose2::new(x, y, theta);
        let input = ControlInput::new(speed, steer);
        let (_, j) = model.predict_with_jacobian(&pose, &input, dt).unwrap();
        let mut analytic = DMatrix::zeros(3, 5);
        analytic.view_mut((0, 0), (3, 3)).copy_from(&j.wrt_pose);
        analytic.view_mut((0, 3), (3, 2)).copy_from(&j.wrt_input);
        let numeric = numeric_jacobian(|s| {
            let p = model
                .predict(&Pose2::new(s[0], s[1], s[2]), &ControlInput::new(s[3], s[4]), dt)
                .unwrap();
            vec![p.x, p.y, p.theta]
        }, &[x, y, theta, speed, steer], H, &[2]);
        assert_jacobians_agree(&analytic, &numeric, REL, ABS).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn power_jacobians_match_finite_differences(
        targets in sorted_targets(), form in form(), loss in -50.0f64..50.0,
    ) {
        let model = PowerModel { form, ..PowerModel::default() };
        let n = targets.len();
        let build = |s: &[f64]| -> Vec<PowerTarget> {
            (0..n).map(|i| PowerTarget {
                range_m: s[3 * i],
                material: Material::new(s[3 * i + 1], s[3 * i + 2]),
            }).collect()
        };
        let x: Vec<f64> = targets.iter().flat_map(|&(r, u, v)| [r, u, v]).collect();
        let bp = beam_powers_with_jacobian(&model, &build(&x), loss).unwrap();
        let mut analytic = DMatrix::zeros(n, 3 * n);
        for i in 0..n {
            for k in 0..n {
                analytic[(i, 3 * k)] = bp.wrt_range[(i, k)];
                analytic[(i, 3 * k + 1)] = bp.wrt_u[(i, k)];
                analytic[(i, 3 * k + 2)] = bp.wrt_v[(i, k)];
            }
        }
        let numeric = numeric_jacobian(|s| {
            let mut out = vec![0.0; n];
            beam_powers_db(&model, &build(s), loss, &mut out).unwrap();
            out
        }, &x, H, &[]);
        assert_jacobians_agree(&analytic, &numeric, REL, ABS).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn observe_beam_jacobian_matches_finite_differences(
        x in -100.0f64..100.0, y in -100.0f64..100.0, theta in -3.2f64..3.2,
        beam in -3.2f64..3.2, targets in sorted_targets(), form in form(),
        loss in -20.0f64..20.0, shuffle in any::<u64>(),
    ) {
        let model = PowerModel { form, ..PowerModel::default() };
        let pose = Pose2::new(x, y, theta);
        let n = targets.len();
        // Spread the features across the beam's width, and hand them over in a scrambled
        // order so the beam-local column order differs from the range order.
        let mut feats: Vec<BeamFeature> = targets.iter().enumerate().map(|(i, &(r, u, v))| {
            let offset = 0.015 * ((i as f64 * 0.7).sin());
            BeamFeature { xy: pose.point_at(r, beam + offset), material: Material::new(u, v) }
        }).collect();
        let rot = (shuffle % n as u64) as usize;
        feats.rotate_left(rot);
        if shuffle % 2 == 1 { feats.reverse(); }
        let mut state = vec![x, y, theta];
        for f in &feats {
            state.extend_from_slice(&[f.xy[0], f.xy[1], f.material.u, f.material.v]);
        }
        state.push(loss);
        let obs = observe_beam(&pose, &feats, loss, &model).unwrap();
        prop_assert_eq!(obs.jacobian.shape(), (3 * n, BeamObservation::loss_column(n) + 1));
        let angle_rows: Vec<usize> = (0..n).map(|i| 3 * i + 1).collect();
        let numeric = numeric_jacobian(|s| {
            let p = Pose2::new(s[0], s[1], s[2]);
            let fs: Vec<BeamFeature> = (0..n).map(|k| {
                let c = 3 + 4 * k;
                BeamFeature { xy: [s[c], s[c + 1]], material: Material::new(s[c + 2], s[c + 3]) }
            }).collect();
            let o = observe_beam(&p, &fs, s[3 + 4 * n], &model).unwrap();
            o.z.iter().flat_map(|z| z.as_array()).collect()
        }, &state, H, &angle_rows);
        assert_jacobians_agree(&obs.jacobian, &numeric, REL, ABS).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn material_shares_stay_valid_and_log_gradients_match(u in -700.0f64..700.0, v in -700.0f64..700.0) {
        let m = Material::new(u, v);
        let s = m.shares();
        for p in [s.rho, s.alpha, s.tau] {
            prop_assert!((0.0..=1.0).contains(&p));
        }
        prop_assert!((s.rho + s.alpha + s.tau - 1.0).abs() < 1e-12);
        let ls = m.log_shares();
        for l in [ls.ln_rho, ls.ln_alpha, ls.ln_tau] {
            prop_assert!(l.is_finite() && l <= 1e-15);
        }
        for g in [ls.d_ln_rho, ls.d_ln_alpha, ls.d_ln_tau] {
            prop_assert!(g[0].abs() <= 1.0 && g[1].abs() <= 1.0);
        }
        let analytic = DMatrix::from_row_slice(3, 2, &[
            ls.d_ln_rho[0], ls.d_ln_rho[1], ls.d_ln_alpha[0], ls.d_ln_alpha[1],
            ls.d_ln_tau[0], ls.d_ln_tau[1],
        ]);
        let numeric = numeric_jacobian(|p| {
            let l = Material::new(p[0], p[1]).log_shares();
            vec![l.ln_rho, l.ln_alpha, l.ln_tau]
        }, &[u, v], H, &[]);
        assert_jacobians_agree(&analytic, &numeric, REL, ABS).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn share_and_feature_initialisation_jacobians_match_finite_differences(
        u in -30.0f64..30.0, v in -30.0f64..30.0,
        x in -100.0f64..100.0, y in -100.0f64..100.0, theta in -3.2f64..3.2,
        range in 0.0f64..300.0, bearing in -3.2f64..3.2,
    ) {
        let js = Material::new(u, v).shares_jacobian();
        let analytic = DMatrix::from_row_slice(2, 2, &[js[0][0], js[0][1], js[1][0], js[1][1]]);
        let numeric = numeric_jacobian(|p| {
            let s = Material::new(p[0], p[1]).shares();
            vec![s.rho, s.alpha]
        }, &[u, v], H, &[]);
        assert_jacobians_agree(&analytic, &numeric, REL, ABS).map_err(TestCaseError::fail)?;

        let (_, jp) = Pose2::new(x, y, theta).point_at_with_jacobian(range, bearing);
        let analytic = DMatrix::from_row_slice(2, 5, &[jp[0], jp[1]].concat());
        let numeric = numeric_jacobian(|p| {
            Pose2::new(p[0], p[1], p[2]).point_at(p[3], p[4]).to_vec()
        }, &[x, y, theta, range, bearing], H, &[]);
        assert_jacobians_agree(&analytic, &numeric, REL, ABS).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn material_round_trips_through_user_shares(rho in 0.0f64..1.0, frac in 0.0f64..1.0) {
        let alpha = (1.0 - rho) * frac;
        let m = Material::from_rho_alpha(rho, alpha).unwrap();
        let s = m.shares();
        // Exact except where a share was clamped up to MIN_SHARE.
        prop_assert!((s.rho - rho).abs() < 1e-8, "rho {} vs {}", s.rho, rho);
        prop_assert!((s.alpha - alpha).abs() < 1e-8, "alpha {} vs {}", s.alpha, alpha);
    }
}
