//! The vehicle's odometry over Zenoh, on loopback only: a publisher in this test (a peer
//! listening on `tcp/127.0.0.1:0`, its port read back from the session, multicast off)
//! publishes the simulated scene's true odometry as ROS 2 messages, and the daemon (in this
//! process, against its embedded simulator as fast as possible, `[odometry] source =
//! "zenoh"`) maps with it. Built only with `--features zenoh`.

mod support;
mod zenoh_support;

use radar_model::motion::MotionModel;
use ros_msgs::builtin::Time;
use ros_msgs::geometry::{Twist, TwistStamped, TwistWithCovariance, Vector3};
use ros_msgs::nav::Odometry;
use ros_msgs::std_msgs::Header;
use ros_msgs::{to_cdr, RosMessage};
use slam_node::daemon::{DaemonOptions, DaemonReport};
use slam_node::output::live::rmw_zenoh_key;
use zenoh::bytes::Encoding;
use zenoh::qos::CongestionControl;
use zenoh::Wait;

/// Where the simulated stream's clock starts (the simulator's test default).
const START_NS: u64 = 1_704_067_200_000_000_000;
/// Odometry rate, Hz.
const RATE_HZ: u64 = 20;
/// Stream time the daemon runs, s.
const DURATION_S: f64 = 20.0;

/// A peer listening on a port the system chose on 127.0.0.1, and its bound locator.
fn listening_session() -> (zenoh::Session, String) {
    slam_node::output::zenoh_node::loopback_peer().expect("a loopback Zenoh peer")
}

/// The scene's true controls every 1/20 s from the start, as (stamp, speed, yaw rate) under
/// its motion model, one second past the run.
fn true_odometry(scene: &sim_sensor::scene::Scene) -> Vec<(Time, f64, f64)> {
    let trajectory = sim_sensor::trajectory::Trajectory::new(scene, DURATION_S + 10.0).unwrap();
    let motion: MotionModel = trajectory.model();
    let period_ns = 1_000_000_000 / RATE_HZ;
    (0..=((DURATION_S as u64 + 1) * RATE_HZ))
        .map(|j| {
            let offset_ns = j * period_ns;
            let (speed_mps, steer_rad) = trajectory.controls_at(offset_ns);
            let sample = slam_filter::OdometrySample {
                timestamp_s: (START_NS + offset_ns) as f64 * 1e-9,
                speed_mps,
                steer_rad,
            };
            let yaw_rate = slam_node::output::ros::yaw_rate(&motion, &sample);
            (Time::from_nanos(START_NS + offset_ns), speed_mps, yaw_rate)
        })
        .collect()
}

fn odometry(stamp: Time, speed_mps: f64, yaw_rate_rps: f64) -> Odometry {
    Odometry {
        header: Header::new(stamp, "odom"),
        child_frame_id: "base_link".into(),
        twist: TwistWithCovariance {
            twist: twist(speed_mps, yaw_rate_rps),
            covariance: [0.0; 36],
        },
        ..Odometry::default()
    }
}

fn twist(speed_mps: f64, yaw_rate_rps: f64) -> Twist {
    Twist {
        linear: Vector3 {
            x: speed_mps,
            y: 0.0,
            z: 0.0,
        },
        angular: Vector3 {
            x: 0.0,
            y: 0.0,
            z: yaw_rate_rps,
        },
    }
}

/// The daemon's options: the outdoor field's simulator without its odometry port, as fast
/// as possible, odometry from Zenoh on `topic` as `message`, the session connecting to
/// `locator` with `convention`.
fn options(
    out: &std::path::Path,
    locator: &str,
    topic: &str,
    message: &str,
    convention: &str,
) -> (DaemonOptions, sim_sensor::scene::Scene) {
    let text = format!(
        "[odometry]\nsource = \"zenoh\"\ntopic = \"{topic}\"\nmessage = \"{message}\"\n\n\
         [output.zenoh]\nconnect = [\"{locator}\"]\nlisten = []\nmulticast_scouting = false\n\
         convention = \"{convention}\"\n"
    );
    let config = config::Config::from_toml_str(&text).unwrap();
    let scene = sim_sensor::scene::shipped::load("outdoor-field").unwrap();
    let mut sim = sim_sensor::SimOptions::for_tests(scene.clone());
    sim.odometry_bind = None;
    sim.start_time_ns = Some(START_NS);
    let opts = support::embedded_options(config, sim, out, DURATION_S);
    (opts, scene)
}

fn rms_position_m(report: &DaemonReport) -> f64 {
    report
        .run
        .summary
        .pose
        .as_ref()
        .expect("scored against the scene's truth")
        .rms_position_m()
}

#[test]
fn odometry_published_over_zenoh_drives_the_daemon_and_its_trajectory_follows_it() {
    let (session, locator) = listening_session();
    let dir = tempfile::tempdir().unwrap();
    let (opts, scene) = options(
        dir.path(),
        &locator,
        "/vehicle/odom",
        "nav_msgs/msg/Odometry",
        "ros2dds",
    );
    let samples = true_odometry(&scene);
    let publisher = session
        .declare_publisher("vehicle/odom")
        .encoding(Encoding::APPLICATION_CDR.with_schema(Odometry::type_name()))
        .congestion_control(CongestionControl::Block)
        .wait()
        .unwrap();
    let report = zenoh_support::run_with(opts, &publisher, || {
        for &(stamp, speed, yaw) in &samples {
            publisher
                .put(to_cdr(&odometry(stamp, speed, yaw)).unwrap())
                .wait()
                .unwrap();
        }
    });
    let text = slam_node::daemon::report::summary_text(&report);
    println!("{text}");
    let z = report
        .zenoh_odometry
        .clone()
        .expect("Zenoh odometry counts");
    assert_eq!(z.key, "vehicle/odom");
    assert_eq!(z.received, samples.len() as u64, "{text}");
    assert_eq!(z.decoded, z.received, "{text}");
    assert_eq!(z.lost(), 0, "{text}");
    assert!(text.contains("Zenoh odometry on vehicle/odom"), "{text}");
    // The pipeline took every sample up to the end of the run and mapped with them.
    let summary = &report.run.summary;
    assert!(
        summary.odometry_samples >= (DURATION_S as u64) * RATE_HZ,
        "{text}"
    );
    assert!(summary.map_size > 20, "{text}");
    // The trajectory follows the odometry (and the truth it came from): the vehicle drove
    // and the pose stayed on the true path.
    let rms = rms_position_m(&report);
    assert!(rms < 0.3, "pose RMS {rms} m\n{text}");
    let trajectory = std::fs::read_to_string(dir.path().join("trajectory.tum")).unwrap();
    let xy: Vec<(f64, f64)> = trajectory
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            (v[1], v[2])
        })
        .collect();
    let (first, last) = (xy[0], xy[xy.len() - 1]);
    let moved = ((last.0 - first.0).powi(2) + (last.1 - first.1).powi(2)).sqrt();
    assert!(moved > 10.0, "moved {moved} m\n{text}");
}

#[test]
fn malformed_cdr_from_a_zenoh_peer_costs_only_that_message_and_is_counted() {
    let (session, locator) = listening_session();
    let dir = tempfile::tempdir().unwrap();
    let topic = "/vehicle/twist";
    let (opts, scene) = options(
        dir.path(),
        &locator,
        topic,
        "geometry_msgs/msg/TwistStamped",
        "rmw_zenoh",
    );
    let samples = true_odometry(&scene);
    // rmw_zenoh's key, as a ROS 2 node on rmw_zenoh_cpp publishes it.
    let key = rmw_zenoh_key(0, "", topic, &TwistStamped::type_name()).unwrap();
    assert!(key.starts_with("0/vehicle/twist/geometry_msgs::msg::dds_::TwistStamped_/RIHS01_"));
    let publisher = session
        .declare_publisher(key.clone())
        .congestion_control(CongestionControl::Block)
        .wait()
        .unwrap();
    let (mut garbage, mut truncated, mut other_layout, mut other_type) = (0u64, 0u64, 0u64, 0u64);
    let report = zenoh_support::run_with(opts, &publisher, || {
        for (k, &(stamp, speed, yaw)) in samples.iter().enumerate() {
            let good = to_cdr(&TwistStamped {
                header: Header::new(stamp, "base_link"),
                twist: twist(speed, yaw),
            })
            .unwrap();
            // Among the good ones: bytes that are no CDR, a payload cut short, an Odometry
            // where a TwistStamped belongs, and one whose encoding names another type.
            match k % 10 {
                3 => {
                    publisher
                        .put(vec![0xde, 0xad, 0xbe, 0xef, 1, 2, 3])
                        .wait()
                        .unwrap();
                    garbage += 1;
                }
                5 => {
                    publisher
                        .put(good[..good.len() / 2].to_vec())
                        .wait()
                        .unwrap();
                    truncated += 1;
                }
                7 => {
                    let wrong = to_cdr(&odometry(stamp, speed, yaw)).unwrap();
                    publisher.put(wrong).wait().unwrap();
                    other_layout += 1;
                }
                9 => {
                    publisher
                        .put(good.clone())
                        .encoding(Encoding::APPLICATION_CDR.with_schema("std_msgs/msg/String"))
                        .wait()
                        .unwrap();
                    other_type += 1;
                }
                _ => {}
            }
            publisher.put(good).wait().unwrap();
        }
    });
    let text = slam_node::daemon::report::summary_text(&report);
    println!("{text}");
    let z = report
        .zenoh_odometry
        .clone()
        .expect("Zenoh odometry counts");
    assert_eq!(z.key, key);
    let bad = garbage + truncated + other_layout + other_type;
    assert_eq!(z.received, samples.len() as u64 + bad, "{text}");
    assert_eq!(z.malformed, garbage + truncated + other_layout, "{text}");
    assert_eq!(z.wrong_type, other_type, "{text}");
    assert_eq!(z.decoded, samples.len() as u64, "{text}");
    assert!(
        text.contains(&format!(
            "lost {bad} (malformed {}, another type {other_type}, queue full 0)",
            garbage + truncated + other_layout
        )),
        "{text}"
    );
    // The run went on to its end and mapped with the good messages.
    assert!(report.run.summary.stream_s() >= DURATION_S - 0.5, "{text}");
    let rms = rms_position_m(&report);
    assert!(rms < 0.3, "pose RMS {rms} m\n{text}");
}
