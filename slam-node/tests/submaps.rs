//! The filter on submaps, through the daemon's pipeline: with limits never reached it is
//! today's dense filter to 1e-9; with a small limit it closes submaps and the published
//! world pose stays where the dense filter's is, and the odometry (the filter's pose chained
//! by the switch poses alone) goes on across every switch without a jump.

mod support;

use radar_model::motion::MotionModel;
use sim_sensor::schedule::{ControlKey, ControlSchedule, Interpolation};
use slam_filter::{OdometrySample, SubmapLimits};
use slam_node::output::{OutputEvent, PoseSample};
use slam_node::pipeline::settings::SubmapOptions;
use slam_node::pipeline::Pipeline;
use support::{add_point, empty_scene, SimRadar};

const T0_NS: u64 = 1_700_000_000_000_000_000;
const T0: f64 = 1.7e9;
const SPEED: f64 = 2.0;
const STEER: f64 = 0.03;

/// A short drive (2 m/s on a gentle curve) past 24 posts, on the paper's unit.
fn drive(rotations: u64) -> Vec<radar_driver::Azimuth> {
    let mut scene = empty_scene("submap-drive", sim_sensor::radar::RadarPreset::Paper200, 11);
    for k in 0..24 {
        let a = k as f64 * 0.7;
        let r = 12.0 + 3.0 * (k % 5) as f64;
        add_point(&mut scene, 15.0 + r * a.cos(), r * a.sin(), 0.5, 0.3);
    }
    scene.schedule = ControlSchedule::new(
        vec![ControlKey {
            t_s: 0.0,
            speed_mps: SPEED,
            steer_rad: STEER,
        }],
        Interpolation::Hold,
    )
    .expect("a valid schedule");
    let mut radar = SimRadar::new(&scene, None, rotations as f64 / 2.5 + 1.0, T0_NS);
    (0..rotations * radar.azimuths())
        .map(|k| radar.azimuth(k))
        .collect()
}

fn run(
    submaps: Option<SubmapOptions>,
    azimuths: &[radar_driver::Azimuth],
) -> (Pipeline, Vec<PoseSample>) {
    let (p, poses, _) = run_with_odometry(submaps, azimuths);
    (p, poses)
}

/// [`run`], with the odometry's poses (`OutputEvent::OdometryPose`).
fn run_with_odometry(
    submaps: Option<SubmapOptions>,
    azimuths: &[radar_driver::Azimuth],
) -> (Pipeline, Vec<PoseSample>, Vec<PoseSample>) {
    let mut s = support::still_radar_settings();
    s.motion = MotionModel::Bicycle { wheelbase_m: 2.7 };
    s.submaps = submaps;
    let mut p = Pipeline::new(s, Some(T0), None).expect("a pipeline");
    let mut events = Vec::new();
    let mut next = T0;
    for az in azimuths {
        while next <= az.timestamp_s + 0.05 {
            p.push_odometry(OdometrySample {
                timestamp_s: next,
                speed_mps: SPEED,
                steer_rad: STEER,
            });
            next += 0.05;
        }
        p.process_azimuth(az, &mut events).expect("processed");
    }
    p.finish(&mut events);
    let (mut poses, mut odometry) = (Vec::new(), Vec::new());
    for e in events {
        match e {
            OutputEvent::Pose(p) => poses.push(p),
            OutputEvent::OdometryPose(p) => odometry.push(p),
            _ => {}
        }
    }
    (p, poses, odometry)
}

fn options(limits: SubmapLimits) -> SubmapOptions {
    SubmapOptions {
        limits,
        global: slam_graph::GlobalSettings::default(),
        scan_max_turn_rad: None,
        wait_for_joins: false,
    }
}

#[test]
fn submaps_that_never_fill_give_the_dense_filter_to_1e_9() {
    let azimuths = drive(30);
    let (dense, dense_poses) = run(None, &azimuths);
    let (sub, sub_poses) = run(Some(options(SubmapLimits::UNBOUNDED)), &azimuths);
    assert!(
        dense.ekf().feature_count() >= 10,
        "the drive maps the posts"
    );
    assert_eq!(sub.submaps().map(|s| s.current()), Some(0));
    let (a, b) = (dense.ekf().state(), sub.ekf().state());
    assert_eq!(a.dim(), b.dim());
    let dm = (a.mean() - b.mean()).abs().max();
    let dc = (&*a.covariance() - &*b.covariance()).abs().max();
    assert!(
        dm <= 1e-9 && dc <= 1e-9,
        "mean differs by {dm}, covariance by {dc}"
    );
    assert_eq!(dense_poses.len(), sub_poses.len());
    for (p, q) in dense_poses.iter().zip(&sub_poses) {
        assert!((p.x_m - q.x_m).abs() <= 1e-9 && (p.y_m - q.y_m).abs() <= 1e-9);
        assert!((p.theta_rad - q.theta_rad).abs() <= 1e-9);
    }
}

#[test]
fn small_submaps_close_and_the_world_pose_stays_with_the_dense_one() {
    let azimuths = drive(40);
    let (dense, _) = run(None, &azimuths);
    let limits = SubmapLimits {
        max_distance_m: 8.0,
        max_features: 1000,
    };
    let (sub, _) = run(Some(options(limits)), &azimuths);
    let s = sub.submaps().expect("submaps on");
    assert!(
        s.current() >= 2,
        "16 m of driving closes submaps of 8 m: {}",
        s.current()
    );
    let (pd, _) = dense.world_pose();
    let (ps, cs) = sub.world_pose();
    let d = (pd.x - ps.x).hypot(pd.y - ps.y);
    assert!(d < 0.5, "world poses {d:.3} m apart");
    // The world covariance carries the frames' uncertainty: positive definite.
    assert!(cs.cholesky().is_some());
}

#[test]
fn the_odometry_goes_on_across_every_submap_switch() {
    let azimuths = drive(40);
    let (dense, dense_poses, dense_odometry) = run_with_odometry(None, &azimuths);
    assert!(
        dense_odometry.is_empty(),
        "no submaps, no separate odometry"
    );
    let limits = SubmapLimits {
        max_distance_m: 4.0,
        max_features: 1000,
    };
    let (sub, poses, odometry) = run_with_odometry(Some(options(limits)), &azimuths);
    assert!(sub.submaps().expect("submaps on").current() >= 3);
    assert_eq!(
        odometry.len(),
        poses.len(),
        "an odometry pose with each pose"
    );
    for (o, p) in odometry.iter().zip(&poses) {
        assert_eq!(o.timestamp_s, p.timestamp_s);
    }
    // At 2 m/s no step between poses is a jump.
    for w in odometry.windows(2) {
        let step = (w[1].x_m - w[0].x_m).hypot(w[1].y_m - w[0].y_m);
        let dt = w[1].timestamp_s - w[0].timestamp_s;
        let turn = (w[1].theta_rad - w[0].theta_rad).abs();
        assert!(
            step < 1.25 * SPEED * dt + 0.05 && turn < 0.1,
            "a step of {step} m in {dt} s, {turn} rad"
        );
    }
    // It ends where the dense filter does (the same motion, the same posts).
    let (a, b) = (dense_poses.last().unwrap(), odometry.last().unwrap());
    let d = (a.x_m - b.x_m).hypot(a.y_m - b.y_m);
    assert!(d < 0.5, "{d} m from the dense filter");
    let _ = dense;
}
