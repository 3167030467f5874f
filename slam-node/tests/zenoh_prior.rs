//! A prior pose over Zenoh (`[map] initial_pose_topic`), on loopback only: a run maps the
//! outdoor field (speckle seed 1), then a second run (seed 2, paced at the radar's own rate)
//! localises in that map from no prior while this test, a peer listening on
//! `tcp/127.0.0.1:0`, publishes one `geometry_msgs/msg/PoseWithCovarianceStamped` on
//! `/initialpose` as RViz's "2D Pose Estimate" does: the true pose two seconds before the
//! stream's clock when it is sent. The localiser carries it to the latest rotation along the
//! vehicle's motion and tracks from it. A pose in another frame and a payload that does not
//! decode, and a prior stamped before every pose the localiser keeps, sent before it, are
//! refused and counted. Built only with `--features zenoh`.

mod support;
mod zenoh_support;

use std::time::{Duration, Instant};

use ros_msgs::builtin::Time;
use ros_msgs::geometry::{Point, Pose, PoseWithCovariance, PoseWithCovarianceStamped, Quaternion};
use ros_msgs::std_msgs::Header;
use ros_msgs::{to_cdr, RosMessage};
use slam_node::daemon::{run_daemon, DaemonOptions, DaemonReport};
use zenoh::bytes::Encoding;
use zenoh::Wait;

/// Where the simulated stream's clock starts (the simulator's test default).
const START_NS: u64 = 1_704_067_200_000_000_000;
/// Stream time each run drives (s).
const DURATION_S: f64 = 12.0;
/// Wall time after the subscription matched when the prior is sent (s), and how far
/// before the stream's clock then it is stamped (s).
const SEND_AFTER_S: f64 = 4.0;
const STAMPED_BEFORE_S: f64 = 2.0;

fn options(
    out: &std::path::Path,
    text: &str,
    seed: u64,
    pacing: sim_sensor::Pacing,
) -> DaemonOptions {
    let config = config::Config::from_toml_str(text).unwrap();
    let scene = sim_sensor::scene::shipped::load("outdoor-field").unwrap();
    let mut sim = sim_sensor::SimOptions::for_tests(scene);
    sim.start_time_ns = Some(START_NS);
    sim.seed = Some(seed);
    sim.pacing = pacing;
    support::embedded_options(config, sim, out, DURATION_S)
}

fn run(opts: DaemonOptions) -> DaemonReport {
    tokio::runtime::Runtime::new()
        .unwrap()
        .block_on(run_daemon(opts, None))
        .expect("the daemon runs")
}

/// RViz's estimate: a yaw-only quaternion, 0.25 m² on x and y, 0.0685 rad² on yaw.
fn estimate(stamp_ns: u64, pose: &radar_model::geometry::Pose2) -> PoseWithCovarianceStamped {
    let mut covariance = [0.0; 36];
    covariance[0] = 0.25;
    covariance[7] = 0.25;
    covariance[35] = 0.0685;
    PoseWithCovarianceStamped {
        header: Header::new(Time::from_nanos(stamp_ns), "map"),
        pose: PoseWithCovariance {
            pose: Pose {
                position: Point {
                    x: pose.x,
                    y: pose.y,
                    z: 0.0,
                },
                orientation: Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: (0.5 * pose.theta).sin(),
                    w: (0.5 * pose.theta).cos(),
                },
            },
            covariance,
        },
    }
}

#[test]
fn a_prior_pose_published_on_initialpose_starts_tracking_in_the_map() {
    let dir = tempfile::tempdir().unwrap();
    let map_out = dir.path().join("map-run");
    let mapped = run(options(
        &map_out,
        "",
        1,
        sim_sensor::Pacing::AsFastAsPossible,
    ));
    assert!(mapped.run.summary.map_size > 10);
    let map = map_out.join("map.slmap");
    assert!(map.exists());

    let (session, locator) =
        slam_node::output::zenoh_node::loopback_peer().expect("a loopback Zenoh peer");
    let text = format!(
        "[map]\nmode = \"localise\"\nfile = \"{}\"\ninitial_pose_topic = \"/initialpose\"\n\n\
         [output.zenoh]\nconnect = [\"{locator}\"]\nlisten = []\nmulticast_scouting = false\n",
        map.display()
    );
    let out = dir.path().join("localise");
    let opts = options(&out, &text, 2, sim_sensor::Pacing::Realtime);
    let scene = sim_sensor::scene::shipped::load("outdoor-field").unwrap();
    let trajectory = sim_sensor::trajectory::Trajectory::new(&scene, DURATION_S + 10.0).unwrap();
    let publisher = session
        .declare_publisher("initialpose")
        .encoding(Encoding::APPLICATION_CDR.with_schema(PoseWithCovarianceStamped::type_name()))
        .wait()
        .unwrap();

    let report = zenoh_support::run_with(opts, &publisher, || {
        let matched = Instant::now();
        std::thread::sleep(Duration::from_secs_f64(SEND_AFTER_S));
        // The stream runs at the radar's rate from about when the subscription matched.
        let stamp_s = matched.elapsed().as_secs_f64() - STAMPED_BEFORE_S;
        let stamp_ns = START_NS + (stamp_s * 1e9) as u64;
        let truth = trajectory.pose_at(stamp_ns - START_NS).unwrap();
        // A pose in another frame, then garbage: each refused and counted, nothing else lost.
        let mut elsewhere = estimate(stamp_ns, &truth);
        elsewhere.header.frame_id = "odom".into();
        publisher.put(to_cdr(&elsewhere).unwrap()).wait().unwrap();
        publisher.put(vec![0u8, 1, 0, 0, 7]).wait().unwrap();
        // A prior stamped a minute before the stream began: before every pose the
        // localiser keeps, so it cannot be carried to now and is refused.
        let stale = estimate(START_NS - 60_000_000_000, &truth);
        publisher.put(to_cdr(&stale).unwrap()).wait().unwrap();
        std::thread::sleep(Duration::from_millis(600));
        publisher
            .put(to_cdr(&estimate(stamp_ns, &truth)).unwrap())
            .wait()
            .unwrap();
    });
    let text = slam_node::daemon::report::summary_text(&report);
    println!("{text}");

    let z = report.zenoh_prior.clone().expect("Zenoh prior counts");
    assert_eq!(z.key, "initialpose");
    assert_eq!(
        (z.received, z.decoded, z.malformed, z.lost()),
        (4, 2, 2, 2),
        "{text}"
    );
    let l = report
        .run
        .summary
        .localise
        .clone()
        .expect("a localisation summary");
    assert_eq!(
        (l.priors_received, l.priors_applied, l.priors_refused),
        (2, 1, 1),
        "{text}"
    );
    assert!(text.contains("prior poses from the topic: 2 received, 1 started tracking, 1 refused"));
    // Tracking began at the latest when the prior came (place recognition may have found
    // the place before it), and held: published poses near the truth in the map's frame.
    let fix_s = l.time_to_fix_s.expect("a fix");
    assert!(fix_s < SEND_AFTER_S + 2.0, "{text}");
    let score = l.score.expect("scored against the scene's truth");
    assert!(
        score.along_rms_m < 0.3 && score.across_rms_m < 0.3,
        "along {} m, across {} m\n{text}",
        score.along_rms_m,
        score.across_rms_m
    );
    assert!(score.heading_rms_rad.to_degrees() < 1.0, "{text}");
}
