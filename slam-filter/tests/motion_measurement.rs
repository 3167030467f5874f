//! A measurement of the motion since a mark (radar odometry) observes the odometry
//! corrections: with no landmarks at all, odometry 5 % fast and steering 0.01 rad off are
//! learned from registrations alone, the pose follows, the covariance stays healthy, and
//! nothing changes when the corrections are not estimated or a measurement is absurd.

use nalgebra::Matrix3;
use radar_model::geometry::{wrap_angle, Pose2};
use radar_model::motion::MotionModel;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam_filter::{Ekf, FilterSettings, MotionOutcome, OdometrySample, RadarBeamModel};

mod registered_drive;
use registered_drive::{drive_registered, Filter, T0, WHEELBASE_M};

/// The measurement's standard deviations (m, rad), as radar odometry's defaults.
const SIGMA_XY: f64 = 0.05;
const SIGMA_THETA: f64 = 0.003;

fn filter(settings: FilterSettings) -> Filter {
    Ekf::new(
        settings,
        Pose2::new(0.0, 0.0, 0.0),
        Matrix3::from_diagonal_element(1e-8),
        T0,
        MotionModel::Bicycle {
            wheelbase_m: WHEELBASE_M,
        },
        RadarBeamModel::default(),
    )
    .unwrap()
}

/// `steps` odometry samples at 20 Hz from `odometry(i, rng)` = (the true speed and
/// steering, what the odometry reads), a registration of the true motion every 0.25 s when
/// `registrations` (with noise of the assumed size when `noisy`). Returns the filter and
/// the true pose at the end.
fn drive_with(
    settings: FilterSettings,
    steps: u32,
    registrations: bool,
    noisy: bool,
    seed: u64,
    odometry: impl FnMut(u32, &mut ChaCha8Rng) -> ((f64, f64), (f64, f64)),
) -> (Filter, Pose2) {
    let mut f = filter(settings);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nxy = Normal::new(0.0, SIGMA_XY).unwrap();
    let nth = Normal::new(0.0, SIGMA_THETA).unwrap();
    let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(
        SIGMA_XY * SIGMA_XY,
        SIGMA_XY * SIGMA_XY,
        SIGMA_THETA * SIGMA_THETA,
    ));
    let truth = drive_registered(&mut f, steps, &mut rng, odometry, |f, rel, rng| {
        if !registrations {
            return;
        }
        let measured = if noisy {
            Pose2::new(
                rel.x + nxy.sample(rng),
                rel.y + nxy.sample(rng),
                rel.theta + nth.sample(rng),
            )
        } else {
            rel
        };
        let outcome = f.observe_motion_since_mark(measured, &cov, 16.27).unwrap();
        assert!(
            matches!(outcome, MotionOutcome::Applied { .. }),
            "{outcome:?}"
        );
    });
    (f, truth)
}

/// 60 s at 8 m/s along a gentle S, odometry reading 5 % fast and steering 0.01 rad left of
/// the truth at 20 Hz, a registration of the true motion (with noise) every 0.25 s.
/// Returns the final position error and the filter.
fn drive(settings: FilterSettings, registrations: bool) -> (f64, Filter) {
    let (f, truth) = drive_with(settings, 1200, registrations, true, 7, |i, _| {
        let (speed, steer) = (8.0, 0.03 * (0.1 * f64::from(i) * 0.05).sin());
        ((speed, steer), (1.05 * speed, steer - 0.01))
    });
    let p = f.pose();
    ((p.x - truth.x).hypot(p.y - truth.y), f)
}

fn learning() -> FilterSettings {
    FilterSettings {
        speed_scale_std: 0.05,
        steer_bias_std_rad: 0.02,
        ..FilterSettings::default()
    }
}

fn assert_healthy(f: &Filter) {
    let h = f.covariance_health(true);
    assert!(h.all_finite && h.cholesky_ok, "{h:?}");
    assert_eq!(h.max_symmetry_error, 0.0);
}

#[test]
fn registrations_alone_learn_a_speed_scale_and_a_steering_offset() {
    let (with, f) = drive(learning(), true);
    let (without, _) = drive(learning(), false);
    let ([k, b], [sk, sb]) = f.odometry_bias().expect("estimated");
    let (k_true, b_true) = (1.0 / 1.05 - 1.0, 0.01);
    eprintln!(
        "final error {with:.3} m with registrations, {without:.3} m without; \
         k {k:.4} +- {sk:.4} (true {k_true:.4}), b {b:.4} +- {sb:.4} (true {b_true})"
    );
    assert_healthy(&f);
    assert!((k - k_true).abs() < 3.0 * sk && sk < 0.005, "k {k} +- {sk}");
    assert!((b - b_true).abs() < 3.0 * sb && sb < 0.002, "b {b} +- {sb}");
    assert_eq!(f.stats().motion_updates, 239);
    // Odometry 5 % fast over 480 m is 23 m off; the registrations leave a few metres of
    // the error made before k was learned.
    assert!(without > 20.0, "without registrations {without} m");
    assert!(with < 0.2 * without, "with registrations {with} m");
}

/// A steering offset learned from registrations, then forgotten (the caller found them
/// not independent of the prediction): its variance is its prior's again, its mean and the
/// rest of the state as they were, the covariance healthy; forgetting again changes
/// nothing, and a filter that does not estimate the offset is untouched.
#[test]
fn a_forgotten_steering_offset_has_its_prior_variance_and_keeps_its_mean() {
    let (_, mut f) = drive(learning(), true);
    let ([k, b], [sk, sb]) = f.odometry_bias().expect("estimated");
    assert!(sb < 0.002, "learned: {b} +- {sb}");
    let pose = f.pose();
    f.forget_steer_bias();
    let ([k2, b2], [sk2, sb2]) = f.odometry_bias().expect("estimated");
    assert_eq!((k2, b2, sk2), (k, b, sk));
    assert!((sb2 - learning().steer_bias_std_rad).abs() < 1e-12, "{sb2}");
    assert_eq!(f.pose(), pose);
    assert_healthy(&f);
    let before = f.state().covariance().into_owned();
    f.forget_steer_bias();
    assert_eq!(f.state().covariance().into_owned(), before);

    let mut plain = filter(FilterSettings::default());
    let before = plain.state().covariance().into_owned();
    plain.forget_steer_bias();
    assert_eq!(plain.state().covariance().into_owned(), before);
}

#[test]
fn without_a_mark_a_measurement_changes_nothing() {
    let mut f = filter(FilterSettings::default());
    let cov = Matrix3::from_diagonal_element(1e-3);
    let before = f.state().clone();
    assert_eq!(
        f.observe_motion_since_mark(Pose2::new(1.0, 0.0, 0.0), &cov, 16.27)
            .unwrap(),
        MotionOutcome::NoMark
    );
    assert_eq!(f.state().mean(), before.mean());
    assert_eq!(f.state().covariance(), before.covariance());
}

/// Noisy odometry (steering noise 0.05 rad at 20 Hz), no corrections estimated: the
/// measurement holds the pose's change itself, so the registrations keep the heading's
/// variance from growing with the drive and the estimate near the truth.
#[test]
fn without_estimated_corrections_a_measurement_holds_the_pose_change() {
    let run = |registrations: bool| {
        let settings = FilterSettings {
            steer_std_rad: 0.05,
            ..FilterSettings::default()
        };
        let steer_noise = Normal::new(0.0, 0.05).unwrap();
        let (f, truth) = drive_with(settings, 400, registrations, false, 11, |_, rng| {
            ((8.0, 0.0), (8.0, steer_noise.sample(rng)))
        });
        assert_healthy(&f);
        let p = f.pose();
        let sigma_theta = f.pose_covariance()[(2, 2)].sqrt();
        (
            wrap_angle(p.theta - truth.theta).abs(),
            sigma_theta,
            f.stats().motion_updates,
        )
    };
    let (err_with, sigma_with, updates) = run(true);
    let (err_without, sigma_without, none) = run(false);
    eprintln!(
        "heading error {err_with:.4} rad (sigma {sigma_with:.4}) with registrations, \
         {err_without:.4} (sigma {sigma_without:.4}) without"
    );
    assert_eq!((updates, none), (79, 0));
    // 80 registrations of sigma 0.003 rad: about 0.027 rad a random walk; the odometry's
    // steering noise alone grows the heading's sigma several times that.
    assert!(sigma_with < 0.04, "sigma with registrations {sigma_with}");
    assert!(
        sigma_without > 2.0 * sigma_with,
        "sigma without {sigma_without}"
    );
    assert!(
        err_with < 3.0 * sigma_with,
        "error {err_with} for sigma {sigma_with}"
    );
}

#[test]
fn an_absurd_or_non_finite_measurement_is_refused_and_changes_nothing() {
    let mut f = filter(learning());
    f.apply_odometry(OdometrySample {
        timestamp_s: T0,
        speed_mps: 8.0,
        steer_rad: 0.0,
    })
    .unwrap();
    assert!(f.pose_since_mark().is_none(), "no mark yet");
    f.mark_motion();
    f.predict_to(T0 + 0.25).unwrap();
    let before = f.state().clone();
    let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.0025, 0.0025, 9e-6));
    // 2 m forward was driven; 20 m is no registration of it.
    let outcome = f
        .observe_motion_since_mark(Pose2::new(20.0, 0.0, 0.0), &cov, 16.27)
        .unwrap();
    assert!(
        matches!(outcome, MotionOutcome::Gated { .. }),
        "{outcome:?}"
    );
    assert!(f
        .observe_motion_since_mark(Pose2::new(f64::NAN, 0.0, 0.0), &cov, 16.27)
        .is_err());
    assert_eq!(f.state().mean(), before.mean());
    assert_eq!(f.state().covariance(), before.covariance());
    // A plausible one is applied and leaves the covariance healthy.
    let outcome = f
        .observe_motion_since_mark(Pose2::new(1.95, 0.0, 0.0), &cov, 16.27)
        .unwrap();
    assert!(
        matches!(outcome, MotionOutcome::Applied { .. }),
        "{outcome:?}"
    );
    assert_healthy(&f);
}

/// Composed (radar odometry *is* the odometry): the pose becomes the mark composed with the
/// measurement whatever the prediction said, the mark does not move, and the pose's
/// covariance is the mark's carried through the composition plus the measurement's:
/// symmetric, positive definite, and its heading variance the sum of the two. A slowing
/// vehicle (the prediction 0.6 m long over the interval) moves nothing sideways.
#[test]
fn a_composed_motion_sets_the_pose_and_leaves_the_mark() {
    let mut f = filter(FilterSettings::default());
    f.apply_odometry(OdometrySample {
        timestamp_s: T0,
        speed_mps: 10.0,
        steer_rad: 0.0,
    })
    .unwrap();
    f.predict_to(T0 + 1.0).unwrap();
    f.mark_motion();
    let mark = f.state().clone_pose_mean();
    let mark_cov = f.state().pose_covariance();
    f.predict_to(T0 + 1.25).unwrap();
    // The vehicle slowed: it moved 1.9 m, not the 2.5 m predicted, and turned a little.
    let measured = Pose2::new(1.9, 0.02, 0.01);
    let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.0025, 0.0025, 9e-6));
    let outcome = f.compose_motion_since_mark(measured, &cov).unwrap();
    assert!(
        matches!(outcome, MotionOutcome::Applied { nis } if nis > 10.0),
        "{outcome:?}"
    );
    let pose = f.pose();
    let (s, c) = mark.theta.sin_cos();
    assert!((pose.x - (mark.x + c * 1.9 - s * 0.02)).abs() < 1e-12);
    assert!((pose.y - (mark.y + s * 1.9 + c * 0.02)).abs() < 1e-12);
    assert!((pose.theta - wrap_angle(mark.theta + 0.01)).abs() < 1e-12);
    // The motion the filter holds since the mark is the measurement composed.
    let held = f.pose_since_mark().expect("a mark");
    assert!(
        (held.x - 1.9).abs() < 1e-9 && (held.y - 0.02).abs() < 1e-9,
        "{held:?}"
    );
    assert!((held.theta - 0.01).abs() < 1e-12, "{held:?}");
    let after = f.state().clone_pose_mean();
    assert_eq!(after, mark, "the mark does not move");
    let p = f.state().pose_covariance();
    assert!((p - p.transpose()).abs().max() < 1e-15);
    assert!(p.cholesky().is_some(), "{p}");
    assert!((p[(2, 2)] - (mark_cov[(2, 2)] + 9e-6)).abs() < 1e-12, "{p}");
    // Bad input changes nothing.
    assert!(f
        .compose_motion_since_mark(Pose2::new(f64::NAN, 0.0, 0.0), &cov)
        .is_err());
    assert_eq!(f.pose(), pose);
}

/// A new submap starts at the vehicle; a mark set before is set again there (the motion
/// since the old one belongs to the old frame), so the motion from the switch on is
/// measured as before. Without a mark none is set.
#[test]
fn a_new_submap_keeps_a_mark_at_the_vehicle() {
    let mut f = filter(FilterSettings::default());
    f.apply_odometry(OdometrySample {
        timestamp_s: T0,
        speed_mps: 8.0,
        steer_rad: 0.0,
    })
    .unwrap();
    f.start_submap();
    assert!(f.motion_tally().is_none(), "no mark before, none after");
    f.mark_motion();
    f.predict_to(T0 + 0.25).unwrap();
    f.start_submap();
    let tally = f.motion_tally().expect("marked again");
    assert_eq!(tally.since_s, T0 + 0.25);
    let held = f.pose_since_mark().expect("a mark");
    assert!(held.x.abs() < 1e-12 && held.y.abs() < 1e-12 && held.theta.abs() < 1e-12);
    f.predict_to(T0 + 0.5).unwrap();
    let moved = f.pose_since_mark().expect("a mark");
    assert!((moved.x - 2.0).abs() < 1e-6, "{moved:?}");
}
