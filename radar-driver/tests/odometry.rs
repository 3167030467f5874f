//! The odometry client over loopback and from a file.

use std::io::Write;
use std::time::Duration;

use radar_driver::odometry::{LineError, ODOMETRY_HEADER};
use radar_driver::{
    shutdown_pair, FileOdometry, OdometryError, OdometryPoll, OdometryRecord, OdometrySource,
    TcpOdometry, TcpOdometrySettings,
};
use tokio::io::AsyncWriteExt;
use tokio::net::TcpListener;

const BOUND: Duration = Duration::from_secs(30);
const STEP: Duration = Duration::from_secs(5);

fn rec(t: f64, v: f64, s: f64) -> OdometryRecord {
    OdometryRecord {
        timestamp_s: t,
        speed_mps: v,
        steer_rad: s,
    }
}

/// The next record or error within `STEP` (blocking this worker, not the runtime).
async fn next(src: &mut TcpOdometry) -> Result<OdometryPoll, OdometryError> {
    tokio::task::block_in_place(|| match src.poll_next(STEP) {
        Ok(OdometryPoll::Pending) => panic!("nothing within {STEP:?}"),
        other => other,
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tcp_odometry_delivers_records_skips_bad_lines_and_survives_a_reconnect() {
    tokio::time::timeout(BOUND, async {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let mut settings = TcpOdometrySettings::new(listener.local_addr().unwrap());
        settings.backoff.initial = Duration::from_millis(10);
        settings.backoff.max = Duration::from_millis(50);
        let (trigger, shutdown) = shutdown_pair();
        let mut src = TcpOdometry::spawn(&tokio::runtime::Handle::current(), settings, shutdown);

        let (mut conn, _) = listener.accept().await.unwrap();
        let text = format!(
            "{ODOMETRY_HEADER}\n100.000000001 1.5 0.01\n100.05 1.6 -0.02\nbad line here\n{}\n100.1 1.7",
            "7".repeat(400)
        );
        conn.write_all(text.as_bytes()).await.unwrap();
        // The last record is split across two writes.
        conn.write_all(b" 0.03\n").await.unwrap();
        assert_eq!(next(&mut src).await.unwrap(), OdometryPoll::Record(rec(100.000000001, 1.5, 0.01)));
        assert_eq!(next(&mut src).await.unwrap(), OdometryPoll::Record(rec(100.05, 1.6, -0.02)));
        assert!(matches!(next(&mut src).await, Err(OdometryError::Line { line: 4, source: LineError::BadNumber { .. } })));
        assert!(matches!(next(&mut src).await, Err(OdometryError::Line { line: 5, source: LineError::TooLong { len: 400 } })));
        assert_eq!(next(&mut src).await.unwrap(), OdometryPoll::Record(rec(100.1, 1.7, 0.03)));
        drop(conn);

        // A new connection starts again with the header.
        let (mut conn, _) = tokio::time::timeout(STEP, listener.accept()).await.unwrap().unwrap();
        conn.write_all(format!("{ODOMETRY_HEADER}\n100.15 1.8 0\n").as_bytes()).await.unwrap();
        assert_eq!(next(&mut src).await.unwrap(), OdometryPoll::Record(rec(100.15, 1.8, 0.0)));
        let stats = src.stats();
        assert_eq!((stats.records, stats.line_errors, stats.connections), (4, 2, 2));

        trigger.trigger();
        // After the shutdown the source ends.
        let end = tokio::task::block_in_place(|| src.poll_next(STEP));
        assert_eq!(end.unwrap(), OdometryPoll::Ended);
    })
    .await
    .expect("bounded");
}

#[test]
fn file_odometry_reads_a_file_written_in_the_stream_format() {
    let mut f = tempfile::NamedTempFile::new().unwrap();
    writeln!(f, "{ODOMETRY_HEADER}").unwrap();
    for k in 0..1000 {
        writeln!(
            f,
            "{}",
            rec(1000.0 + f64::from(k) * 0.05, 2.0, 0.001 * f64::from(k)).to_line()
        )
        .unwrap();
    }
    f.flush().unwrap();
    let mut src = FileOdometry::open(f.path()).unwrap();
    let mut n = 0;
    while let OdometryPoll::Record(r) = src.poll_next(Duration::ZERO).unwrap() {
        assert!((r.timestamp_s - (1000.0 + f64::from(n) * 0.05)).abs() < 1e-9);
        n += 1;
    }
    assert_eq!(n, 1000);
}

/// The seam is object safe: a daemon holds any source as a box.
#[test]
fn any_odometry_source_can_stand_behind_the_trait() {
    mockall::mock! {
        Source {}
        impl OdometrySource for Source {
            fn poll_next(&mut self, timeout: Duration) -> Result<OdometryPoll, OdometryError>;
        }
    }
    let mut mock = MockSource::new();
    let mut seq = mockall::Sequence::new();
    mock.expect_poll_next()
        .times(1)
        .in_sequence(&mut seq)
        .returning(|_| Ok(OdometryPoll::Record(rec(1.0, 2.0, 3.0))));
    mock.expect_poll_next()
        .times(1)
        .in_sequence(&mut seq)
        .returning(|_| Ok(OdometryPoll::Ended));
    let mut boxed: Box<dyn OdometrySource> = Box::new(mock);
    assert_eq!(
        boxed.poll_next(Duration::ZERO).unwrap(),
        OdometryPoll::Record(rec(1.0, 2.0, 3.0))
    );
    assert_eq!(
        boxed.poll_next(Duration::ZERO).unwrap(),
        OdometryPoll::Ended
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_configured_source_is_opened_from_the_odometry_section() {
    let mut f = tempfile::NamedTempFile::new().unwrap();
    writeln!(f, "{ODOMETRY_HEADER}\n5.0 1.0 0.0").unwrap();
    let text = format!(
        "[odometry]\nsource = \"file\"\npath = {:?}\n",
        f.path().display().to_string()
    );
    let config = config::Config::from_toml_str(&text).unwrap();
    let (_trigger, shutdown) = shutdown_pair();
    let rt = tokio::runtime::Handle::current();
    let mut src = radar_driver::odometry::open_configured(&config.odometry, &rt, shutdown.clone())
        .unwrap()
        .expect("a file source");
    assert_eq!(
        src.poll_next(Duration::ZERO).unwrap(),
        OdometryPoll::Record(rec(5.0, 1.0, 0.0))
    );
    let none = config::Config::from_toml_str("[odometry]\nsource = \"none\"\n").unwrap();
    assert!(
        radar_driver::odometry::open_configured(&none.odometry, &rt, shutdown)
            .unwrap()
            .is_none()
    );
}

// The pipeline polls its odometry with a zero timeout for every azimuth. On a loaded machine
// (every core busy) such a poll must answer at once: crossbeam's recv_timeout spins and then
// yields the thread four times before it looks at its deadline, and each yield hands the
// core to a busy thread for a scheduler slice (11.5 ms an azimuth: the README's first command
// took 43 s instead of about 12 on one contended core). Here every core is kept busy by
// spinning threads while 50 zero-timeout polls of a connected, silent source are timed
// (before: 1.7 s and more; each poll gave the core away four times).
#[test]
fn a_zero_timeout_poll_of_a_silent_tcp_source_answers_at_once_on_a_busy_machine() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap();
    let listener = runtime.block_on(TcpListener::bind("127.0.0.1:0")).unwrap();
    let settings = TcpOdometrySettings::new(listener.local_addr().unwrap());
    let (trigger, shutdown) = shutdown_pair();
    let mut src = TcpOdometry::spawn(runtime.handle(), settings, shutdown);
    // Connected, header sent, then silent.
    let _conn = runtime.block_on(async {
        let (mut conn, _) = tokio::time::timeout(STEP, listener.accept())
            .await
            .unwrap()
            .unwrap();
        conn.write_all(format!("{ODOMETRY_HEADER}\n").as_bytes())
            .await
            .unwrap();
        conn
    });
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    let stop = Arc::new(AtomicBool::new(false));
    let busy: Vec<_> = (0..2 * cores)
        .map(|_| {
            let stop = Arc::clone(&stop);
            std::thread::spawn(move || {
                let deadline = std::time::Instant::now() + BOUND;
                while !stop.load(Ordering::Relaxed) && std::time::Instant::now() < deadline {
                    std::hint::spin_loop();
                }
            })
        })
        .collect();
    std::thread::sleep(Duration::from_millis(50));
    let started = std::time::Instant::now();
    for _ in 0..50 {
        assert_eq!(
            src.poll_next(Duration::ZERO).unwrap(),
            OdometryPoll::Pending
        );
    }
    let took = started.elapsed();
    stop.store(true, Ordering::Relaxed);
    for b in busy {
        b.join().unwrap();
    }
    trigger.trigger();
    assert!(
        took < Duration::from_millis(100),
        "50 zero-timeout polls took {took:?} on a busy machine"
    );
}

// The odometry client and its bridge frozen together past the idle timeout (the simulator
// runs in the daemon's process: kill -STOP stops both), the bridge resuming a moment after
// the client: on resume nothing is in the socket yet. The idle deadline was noticed late
// (this process was not running), so the bridge is given a moment before the link is
// judged; before, the client dropped the link at once, and the records the bridge had just
// written to it were lost with it (the simulator's next client starts after them).
#[test]
fn an_odometry_client_frozen_together_with_its_bridge_gives_it_a_moment_on_resume() {
    use std::io::{Read, Write as _};
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    use std::sync::Arc;
    const RECORDS: u64 = 300;
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap();
    let paused = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicBool::new(false));
    let connections = Arc::new(AtomicUsize::new(0));
    // The bridge: a record every 10 ms on its first connection, holding back while paused;
    // later connections are only counted.
    let bridge = {
        let (paused, done, connections) = (
            Arc::clone(&paused),
            Arc::clone(&done),
            Arc::clone(&connections),
        );
        std::thread::spawn(move || {
            let deadline = std::time::Instant::now() + BOUND;
            listener.set_nonblocking(true).unwrap();
            let mut held = Vec::new();
            let accept = |held: &mut Vec<std::net::TcpStream>| {
                if let Ok((s, _)) = listener.accept() {
                    s.set_nonblocking(false).unwrap();
                    connections.fetch_add(1, Ordering::Relaxed);
                    held.push(s);
                }
            };
            while held.is_empty() && std::time::Instant::now() < deadline {
                accept(&mut held);
                std::thread::sleep(Duration::from_millis(5));
            }
            let conn = &mut held[0];
            conn.write_all(format!("{ODOMETRY_HEADER}\n").as_bytes())
                .unwrap();
            for k in 0..RECORDS {
                while paused.load(Ordering::Relaxed) {
                    std::thread::sleep(Duration::from_millis(1));
                }
                let line = rec(100.0 + 0.01 * k as f64, 1.0, 0.0).to_line();
                if conn.write_all(format!("{line}\n").as_bytes()).is_err() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            while !done.load(Ordering::Relaxed) && std::time::Instant::now() < deadline {
                accept(&mut held);
                std::thread::sleep(Duration::from_millis(5));
            }
            // Drain what a dropped link left unread, so nothing blocks.
            let _ = held[0].set_nonblocking(true);
            let _ = held[0].read(&mut [0u8; 64]);
        })
    };
    // One thread: blocking it freezes the client as a stopped process would be frozen.
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let mut settings = TcpOdometrySettings::new(address);
    settings.idle_timeout = Duration::from_secs(1);
    settings.backoff.initial = Duration::from_millis(10);
    settings.backoff.max = Duration::from_millis(50);
    let (trigger, shutdown) = shutdown_pair();
    let mut src = TcpOdometry::spawn(runtime.handle(), settings, shutdown);
    let received = runtime.block_on(async {
        tokio::time::timeout(Duration::from_secs(10), async {
            let mut received = Vec::new();
            let mut frozen = false;
            while (received.len() as u64) < RECORDS {
                match src.poll_next(Duration::ZERO).unwrap() {
                    OdometryPoll::Record(r) => received.push(r.timestamp_s),
                    OdometryPoll::Pending => tokio::time::sleep(Duration::from_millis(5)).await,
                    OdometryPoll::Ended => break,
                }
                if !frozen && received.len() >= 20 {
                    // Both frozen for 1.5 idle timeouts; the bridge resumes 100 ms after.
                    frozen = true;
                    paused.store(true, Ordering::Relaxed);
                    std::thread::sleep(Duration::from_millis(1500));
                    let resume = Arc::clone(&paused);
                    std::thread::spawn(move || {
                        std::thread::sleep(Duration::from_millis(100));
                        resume.store(false, Ordering::Relaxed);
                    });
                }
            }
            received
        })
        .await
        .unwrap_or_default()
    });
    let stats = src.stats();
    trigger.trigger();
    done.store(true, Ordering::Relaxed);
    paused.store(false, Ordering::Relaxed);
    bridge.join().unwrap();
    assert_eq!(
        (connections.load(Ordering::Relaxed), stats.connections),
        (1, 1),
        "the link was kept: {stats:?}"
    );
    assert_eq!(received.len() as u64, RECORDS, "every record arrived");
}
