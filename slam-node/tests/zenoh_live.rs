//! Live topics over Zenoh, on loopback only: a subscriber in this test (a peer listening on
//! 127.0.0.1, multicast scouting off, no router) receives the daemon's pose, tf, map and
//! detections and decodes them as ROS 2 messages. Built only with `--features zenoh`.

use std::net::TcpListener;
use std::process::Command;
use std::time::{Duration, Instant};

use radar_model::motion::MotionModel;
use ros_msgs::nav::{Odometry, TFMessage};
use ros_msgs::sensor::PointCloud2;
use ros_msgs::visualization::MarkerArray;
use ros_msgs::{from_cdr, RosMessage};
use slam_node::output::live::{
    bridge_liveliness_key, bridge_qos, dds_type_name, rmw_zenoh_attachment, rmw_zenoh_entity_token,
    rmw_zenoh_key, rmw_zenoh_node_token, rmw_zenoh_qos, topic_key, type_hash, EntityKind,
    LivePublisher,
};
use slam_node::output::{LiveError, LiveOutput, OutputEvent, PoseSample};
use zenoh::Wait;

/// A peer listening on a port the system chose on 127.0.0.1, and its bound locator.
fn subscriber_session() -> (zenoh::Session, String) {
    slam_node::output::zenoh_node::loopback_peer().expect("a loopback Zenoh peer")
}

/// A TCP port on 127.0.0.1 held by this test for its whole life, whose every connection is
/// closed at once: a Zenoh client finds no router there.
fn port_that_closes_every_connection() -> u16 {
    let listener = TcpListener::bind("127.0.0.1:0").expect("a loopback port");
    let port = listener.local_addr().expect("its address").port();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            drop(stream);
        }
    });
    port
}

fn write_config(dir: &std::path::Path, connect: &str, listen: &str) -> std::path::PathBuf {
    let path = dir.join("live.toml");
    std::fs::write(
        &path,
        format!(
            "[output]\npictures = false\nprogress = false\n\n[output.zenoh]\nenabled = true\n\
             connect = [{connect}]\nlisten = [{listen}]\nmulticast_scouting = false\n"
        ),
    )
    .unwrap();
    path
}

/// TUM lines as (t, x, y).
fn tum(path: &std::path::Path) -> Vec<(f64, f64, f64)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            (v[0], v[1], v[2])
        })
        .collect()
}

#[test]
fn a_running_daemon_publishes_its_pose_tf_map_and_detections_to_a_loopback_subscriber() {
    let (session, endpoint) = subscriber_session();
    let subscriber = session.declare_subscriber("**").wait().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), &format!("\"{endpoint}\""), "");
    let mut child = Command::new(env!("CARGO_BIN_EXE_slam-node"))
        .arg("--config")
        .arg(&config)
        .args([
            "--embedded-sim",
            "--fast",
            "--duration",
            "30",
            "--no-figures",
        ])
        .arg("--out")
        .arg(dir.path().join("out"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // 30 s of stream (75 rotations, about a second with --fast): the peers may meet after
    // the first poses, and tf_static goes out only every 10 poses.
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut poses: Vec<Odometry> = Vec::new();
    let mut keys = std::collections::BTreeSet::new();
    let mut decoded_other = 0;
    while Instant::now() < deadline {
        let Ok(Some(sample)) = subscriber.recv_timeout(Duration::from_millis(200)) else {
            if child.try_wait().unwrap().is_some() {
                // The daemon is done; take what is still queued.
                match subscriber.try_recv() {
                    Ok(Some(_)) => {}
                    _ => break,
                }
            }
            continue;
        };
        let key = sample.key_expr().as_str().to_owned();
        let bytes = sample.payload().to_bytes();
        match key.as_str() {
            "slam/odometry" => poses.push(from_cdr(&bytes).expect("an Odometry")),
            "tf" | "tf_static" => {
                let tf: TFMessage = from_cdr(&bytes).expect("a TFMessage");
                assert_eq!(tf.transforms.len(), 1);
                decoded_other += 1;
            }
            "slam/map" | "slam/detections" => {
                let cloud: PointCloud2 = from_cdr(&bytes).expect("a PointCloud2");
                assert_eq!(cloud.data.len(), (cloud.row_step * cloud.height) as usize);
                decoded_other += 1;
            }
            "slam/map_covariance" => {
                let _: MarkerArray = from_cdr(&bytes).expect("a MarkerArray");
                decoded_other += 1;
            }
            other => panic!("unexpected key {other}"),
        }
        let encoding = sample.encoding().to_string();
        assert!(encoding.starts_with("application/cdr"), "{encoding}");
        keys.insert(key);
    }
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("Zenoh: "), "{stdout}");
    for key in [
        "slam/odometry",
        "tf",
        "tf_static",
        "slam/map",
        "slam/map_covariance",
        "slam/detections",
    ] {
        assert!(keys.contains(key), "nothing on {key}: {keys:?}");
    }
    assert!(decoded_other > 10);
    // Every pose received is a pose of the trajectory file, with its covariance.
    let trajectory = tum(&dir.path().join("out").join("trajectory.tum"));
    assert!(poses.len() > 10, "{} poses received", poses.len());
    for p in &poses {
        assert_eq!(p.header.frame_id, "map");
        assert_eq!(p.child_frame_id, "base_link");
        let t = p.header.stamp.sec as f64 + f64::from(p.header.stamp.nanosec) * 1e-9;
        let line = trajectory
            .iter()
            .find(|l| (l.0 - t).abs() < 2e-6)
            .unwrap_or_else(|| panic!("pose at {t} is not in trajectory.tum"));
        assert!((line.1 - p.pose.pose.position.x).abs() < 1e-5);
        assert!((line.2 - p.pose.pose.position.y).abs() < 1e-5);
        let c = &p.pose.covariance;
        assert!(c[0] >= 0.0 && c[7] >= 0.0 && c[35] >= 0.0, "{c:?}");
    }
    // The map frame starts at the true pose (covariance 0); once driving, it grows.
    let c = &poses.last().unwrap().pose.covariance;
    assert!(c[0] > 0.0 && c[7] > 0.0 && c[35] > 0.0, "{c:?}");
}

#[test]
fn an_endpoint_the_daemon_cannot_listen_on_stops_it_with_the_reason() {
    // A port this test holds.
    let held = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = held.local_addr().unwrap().port();
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "", &format!("\"tcp/127.0.0.1:{port}\""));
    let out = Command::new(env!("CARGO_BIN_EXE_slam-node"))
        .arg("--config")
        .arg(&config)
        .args([
            "--embedded-sim",
            "--fast",
            "--duration",
            "1",
            "--no-figures",
        ])
        .arg("--out")
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("opening the Zenoh session"), "{err}");
}

fn pose(t: f64) -> OutputEvent {
    OutputEvent::Pose(PoseSample {
        timestamp_s: t,
        x_m: 1.0,
        y_m: 2.0,
        theta_rad: 0.5,
        covariance: [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.001]],
    })
}

fn live(queue: i64, connect: Vec<String>) -> LiveOutput {
    let raw = config::live::RawZenoh {
        enabled: true,
        connect,
        listen: Vec::new(),
        queue,
        ..Default::default()
    };
    LiveOutput {
        zenoh: raw.validate().unwrap(),
        motion: MotionModel::Paper { step_s: 0.25 },
        node: None,
    }
}

#[test]
fn a_full_publisher_queue_drops_and_counts_instead_of_blocking_the_caller() {
    let publisher = LivePublisher::spawn(live(1, Vec::new())).unwrap();
    let started = Instant::now();
    for k in 0..20_000 {
        publisher.offer(&pose(f64::from(k)));
    }
    let offered_in = started.elapsed();
    let summary = publisher.finish();
    assert!(summary.dropped > 0, "{summary:?}");
    assert_eq!(
        summary.dropped + summary.published.get("slam/odometry").copied().unwrap_or(0),
        20_000,
        "{summary:?}"
    );
    // 20,000 offers in well under a second: none of them waited for the publisher.
    assert!(offered_in < Duration::from_secs(2), "{offered_in:?}");
}

#[test]
fn poses_offered_to_the_publisher_arrive_as_cdr_odometry_with_their_covariance() {
    let (session, endpoint) = subscriber_session();
    let subscriber = session.declare_subscriber("slam/odometry").wait().unwrap();
    let publisher = LivePublisher::spawn(live(64, vec![endpoint])).unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut got: Option<Odometry> = None;
    let mut t = 0.0;
    // Until the peers have met, puts go nowhere: keep offering.
    while got.is_none() && Instant::now() < deadline {
        t += 1.0;
        publisher.offer(&pose(1.7e9 + t));
        if let Ok(Some(sample)) = subscriber.recv_timeout(Duration::from_millis(50)) {
            got = Some(from_cdr(&sample.payload().to_bytes()).unwrap());
        }
    }
    let odometry = got.expect("a pose within 20 s");
    assert!((odometry.pose.pose.position.x - 1.0).abs() < 1e-12);
    assert!((odometry.pose.covariance[0] - 0.01).abs() < 1e-12);
    assert!((odometry.pose.covariance[35] - 0.001).abs() < 1e-12);
    assert_eq!(odometry.header.frame_id, "map");
    drop(publisher);
}

#[test]
fn a_bad_endpoint_is_a_typed_error_not_a_panic() {
    // Client mode with no router behind the endpoint: Zenoh gives up at once.
    let raw = config::live::RawZenoh {
        enabled: true,
        mode: config::live::ZenohMode::Client,
        connect: vec![format!(
            "tcp/127.0.0.1:{}",
            port_that_closes_every_connection()
        )],
        listen: Vec::new(),
        ..Default::default()
    };
    let result = LivePublisher::spawn(LiveOutput {
        zenoh: raw.validate().unwrap(),
        motion: MotionModel::Paper { step_s: 0.25 },
        node: None,
    });
    assert!(matches!(result, Err(LiveError::Open(_))), "{result:?}");
}

#[test]
fn keys_and_liveliness_tokens_follow_the_ros2dds_bridge() {
    assert_eq!(topic_key("", "/slam/odometry"), "slam/odometry");
    assert_eq!(topic_key("robot1", "/tf"), "robot1/tf");
    assert_eq!(bridge_qos(false, 10), ":1::0,10");
    assert_eq!(bridge_qos(true, 1), ":1:1:0,1");
    assert_eq!(
        bridge_liveliness_key("abc", "slam/odometry", &Odometry::type_name(), ":1::0,10"),
        "@/abc/@ros2_lv/MP/slam§odometry/nav_msgs§msg§Odometry/:1::0,10"
    );
    // The key is a valid Zenoh key expression.
    let ke = bridge_liveliness_key("abc", "slam/odometry", &Odometry::type_name(), ":1::0,10");
    assert!(zenoh::key_expr::KeyExpr::try_from(ke).is_ok());
}

#[test]
fn keys_and_liveliness_tokens_follow_rmw_zenoh_as_its_design_document_shows_them() {
    assert_eq!(
        dds_type_name("nav_msgs/msg/Odometry"),
        "nav_msgs::msg::dds_::Odometry_"
    );
    // rmw_zenoh's docs/design.md: the `chatter` topic of demo_nodes_cpp.
    assert_eq!(
        rmw_zenoh_key(0, "robot1", "/chatter", "std_msgs/msg/String").unwrap(),
        "0/robot1/chatter/std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
    );
    assert_eq!(
        rmw_zenoh_node_token(2, "aac3178e146ba6f1fc6e6a4085e77f21", 0, "", "listener"),
        "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
    );
    assert_eq!(
        rmw_zenoh_entity_token(
            2,
            "8b20917502ee955ac4476e0266340d5c",
            0,
            10,
            EntityKind::Publisher,
            "",
            "talker",
            "/chatter",
            "std_msgs/msg/String",
            "::,7:,:,:,,"
        )
        .unwrap(),
        "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18/::,7:,:,:,,"
    );
    assert_eq!(rmw_zenoh_qos(false, 10), "::,10:,:,:,,");
    assert_eq!(rmw_zenoh_qos(true, 1), ":1:,1:,:,:,,");
    // Our own topic, namespaced, and a type whose hash is not tabulated.
    let key = rmw_zenoh_key(3, "robot1", "/slam/odometry", &Odometry::type_name()).unwrap();
    assert_eq!(
        key,
        format!(
            "3/robot1/slam/odometry/nav_msgs::msg::dds_::Odometry_/{}",
            type_hash("nav_msgs/msg/Odometry").unwrap()
        )
    );
    assert!(zenoh::key_expr::KeyExpr::try_from(key).is_ok());
    assert!(matches!(
        rmw_zenoh_key(0, "", "/x", "std_msgs/msg/Bool"),
        Err(LiveError::UnknownTypeHash(_))
    ));
    let a = rmw_zenoh_attachment(7, -2, &[9; 16]);
    assert_eq!(&a[..8], &7i64.to_le_bytes());
    assert_eq!(&a[8..16], &(-2i64).to_le_bytes());
    assert_eq!(a[16], 16);
    assert_eq!(&a[17..], &[9; 16]);
}

#[test]
fn under_rmw_zenoh_poses_arrive_on_its_key_with_its_attachment_and_its_graph_tokens() {
    let (session, endpoint) = subscriber_session();
    let key = rmw_zenoh_key(0, "", "/slam/odometry", &Odometry::type_name()).unwrap();
    let subscriber = session.declare_subscriber(key.as_str()).wait().unwrap();
    let mut out = live(64, vec![endpoint]);
    out.zenoh.convention = config::live::ZenohConvention::RmwZenoh;
    let publisher = LivePublisher::spawn(out).unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut got = None;
    let mut t = 0.0;
    while got.is_none() && Instant::now() < deadline {
        t += 1.0;
        publisher.offer(&pose(1.7e9 + t));
        if let Ok(Some(sample)) = subscriber.recv_timeout(Duration::from_millis(50)) {
            got = Some(sample);
        }
    }
    let sample = got.expect("a pose within 20 s");
    let odometry: Odometry = from_cdr(&sample.payload().to_bytes()).unwrap();
    assert!((odometry.pose.pose.position.x - 1.0).abs() < 1e-12);
    let attachment = sample
        .attachment()
        .expect("rmw_zenoh's attachment")
        .to_bytes();
    assert_eq!(attachment.len(), 33);
    assert!(i64::from_le_bytes(attachment[..8].try_into().unwrap()) >= 1);
    assert_eq!(attachment[16], 16);
    // The graph: the node's token and its publisher's.
    let replies = session.liveliness().get("@ros2_lv/0/**").wait().unwrap();
    let mut tokens = Vec::new();
    while let Ok(Some(reply)) = replies.recv_timeout(Duration::from_secs(2)) {
        if let Ok(s) = reply.result() {
            tokens.push(s.key_expr().as_str().to_owned());
        }
    }
    assert!(
        tokens.iter().any(|t| t.ends_with("/0/0/NN/%/%/slam_node")),
        "{tokens:?}"
    );
    assert!(
        tokens.iter().any(|t| t
            .contains("/MP/%/%/slam_node/%slam%odometry/nav_msgs::msg::dds_::Odometry_/RIHS01_")
            && t.ends_with("/::,10:,:,:,,")),
        "{tokens:?}"
    );
    drop(publisher);
}

/// A simulated radar (the shipped penetration-wood scene, paper unit, real time) on
/// 127.0.0.1:0, without its odometry server.
async fn simulated_radar() -> sim_sensor::SimHandle {
    let scene = sim_sensor::scene::shipped::load("penetration-wood").expect("a shipped scene");
    let mut options = sim_sensor::SimOptions::for_tests(scene);
    options.odometry_bind = None;
    options.pacing = sim_sensor::settings::Pacing::Realtime;
    sim_sensor::SimServer::spawn(options)
        .await
        .expect("the simulator starts")
}

#[test]
fn radar_zenoh_publishes_a_radar_as_navtech_b_scans_and_configuration_without_the_slam() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let sim = runtime.block_on(simulated_radar());
    let (session, endpoint) = subscriber_session();
    let subscriber = session.declare_subscriber("radar_data/**").wait().unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_radar-zenoh"))
        .args(["--address", &sim.local_addr().to_string()])
        .args(["--connect", &endpoint, "--fft", "--duration-s", "4"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(30);
    let (mut scans, mut ffts) = (Vec::new(), 0);
    while Instant::now() < deadline && scans.len() < 3 {
        let Ok(Some(sample)) = subscriber.recv_timeout(Duration::from_millis(200)) else {
            continue;
        };
        let bytes = sample.payload().to_bytes();
        match sample.key_expr().as_str() {
            "radar_data/b_scan_msg" => {
                scans.push(from_cdr::<ros_msgs::navtech::RadarBScanMsg>(&bytes).unwrap());
            }
            "radar_data/configuration_data" => {
                let c: ros_msgs::navtech::RadarConfigurationMsg = from_cdr(&bytes).unwrap();
                assert_eq!(c.azimuth_samples, sim.configuration().azimuth_samples);
            }
            "radar_data/fft_data" => {
                let f: ros_msgs::navtech::RadarFftDataMsg = from_cdr(&bytes).unwrap();
                assert_eq!(usize::from(f.data_length), f.data.len());
                ffts += 1;
            }
            other => panic!("unexpected key {other}"),
        }
    }
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let c = sim.configuration().clone();
    runtime.block_on(sim.shutdown()).unwrap();
    assert!(stdout.contains("published"), "{stdout}");
    assert!(scans.len() >= 3, "{} B-scans", scans.len());
    assert!(ffts > 0);
    // The configuration is sent once at the start, before the peers may have met: the
    // B-scans carry the geometry too.
    // The first may be a rotation joined half-way.
    for scan in &scans[1..] {
        let img = &scan.b_scan_img;
        assert_eq!(img.height, u32::from(c.azimuth_samples));
        assert_eq!(img.width, u32::from(c.range_in_bins));
        assert_eq!(img.data.len(), (img.step * img.height) as usize);
        assert_eq!(scan.timestamps.len(), img.height as usize);
        // Most rows arrived (a real-time radar over loopback drops none).
        let rows = scan.timestamps.iter().filter(|t| **t > 0).count();
        assert!(rows * 10 >= img.height as usize * 9, "{rows} rows");
    }
}
