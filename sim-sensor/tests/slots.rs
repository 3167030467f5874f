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
