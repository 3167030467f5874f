//! The named hard cases every change must pass (docs/radar-model.md, section 6).

mod common;

use std::f64::consts::PI;

use nalgebra::Matrix3;
use radar_model::geometry::{range_bearing, wrap_angle, Pose2};
use radar_model::material::Material;
use radar_model::motion::{ControlInput, MotionModel};
use radar_model::noise::NoiseModel;
use radar_model::observation::{observe_beam, BeamFeature};
use radar_model::power::PowerModel;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::Distribution;
use slam_filter::{
    BeamObservation, Ekf, FilterError, FilterSettings, OdometrySample, RadarBeamModel, Target,
};

type Filter = Ekf<MotionModel, RadarBeamModel>;

const T0: f64 = 1_700_000_000.0;

fn settings() -> FilterSettings {
    let var = NoiseModel::default().observation_variances();
    FilterSettings {
        range_std_m: var[0].sqrt(),
        bearing_std_rad: var[1].sqrt(),
        power_std_db: var[2].sqrt(),
        ..FilterSettings::default()
    }
}

fn filter(s: FilterSettings, pose: Pose2, pose_var: [f64; 3]) -> Filter {
    let p0 = Matrix3::from_diagonal(&nalgebra::Vector3::new(
        pose_var[0],
        pose_var[1],
        pose_var[2],
    ));
    let mut f = Ekf::new(
        s,
        pose,
        p0,
        T0,
        MotionModel::Bicycle { wheelbase_m: 2.5 },
        RadarBeamModel::default(),
    )
    .unwrap();
    f.apply_odometry(OdometrySample {
        timestamp_s: T0,
        speed_mps: 0.0,
        steer_rad: 0.0,
    })
    .unwrap();
    f
}

/// Noise-free targets of `features` as seen from `truth` down the beam at `beam_rad`.
fn targets(truth: &Pose2, features: &[BeamFeature], loss_db: f64) -> Vec<Target> {
    let obs = observe_beam(truth, features, loss_db, &PowerModel::default()).unwrap();
    obs.z
        .iter()
        .map(|z| Target {
            range_m: z.range_m,
            bearing_rad: z.bearing_rad,
            power_db: z.power_db,
        })
        .collect()
}

fn noisy(
    truth: &Pose2,
    features: &[BeamFeature],
    loss_db: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Target> {
    let noise = NoiseModel::default();
    targets(truth, features, loss_db)
        .iter()
        .map(|t| {
            let z = noise.perturb_observation([t.range_m, t.bearing_rad, t.power_db], rng);
            Target {
                range_m: z[0],
                bearing_rad: z[1],
                power_db: z[2],
            }
        })
        .collect()
}

fn assert_healthy(f: &Filter) {
    let h = f.covariance_health(true);
    assert!(h.all_finite, "non-finite covariance");
    assert_eq!(
        h.max_symmetry_error, 0.0,
        "covariance not exactly symmetric"
    );
    assert!(h.cholesky_ok, "covariance not positive definite: {h:?}");
    // Scale-free definiteness (the plain eigenvalue's accuracy is ~eps * max variance).
    assert!(
        h.min_correlation_eigenvalue.is_some_and(|e| e > 0.0),
        "{h:?}"
    );
    let theta = f.pose().theta;
    assert!(theta > -PI && theta <= PI, "heading {theta} not wrapped");
    for feat in f.features() {
        assert!((0.0..=1.0).contains(&feat.rho) && (0.0..=1.0).contains(&feat.alpha));
        assert!(feat.rho + feat.alpha <= 1.0 + 1e-12);
    }
}

fn feature(x: f64, y: f64, rho: f64, alpha: f64) -> BeamFeature {
    BeamFeature {
        xy: [x, y],
        material: Material::from_rho_alpha(rho, alpha).unwrap(),
    }
}

#[test]
fn two_targets_at_equal_range_down_one_beam_are_both_used_without_their_power() {
    let truth = Pose2::new(0.0, 0.0, 0.0);
    let mut f = filter(settings(), truth, [1e-4, 1e-4, 1e-6]);
    // Two features 20 m ahead, 0.1 m apart across the beam: equal range, both inside it.
    let pair = [
        feature(20.0, 0.05, 0.3, 0.1),
        feature(20.0, -0.05, 0.3, 0.1),
    ];
    let z = targets(&truth, &pair, 0.0);
    assert!((z[0].range_m - z[1].range_m).abs() < 1e-9);
    let a = f.initialise_feature(&z[0], 0.0, T0).unwrap();
    let b = f.initialise_feature(&z[1], 0.0, T0).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for k in 1..=50 {
        let report = f
            .process_beam(&BeamObservation {
                timestamp_s: T0 + 0.25 * k as f64,
                bearing_rad: 0.0,
                targets: noisy(&truth, &pair, 0.0, &mut rng),
            })
            .unwrap();
        assert_eq!(report.candidates.len(), 2);
        // Unresolvable: only range and bearing of each (2 + 2 rows) when both are used.
        if let Some(u) = report.update {
            assert!(u.dof % 2 == 0 && u.dof <= 4, "dof {}", u.dof);
            assert!(u.nis.is_finite());
        }
        assert!(
            report.initialised.is_empty(),
            "no duplicate from an equal-range pair"
        );
    }
    assert_healthy(&f);
    assert_eq!(f.feature_count(), 2);
    assert!(f.feature(a).is_some() && f.feature(b).is_some());
}

#[test]
fn rho_plus_alpha_near_one_keeps_shares_in_range_and_the_covariance_sound() {
    let truth = Pose2::new(0.0, 0.0, 0.0);
    // The 400 looks here are drawn independently, and the point is the numerics once the
    // estimates are precise: count them as independent (no repeat-look inflation, which
    // would rightly keep a parked radar's estimates loose).
    let s = FilterSettings {
        repeat_look_range_m: 0.0,
        ..settings()
    };
    let mut f = filter(s, truth, [1e-4, 1e-4, 1e-6]);
    // A nearly opaque feature (tau = 1e-6) in front of a bright one, both in the beam.
    let scene = [
        feature(10.0, 0.0, 0.7, 0.299_999),
        feature(25.0, 0.0, 0.8, 0.1),
    ];
    let z = targets(&truth, &scene, 0.0);
    // The one behind is 120 dB down (20 log10 tau twice over): still handled in dB.
    assert!(z[1].power_db < z[0].power_db - 100.0, "{z:?}");
    f.initialise_feature(&z[0], 0.0, T0).unwrap();
    f.initialise_feature(&z[1], 0.0, T0).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for k in 1..=400 {
        f.process_beam(&BeamObservation {
            timestamp_s: T0 + 0.25 * k as f64,
            bearing_rad: 0.0,
            targets: noisy(&truth, &scene, 0.0, &mut rng),
        })
        .unwrap();
    }
    assert_healthy(&f);
    // rho, alpha and L are not separately observable from two powers (10 log rho - L trades
    // off, and tau_1 only shows through rho_2 tau_1^2): what must hold is that the shares stay
    // valid, the covariance sound, and the predictions fit what is measured.
    let mut est = f.features();
    est.sort_by(|a, b| a.x_m.total_cmp(&b.x_m));
    assert_eq!(est.len(), 2);
    println!(
        "front: rho {:.3e} alpha {:.6}, tau {:.3e} (true 0.7, 0.299999, 1e-6); behind: rho {:.3e} \
         alpha {:.3} (true 0.8, 0.1); L {:.2} dB (true 0); ids {:?} {:?}",
        est[0].rho,
        est[0].alpha,
        1.0 - est[0].rho - est[0].alpha,
        est[1].rho,
        est[1].alpha,
        f.state().loss_db(),
        est[0].id,
        est[1].id
    );
    let report = f
        .process_beam(&BeamObservation {
            timestamp_s: T0 + 0.25 * 401.0,
            bearing_rad: 0.0,
            targets: targets(&truth, &scene, 0.0),
        })
        .unwrap();
    let u = report.update.unwrap();
    assert_eq!(u.dof, 6, "both powers used");
    assert!(
        u.nis < 16.81,
        "noise-free observation NIS {} beyond the 99% gate of 6 dof",
        u.nis
    );
}

#[test]
fn a_feature_at_the_vehicles_position_neither_panics_nor_poisons_the_state() {
    // The vehicle drives straight through a mapped feature while the radar sweeps.
    let s = FilterSettings {
        max_predict_step_s: 0.01,
        ..settings()
    };
    let mut truth = Pose2::new(0.0, 0.0, 0.0);
    let mut f = filter(s.clone(), truth, [1e-4, 1e-4, 1e-6]);
    let scene = [feature(5.0, 0.0, 0.4, 0.1), feature(12.0, -20.0, 0.4, 0.1)];
    for lm in &scene {
        let rb = range_bearing(&truth, lm.xy);
        let z = targets(&truth, std::slice::from_ref(lm), 0.0);
        f.initialise_feature(&z[0], rb.bearing_rad, T0).unwrap();
    }
    let input = ControlInput::new(1.0, 0.0);
    f.apply_odometry(OdometrySample {
        timestamp_s: T0,
        speed_mps: 1.0,
        steer_rad: 0.0,
    })
    .unwrap();
    let motion = MotionModel::Bicycle { wheelbase_m: 2.5 };
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let dt = 0.25 / 200.0;
    let mut min_range = f64::INFINITY;
    for k in 1..=8000usize {
        truth = motion.predict(&truth, &input, dt).unwrap();
        let beam = wrap_angle((k % 200) as f64 * 2.0 * PI / 200.0);
        let seen: Vec<BeamFeature> = scene
            .iter()
            .filter(|lm| {
                let rb = range_bearing(&truth, lm.xy);
                rb.range_m > 0.5 && wrap_angle(rb.bearing_rad - beam).abs() <= 0.9_f64.to_radians()
            })
            .copied()
            .collect();
        min_range = min_range.min(range_bearing(&truth, scene[0].xy).range_m);
        let tg = if seen.is_empty() {
            Vec::new()
        } else {
            noisy(&truth, &seen, 0.0, &mut rng)
        };
        f.process_beam(&BeamObservation {
            timestamp_s: T0 + dt * k as f64,
            bearing_rad: beam,
            targets: tg,
        })
        .unwrap();
        assert!(f.state().mean().iter().all(|v| v.is_finite()), "step {k}");
    }
    println!(
        "closest approach {min_range} m; features {}",
        f.feature_count()
    );
    assert!(min_range < 0.01, "the vehicle must pass over the feature");
    assert_eq!(
        f.feature_count(),
        2,
        "the feature survives being driven over"
    );
    assert_healthy(&f);
    // Placing a feature on top of the radar is refused with a typed error.
    let at_vehicle = Target {
        range_m: 0.0,
        bearing_rad: 0.0,
        power_db: -10.0,
    };
    assert!(matches!(
        f.initialise_feature(&at_vehicle, 0.0, T0 + 10.0),
        Err(FilterError::TargetTooClose { .. })
    ));
}

#[test]
fn heading_across_plus_minus_pi_stays_wrapped_and_tracks_the_truth() {
    let s = FilterSettings {
        max_predict_step_s: 0.01,
        ..settings()
    };
    let mut truth = Pose2::new(0.0, 0.0, PI - 0.05);
    let mut f = filter(s, truth, [1e-4, 1e-4, 1e-6]);
    let motion = MotionModel::Bicycle { wheelbase_m: 2.5 };
    // Turning left at 0.1 rad/s: heading goes from pi - 0.05 through pi to about -pi + 0.15.
    let input = ControlInput::new(1.0, (0.1_f64 * 2.5).atan());
    f.apply_odometry(OdometrySample {
        timestamp_s: T0,
        speed_mps: input.speed_mps,
        steer_rad: input.steer_rad,
    })
    .unwrap();
    // One feature behind the vehicle (bearing near +/- pi) and one ahead-left.
    let scene = [feature(30.0, 1.0, 0.4, 0.1), feature(-30.0, 8.0, 0.4, 0.1)];
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let dt = 0.05;
    let mut crossed = false;
    for k in 1..=80 {
        truth = motion.predict(&truth, &input, dt).unwrap();
        let t = T0 + dt * k as f64;
        for lm in &scene {
            let rb = range_bearing(&truth, lm.xy);
            f.process_beam(&BeamObservation {
                timestamp_s: t,
                bearing_rad: rb.bearing_rad,
                targets: noisy(&truth, std::slice::from_ref(lm), 0.0, &mut rng),
            })
            .unwrap();
        }
        let est = f.pose().theta;
        assert!(est > -PI && est <= PI);
        let err = wrap_angle(est - truth.theta);
        assert!(err.abs() < 0.02, "heading error {err} at step {k}");
        crossed |= truth.theta < 0.0;
    }
    assert!(crossed, "the run must cross +/- pi");
    assert_eq!(f.feature_count(), 2, "no duplicates from a wrapped bearing");
    assert_healthy(&f);
}

#[test]
fn a_stationary_vehicle_re_observing_one_feature_100000_times_keeps_its_heading_variance() {
    let truth = Pose2::new(0.0, 0.0, 0.3);
    let s = FilterSettings {
        material_variance_per_s: 1e-6,
        ..settings()
    };
    let p_theta0 = 1e-4;
    let mut f = filter(s, truth, [1e-3, 1e-3, p_theta0]);
    let lm = [feature(12.0, 7.0, 0.5, 0.2)];
    let rb = range_bearing(&truth, lm[0].xy);
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    for k in 1..=100_000u32 {
        f.process_beam(&BeamObservation {
            timestamp_s: T0 + 0.00125 * f64::from(k),
            bearing_rad: rb.bearing_rad,
            targets: noisy(&truth, &lm, 0.0, &mut rng),
        })
        .unwrap();
    }
    // Relative observations carry no information on the absolute heading; a stationary
    // vehicle gets no heading process noise. A consistent filter keeps P_theta at its prior.
    let p_theta = f.pose_covariance()[(2, 2)];
    println!(
        "heading variance after 1e5 updates: {p_theta:e} (prior {p_theta0:e}), ratio {}",
        p_theta / p_theta0
    );
    assert!(
        p_theta > 0.5 * p_theta0,
        "heading variance collapsed to {p_theta:e}"
    );
    assert_eq!(f.feature_count(), 1);
    assert_healthy(&f);
}

#[test]
fn variances_from_1e_minus_12_to_1e6_in_one_covariance_stay_positive_definite() {
    let s = FilterSettings {
        initial_loss_std_db: 1e3,
        initial_material_std: 1e3,
        ..settings()
    };
    let truth = Pose2::new(0.0, 0.0, 0.0);
    let mut f = filter(s, truth, [1e-12, 1e-12, 1e-12]);
    let scene = [feature(15.0, 5.0, 0.4, 0.2), feature(-10.0, 20.0, 0.4, 0.2)];
    for lm in &scene {
        let rb = range_bearing(&truth, lm.xy);
        let z = targets(&truth, std::slice::from_ref(lm), 0.0);
        f.initialise_feature(&z[0], rb.bearing_rad, T0).unwrap();
    }
    let d = f.state().covariance().diagonal();
    let (lo, hi) = (d.min(), d.max());
    println!("variances span {lo:e} .. {hi:e}");
    assert!(
        lo <= 1e-11 && hi >= 1e5,
        "the case must span the range: {lo:e} .. {hi:e}"
    );
    assert_healthy(&f);
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    for k in 1..=100 {
        for lm in &scene {
            let rb = range_bearing(&truth, lm.xy);
            f.process_beam(&BeamObservation {
                timestamp_s: T0 + 0.25 * k as f64,
                bearing_rad: rb.bearing_rad,
                targets: noisy(&truth, std::slice::from_ref(lm), 0.0, &mut rng),
            })
            .unwrap();
        }
    }
    assert_healthy(&f);
}

#[test]
fn nan_and_infinite_observations_are_rejected_before_touching_the_state() {
    let truth = Pose2::new(1.0, 2.0, 0.5);
    let mut f = filter(settings(), truth, [1e-2, 1e-2, 1e-3]);
    let lm = [feature(20.0, 10.0, 0.4, 0.2)];
    let rb = range_bearing(&truth, lm[0].xy);
    let good = targets(&truth, &lm, 0.0)[0];
    f.initialise_feature(&good, rb.bearing_rad, T0).unwrap();
    let mean = f.state().mean().clone();
    let cov = f.state().covariance().into_owned();
    let time = f.state().time_s();
    let bad_targets = [
        Target {
            range_m: f64::NAN,
            ..good
        },
        Target {
            bearing_rad: f64::INFINITY,
            ..good
        },
        Target {
            power_db: f64::NEG_INFINITY,
            ..good
        },
        Target {
            power_db: f64::NAN,
            ..good
        },
    ];
    for bad in bad_targets {
        let beam = BeamObservation {
            timestamp_s: T0 + 1.0,
            bearing_rad: rb.bearing_rad,
            targets: vec![good, bad],
        };
        assert!(matches!(
            f.process_beam(&beam),
            Err(FilterError::NonFiniteObservation { .. })
        ));
        assert!(matches!(
            f.initialise_feature(&bad, rb.bearing_rad, T0),
            Err(FilterError::NonFiniteObservation { .. })
        ));
    }
    for (ts, bearing) in [(f64::NAN, 0.0), (f64::INFINITY, 0.0), (T0 + 1.0, f64::NAN)] {
        let beam = BeamObservation {
            timestamp_s: ts,
            bearing_rad: bearing,
            targets: vec![good],
        };
        assert!(matches!(
            f.process_beam(&beam),
            Err(FilterError::NonFiniteObservation { .. })
        ));
    }
    assert!(matches!(
        f.apply_odometry(OdometrySample {
            timestamp_s: T0 + 1.0,
            speed_mps: f64::NAN,
            steer_rad: 0.0
        }),
        Err(FilterError::NonFiniteOdometry { .. })
    ));
    // A flood of targets is refused too.
    let flood = BeamObservation {
        timestamp_s: T0 + 1.0,
        bearing_rad: rb.bearing_rad,
        targets: vec![good; 10_000],
    };
    assert!(matches!(
        f.process_beam(&flood),
        Err(FilterError::TooManyTargets { .. })
    ));
    // Bit for bit unchanged.
    assert_eq!(f.state().mean(), &mean);
    assert_eq!(*f.state().covariance(), cov);
    assert_eq!(f.state().time_s(), time);
    assert_eq!(f.stats().updates, 0);
}

#[test]
fn predicting_backwards_or_across_a_huge_gap_is_a_typed_error() {
    let mut f = filter(settings(), Pose2::default(), [1e-2, 1e-2, 1e-3]);
    f.predict_to(T0 + 1.0).unwrap();
    assert!(matches!(
        f.predict_to(T0 + 0.5),
        Err(FilterError::TimeWentBackwards { .. })
    ));
    assert!(matches!(
        f.predict_to(T0 + 1e6),
        Err(FilterError::GapTooLong { .. })
    ));
}

#[test]
fn a_vehicle_started_exactly_known_and_parked_keeps_updating() {
    // The configuration's default: the map frame is the start pose, with zero covariance.
    // Parked, with wheel odometry reporting exactly zero, y and heading gain no variance;
    // the updates must leave those zero rows alone rather than refuse (an earlier check
    // treated the untouched zero variance as a lost definiteness and failed every beam).
    let truth = Pose2::new(0.0, 0.0, 0.0);
    let mut f = filter(settings(), truth, [0.0, 0.0, 0.0]);
    let scene = [feature(12.0, 0.0, 0.5, 0.2), feature(30.0, 0.0, 0.7, 0.1)];
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for k in 0..40 {
        let t = T0 + 0.25 * k as f64;
        f.apply_odometry(OdometrySample {
            timestamp_s: t,
            speed_mps: 0.0,
            steer_rad: 0.0,
        })
        .unwrap();
        f.process_beam(&BeamObservation {
            timestamp_s: t,
            bearing_rad: 0.0,
            targets: noisy(&truth, &scene, 0.0, &mut rng),
        })
        .unwrap();
    }
    assert_eq!(f.feature_count(), 2);
    assert_healthy_or_exactly_known(&f);
}

/// Symmetric, no negative variance, and positive definite on the elements that are not
/// exactly known.
fn assert_healthy_or_exactly_known(f: &Filter) {
    let p = f.state().covariance();
    assert_eq!(*p, p.transpose());
    let known: Vec<usize> = (0..p.nrows()).filter(|&i| p[(i, i)] == 0.0).collect();
    assert!(known.iter().all(|&i| p.row(i).iter().all(|&v| v == 0.0)));
    let free: Vec<usize> = (0..p.nrows()).filter(|i| !known.contains(i)).collect();
    let sub = p.select_rows(free.iter()).select_columns(free.iter());
    assert!(sub.cholesky().is_some(), "not positive definite");
}

#[test]
fn an_odometry_gap_past_the_limit_is_bridged_not_refused_forever() {
    let mut f = filter(settings(), Pose2::default(), [1e-2, 1e-2, 1e-3]);
    let odo = |t: f64| OdometrySample {
        timestamp_s: t,
        speed_mps: 1.0,
        steer_rad: 0.0,
    };
    f.apply_odometry(odo(T0)).unwrap();
    f.apply_odometry(odo(T0 + 0.1)).unwrap();
    // A map to relocalise against exists (without one, a gap re-anchors the map frame
    // instead: below).
    map_three_posts(&mut f, T0 + 0.1);
    let before = f.pose_covariance();
    // The bridge is silent for 60 s, then odometry returns.
    f.apply_odometry(odo(T0 + 60.1)).unwrap();
    assert_eq!(f.stats().bridged_gaps, 1);
    assert_eq!(f.stats().reanchored_gaps, 0);
    assert_eq!(f.state().time_s(), T0 + 60.1);
    let after = f.pose_covariance();
    assert!(
        after[(0, 0)] > before[(0, 0)] + 100.0,
        "x variance {}",
        after[(0, 0)]
    );
    assert!(after[(2, 2)] > before[(2, 2)], "heading variance");
    // And the filter goes on: the next samples predict normally.
    f.apply_odometry(odo(T0 + 60.2)).unwrap();
    f.predict_to(T0 + 60.3).unwrap();
    assert_eq!(f.stats().bridged_gaps, 1);
}

/// Issue 38, item 10: odometry that went back in time for 10 s before the map existed was
/// bridged by growing the pose covariance (20 m, 120 degrees), which no measurement can take
/// back once features are mapped from it. With no feature mapped the map frame is only the
/// pose: a gap or a clock resynchronisation re-anchors it at the estimate instead; so it
/// does with one or two features, too few to relocalise against (they are dropped).
#[test]
fn a_gap_or_clock_jump_before_any_feature_is_mapped_re_anchors_the_map_frame() {
    let mut f = filter(settings(), Pose2::default(), [1e-4, 1e-4, 1e-6]);
    let still = |t: f64| OdometrySample {
        timestamp_s: t,
        speed_mps: 0.0,
        steer_rad: 0.0,
    };
    f.apply_odometry(still(T0 + 0.1)).unwrap();
    let before = f.pose_covariance();
    f.apply_odometry(still(T0 + 10.1)).unwrap();
    f.resync_clock(T0 - 100.0).unwrap();
    f.apply_odometry(still(T0 - 99.9)).unwrap();
    let stats = f.stats();
    assert_eq!((stats.bridged_gaps, stats.reanchored_gaps), (2, 2));
    assert_eq!(f.pose_covariance(), before, "the pose covariance grew");
    assert_eq!(f.state().time_s(), T0 - 99.9);
    // Two features, too few to relocalise against: dropped, and the frame re-anchored.
    for xy in [[20.0, 5.0], [-8.0, 12.0]] {
        let z = targets(&Pose2::default(), &[feature(xy[0], xy[1], 0.5, 0.2)], 0.0);
        f.initialise_feature(&z[0], z[0].bearing_rad, T0 - 99.9)
            .unwrap();
    }
    let retired = f.stats().retired;
    f.apply_odometry(still(T0 - 90.0)).unwrap();
    assert_eq!((f.stats().bridged_gaps, f.stats().reanchored_gaps), (3, 3));
    assert_eq!((f.feature_count(), f.stats().retired), (0, retired + 2));
    assert_eq!(f.pose_covariance(), before, "the pose covariance grew");
    // With a map to relocalise against, a gap grows the pose covariance again.
    map_three_posts(&mut f, T0 - 90.0);
    f.apply_odometry(still(T0 - 80.0)).unwrap();
    assert_eq!((f.stats().bridged_gaps, f.stats().reanchored_gaps), (4, 3));
    assert_eq!(f.feature_count(), 3);
    assert!(f.pose_covariance()[(0, 0)] > before[(0, 0)] + 100.0);
    assert_healthy(&f);
}

/// Maps three posts seen from the origin at `t` (enough to relocalise against).
fn map_three_posts(f: &mut Filter, t: f64) {
    for xy in [[20.0, 5.0], [-8.0, 12.0], [6.0, -14.0]] {
        let z = targets(&Pose2::default(), &[feature(xy[0], xy[1], 0.5, 0.2)], 0.0);
        f.initialise_feature(&z[0], z[0].bearing_rad, t).unwrap();
    }
}

/// The beam at `xy`'s bearing from `truth`, with its one target where `xy` is, noise-free.
fn single_target_beam(truth: &Pose2, xy: [f64; 2], t: f64) -> BeamObservation {
    let power = PowerModel::default();
    let z = observe_beam(truth, &[feature(xy[0], xy[1], 0.5, 0.2)], 0.0, &power).unwrap();
    BeamObservation {
        timestamp_s: t,
        bearing_rad: z.z[0].bearing_rad,
        targets: vec![Target {
            range_m: z.z[0].range_m,
            bearing_rad: z.z[0].bearing_rad,
            power_db: z.z[0].power_db,
        }],
    }
}

/// One look of a parked radar at `t`: odometry standing still, then a beam for each point
/// of `seen` (the first at `t`, the others 0.1 s later).
fn parked_look(f: &mut Filter, truth: &Pose2, t: f64, seen: &[[f64; 2]]) {
    f.apply_odometry(OdometrySample {
        timestamp_s: t,
        speed_mps: 0.0,
        steer_rad: 0.0,
    })
    .unwrap();
    for (i, &xy) in seen.iter().enumerate() {
        let at = if i == 0 { t } else { t + 0.1 };
        f.process_beam(&single_target_beam(truth, xy, at)).unwrap();
    }
}

#[test]
fn phantoms_in_directions_that_stay_empty_are_retired_and_the_seen_feature_kept() {
    let s = FilterSettings {
        retire_unseen_after_s: 2.0,
        max_range_m: 100.0,
        ..settings()
    };
    let truth = Pose2::new(0.0, 0.0, 0.0);
    let mut f = filter(s, truth, [1e-4, 1e-4, 1e-6]);
    let post = [12.0, 3.0];
    let phantom = [-9.0, 7.0];
    // A burst: the phantom is seen for a second, the post all along.
    for k in 0..40 {
        let t = T0 + 0.25 * f64::from(k);
        let seen: &[[f64; 2]] = if k < 4 { &[post, phantom] } else { &[post] };
        parked_look(&mut f, &truth, t, seen);
        f.retire_unseen().unwrap();
    }
    let left: Vec<[f64; 2]> = f.features().iter().map(|e| [e.x_m, e.y_m]).collect();
    assert_eq!(left.len(), 1, "features left: {left:?}");
    assert!((left[0][0] - post[0]).abs() < 0.5 && (left[0][1] - post[1]).abs() < 0.5);
    assert_eq!(f.stats().retired, 1);
}

/// A post seen every rotation and a flicker (clutter that comes back once after it is
/// mapped, then no more): with `retire_unrepeatable_below` 0.5 the flicker is retired once
/// it has been in view for `repeatability_min_rotations`, not before, and the post is kept;
/// with it off both stay, and the rotation scores are the same either way until then.
#[test]
fn a_feature_re_observed_in_too_few_rotations_in_view_is_retired() {
    let run = |below: f64| {
        let s = FilterSettings {
            max_range_m: 100.0,
            retire_unrepeatable_below: below,
            repeatability_min_rotations: 8,
            ..settings()
        };
        let truth = Pose2::new(0.0, 0.0, 0.0);
        let mut f = filter(s, truth, [1e-4, 1e-4, 1e-6]);
        let (post, flicker) = ([12.0, 3.0], [-9.0, 7.0]);
        let mut scores = Vec::new();
        for k in 0..30 {
            let t = T0 + 0.25 * f64::from(k);
            let seen: &[[f64; 2]] = if k < 3 || k == 5 {
                &[post, flicker]
            } else {
                &[post]
            };
            parked_look(&mut f, &truth, t, seen);
            scores.push(f.score_rotation(t, |_, _| true).unwrap());
        }
        (f, scores)
    };
    let (on, on_scores) = run(0.5);
    let (off, off_scores) = run(0.0);
    // Off: both mapped features stay, and nothing is retired.
    assert_eq!(off.features().len(), 2);
    assert_eq!(off.stats().retired_unrepeatable, 0);
    // On: the flicker goes, the post stays.
    let left: Vec<[f64; 2]> = on.features().iter().map(|e| [e.x_m, e.y_m]).collect();
    assert_eq!(left.len(), 1, "features left: {left:?}");
    assert!((left[0][0] - 12.0).abs() < 0.5 && (left[0][1] - 3.0).abs() < 0.5);
    assert_eq!(on.stats().retired_unrepeatable, 1);
    assert_eq!(on.stats().retired, 1);
    // Retired exactly once, at the first rotation it had been in view for 8 of, and the
    // counts agree with the run that keeps it until then.
    let when = on_scores
        .iter()
        .position(|s| !s.retired.is_empty())
        .expect("retired");
    assert_eq!(on_scores[..when], off_scores[..when]);
    let flicker_in_view = on_scores[..=when].iter().filter(|s| s.in_view == 2).count();
    assert_eq!(flicker_in_view, 8);
    assert!(on_scores[when + 1..].iter().all(|s| s.retired.is_empty()));
    // The post was re-observed in every rotation it was in view.
    let last = on_scores.last().unwrap();
    assert_eq!((last.in_view, last.reobserved), (1, 1));
}

/// A row of six posts 5 m apart and three pillars elsewhere.
fn map_of_posts() -> Vec<BeamFeature> {
    let mut map: Vec<BeamFeature> = (0..6)
        .map(|k| feature(-12.0 + 5.0 * f64::from(k), 9.0, 0.6, 0.2))
        .collect();
    map.push(feature(14.0, -6.0, 0.6, 0.2));
    map.push(feature(-7.0, -15.0, 0.6, 0.2));
    map.push(feature(3.0, -22.0, 0.6, 0.2));
    map
}

/// A parked radar mapping [`map_of_posts`] (a row of evenly spaced posts and a few others) with
/// exactly known odometry, clutter in one beam in `clutter_every`; after `gap_at_rotation`
/// rotations the odometry stops for 6 s (past the 5 s limit) while the vehicle stays put,
/// then returns. Returns the largest distance of the pose estimate from the truth after
/// the gap, and the filter.
fn parked_across_a_gap(s: FilterSettings, clutter_every: usize) -> (f64, Filter) {
    let truth = Pose2::new(0.0, 0.0, 0.0);
    let map = map_of_posts();
    let mut f = filter(s, truth, [1e-4, 1e-4, 1e-6]);
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let azimuths = 200usize;
    let rotation_s = 0.4;
    let step = 2.0 * PI / azimuths as f64;
    let half = f.settings().beam_half_width_rad;
    let mut next_odometry = T0;
    let gap = (T0 + 8.0, T0 + 14.0);
    let mut worst_after_gap = 0.0f64;
    let mut clutter = 0usize;
    for rotation in 0..60usize {
        for k in 0..azimuths {
            let t = T0 + rotation as f64 * rotation_s + k as f64 * rotation_s / azimuths as f64;
            while next_odometry <= t {
                if !(next_odometry > gap.0 && next_odometry < gap.1) {
                    f.apply_odometry(OdometrySample {
                        timestamp_s: next_odometry,
                        speed_mps: 0.0,
                        steer_rad: 0.0,
                    })
                    .unwrap();
                }
                next_odometry += 0.05;
            }
            if f.held_odometry().is_some_and(|o| t - o.timestamp_s > 0.5) {
                continue; // The daemon refuses beams while the odometry is stale.
            }
            let bearing = wrap_angle(k as f64 * step);
            let in_beam = common::in_beam(&truth, &map, bearing, half, f64::INFINITY);
            let mut seen = noisy(&truth, &in_beam, 0.0, &mut rng);
            clutter += 1;
            if clutter.is_multiple_of(clutter_every) {
                use rand::Rng;
                seen.push(Target {
                    range_m: rng.gen_range(3.0..30.0),
                    bearing_rad: bearing + rng.gen_range(-half..half),
                    power_db: seen.first().map_or(-60.0, |t| t.power_db),
                });
            }
            seen.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
            let beam = BeamObservation {
                timestamp_s: t,
                bearing_rad: bearing,
                targets: seen,
            };
            f.process_beam(&beam).unwrap();
            if t > gap.1 {
                let p = f.pose();
                worst_after_gap = worst_after_gap.max(p.x.hypot(p.y));
            }
        }
        f.retire_unseen().unwrap();
    }
    assert_eq!(f.stats().bridged_gaps, 1);
    (worst_after_gap, f)
}

#[test]
fn after_an_odometry_gap_a_parked_vehicle_relocalises_where_it_is_not_onto_other_features() {
    let (worst, f) = parked_across_a_gap(settings(), 7);
    println!(
        "relocalising: worst {worst:.2} m, stats {:?}, pose {:?}, cov {:?}",
        f.stats(),
        f.pose(),
        f.pose_covariance().diagonal()
    );
    assert_eq!(f.stats().relocalisations, 1);
    assert!(worst < 0.5, "the pose went {worst:.2} m off after the gap");
    assert!(f.pose_covariance()[(0, 0)].sqrt() < 0.5);
    // The map was kept: every post and pillar is still there (clutter in one beam in seven
    // also leaves phantoms, which is not this test's subject).
    for m in map_of_posts() {
        let nearest = f
            .features()
            .iter()
            .map(|e| (e.x_m - m.xy[0]).hypot(e.y_m - m.xy[1]))
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 0.5, "{:?} mapped {nearest:.2} m away", m.xy);
    }
    assert_healthy(&f);
}

#[test]
fn without_relocalising_one_beam_at_a_time_the_same_gap_sends_the_pose_off() {
    // The failure the relocalisation fixes: under the bridged covariance (12 m, 69
    // degrees), each beam's nearest neighbour pairs targets with whichever feature's wide
    // gate they fall in.
    let s = FilterSettings {
        relocalise_after_gap: false,
        ..settings()
    };
    let (worst, f) = parked_across_a_gap(s, 7);
    println!(
        "beam by beam: worst {worst:.2} m, stats {:?}, pose {:?}",
        f.stats(),
        f.pose()
    );
    assert!(worst > 2.0, "worst {worst:.2} m");
}

/// Four posts seen by a parked radar, 500 beams a second; from 5 s to 6 s every beam also
/// holds 12 targets at random ranges (a receiver's noise burst); a fifth post appears at
/// 10 s. The map may hold `max_features`. Returns the most features the map held, the
/// posts, and the filter at 16 s.
fn a_second_of_noise(burst_factor: f64, max_features: usize) -> (usize, Vec<BeamFeature>, Filter) {
    let (most, _, posts, f) = a_burst_of_noise(1.0, burst_factor, max_features);
    (most, posts, f)
}

/// As [`a_second_of_noise`] with a burst of `burst_s` from 5 s (the fifth post appears
/// 4 s after the burst, the run ends 10 s after it); also returns the fewest features the
/// map held during the burst.
fn a_burst_of_noise(
    burst_s: f64,
    burst_factor: f64,
    max_features: usize,
) -> (usize, usize, Vec<BeamFeature>, Filter) {
    let s = FilterSettings {
        max_features,
        retire_unseen_after_s: 4.0,
        burst_factor,
        ..settings()
    };
    let truth = Pose2::new(0.0, 0.0, 0.0);
    let mut posts = vec![
        feature(10.0, 5.0, 0.6, 0.2),
        feature(-8.0, 12.0, 0.6, 0.2),
        feature(20.0, -15.0, 0.6, 0.2),
        feature(-12.0, -9.0, 0.6, 0.2),
    ];
    let mut f = filter(s, truth, [1e-4, 1e-4, 1e-6]);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let azimuths = 200usize;
    let rotation_s = 0.4;
    let step = 2.0 * PI / azimuths as f64;
    let half = f.settings().beam_half_width_rad;
    let mut next_odometry = T0;
    let mut most = 0usize;
    let mut fewest = usize::MAX;
    let rotations = ((15.0 + burst_s) / rotation_s).round() as usize;
    let new_post = ((9.0 + burst_s) / rotation_s).round() as usize;
    for rotation in 0..rotations {
        if rotation == new_post {
            // A new post appears after the burst: it must still be mapped.
            posts.push(feature(6.0, -14.0, 0.6, 0.2));
        }
        for k in 0..azimuths {
            let t = T0 + rotation as f64 * rotation_s + k as f64 * rotation_s / azimuths as f64;
            while next_odometry <= t {
                f.apply_odometry(OdometrySample {
                    timestamp_s: next_odometry,
                    speed_mps: 0.0,
                    steer_rad: 0.0,
                })
                .unwrap();
                next_odometry += 0.05;
            }
            let bearing = wrap_angle(k as f64 * step);
            let in_beam = common::in_beam(&truth, &posts, bearing, half, f64::INFINITY);
            let mut seen = noisy(&truth, &in_beam, 0.0, &mut rng);
            let in_burst = (5.0..5.0 + burst_s).contains(&(t - T0));
            if in_burst {
                use rand::Rng;
                for _ in 0..12 {
                    seen.push(Target {
                        range_m: rng.gen_range(2.0..60.0),
                        bearing_rad: bearing + rng.gen_range(-half..half),
                        power_db: rng.gen_range(-80.0..-40.0),
                    });
                }
            }
            seen.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
            f.process_beam(&BeamObservation {
                timestamp_s: t,
                bearing_rad: bearing,
                targets: seen,
            })
            .unwrap();
            most = most.max(f.feature_count());
            if in_burst {
                fewest = fewest.min(f.feature_count());
            }
        }
        f.retire_unseen().unwrap();
    }
    (most, fewest, posts, f)
}

#[test]
fn a_second_of_noise_does_not_flood_the_map_and_mapping_resumes_after_it() {
    let (most, posts, f) = a_second_of_noise(FilterSettings::default().burst_factor, 1000);
    println!(
        "most features {most}, at the end {}, stats {:?}",
        f.feature_count(),
        f.stats()
    );
    assert!(f.stats().burst_beams > 0);
    assert!(most <= 8, "the burst grew the map to {most} features");
    for m in &posts {
        let nearest = f
            .features()
            .iter()
            .map(|e| (e.x_m - m.xy[0]).hypot(e.y_m - m.xy[1]))
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 0.5, "{:?} mapped {nearest:.2} m away", m.xy);
    }
    assert!(f.feature_count() <= 6, "{} features", f.feature_count());
}

/// Issue 38, item 11: a burst longer than a few seconds became its own norm (the guard
/// learned every burst target), and from then on the noise started features (the map
/// filled to its limit), re-observed the posts from inside their gates (the heading went)
/// and missed them until they were retired. Now the norm learns at most the threshold's rate
/// from a burst, and a burst's beams are not used at all.
#[test]
fn six_seconds_of_noise_neither_flood_the_map_nor_cost_it_its_posts_nor_turn_the_vehicle() {
    let (most, fewest, posts, f) =
        a_burst_of_noise(6.0, FilterSettings::default().burst_factor, 300);
    println!(
        "6 s of noise: most features {most}, fewest during it {fewest}, at the end {}, pose {:?}, stats {:?}",
        f.feature_count(),
        f.pose(),
        f.stats()
    );
    assert!(most <= 8, "the burst grew the map to {most} features");
    assert!(
        fewest >= 4,
        "the posts were retired during the burst: {fewest} left"
    );
    let pose = f.pose();
    assert!(pose.theta.abs() < 0.5_f64.to_radians(), "heading {pose:?}");
    assert!(pose.x.hypot(pose.y) < 0.1, "{pose:?}");
    for m in &posts {
        let nearest = f
            .features()
            .iter()
            .map(|e| (e.x_m - m.xy[0]).hypot(e.y_m - m.xy[1]))
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 0.5, "{:?} mapped {nearest:.2} m away", m.xy);
    }
}

#[test]
fn without_the_burst_guard_the_same_second_of_noise_floods_the_map() {
    // (A limit of 300 keeps the test quick; with 1000 the map reached 1000.)
    let (most, _, f) = a_second_of_noise(f64::INFINITY, 300);
    println!(
        "without the guard: most features {most}, stats {:?}",
        f.stats()
    );
    assert_eq!(most, 300, "the map stopped at {most} features");
}

/// Drives 100 m past posts on both sides of a road with gentle bends, the odometry reading
/// the speed 5 % fast and the steering 0.01 rad off (a mis-calibrated wheel and steering
/// sensor), and returns the final position error and the filter.
fn drive_with_biased_odometry(s: FilterSettings) -> (f64, Filter) {
    const AZ: usize = 100;
    const ROTATION_S: f64 = 0.25;
    let step = std::f64::consts::TAU / AZ as f64;
    let s = FilterSettings {
        beam_half_width_rad: 0.5 * step,
        ..s
    };
    let mut f = filter(s, Pose2::new(0.0, 0.0, 0.0), [0.0; 3]);
    let motion = MotionModel::Bicycle { wheelbase_m: 2.5 };
    let posts: Vec<BeamFeature> = (0..24)
        .flat_map(|i| {
            let x = -10.0 + 6.0 * f64::from(i);
            let wiggle = 1.5 * (0.7 * f64::from(i)).sin();
            [
                feature(x, 8.0 + wiggle, 0.7, 0.1),
                feature(x + 3.0, -9.0 + wiggle, 0.6, 0.1),
            ]
        })
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut truth = Pose2::new(0.0, 0.0, 0.0);
    let dt = ROTATION_S / AZ as f64;
    let mut t = T0;
    let speed = 5.0;
    for rotation in 0..80 {
        let steer = 0.02 * (0.15 * f64::from(rotation)).sin();
        for a in 0..AZ {
            t += dt;
            truth = motion
                .predict(&truth, &ControlInput::new(speed, steer), dt)
                .unwrap();
            if a % 12 == 0 {
                let n: f64 = rand_distr::StandardNormal.sample(&mut rng);
                f.apply_odometry(OdometrySample {
                    timestamp_s: t,
                    speed_mps: 1.05 * speed + 0.02 * n,
                    steer_rad: steer - 0.01,
                })
                .unwrap();
            }
            let beam = wrap_angle(a as f64 * step);
            let in_beam = common::in_beam_by_range(&truth, &posts, beam, 0.5 * step, 40.0);
            let targets = if in_beam.is_empty() {
                Vec::new()
            } else {
                noisy(&truth, &in_beam, 0.0, &mut rng)
            };
            f.process_beam(&BeamObservation {
                timestamp_s: t,
                bearing_rad: beam,
                targets,
            })
            .unwrap();
        }
    }
    let p = f.pose();
    ((p.x - truth.x).hypot(p.y - truth.y), f)
}

#[test]
fn odometry_five_percent_fast_and_steering_off_is_learned_and_the_pose_stays_on_the_road() {
    let learn = FilterSettings {
        speed_scale_std: 0.1,
        steer_bias_std_rad: 0.02,
        ..settings()
    };
    let (with, f) = drive_with_biased_odometry(learn);
    let (without, g) = drive_with_biased_odometry(settings());
    assert!(g.odometry_bias().is_none());
    let ([k, b], [sk, sb]) = f.odometry_bias().expect("estimated");
    // The model's speed is reading * (1 + k): the truth is k = 1/1.05 - 1, b = +0.01.
    let (k_true, b_true) = (1.0 / 1.05 - 1.0, 0.01);
    eprintln!(
        "final error {with:.3} m with the corrections, {without:.3} m without; \
         k {k:.4} +- {sk:.4} (true {k_true:.4}), b {b:.4} +- {sb:.4} (true {b_true})"
    );
    assert_healthy(&f);
    assert!(
        (k - k_true).abs() < 0.01 && (k - k_true).abs() < 4.0 * sk,
        "k {k}"
    );
    assert!(
        (b - b_true).abs() < 0.004 && (b - b_true).abs() < 4.0 * sb,
        "b {b}"
    );
    assert!(with < 0.5, "final error {with} m");
    assert!(without > 2.0 * with, "without the corrections {without} m");
}

/// With the speed scale held out of the landmarks' updates (`speed_scale_from_landmarks`
/// off) and no motion measurement, the same drive leaves `k` exactly at its prior while the
/// steering offset is still learned from the landmarks, and the covariance stays healthy
/// (the Schmidt-Kalman update keeps it that of the estimator's actual error).
#[test]
fn a_speed_scale_held_from_the_landmarks_stays_at_its_prior_and_the_filter_stays_healthy() {
    let held = FilterSettings {
        speed_scale_std: 0.1,
        steer_bias_std_rad: 0.02,
        speed_scale_from_landmarks: false,
        ..settings()
    };
    let (error, f) = drive_with_biased_odometry(held);
    let ([k, b], [sk, sb]) = f.odometry_bias().expect("estimated");
    eprintln!("final error {error:.3} m; k {k:.4} +- {sk:.4}, b {b:.4} +- {sb:.4}");
    assert_healthy(&f);
    assert_eq!(k, 0.0, "no landmark update moves k");
    assert!(sk >= 0.1, "nor shrinks its variance: {sk}");
    assert!(
        (b - 0.01).abs() < 0.004 && (b - 0.01).abs() < 4.0 * sb,
        "b {b}"
    );
}

/// The same for the steering offset (`steer_bias_from_landmarks` off, as slam-node runs a
/// gyro's bias): no landmark update moves `b` or shrinks its variance, `k` is still learned,
/// and the covariance stays healthy.
#[test]
fn a_steering_offset_held_from_the_landmarks_stays_at_its_prior_and_the_filter_stays_healthy() {
    let held = FilterSettings {
        speed_scale_std: 0.1,
        steer_bias_std_rad: 0.02,
        steer_bias_from_landmarks: false,
        ..settings()
    };
    let (error, f) = drive_with_biased_odometry(held);
    let ([k, b], [sk, sb]) = f.odometry_bias().expect("estimated");
    eprintln!("final error {error:.3} m; k {k:.4} +- {sk:.4}, b {b:.4} +- {sb:.4}");
    assert_healthy(&f);
    assert_eq!(b, 0.0, "no landmark update moves b");
    assert!(sb >= 0.02, "nor shrinks its variance: {sb}");
    let k_true = 1.0 / 1.05 - 1.0;
    assert!((k - k_true).abs() < 4.0 * sk, "k {k} +- {sk}");
}
