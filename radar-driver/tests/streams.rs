//! The hand-off as async streams: azimuths and rotations arrive in order; a consumer that
//! asks for azimuths only gets no rotation assembled and none counted as dropped.

mod common;

use std::time::Duration;

use common::*;
use radar_driver::Driver;

const BOUND: Duration = Duration::from_secs(30);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn azimuths_and_rotations_arrive_on_async_streams_in_order() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (driver, mut streams) = Driver::with_streams(test_settings(radar.addr));
        let handle = driver.spawn();
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        send_ffts(&mut conn, &config, 0..40).await;
        let azimuths = streams.azimuths.as_mut().unwrap();
        let mut sweeps = Vec::new();
        for _ in 0..40 {
            sweeps.push(azimuths.next().await.unwrap().sweep_counter);
        }
        assert_eq!(sweeps, (0..40).collect::<Vec<u16>>());
        let rotations = streams.rotations.as_mut().unwrap();
        let first = rotations.next().await.unwrap();
        assert_eq!(first.azimuths.len(), 16);
        assert!(first.complete);
        handle.stop().await.unwrap();
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn azimuths_only_assembles_no_rotation_and_counts_none_dropped() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let mut settings = test_settings(radar.addr);
        settings.handoff.rotation_capacity = None;
        let (driver, mut streams) = Driver::with_streams(settings);
        assert!(streams.rotations.is_none());
        let handle = driver.spawn();
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        send_ffts(&mut conn, &config, 0..64).await;
        let azimuths = streams.azimuths.as_mut().unwrap();
        for _ in 0..64 {
            azimuths.next().await.unwrap();
        }
        let m = handle.stop().await.unwrap().metrics;
        assert_eq!((m.rotations_sent, m.rotation_drops), (0, 0));
    })
    .await
    .expect("bounded");
}
