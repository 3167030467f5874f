//! The driver against the project's simulator (`sim-sensor`) as the fake radar: a clean
//! stream, each of the simulator's fault modes, and a recording replayed by the simulator.

use std::time::Duration;

use radar_driver::{
    Azimuth, Driver, DriverHandle, DriverSettings, HandoffSettings, MetricsSnapshot, Rotation,
};
use sim_sensor::scene::shipped;
use sim_sensor::{FaultScope, FaultSettings, SimHandle, SimOptions, SimServer, SourceSpec, Stall};

const BOUND: Duration = Duration::from_secs(60);
const STEP: Duration = Duration::from_secs(10);

fn settings(addr: std::net::SocketAddr) -> DriverSettings {
    let mut s = DriverSettings::new(addr);
    s.watchdog_timeout = Duration::from_millis(1000);
    s.backoff.initial = Duration::from_millis(10);
    s.backoff.max = Duration::from_millis(50);
    s.handoff = HandoffSettings {
        azimuth_capacity: Some(100_000),
        rotation_capacity: Some(1000),
        drop_policy: radar_driver::DropPolicy::DropNewest,
    };
    s
}

async fn sim(configure: impl FnOnce(&mut SimOptions)) -> SimHandle {
    let scene = shipped::load("penetration-wood").expect("a shipped scene");
    let mut options = SimOptions::for_tests(scene);
    options.odometry_bind = None;
    configure(&mut options);
    SimServer::spawn(options)
        .await
        .expect("the simulator starts")
}

/// Collects azimuths until `n` arrived (or `STEP` passes without one).
async fn collect(rx: &crossbeam_channel::Receiver<Azimuth>, n: usize) -> Vec<Azimuth> {
    let rx = rx.clone();
    tokio::task::spawn_blocking(move || {
        let mut out = Vec::new();
        while out.len() < n {
            match rx.recv_timeout(STEP) {
                Ok(a) => out.push(a),
                Err(_) => break,
            }
        }
        out
    })
    .await
    .unwrap()
}

fn sweeps(az: &[Azimuth]) -> Vec<u16> {
    az.iter().map(|a| a.sweep_counter).collect()
}

/// The sweep counters are strictly increasing; returns how many are missing in between.
fn missing_between(az: &[Azimuth]) -> u32 {
    let s = sweeps(az);
    let mut missing = 0;
    for w in s.windows(2) {
        assert!(
            w[1] > w[0],
            "out of order or duplicated: {} then {}",
            w[0],
            w[1]
        );
        missing += u32::from(w[1] - w[0] - 1);
    }
    missing
}

/// Runs a driver until `n` azimuths arrived, stops it, and returns every azimuth it
/// delivered (those that arrived before the stop included), so counts match the metrics.
async fn run(sim: &SimHandle, n: usize) -> (Vec<Azimuth>, Vec<Rotation>, MetricsSnapshot) {
    let (driver, rx) = Driver::new(settings(sim.local_addr()));
    let handle: DriverHandle = driver.spawn();
    let az_rx = rx.azimuths.unwrap();
    let mut az = collect(&az_rx, n).await;
    assert_eq!(az.len(), n, "{n} azimuths within the time allowed");
    let exit = handle.stop().await.unwrap();
    az.extend(az_rx.try_iter());
    assert_eq!(az.len() as u64, exit.metrics.azimuths_sent);
    let rotations: Vec<Rotation> = rx.rotations.unwrap().try_iter().collect();
    (az, rotations, exit.metrics)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_simulators_stream_arrives_whole_in_rotations_with_its_own_geometry() {
    tokio::time::timeout(BOUND, async {
        let sim = sim(|_| {}).await;
        let samples = usize::from(sim.configuration().azimuth_samples);
        let (az, rotations, m) = run(&sim, 3 * samples + 1).await;
        assert!(az.len() > 3 * samples);
        assert_eq!(missing_between(&az), 0);
        let geometry = sim.configuration().geometry().unwrap();
        assert_eq!(*az[0].geometry, geometry);
        assert!(az.windows(2).all(|w| w[1].timestamp_s > w[0].timestamp_s));
        // Range from the fixed part and from the protobuf's resolution agree.
        if let Some(by_resolution) = geometry.bin_range_m_by_resolution(100.0) {
            assert!(
                (geometry.bin_range_m(100.0) - by_resolution).abs()
                    < 0.01 * geometry.bin_range_m(100.0).abs().max(1.0)
            );
        }
        let complete: Vec<&Rotation> = rotations.iter().filter(|r| r.complete).collect();
        assert!(complete.len() >= 2, "{} complete rotations", complete.len());
        for r in complete {
            assert_eq!(r.azimuths.len(), samples);
            assert_eq!(r.skipped_azimuths, 0);
            assert!(r.azimuths.windows(2).all(|w| w[1].encoder > w[0].encoder));
        }
        assert_eq!(m.decode_errors.total(), 0);
        assert_eq!(m.reconnects, 0);
        sim.shutdown().await.unwrap();
    })
    .await
    .expect("bounded");
}

async fn with_fault(
    faults: FaultSettings,
    n: usize,
) -> (Vec<Azimuth>, MetricsSnapshot, sim_sensor::SimStatsSnapshot) {
    let sim = sim(|o| {
        o.faults = faults;
        o.fault_scope = FaultScope::FirstConnections(1);
    })
    .await;
    let (az, _, m) = run(&sim, n).await;
    let stats = sim.stats();
    sim.shutdown().await.unwrap();
    (az, m, stats)
}

fn nz(n: u64) -> Option<std::num::NonZeroU64> {
    std::num::NonZeroU64::new(n)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn after_the_simulator_drops_the_connection_every_later_azimuth_arrives() {
    tokio::time::timeout(BOUND, async {
        let faults = FaultSettings {
            drop_after_messages: nz(50),
            ..FaultSettings::default()
        };
        let (az, m, _) = with_fault(faults, 300).await;
        assert!(az.len() >= 300);
        assert_eq!(
            missing_between(&az),
            0,
            "nothing lost across the reconnection"
        );
        assert_eq!(m.reconnects, 1);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn after_a_cut_frame_only_that_azimuth_is_missing() {
    tokio::time::timeout(BOUND, async {
        let faults = FaultSettings {
            cut_frame_at_message: nz(40),
            ..FaultSettings::default()
        };
        let (az, m, _) = with_fault(faults, 300).await;
        assert!(az.len() >= 300);
        assert_eq!(missing_between(&az), 1);
        assert_eq!(m.reconnects, 1);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn corrupt_frames_cost_only_themselves() {
    tokio::time::timeout(BOUND, async {
        let faults = FaultSettings {
            corrupt_every_n: nz(25),
            ..FaultSettings::default()
        };
        let (az, m, _) = with_fault(faults, 300).await;
        assert!(az.len() >= 300);
        let missing = missing_between(&az);
        assert!(missing >= 10, "{missing}");
        assert_eq!(u64::from(missing), m.sweep_missing);
        assert!(m.decode_errors.signature >= u64::from(missing));
        assert_eq!(m.reconnects, 0);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn skipped_azimuths_are_counted_as_skipped_and_as_sweep_gaps() {
    tokio::time::timeout(BOUND, async {
        let faults = FaultSettings {
            skip_azimuth_every_n: nz(10),
            ..FaultSettings::default()
        };
        let (az, m, _) = with_fault(faults, 300).await;
        assert!(az.len() >= 300);
        let missing = missing_between(&az);
        assert!(missing >= 29, "{missing}");
        assert_eq!(m.sweep_missing, u64::from(missing));
        assert_eq!(m.skipped_azimuths, u64::from(missing));
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stall_longer_than_the_watchdog_costs_a_reconnect_and_no_azimuth() {
    tokio::time::timeout(BOUND, async {
        let faults = FaultSettings {
            stall: Some(Stall {
                after_messages: nz(30).unwrap(),
                duration: Duration::from_millis(2500),
            }),
            ..FaultSettings::default()
        };
        let (az, m, _) = with_fault(faults, 300).await;
        assert!(az.len() >= 300);
        assert_eq!(missing_between(&az), 0);
        assert_eq!((m.watchdog_timeouts, m.reconnects), (1, 1));
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_oversized_length_costs_one_frame() {
    tokio::time::timeout(BOUND, async {
        let faults = FaultSettings {
            oversized_at_message: nz(20),
            ..FaultSettings::default()
        };
        let (az, m, _) = with_fault(faults, 300).await;
        assert!(az.len() >= 300);
        assert_eq!(missing_between(&az), 1);
        assert_eq!(m.decode_errors.oversized, 1);
        assert_eq!(m.reconnects, 0);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_keep_alives_a_finished_stream_trips_the_watchdog() {
    tokio::time::timeout(BOUND, async {
        let sim = sim(|o| {
            o.faults = FaultSettings {
                no_keepalive: true,
                ..FaultSettings::default()
            };
            o.stop_after_azimuths = Some(100);
        })
        .await;
        let (driver, rx) = Driver::new(settings(sim.local_addr()));
        let handle = driver.spawn();
        let az = collect(rx.azimuths.as_ref().unwrap(), 100).await;
        assert_eq!(az.len(), 100);
        // The scene has ended and no keep-alive comes: silence is a dead link, and the
        // driver reconnects.
        let deadline = tokio::time::Instant::now() + STEP;
        while handle.metrics().reconnects == 0 && tokio::time::Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let m = handle.stop().await.unwrap().metrics;
        assert!(m.watchdog_timeouts >= 1);
        assert!(m.reconnects >= 1);
        sim.shutdown().await.unwrap();
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recording_made_by_the_driver_is_replayed_by_the_simulator_azimuth_for_azimuth() {
    tokio::time::timeout(BOUND, async {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sim.colossus");
        let live = sim(|_| {}).await;
        let mut s = settings(live.local_addr());
        s.record_path = Some(path.clone());
        let (driver, rx) = Driver::new(s);
        let handle = driver.spawn();
        let recorded = collect(rx.azimuths.as_ref().unwrap(), 250).await;
        let exit = handle.stop().await.unwrap();
        live.shutdown().await.unwrap();
        assert!(exit.recording.unwrap().bytes_written > 0);

        let replay = sim(|o| o.source = SourceSpec::RawStream(path.clone())).await;
        let (driver, rx) = Driver::new(settings(replay.local_addr()));
        let handle = driver.spawn();
        let replayed = collect(rx.azimuths.as_ref().unwrap(), 250).await;
        handle.stop().await.unwrap();
        replay.shutdown().await.unwrap();
        // The recording may hold a few azimuths more than were collected live.
        assert!(replayed.len() >= 250, "{} replayed", replayed.len());
        for (a, b) in recorded.iter().zip(&replayed) {
            assert_eq!(
                (a.encoder, a.sweep_counter, a.width),
                (b.encoder, b.sweep_counter, b.width)
            );
            assert_eq!(a.timestamp_s, b.timestamp_s);
            assert_eq!(a.bins, b.bins);
            assert_eq!(*a.geometry, *b.geometry);
        }
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_simulators_odometry_stream_parses_without_a_bad_line() {
    use radar_driver::{
        shutdown_pair, OdometryPoll, OdometrySource, TcpOdometry, TcpOdometrySettings,
    };
    tokio::time::timeout(BOUND, async {
        let scene = shipped::load("penetration-wood").expect("a shipped scene");
        let mut options = SimOptions::for_tests(scene);
        options.pacing = sim_sensor::Pacing::Realtime;
        let sim = SimServer::spawn(options).await.unwrap();
        let addr = sim.odometry_addr().expect("an odometry port");
        let (trigger, shutdown) = shutdown_pair();
        let mut src = TcpOdometry::spawn(
            &tokio::runtime::Handle::current(),
            TcpOdometrySettings::new(addr),
            shutdown,
        );
        let records = tokio::task::block_in_place(|| {
            let mut out = Vec::new();
            while out.len() < 10 {
                match src.poll_next(STEP) {
                    Ok(OdometryPoll::Record(r)) => out.push(r),
                    other => panic!("expected a record, got {other:?}"),
                }
            }
            out
        });
        assert!(records
            .windows(2)
            .all(|w| w[1].timestamp_s > w[0].timestamp_s));
        assert!(records
            .iter()
            .all(|r| r.speed_mps.is_finite() && r.steer_rad.is_finite()));
        assert_eq!(src.stats().line_errors, 0);
        trigger.trigger();
        sim.shutdown().await.unwrap();
    })
    .await
    .expect("bounded");
}
