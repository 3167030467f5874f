//! The filter on submaps, through the daemon's pipeline: with limits never reached it is
//! today's dense filter to 1e-9; with a small limit it closes submaps and the published
//! world pose stays where the dense filter's is.

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
    let poses = events
        .into_iter()
        .filter_map(|e| match e {
            OutputEvent::Pose(p) => Some(p),
            _ => None,
        })
        .collect();
    (p, poses)
}

fn options(limits: SubmapLimits) -> SubmapOptions {
    SubmapOptions {
        limits,
        global: slam_graph::GlobalSettings::default(),
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
