//! Idle or never-reading clients give their slot back: a client that does not read is
//! dropped after the write timeout, one that never asks for data after the idle timeout.

mod common;

use std::time::Duration;

use common::TestClient;
use protocol::Message;
use sim_sensor::scene::shipped;
use sim_sensor::{Pacing, SimOptions, SimServer};

const BOUND: Duration = Duration::from_secs(30);

fn one_slot() -> SimOptions {
    let mut o = SimOptions::for_tests(shipped::load("outdoor-field").expect("scene"));
    o.max_clients = 1;
    o.pacing = Pacing::AsFastAsPossible;
    o.write_timeout = Duration::from_millis(500);
    o.idle_timeout = Duration::from_millis(500);
    o
}

#[tokio::test]
async fn a_client_that_never_asks_for_data_gives_its_slot_back() {
    tokio::time::timeout(BOUND, async {
        let handle = SimServer::spawn(one_slot()).await.expect("spawn");
        let mut idle = TestClient::connect(handle.local_addr()).await;
        idle.configuration().await;
        tokio::time::sleep(Duration::from_millis(900)).await;
        let mut next = TestClient::connect(handle.local_addr()).await;
        let config = next.configuration().await;
        assert!(config.azimuth_samples > 0);
    })
    .await
    .expect("bounded");
}

#[tokio::test]
async fn a_client_that_stops_reading_is_dropped_and_its_slot_freed() {
    tokio::time::timeout(BOUND, async {
        let handle = SimServer::spawn(one_slot()).await.expect("spawn");
        let mut stuck = TestClient::connect(handle.local_addr()).await;
        stuck.configuration().await;
        stuck.send(Message::StartFftData).await;
        // It never reads again: the socket buffers fill, the write times out.
        let mut next = None;
        for _ in 0..40 {
            tokio::time::sleep(Duration::from_millis(250)).await;
            let mut c = TestClient::connect(handle.local_addr()).await;
            if let Some(Message::Configuration(_)) = c.next_within(Duration::from_millis(300)).await
            {
                next = Some(c);
                break;
            }
        }
        assert!(next.is_some(), "the slot was never freed");
        drop(stuck);
    })
    .await
    .expect("bounded");
}

// The simulator's process frozen (kill -STOP: the daemon runs it in its own process) past
// the write timeout while its client's socket was full, the client reading again a moment
// after the simulator resumes (it was frozen too). The write's deadline was noticed late
// (this process was not running), so the client is given a moment; before, the simulator
// dropped it at once ("took no data for ..."), and the daemon had to reconnect.
#[test]
fn a_simulator_frozen_past_its_write_timeout_gives_its_client_a_moment_on_resume() {
    use std::io::{Read, Write};
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::sync::Arc;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let mut options = one_slot();
    options.write_timeout = Duration::from_secs(1);
    let handle = runtime.block_on(SimServer::spawn(options)).expect("spawn");
    let address = handle.local_addr();
    let reading = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicBool::new(false));
    let after_resume = Arc::new(AtomicU64::new(0));
    // The client, on a thread of its own: asks for data, then reads only while `reading`.
    let client = {
        let (reading, done, after_resume) = (
            Arc::clone(&reading),
            Arc::clone(&done),
            Arc::clone(&after_resume),
        );
        std::thread::spawn(move || -> bool {
            let mut s = std::net::TcpStream::connect(address).unwrap();
            s.set_read_timeout(Some(Duration::from_millis(100)))
                .unwrap();
            let mut start = bytes::BytesMut::new();
            Message::StartFftData.encode(&mut start).unwrap();
            s.write_all(&start).unwrap();
            let mut buf = vec![0u8; 1 << 16];
            let deadline = std::time::Instant::now() + BOUND;
            while !done.load(Ordering::Relaxed) && std::time::Instant::now() < deadline {
                if !reading.load(Ordering::Relaxed) {
                    std::thread::sleep(Duration::from_millis(1));
                    continue;
                }
                match s.read(&mut buf) {
                    Ok(0) => return false, // dropped by the simulator
                    Ok(n) => {
                        after_resume.fetch_add(n as u64, Ordering::Relaxed);
                    }
                    Err(_) => {} // nothing within 100 ms
                }
            }
            true
        })
    };
    // Let the client connect and the simulator fill the socket (it then waits to write).
    runtime.block_on(async { tokio::time::sleep(Duration::from_millis(300)).await });
    // Frozen for 1.5 write timeouts; the client reads again 100 ms after the resume.
    std::thread::sleep(Duration::from_millis(1500));
    let resume = Arc::clone(&reading);
    let client_resumes = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(100));
        resume.store(true, Ordering::Relaxed);
    });
    runtime.block_on(async { tokio::time::sleep(Duration::from_millis(1500)).await });
    client_resumes.join().unwrap();
    done.store(true, Ordering::Relaxed);
    let kept = client.join().unwrap();
    let read = after_resume.load(Ordering::Relaxed);
    runtime.block_on(async {
        let _ = tokio::time::timeout(Duration::from_secs(5), handle.shutdown()).await;
    });
    assert!(
        kept,
        "the simulator dropped its client on resume ({read} bytes read after)"
    );
    assert!(
        read > 1 << 20,
        "the stream went on after the resume: {read} bytes"
    );
}
