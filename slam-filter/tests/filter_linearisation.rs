//! The filter's linearisation choices against what they are for.
//!
//! First-estimates Jacobians (FEJ): EKF-SLAM's observations are unchanged by a rotation of
//! the whole world (vehicle and map together) about the origin, so that direction must stay
//! unobservable. The standard EKF linearises each feature at its latest estimate, which
//! moves between updates, and the Jacobians of different times then disagree on that
//! direction: the filter gains information about the map's global heading that no
//! measurement carries, and becomes over-confident in it. With every feature linearised at
//! its first estimate, each beam's Jacobian (range, bearing and the multi-target power)
//! annihilates the same rotation generator, and the propagation maps it onto itself.
//!
//! Repeated looks: a stationary radar sees a feature from the same cell again and again, and
//! the errors that depend on the geometry repeat; the k-th look of such a run counts with
//! k times its noise variance.

use nalgebra::{DVector, Matrix2, Matrix3};
use radar_model::geometry::Pose2;
use radar_model::material::Material;
use radar_model::motion::MotionModel;
use radar_model::power::PowerModel;
use slam_filter::fej::relinearise_at_first_estimates;
use slam_filter::state::FeatureParams;
use slam_filter::{
    BeamObservation, BeamObservationModel, Ekf, FilterSettings, OdometrySample, RadarBeamModel,
    RangeBearingModel, Target,
};

fn feature(x: f64, y: f64, rho: f64, alpha: f64) -> FeatureParams {
    let m = Material::from_rho_alpha(rho, alpha).unwrap();
    FeatureParams {
        x_m: x,
        y_m: y,
        u: m.u,
        v: m.v,
    }
}

/// Three features down one beam (a fence, a tree behind it, a wall), seen from `pose`.
fn beam_features() -> Vec<FeatureParams> {
    vec![
        feature(8.0, 0.3, 0.2, 0.3),
        feature(14.0, 0.6, 0.4, 0.2),
        feature(25.0, 1.0, 0.7, 0.1),
    ]
}

fn xy(fs: &[FeatureParams]) -> Vec<[f64; 2]> {
    fs.iter().map(|f| [f.x_m, f.y_m]).collect()
}

/// The generator of a rotation of the whole world about the origin, in beam-column order
/// `[x, y, theta, (x, y, u, v) per feature, L]`, at the pose and feature positions given.
fn rotation_generator(pose: &Pose2, features: &[[f64; 2]]) -> DVector<f64> {
    let mut n = DVector::zeros(3 + 4 * features.len() + 1);
    n[0] = -pose.y;
    n[1] = pose.x;
    n[2] = 1.0;
    for (i, p) in features.iter().enumerate() {
        n[3 + 4 * i] = -p[1];
        n[3 + 4 * i + 1] = p[0];
    }
    n
}

fn translation_generator(features: usize, axis: usize) -> DVector<f64> {
    let mut n = DVector::zeros(3 + 4 * features + 1);
    n[axis] = 1.0;
    for i in 0..features {
        n[3 + 4 * i + axis] = 1.0;
    }
    n
}

fn radar() -> RadarBeamModel {
    RadarBeamModel {
        power: PowerModel::default(),
    }
}

#[test]
fn relinearising_at_the_current_estimates_changes_nothing() {
    // Also checks the premise of the power rows' rebuild: the multi-target power depends on
    // the pose and the positions only through the ranges.
    let pose = Pose2::new(1.0, -0.5, 0.05);
    let fs = beam_features();
    let pred = radar().predict_beam(&pose, &fs, 2.0).unwrap();
    let mut j = pred.jacobian.clone();
    relinearise_at_first_estimates(&mut j, &pose, &xy(&fs), &xy(&fs));
    let diff = (&j - &pred.jacobian).abs().max();
    let scale = pred.jacobian.abs().max();
    assert!(diff <= 1e-12 * scale, "changed by {diff} (scale {scale})");
}

#[test]
fn first_estimate_jacobians_keep_a_global_rotation_unobservable() {
    let first = beam_features();
    // Later: the vehicle has moved and every estimate has moved by a different amount.
    let pose = Pose2::new(2.0, 0.4, 0.08);
    let current: Vec<FeatureParams> = first
        .iter()
        .zip([[0.3, -0.4], [-0.2, 0.5], [0.6, 0.2]])
        .map(|(f, d)| FeatureParams {
            x_m: f.x_m + d[0],
            y_m: f.y_m + d[1],
            ..*f
        })
        .collect();
    let pred = radar().predict_beam(&pose, &current, 2.0).unwrap();
    let standard = pred.jacobian.clone();
    let mut fej = pred.jacobian.clone();
    relinearise_at_first_estimates(&mut fej, &pose, &xy(&current), &xy(&first));

    // The rotation generator as the filter's first estimates define it.
    let n = rotation_generator(&pose, &xy(&first));
    let fej_n = &fej * &n;
    assert!(
        fej_n.abs().max() < 1e-9,
        "FEJ Jacobian observes the global rotation: {fej_n}"
    );
    // The standard Jacobian, linearised at the moved estimates, does not annihilate it:
    // combined with the Jacobians of earlier beams it makes the rotation look observable.
    let std_n = &standard * &n;
    assert!(
        std_n.abs().max() > 1e-3,
        "expected the standard Jacobian to see the rotation: {std_n}"
    );
    // Translations are unobservable either way.
    for axis in 0..2 {
        let t = translation_generator(first.len(), axis);
        assert!((&fej * &t).abs().max() < 1e-9);
        assert!((&standard * &t).abs().max() < 1e-9);
    }
    // The u, v and L columns are untouched.
    for c in 0..standard.ncols() {
        let geometric = c < 3 || ((c - 3) % 4 < 2 && c < standard.ncols() - 1);
        if !geometric {
            let d: f64 = (standard.column(c) - fej.column(c)).abs().max();
            assert!(d == 0.0, "column {c} changed by {d}");
        }
    }
}

/// A range-bearing filter at the origin, exactly known, with repeat-look decorrelation on
/// (cells of one 0.25 m bin and one 1.8 deg beam) or off.
fn range_bearing_filter(repeat_look: bool) -> Ekf<MotionModel, RangeBearingModel> {
    let settings = FilterSettings {
        use_power: false,
        repeat_look_range_m: if repeat_look { 0.25 } else { 0.0 },
        repeat_look_bearing_rad: if repeat_look {
            1.8_f64.to_radians()
        } else {
            0.0
        },
        ..FilterSettings::default()
    };
    Ekf::new(
        settings,
        Pose2::new(0.0, 0.0, 0.0),
        Matrix3::zeros(),
        0.0,
        MotionModel::Bicycle { wheelbase_m: 2.7 },
        RangeBearingModel,
    )
    .unwrap()
}

/// One look at a target straight ahead at `range_m`, with the held odometry `speed_mps`.
fn look(
    ekf: &mut Ekf<MotionModel, RangeBearingModel>,
    t: f64,
    speed_mps: f64,
    range_m: f64,
    bearing_rad: f64,
) {
    ekf.apply_odometry(OdometrySample {
        timestamp_s: t,
        speed_mps,
        steer_rad: 0.0,
    })
    .unwrap();
    ekf.predict_to(t).unwrap();
    ekf.process_beam(&BeamObservation {
        timestamp_s: t,
        bearing_rad: 0.0,
        targets: vec![Target {
            range_m,
            bearing_rad,
            power_db: 60.0,
        }],
    })
    .unwrap();
}

/// The first feature's position covariance is the same with repeat-look decorrelation on and
/// off.
fn assert_setting_changes_nothing(run: impl Fn(bool) -> Matrix2<f64>) {
    let on = run(true);
    let off = run(false);
    assert!(
        (on - off).abs().max() <= 1e-12 * off.abs().max(),
        "on {on}, off {off}"
    );
}

/// A filter at the origin, still, seeing one feature straight ahead at 20 m in every
/// rotation: returns the feature's position variance along and across the line of sight
/// after `rotations` looks.
fn stationary_looks(rotations: usize, repeat_look: bool) -> (f64, f64) {
    let mut ekf = range_bearing_filter(repeat_look);
    let mut noise = [0.03, -0.02, 0.01, 0.04, -0.03, 0.0, 0.02, -0.01]
        .iter()
        .cycle();
    for k in 0..rotations + 1 {
        let e = noise.next().copied().unwrap_or(0.0);
        look(&mut ekf, 0.4 * k as f64, 0.0, 20.0 + e, 0.2 * e);
    }
    let f = ekf.features();
    assert_eq!(f.len(), 1, "one feature mapped");
    let c = f[0].position_cov;
    (c[(0, 0)], c[(1, 1)])
}

#[test]
fn repeated_looks_from_one_viewpoint_count_as_correlated() {
    let looks = 60;
    let (along_off, across_off) = stationary_looks(looks, false);
    let (along_on, across_on) = stationary_looks(looks, true);
    let (along_one, across_one) = stationary_looks(1, true);
    // Independent looks: variance ~ 1/k. Correlated: ~ 1/ln k. After 60 looks the ratio is
    // about 60 / (ln 60 + 0.58) = 12.8, less what the pose uncertainty adds to both.
    assert!(
        along_on > 5.0 * along_off && across_on > 5.0 * across_off,
        "on {along_on:.3e}/{across_on:.3e}, off {along_off:.3e}/{across_off:.3e}"
    );
    // Still, more looks never make the estimate worse.
    assert!(along_on < along_one && across_on < across_one);
}

#[test]
fn a_moving_viewpoint_starts_a_new_run_of_looks() {
    // The same feature seen from positions 1 m apart: every look is a fresh one, so the
    // setting changes nothing.
    let run = |repeat_look: bool| {
        let mut ekf = range_bearing_filter(repeat_look);
        for k in 0..12 {
            let t = 0.4 * k as f64;
            let x = ekf.pose().x + 2.5 * (t - ekf.state().time_s()).max(0.0);
            look(&mut ekf, t, 2.5, 40.0 - x, 0.0);
        }
        ekf.features()[0].position_cov
    };
    assert_setting_changes_nothing(run);
}

#[test]
fn looks_of_one_sweep_stay_independent() {
    // Neighbouring azimuths of one sweep (2 ms apart) see a target quantised differently:
    // with the setting on, they count as independent looks, as with it off.
    let run = |repeat_look: bool| {
        let mut ekf = range_bearing_filter(repeat_look);
        look(&mut ekf, 0.0, 0.0, 20.0, 0.0);
        look(&mut ekf, 0.4, 0.0, 20.02, 0.001);
        for (k, e) in [0.01, -0.02, 0.03, 0.0, -0.01].iter().enumerate() {
            look(&mut ekf, 0.8 + 0.002 * k as f64, 0.0, 20.0 + e, 0.1 * e);
        }
        ekf.features()[0].position_cov
    };
    assert_setting_changes_nothing(run);
}
