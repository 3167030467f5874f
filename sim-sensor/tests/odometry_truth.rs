//! The odometry port (format of docs/contracts.md) and the ground-truth file, over loopback.

mod common;

use std::time::Duration;

use common::{TestClient, STEP};
use protocol::Message;
use sim_sensor::scene::shipped;
use sim_sensor::truth::{GroundTruth, TruthRecord};
use sim_sensor::{OdometryNoise, SimHandle, SimOptions, SimServer};
use tokio::io::{AsyncBufReadExt, BufReader};
use tokio::net::TcpStream;

const START_NS: u64 = 1_704_067_200_000_000_000;

async fn read_line(reader: &mut BufReader<TcpStream>) -> String {
    let mut line = String::new();
    let n = tokio::time::timeout(STEP, reader.read_line(&mut line))
        .await
        .expect("a line in time")
        .expect("read");
    assert!(n > 0, "the line stream ended");
    line
}

/// The first `count` records of the line stream at `address` (odometry or gyro, format of
/// docs/contracts.md) while a radar client drives the scene (as fast as possible, the
/// stream follows it): the header is `header`, each line at most 256 bytes ending in a
/// newline, fields separated by single spaces, the timestamp with nine decimals. Each
/// record: its time, ns, and its other fields.
async fn contract_lines(
    handle: &SimHandle,
    address: std::net::SocketAddr,
    header: &str,
    count: usize,
) -> Vec<(u64, Vec<f64>)> {
    let fields = header.split(' ').count() - 3;
    let stream = TcpStream::connect(address).await.expect("connect");
    let mut reader = BufReader::new(stream);
    assert_eq!(read_line(&mut reader).await, format!("{header}\n"));
    // Drive the radar so the world moves: 12 s of scene time at 500 azimuths a second.
    let mut radar = TestClient::connect(handle.local_addr()).await;
    radar.configuration().await;
    radar.send(Message::StartFftData).await;
    let reader_task = tokio::spawn(async move {
        for _ in 0..6000 {
            radar.next_fft().await;
        }
        radar
    });
    let mut records = Vec::new();
    while records.len() < count {
        let line = read_line(&mut reader).await;
        assert!(line.len() <= 256 && line.ends_with('\n'));
        let parts: Vec<&str> = line.trim_end().split(' ').collect();
        assert_eq!(parts.len(), fields, "{line:?}");
        let (secs, nanos) = parts[0].split_once('.').expect("decimal timestamp");
        assert_eq!(nanos.len(), 9);
        let t_ns = secs.parse::<u64>().expect("secs") * 1_000_000_000
            + nanos.parse::<u64>().expect("nanos");
        let values = parts[1..]
            .iter()
            .map(|f| f.parse::<f64>().expect("a number"))
            .collect();
        records.push((t_ns, values));
    }
    let _radar = reader_task.await.expect("radar reader");
    records
}

#[tokio::test]
async fn odometry_lines_follow_the_contract_and_carry_the_true_controls_without_noise() {
    let scene = shipped::load("outdoor-field").expect("scene");
    let mut options = SimOptions::for_tests(scene);
    options.odometry = OdometryNoise {
        rate_hz: 20.0,
        sigma_speed_mps: 0.0,
        sigma_steer_rad: 0.0,
        bias_speed_mps: 0.0,
        bias_steer_rad: 0.0,
    };
    let handle = SimServer::spawn(options).await.expect("spawn");
    let address = handle.odometry_addr().expect("odometry port");
    let records = contract_lines(
        &handle,
        address,
        "# odometry v1 timestamp_s speed_mps steer_rad",
        220,
    )
    .await;
    for (j, (t_ns, fields)) in records.iter().enumerate() {
        let [v, a] = fields[..] else {
            panic!("record {j}: {fields:?}")
        };
        assert_eq!(
            *t_ns,
            START_NS + 50_000_000 * j as u64,
            "record {j} every 50 ms from the start"
        );
        let t_s = j as f64 * 0.05;
        // outdoor-field: 1 m/s straight, steer 0.04 from 10 s.
        let (ev, ea) = if t_s < 10.0 { (1.0, 0.0) } else { (1.0, 0.04) };
        assert_eq!((v, a), (ev, ea), "record {j} at {t_s} s");
    }
    handle.shutdown().await.expect("shutdown");
}

/// The record number of an odometry line (records are 50 ms apart from the start).
fn record_index(line: &str) -> u64 {
    let stamp = line.split(' ').next().expect("a timestamp");
    let (secs, nanos) = stamp.split_once('.').expect("decimal timestamp");
    let t_ns =
        secs.parse::<u64>().expect("secs") * 1_000_000_000 + nanos.parse::<u64>().expect("nanos");
    (t_ns - START_NS) / 50_000_000
}

#[tokio::test]
async fn as_fast_as_possible_odometry_starts_at_the_first_record_and_resumes_without_a_gap() {
    let scene = shipped::load("outdoor-field").expect("scene");
    let handle = SimServer::spawn(SimOptions::for_tests(scene))
        .await
        .expect("spawn");
    // The radar runs 5 s ahead before any odometry client connects.
    let mut radar = TestClient::connect(handle.local_addr()).await;
    radar.configuration().await;
    radar.send(Message::StartFftData).await;
    for _ in 0..2500 {
        radar.next_fft().await;
    }
    let addr = handle.odometry_addr().expect("odometry port");
    let mut reader = BufReader::new(TcpStream::connect(addr).await.expect("connect"));
    read_line(&mut reader).await;
    assert_eq!(
        record_index(&read_line(&mut reader).await),
        0,
        "a client connecting late still starts at the scene's first record"
    );
    // Read everything the server has sent (the radar is not read, so its frontier stands
    // still), then the link goes quiet and is dropped, as an idle client drops it.
    let mut last = 0;
    loop {
        let mut line = String::new();
        match tokio::time::timeout(Duration::from_secs(1), reader.read_line(&mut line)).await {
            Ok(Ok(n)) if n > 0 => {
                let j = record_index(&line);
                assert_eq!(j, last + 1, "records in order without gaps");
                last = j;
            }
            Ok(_) => panic!("odometry stream ended"),
            Err(_) => break,
        }
    }
    assert!(last >= 100, "records up to the radar's frontier: {last}");
    drop(reader);
    let mut reader = BufReader::new(TcpStream::connect(addr).await.expect("reconnect"));
    read_line(&mut reader).await;
    // The radar moves on (read until the record comes: a socket's window may reopen only
    // once much of its buffer has been read); the reconnected stream carries on after the
    // last record sent.
    let radar_task = tokio::spawn(async move {
        loop {
            radar.next_fft().await;
        }
    });
    // It is sent again the last REPLAY_ON_CONNECT_S of what was written (what a closed link
    // may have held unread; the daemon drops the repeats), then carries on without a gap.
    let replay = (sim_sensor::odometry::REPLAY_ON_CONNECT_S / 0.05).ceil() as u64;
    let first = record_index(&read_line(&mut reader).await);
    assert_eq!(
        first,
        (last + 1).saturating_sub(replay),
        "a reconnected client misses no record"
    );
    for j in first + 1..=last + 2 {
        assert_eq!(record_index(&read_line(&mut reader).await), j, "in order");
    }
    radar_task.abort();
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn the_ground_truth_file_holds_the_scene_and_a_pose_for_every_served_azimuth() {
    let scene = shipped::load("outdoor-field").expect("scene");
    let n_features = scene.features.len();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("truth.jsonl");
    let mut options = SimOptions::for_tests(scene.clone());
    options.ground_truth_path = Some(path.clone());
    let handle = SimServer::spawn(options).await.expect("spawn");
    let mut radar = TestClient::connect(handle.local_addr()).await;
    radar.configuration().await;
    radar.send(Message::StartFftData).await;
    for _ in 0..1000 {
        radar.next_fft().await;
    }
    radar.send(Message::StopFftData).await;
    while radar
        .next_within(Duration::from_millis(200))
        .await
        .is_some()
    {}
    let served = handle.stats().azimuths_sent;
    handle.shutdown().await.expect("shutdown");

    let truth = GroundTruth::read(&path).expect("reads back");
    match &truth.header {
        TruthRecord::Header {
            scene: name,
            radar,
            start_time_s,
            ..
        } => {
            assert_eq!(name, "outdoor-field");
            assert_eq!(radar.azimuths, 200);
            assert!((start_time_s - 1_704_067_200.0).abs() < 1e-6);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(truth.features.len(), n_features);
    assert!(
        truth.poses.len() as u64 >= served,
        "{} poses for {served} azimuths",
        truth.poses.len()
    );
    let trajectory = sim_sensor::trajectory::Trajectory::new(&scene, 60.0).expect("trajectory");
    for (k, record) in truth.poses.iter().enumerate() {
        let TruthRecord::Pose {
            azimuth_index,
            encoder,
            x_m,
            y_m,
            theta_rad,
            timestamp_s,
            ..
        } = record
        else {
            panic!("not a pose");
        };
        assert_eq!(*azimuth_index, k as u64);
        assert_eq!(*encoder, (k % 200) as u16 * 28);
        let pose = trajectory.pose_at(2_000_000 * k as u64).expect("pose");
        assert_eq!(
            (*x_m, *y_m, *theta_rad),
            (pose.x, pose.y, pose.theta),
            "azimuth {k}"
        );
        assert!((timestamp_s - (1_704_067_200.0 + 0.002 * k as f64)).abs() < 1e-6);
    }
    // The vehicle moved: 1000 azimuths at 500/s is 2 s at 1 m/s.
    let TruthRecord::Pose { x_m, .. } = &truth.poses[1000] else {
        panic!()
    };
    assert!((x_m - 2.0).abs() < 1e-6, "{x_m}");
}

#[tokio::test]
async fn a_ground_truth_file_that_is_not_one_is_a_typed_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("x.jsonl");
    std::fs::write(&path, "{\"type\":\"pose\"}\n").expect("write");
    assert!(GroundTruth::read(&path).is_err());
    std::fs::write(&path, vec![b'a'; 10_000]).expect("write");
    assert!(GroundTruth::read(&path).is_err());
}

/// The outdoor field served as fast as possible, and its odometry port.
async fn fast_odometry_server() -> (SimHandle, std::net::SocketAddr) {
    let scene = shipped::load("outdoor-field").expect("scene");
    let mut options = SimOptions::for_tests(scene);
    options.pacing = sim_sensor::Pacing::AsFastAsPossible;
    let handle = SimServer::spawn(options).await.expect("spawn");
    let address = handle.odometry_addr().expect("odometry port");
    (handle, address)
}

// Odometry clients that go away while their stream waits for the radar's frontier (as fast
// as possible, no radar client is reading: the daemon's driver is reconnecting, or the
// pipeline is behind) give their slot back. Before, a client's task noticed it had gone
// only at its next write, so after eight quiet reconnections every new client was refused
// ("too many connected") until the radar moved: in a run on one busy core frozen for 8 s,
// the daemon's odometry client was refused 147 times in 15 s.
#[tokio::test]
async fn odometry_clients_that_leave_while_the_radar_stands_still_give_their_slot_back() {
    tokio::time::timeout(Duration::from_secs(30), async {
        let (_handle, address) = fast_odometry_server().await;
        for client in 0..2 * sim_sensor::odometry::MAX_ODOMETRY_CLIENTS {
            let odometry = TcpStream::connect(address).await.expect("connect");
            let mut reader = BufReader::new(odometry);
            let mut header = String::new();
            let n = tokio::time::timeout(STEP, reader.read_line(&mut header))
                .await
                .expect("a line in time")
                .expect("read");
            assert!(
                n > 0 && header.starts_with("# odometry v1"),
                "client {client} was refused"
            );
            // Gone before the radar moved.
            drop(reader);
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await
    .expect("bounded");
}

/// A client reads a few records and closes while the server has written more to its link:
/// those were written, not delivered, and the next client is sent them (before, it started
/// after the last record written, and they were lost).
#[tokio::test]
async fn records_written_to_a_link_that_closed_unread_reach_the_next_client() {
    tokio::time::timeout(Duration::from_secs(30), async {
        let (handle, address) = fast_odometry_server().await;
        // No radar client: the frontier stays at the start, and the server writes the
        // records up to its lead (0.5 s: 10 records) at once.
        let mut reader = BufReader::new(TcpStream::connect(address).await.expect("connect"));
        read_line(&mut reader).await;
        for j in 0..3 {
            assert_eq!(record_index(&read_line(&mut reader).await), j);
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
        drop(reader);
        tokio::time::sleep(Duration::from_millis(100)).await;
        let mut reader = BufReader::new(TcpStream::connect(address).await.expect("reconnect"));
        read_line(&mut reader).await;
        let first = record_index(&read_line(&mut reader).await);
        assert!(
            first <= 3,
            "the next client starts at record {first}, after unread ones"
        );
        handle.shutdown().await.expect("shutdown");
    })
    .await
    .expect("bounded");
}

/// Issue 38 item 14: eight clients connected and idle (never reading, never closing) no
/// longer lock the port: a ninth is served (the longest-connected is closed for it).
/// Before, the ninth was closed at once ("too many connected").
#[tokio::test]
async fn eight_idle_odometry_clients_do_not_lock_out_a_ninth() {
    tokio::time::timeout(Duration::from_secs(30), async {
        let (_handle, address) = fast_odometry_server().await;
        let mut idle = Vec::new();
        for _ in 0..sim_sensor::odometry::MAX_ODOMETRY_CLIENTS {
            idle.push(TcpStream::connect(address).await.expect("connect"));
        }
        // Let the server take all eight before the ninth comes.
        tokio::time::sleep(Duration::from_millis(200)).await;
        let mut reader = BufReader::new(TcpStream::connect(address).await.expect("connect"));
        assert!(read_line(&mut reader).await.starts_with("# odometry v1"));
        for j in 0..3 {
            assert_eq!(record_index(&read_line(&mut reader).await), j);
        }
        // The first idle client's connection was the one closed for it.
        let mut first = BufReader::new(idle.remove(0));
        let mut all = String::new();
        let ended = tokio::time::timeout(STEP, async {
            while first.read_line(&mut all).await.is_ok_and(|n| n > 0) {}
        })
        .await;
        assert!(ended.is_ok(), "the oldest idle client was not closed");
    })
    .await
    .expect("bounded");
}

/// Issue 38 item 14: a client that closes its sending side at once (`shutdown(SHUT_WR)`)
/// still gets the records. Before, the server took the end of its sending side for its
/// leaving and closed the link after the header.
#[tokio::test]
async fn an_odometry_client_that_closes_its_sending_side_still_gets_the_records() {
    tokio::time::timeout(Duration::from_secs(30), async {
        use tokio::io::AsyncWriteExt;
        let scene = shipped::load("outdoor-field").expect("scene");
        let mut options = SimOptions::for_tests(scene);
        // Real time: records leave one by one (50 Hz), after the server has seen the end.
        options.pacing = sim_sensor::Pacing::Realtime;
        let handle = SimServer::spawn(options).await.expect("spawn");
        let mut socket = TcpStream::connect(handle.odometry_addr().expect("odometry port"))
            .await
            .expect("connect");
        socket.shutdown().await.expect("shutdown(SHUT_WR)");
        let mut reader = BufReader::new(socket);
        assert!(read_line(&mut reader).await.starts_with("# odometry v1"));
        let first = record_index(&read_line(&mut reader).await);
        for j in 1..25 {
            assert_eq!(record_index(&read_line(&mut reader).await), first + j);
        }
    })
    .await
    .expect("bounded");
}

/// The gyro port (docs/contracts.md, "Gyro stream"): its header, then a sample every 10 ms
/// from the start carrying the true yaw rate plus the configured bias (no noise here).
#[tokio::test]
async fn gyro_lines_follow_the_contract_and_carry_the_true_yaw_rate_plus_the_bias() {
    let scene = shipped::load("outdoor-field").expect("scene");
    let model = sim_sensor::trajectory::motion_model(scene.motion);
    let mut options = SimOptions::for_tests(scene);
    options.gyro = sim_sensor::gyro::GyroNoise {
        rate_hz: 100.0,
        noise_density_rad_s_per_sqrt_hz: 0.0,
        bias_rad_s: 0.005,
    };
    let handle = SimServer::spawn(options).await.expect("spawn");
    let address = handle.gyro_addr().expect("gyro port");
    let samples = contract_lines(
        &handle,
        address,
        "# gyro v1 timestamp_s yaw_rate_rad_s",
        1100,
    )
    .await;
    for (j, (t_ns, fields)) in samples.iter().enumerate() {
        let [w] = fields[..] else {
            panic!("sample {j}: {fields:?}")
        };
        assert_eq!(*t_ns, START_NS + 10_000_000 * j as u64, "sample {j}");
        // outdoor-field: 1 m/s straight, steer 0.04 from 10 s.
        let steer = if j < 1000 { 0.0 } else { 0.04 };
        let want = sim_sensor::gyro::yaw_rate_of(&model, (1.0, steer)) + 0.005;
        assert!((w - want).abs() < 1e-6, "sample {j}: {w} vs {want}");
    }
    handle.shutdown().await.expect("shutdown");
}
