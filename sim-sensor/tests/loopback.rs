//! The simulator over loopback, read by a minimal client written here: the handshake, a
//! whole rotation checked field by field against the configuration and the scene, the
//! session commands, pacing, client limits and garbage handling.

mod common;

use std::time::{Duration, Instant};

use common::{TestClient, STEP};
use protocol::{BinWidth, Message};
use sim_sensor::radar::{DataWidth, RadarPreset};
use sim_sensor::scene::shipped;
use sim_sensor::{Pacing, SimOptions, SimServer};
use tokio::io::AsyncWriteExt;

const START_NS: u64 = 1_704_067_200_000_000_000;

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

#[tokio::test]
async fn the_handshake_and_a_whole_rotation_match_the_configuration_and_the_scene() {
    let scene = shipped::load("penetration-wood").expect("scene");
    let radar = scene.radar.clone();
    let handle = SimServer::spawn(SimOptions::for_tests(scene))
        .await
        .expect("spawn");
    let mut client = TestClient::connect(handle.local_addr()).await;

    // The configuration comes first, unasked, and describes the paper's unit.
    let config = client.configuration().await;
    assert_eq!(config.azimuth_samples, 200);
    assert_eq!(config.bin_size, 2500);
    assert_eq!(config.range_in_bins, 800);
    assert_eq!(config.encoder_size, 5600);
    assert_eq!(config.rotation_speed_millihertz, 2500);
    assert_eq!(config.packet_rate, 500);
    assert_eq!(config.data_width().expect("width"), BinWidth::Eight);
    let geometry = config.geometry().expect("geometry");
    // Range of a bin from the fixed part and from the protobuf's resolution agree.
    for bin in [0.0, 56.0, 799.0] {
        let by_size = geometry.bin_range_m(bin);
        let by_resolution = geometry
            .bin_range_m_by_resolution(bin)
            .expect("resolution present");
        assert!(
            (by_size - by_resolution).abs() < 1e-5,
            "bin {bin}: {by_size} vs {by_resolution}"
        );
    }

    client.send(Message::StartFftData).await;
    let mut rotation = Vec::new();
    while rotation.len() < 200 {
        rotation.push(client.next_fft().await);
    }
    for (k, fft) in rotation.iter().enumerate() {
        let k16 = u16::try_from(k).expect("small");
        assert_eq!(fft.width, BinWidth::Eight);
        assert_eq!(fft.azimuth, radar.encoder_of(k16), "encoder of azimuth {k}");
        assert_eq!(fft.azimuth, k16 * 28);
        assert_eq!(fft.sweep_counter, k16, "sweep counter");
        assert_eq!(fft.bin_count(), 800);
        // 500 azimuths a second: azimuth k is 2 ms x k after the start, exactly.
        let expect_ns = START_NS + 2_000_000 * k as u64;
        assert_eq!(
            u64::from(fft.timestamp.seconds()),
            expect_ns / 1_000_000_000
        );
        assert_eq!(
            u64::from(fft.timestamp.nanos()),
            expect_ns % 1_000_000_000,
            "azimuth {k}"
        );
    }

    // The reflector at 14 m (bin 56) straight ahead: the strongest bin-56 return of the
    // rotation is within two azimuths of encoder 0 (bearing noise is 1 degree), stands
    // far above the floor, and is its spectrum's maximum.
    let power = |k: usize, b: usize| rotation[k].power_db(b).expect("bin");
    let peak_near = |k: usize, centre: usize| {
        (centre - 2..=centre + 2)
            .map(|b| power(k, b))
            .fold(f64::MIN, f64::max)
    };
    let best = (0..200)
        .max_by(|&a, &b| peak_near(a, 56).total_cmp(&peak_near(b, 56)))
        .expect("some");
    let distance = best.min(200 - best);
    assert!(distance <= 2, "reflector seen strongest at azimuth {best}");
    let mut floor: Vec<f64> = (0..800).map(|b| power(best, b)).collect();
    let floor_median = median(&mut floor);
    let spectrum_max = (0..800).map(|b| power(best, b)).fold(f64::MIN, f64::max);
    assert!(
        peak_near(best, 56) >= spectrum_max,
        "the reflector is the strongest return"
    );
    assert!(
        peak_near(best, 56) > floor_median + 30.0,
        "{} vs floor {floor_median}",
        peak_near(best, 56)
    );
    // The wooden sheet at 8.5 m (bin 34) in front of it shows as a second peak.
    assert!(
        peak_near(best, 34) > floor_median + 15.0,
        "{} vs floor {floor_median}",
        peak_near(best, 34)
    );
    // Looking sideways (azimuth 50 = 90 degrees) there is no return at either range.
    assert!(peak_near(50, 56) < floor_median + 15.0);
    assert!(peak_near(50, 34) < floor_median + 15.0);

    handle.shutdown().await.expect("clean shutdown");
}

#[tokio::test]
async fn sixteen_bit_data_arrives_as_message_31_with_two_bytes_a_bin() {
    let scene = shipped::load("penetration-perspex")
        .expect("scene")
        .with_preset(RadarPreset::Cts350x400)
        .with_data_width(DataWidth::Bits16);
    let handle = SimServer::spawn(SimOptions::for_tests(scene))
        .await
        .expect("spawn");
    let mut client = TestClient::connect(handle.local_addr()).await;
    let config = client.configuration().await;
    assert_eq!(config.data_width().expect("width"), BinWidth::Sixteen);
    assert_eq!(
        (
            config.azimuth_samples,
            config.range_in_bins,
            config.bin_size
        ),
        (400, 3768, 438)
    );
    client.send(Message::StartNonContourFftData).await;
    let fft = client.next_fft().await;
    assert_eq!(fft.width, BinWidth::Sixteen);
    assert_eq!(fft.bins.len(), 2 * 3768);
    // The reflector at 14 m: bin 14 / 0.0438 = 319.6.
    let peak = (315..=325)
        .map(|b| fft.power_db(b).expect("bin"))
        .fold(f64::MIN, f64::max);
    let far = (2000..2100)
        .map(|b| fft.power_db(b).expect("bin"))
        .fold(f64::MIN, f64::max);
    assert!(peak > far + 20.0, "peak {peak} far {far}");
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn stop_halts_the_stream_and_a_configuration_request_is_answered() {
    let scene = shipped::load("outdoor-field").expect("scene");
    let mut options = SimOptions::for_tests(scene);
    options.keepalive_interval = Duration::from_secs(30);
    let handle = SimServer::spawn(options).await.expect("spawn");
    let mut client = TestClient::connect(handle.local_addr()).await;
    client.configuration().await;
    client.send(Message::StartFftData).await;
    for _ in 0..50 {
        client.next_fft().await;
    }
    client.send(Message::StopFftData).await;
    // Drain what was already in flight, until the line goes quiet.
    while client
        .next_within(Duration::from_millis(300))
        .await
        .is_some()
    {}
    let sent_before = handle.stats().azimuths_sent;
    assert!(
        client
            .next_within(Duration::from_millis(400))
            .await
            .is_none(),
        "nothing after stop"
    );
    assert_eq!(handle.stats().azimuths_sent, sent_before);

    client.send(Message::ConfigurationRequest).await;
    match client.next().await {
        Message::Configuration(c) => assert_eq!(c.azimuth_samples, 200),
        other => panic!("expected a configuration, got {}", other.id()),
    }
    // Starting again resumes where the world is: the sweep counter goes on.
    client.send(Message::StartFftData).await;
    let resumed = client.next_fft().await;
    assert!(resumed.sweep_counter >= 50, "{}", resumed.sweep_counter);
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn keep_alives_arrive_at_the_configured_interval() {
    let scene = shipped::load("penetration-wood").expect("scene");
    let mut options = SimOptions::for_tests(scene);
    options.keepalive_interval = Duration::from_millis(100);
    let handle = SimServer::spawn(options).await.expect("spawn");
    let mut client = TestClient::connect(handle.local_addr()).await;
    client.configuration().await;
    let start = Instant::now();
    let mut keepalives = 0;
    while start.elapsed() < Duration::from_millis(1050) {
        if let Some(m) = client.next_within(Duration::from_millis(200)).await {
            assert_eq!(m, Message::KeepAlive);
            keepalives += 1;
        }
    }
    // Ten are due (the loop may run to 1.25 s); a loaded machine may delay timer ticks.
    assert!(
        (4..=12).contains(&keepalives),
        "{keepalives} keep-alives in about 1 s at 100 ms"
    );
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn real_time_pacing_never_sends_an_azimuth_before_its_time() {
    let scene = shipped::load("penetration-wood").expect("scene");
    let mut options = SimOptions::for_tests(scene);
    options.pacing = Pacing::Realtime;
    options.start_time_ns = None; // azimuth 0 is "now" on the system clock
    let handle = SimServer::spawn(options).await.expect("spawn");
    let mut client = TestClient::connect(handle.local_addr()).await;
    client.configuration().await;
    client.send(Message::StartFftData).await;
    let unix_ns =
        |t: protocol::Timestamp| u64::from(t.seconds()) * 1_000_000_000 + u64::from(t.nanos());
    let now_ns = || {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos() as u64)
            .expect("clock")
    };
    let first = client.next_fft().await;
    let mut last = first.clone();
    for _ in 0..100 {
        last = client.next_fft().await;
        // Received no earlier than the moment it describes (1 ms for clock granularity).
        assert!(
            now_ns() + 1_000_000 >= unix_ns(last.timestamp),
            "azimuth arrived early"
        );
    }
    // 500 azimuths a second: consecutive timestamps 2 ms apart.
    assert_eq!(
        unix_ns(last.timestamp) - unix_ns(first.timestamp),
        100 * 2_000_000
    );
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn a_fourth_client_is_refused_while_three_are_served() {
    let scene = shipped::load("penetration-wood").expect("scene");
    let handle = SimServer::spawn(SimOptions::for_tests(scene))
        .await
        .expect("spawn");
    let mut clients = Vec::new();
    for _ in 0..3 {
        let mut c = TestClient::connect(handle.local_addr()).await;
        c.configuration().await;
        clients.push(c);
    }
    let mut fourth = TestClient::connect(handle.local_addr()).await;
    assert!(
        fourth.next_within(STEP).await.is_none(),
        "the fourth client is closed without a configuration"
    );
    assert_eq!(handle.stats().connections_refused, 1);
    // When one leaves, a new client is served again.
    drop(clients.pop());
    let mut fifth = None;
    for _ in 0..50 {
        let mut c = TestClient::connect(handle.local_addr()).await;
        if let Some(Message::Configuration(_)) = c.next_within(Duration::from_millis(200)).await {
            fifth = Some(c);
            break;
        }
    }
    assert!(fifth.is_some(), "a slot freed up");
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn garbage_from_a_client_closes_that_client_and_not_the_server() {
    let scene = shipped::load("penetration-wood").expect("scene");
    let handle = SimServer::spawn(SimOptions::for_tests(scene))
        .await
        .expect("spawn");
    let mut bad = TestClient::connect(handle.local_addr()).await;
    let mut good = TestClient::connect(handle.local_addr()).await;
    bad.configuration().await;
    good.configuration().await;
    bad.stream
        .write_all(b"GET / HTTP/1.1\r\nHost: radar\r\n\r\n")
        .await
        .expect("write");
    // The bad client's connection ends.
    let rest = bad.read_to_end().await;
    assert!(
        rest.len() < 64,
        "only keep-alives may have slipped out: {} bytes",
        rest.len()
    );
    assert_eq!(handle.stats().garbage_closes, 1);
    // The other client is still served.
    good.send(Message::StartFftData).await;
    good.next_fft().await;
    let mut again = TestClient::connect(handle.local_addr()).await;
    again.configuration().await;
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn a_client_that_stops_reading_stalls_its_stream_instead_of_growing_memory() {
    let scene = shipped::load("long-loop").expect("scene");
    let handle = SimServer::spawn(SimOptions::for_tests(scene))
        .await
        .expect("spawn");
    let mut client = TestClient::connect(handle.local_addr()).await;
    client.configuration().await;
    client.send(Message::StartFftData).await;
    // Read nothing more. Once the socket buffers are full the server's writer waits.
    let mut last = handle.stats().bytes_sent;
    let mut settled = false;
    for _ in 0..40 {
        tokio::time::sleep(Duration::from_millis(500)).await;
        let now = handle.stats().bytes_sent;
        if now == last {
            settled = true;
            break;
        }
        last = now;
    }
    assert!(
        settled,
        "the server kept writing to a client that reads nothing"
    );
    // What it wrote is what the kernel buffers hold, nowhere near an unbounded backlog.
    assert!(last < 64 << 20, "{last} bytes written");
    // Reading again resumes the stream.
    for _ in 0..10 {
        client.next_fft().await;
    }
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn each_azimuth_is_rendered_from_the_pose_at_its_own_timestamp() {
    // Driving at 10 m/s along +x between two reflectors 50 m ahead and 50 m behind. On the
    // paper's unit (2.5 Hz) the rear-facing azimuth 100 is measured 0.2 s after azimuth 0,
    // 2 m further on: the rear reflector must read 52 m from the start of the first
    // rotation (bin 208), not 50 m (bin 200) as from a pose frozen at the rotation's start.
    let text = r#"
        name = "two-reflectors"
        [noise]
        enabled = false
        [motion]
        model = "bicycle"
        wheelbase_m = 2.7
        [[control]]
        t_s = 0.0
        speed_mps = 10.0
        steer_rad = 0.0
        [[features]]
        kind = "reflector"
        x_m = 50.0
        y_m = 0.0
        [[features]]
        kind = "reflector"
        x_m = -50.0
        y_m = 0.0
    "#;
    let scene = sim_sensor::scene::Scene::from_toml_str("two-reflectors", text).expect("scene");
    let handle = SimServer::spawn(SimOptions::for_tests(scene))
        .await
        .expect("spawn");
    let mut client = TestClient::connect(handle.local_addr()).await;
    client.configuration().await;
    client.send(Message::StartFftData).await;
    let mut rotation = Vec::new();
    while rotation.len() < 400 {
        rotation.push(client.next_fft().await);
    }
    let peak_bin = |k: usize| {
        (0..800)
            .max_by(|&a, &b| {
                rotation[k]
                    .power_db(a)
                    .expect("bin")
                    .total_cmp(&rotation[k].power_db(b).expect("bin"))
            })
            .expect("bins")
    };
    // Ahead at azimuth 0 (t = 0): 50 m. Behind at azimuth 100 (t = 0.2 s): 52 m.
    assert_eq!(peak_bin(0), 200);
    assert_eq!(peak_bin(100), 208);
    // One rotation later (t = 0.4 s and 0.6 s): 46 m ahead, 56 m behind.
    assert_eq!(peak_bin(200), 184);
    assert_eq!(peak_bin(300), 224);
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn any_bytes_from_clients_never_take_the_server_down() {
    use rand::{Rng, SeedableRng};
    let scene = shipped::load("penetration-wood").expect("scene");
    let mut options = SimOptions::for_tests(scene);
    options.max_clients = 3;
    let handle = SimServer::spawn(options).await.expect("spawn");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    for round in 0..30 {
        let mut client = TestClient::connect(handle.local_addr()).await;
        client.configuration().await;
        // Random bytes, sometimes behind a valid signature with a random header (so the
        // decoder sees bad versions, huge lengths, unknown ids and truncated payloads).
        let mut bytes: Vec<u8> = Vec::new();
        if round % 2 == 0 {
            bytes.extend_from_slice(&protocol::SIGNATURE);
        }
        let n = rng.gen_range(1..2000);
        bytes.extend((0..n).map(|_| rng.gen::<u8>()));
        let _ = client.stream.write_all(&bytes).await;
        let _ = client.stream.shutdown().await;
        // Whatever happened to that client, the server ends its session and serves others.
        let _ = client.read_to_end().await;
    }
    let mut client = TestClient::connect(handle.local_addr()).await;
    client.configuration().await;
    client.send(Message::StartFftData).await;
    client.next_fft().await;
    assert_eq!(
        handle.stats().connections_refused,
        0,
        "every session was released"
    );
    handle.shutdown().await.expect("shutdown");
}

#[tokio::test]
async fn in_real_time_a_client_left_more_than_a_rotation_behind_is_moved_to_now() {
    // A CTS350-X with 16-bit bins sends about 12 MB a second, so a client that stops reading
    // fills the socket buffers quickly and falls behind the wall clock.
    let scene = shipped::load("long-loop")
        .expect("scene")
        .with_data_width(DataWidth::Bits16);
    let mut options = SimOptions::for_tests(scene);
    options.pacing = Pacing::Realtime;
    let handle = SimServer::spawn(options).await.expect("spawn");
    let mut client = TestClient::connect(handle.local_addr()).await;
    client.configuration().await;
    client.send(Message::StartFftData).await;
    let first = client.next_fft().await;
    tokio::time::sleep(Duration::from_millis(2500)).await;
    // Read the backlog: somewhere the sweep counter jumps by more than a rotation (400),
    // and nothing else is out of order.
    let mut last = first.sweep_counter;
    let mut jump = None;
    for _ in 0..20_000 {
        let fft = client.next_fft().await;
        let step = fft.sweep_counter.wrapping_sub(last);
        assert!(step >= 1, "sweep counter went backwards");
        if step > 400 {
            jump = Some(step);
            break;
        }
        assert_eq!(step, 1, "gaps other than the catch-up jump");
        last = fft.sweep_counter;
    }
    let jump = jump.expect("the server skipped ahead to the wall clock");
    assert!(jump > 400, "{jump}");
    handle.shutdown().await.expect("shutdown");
}
