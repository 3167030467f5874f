//! An odometry bridge on 127.0.0.1:0 whose link drops and comes back, read by the daemon's
//! TCP odometry client into the pipeline thread, against rendered radar azimuths: what the
//! bridge sends again after reconnecting (its last half second, as a bridge replaying its
//! buffer does) is dropped as duplicates, the odometry's clock is not resynchronised, no
//! held odometry is lost, and every pose equals the run whose link never dropped.

mod support;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use radar_driver::odometry::ODOMETRY_HEADER;
use radar_driver::{Shutdown, TcpOdometry, TcpOdometrySettings};
use slam_node::pipeline::{Pipeline, RunControl, RunReport};
use tokio::io::AsyncWriteExt;
use tokio::net::TcpListener;

const T0_NS: u64 = 1_700_000_000_000_000_000;
const T0: f64 = 1.7e9;
/// Fifteen rotations of the paper's radar: 6 s of stream.
const ROTATIONS: u64 = 15;
/// Records every 50 ms up to 0.5 s past the last azimuth.
const RECORDS: u64 = 130;
/// The bridge's link drops after this many records (at 2.95 s of stream)...
const DROP_AFTER: u64 = 60;
/// ...and on reconnecting it sends its last half second again.
const REPLAYED: u64 = 10;
/// Every wait of the test ends within this.
const BOUND: Duration = Duration::from_secs(60);

/// Record `k`'s line: a parked vehicle, stamped `T0 + k * 50 ms` exactly.
fn line(k: u64) -> String {
    let ns = T0_NS + k * 50_000_000;
    format!(
        "{}.{:09} 0.000000 0.000000\n",
        ns / 1_000_000_000,
        ns % 1_000_000_000
    )
}

/// Serves the records as fast as they are read. With `drop_after`, the first connection
/// ends after that many and the next one starts `REPLAYED` records earlier; the last
/// connection stays open until the test ends.
async fn bridge(listener: TcpListener, drop_after: Option<u64>) {
    let (mut from, mut drop_after) = (0, drop_after);
    loop {
        let Ok((mut socket, _)) = listener.accept().await else {
            return;
        };
        let to = drop_after.take().unwrap_or(RECORDS);
        let mut text = format!("{ODOMETRY_HEADER}\n");
        for k in from..to {
            text.push_str(&line(k));
        }
        if socket.write_all(text.as_bytes()).await.is_err() {
            return;
        }
        if to == RECORDS {
            // Hold the link open (the client would reconnect after a close).
            std::future::pending::<()>().await;
        }
        drop(socket);
        from = to - REPLAYED;
    }
}

/// Runs the pipeline thread over the azimuths with odometry from the bridge; returns the
/// report and the pose after every rotation.
fn run(drop_after: Option<u64>) -> (RunReport, Vec<(f64, f64, f64)>) {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    let listener = runtime
        .block_on(TcpListener::bind("127.0.0.1:0"))
        .expect("bind");
    let address = listener.local_addr().expect("address");
    runtime.spawn(bridge(listener, drop_after));
    let mut odometry_settings = TcpOdometrySettings::new(address);
    odometry_settings.backoff.initial = Duration::from_millis(20);
    odometry_settings.backoff.max = Duration::from_millis(50);
    let odometry = TcpOdometry::spawn(runtime.handle(), odometry_settings, Shutdown::never());

    let mut settings = support::still_radar_settings();
    // Each azimuth waits for the odometry reaching its time (the reconnection included):
    // what the pipeline is given is then the same however the threads are scheduled.
    settings.odometry_wait = Duration::from_secs(5);
    let pipeline = Pipeline::new(settings, Some(T0), None).expect("pipeline");
    let poses = Arc::new(Mutex::new(Vec::new()));
    let seen = Arc::clone(&poses);
    let stop = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicBool::new(false));
    let bound = {
        let (stop, done) = (Arc::clone(&stop), Arc::clone(&done));
        std::thread::spawn(move || {
            let deadline = Instant::now() + BOUND;
            while !done.load(Ordering::Relaxed) && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(20));
            }
            stop.store(true, Ordering::Relaxed);
        })
    };
    let report = support::run_queued(
        pipeline,
        support::still_radar_azimuths(ROTATIONS, T0_NS),
        Box::new(odometry),
        RunControl {
            stop,
            max_stream_s: None,
            progress: Some(Box::new(move |_, ekf| {
                let p = ekf.pose();
                seen.lock().expect("poses").push((p.x, p.y, p.theta));
            })),
            end_after_silence: None,
            played_out: None,
        },
    );
    done.store(true, Ordering::Relaxed);
    bound.join().expect("bound");
    runtime.shutdown_timeout(Duration::from_secs(1));
    let poses = poses.lock().expect("poses").clone();
    (report, poses)
}

#[test]
fn records_a_reconnected_odometry_bridge_sends_again_are_dropped_as_duplicates_and_mapping_goes_on()
{
    let (undisturbed, undisturbed_poses) = run(None);
    let u = &undisturbed.summary;
    assert_eq!(u.odometry_samples, RECORDS);
    assert_eq!(u.refused.stale_odometry + u.refused.no_odometry, 0);
    assert!(u.beams > 0 && u.rotations >= ROTATIONS - 1, "{u:?}");

    let (report, poses) = run(Some(DROP_AFTER));
    let s = &report.summary;
    let moved = poses
        .iter()
        .zip(&undisturbed_poses)
        .filter(|(a, b)| a != b)
        .count();
    eprintln!(
        "after the reconnection: {} duplicates, {} refused, {} odometry clock jumps, {} beams refused as stale, {} filter errors, {} beams (undisturbed {}), {moved} of {} poses differ",
        s.odometry_duplicates,
        s.odometry_refused,
        s.odometry_clock_jumps,
        s.refused.stale_odometry,
        s.filter_errors,
        s.beams,
        u.beams,
        poses.len()
    );
    assert_eq!(
        s.odometry_samples,
        RECORDS + REPLAYED,
        "the replay was read"
    );
    assert_eq!(
        (
            s.odometry_duplicates,
            s.odometry_refused,
            s.odometry_clock_jumps
        ),
        (REPLAYED, 0, 0),
        "the replay is duplicates, not a wild clock"
    );
    assert_eq!(
        (
            s.refused.stale_odometry,
            s.refused.no_odometry,
            s.filter_errors
        ),
        (0, 0, 0),
        "no held odometry was lost"
    );
    assert_eq!(
        (s.rotations, s.beams, s.associations),
        (u.rotations, u.beams, u.associations)
    );
    assert_eq!(
        poses, undisturbed_poses,
        "every pose equals the undisturbed run's"
    );
}
