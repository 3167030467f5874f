//! The session over loopback: handshake, a rotation checked field by field, clean shutdown.

mod common;

use std::time::Duration;

use common::*;
use protocol::BinWidth;
use radar_driver::Driver;

const BOUND: Duration = Duration::from_secs(30);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_driver_waits_for_the_configuration_then_requests_fft_data_and_stops_it_on_shutdown() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (driver, _rx) = Driver::new(test_settings(radar.addr));
        let handle = driver.spawn();
        let mut conn = radar.accept().await;
        // Nothing is asked for before the radar has spoken.
        assert!(
            tokio::time::timeout(Duration::from_millis(200), conn.recv())
                .await
                .is_err(),
            "the client must not send anything before the configuration"
        );
        assert_eq!(conn.handshake(&small_configuration()).await, 21);
        let mut watch = handle.configuration();
        tokio::time::timeout(STEP, watch.wait_for(Option::is_some))
            .await
            .expect("the configuration is published")
            .unwrap();
        assert_eq!(
            watch.borrow().as_deref(),
            Some(&small_configuration()),
            "the configuration is published as received"
        );
        handle.shutdown();
        assert_eq!(
            conn.recv().await.map(|m| m.id()),
            Some(22),
            "stop FFT data before closing"
        );
        assert!(conn.closed_by_client().await);
        let exit = handle.join().await.unwrap();
        assert_eq!(exit.metrics.configurations, 1);
        assert_eq!(exit.metrics.connections, 1);
        assert_eq!(exit.metrics.reconnects, 0);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn non_contoured_data_is_requested_with_message_140() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let mut settings = test_settings(radar.addr);
        settings.non_contoured = true;
        let (driver, _rx) = Driver::new(settings);
        let handle = driver.spawn();
        let mut conn = radar.accept().await;
        assert_eq!(conn.handshake(&small_configuration()).await, 140);
        handle.stop().await.unwrap();
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rotation_arrives_with_every_field_as_the_radar_sent_it() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (driver, rx) = Driver::new(test_settings(radar.addr));
        let handle = driver.spawn();
        let mut conn = radar.accept().await;
        let config = small_configuration();
        conn.handshake(&config).await;
        // Two whole rotations and the first azimuth of a third, which closes the second.
        send_ffts(&mut conn, &config, 0..33).await;
        let rotations = take_async(rx.rotations.as_ref().unwrap(), 2).await;
        let azimuths = take_async(rx.azimuths.as_ref().unwrap(), 33).await;
        assert_eq!(sweeps(&azimuths), (0..33).collect::<Vec<u16>>());

        for (seq, rot) in rotations.iter().enumerate() {
            assert_eq!(rot.sequence, seq as u64);
            assert!(rot.complete);
            assert_eq!(
                (
                    rot.skipped_azimuths,
                    rot.sweep_gaps,
                    rot.sweep_missing,
                    rot.duplicate_azimuths
                ),
                (0, 0, 0, 0)
            );
            assert_eq!(rot.azimuths.len(), 16);
            let g = &rot.geometry;
            assert_eq!(
                (
                    g.azimuth_samples,
                    g.encoder_size,
                    g.range_in_bins,
                    g.packet_rate
                ),
                (16, 5600, 32, 64)
            );
            assert!((g.bin_size_m - 0.0438).abs() < 1e-12);
            assert!((g.rotation_hz - 4.0).abs() < 1e-12);
            assert_eq!((g.range_gain, g.range_offset_m), (1.0, -0.25));
            assert_eq!(g.data_width, BinWidth::Eight);
            assert!((g.range_resolution_m.unwrap() - 0.0438).abs() < 1e-7);
            for (k, az) in rot.azimuths.iter().enumerate() {
                let sweep = (seq * 16 + k) as u64;
                assert_eq!(az.encoder, (k * 350) as u16);
                assert!((az.angle_rad - k as f64 * std::f64::consts::TAU / 16.0).abs() < 1e-12);
                assert!((az.timestamp_s - timestamp_for(sweep).as_secs_f64()).abs() < 1e-9);
                assert_eq!(u64::from(az.sweep_counter), sweep);
                assert_eq!(az.width, BinWidth::Eight);
                let bins = bins_for(sweep as u16, 32);
                assert_eq!(az.bins, bins);
                assert_eq!(az.bin_count(), 32);
                for (i, (db, raw)) in az.bins_db().zip(bins.iter()).enumerate() {
                    assert_eq!(db, f64::from(*raw) / 2.0);
                    assert_eq!(az.power_db(i), Some(db));
                }
                assert_eq!(az.power_db(32), None);
                assert!((az.range_m(10.0) - (10.0 * 0.0438 - 0.25)).abs() < 1e-12);
                assert!(std::sync::Arc::ptr_eq(&az.geometry, &rot.geometry));
            }
        }
        let exit = handle.stop().await.unwrap();
        let m = exit.metrics;
        assert_eq!(
            (
                m.fft_frames,
                m.azimuths_sent,
                m.azimuths_delivered,
                m.azimuth_drops
            ),
            (33, 33, 33, 0)
        );
        // The third rotation (one azimuth) is handed out as partial at shutdown.
        assert_eq!(m.rotations_sent, 3);
        let last = rx.rotations.unwrap().recv_timeout(STEP).unwrap();
        assert!(!last.complete);
        assert_eq!(last.azimuths.len(), 1);
        assert_eq!(m.decode_errors.total(), 0);
        assert_eq!(m.latency.count, 33);
        assert!(m.latency.p99_ns >= m.latency.median_ns);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_re_sent_configuration_replaces_the_geometry_and_restarts_the_data() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (driver, rx) = Driver::new(test_settings(radar.addr));
        let handle = driver.spawn();
        let mut conn = radar.accept().await;
        let config = small_configuration();
        conn.handshake(&config).await;
        send_ffts(&mut conn, &config, 0..5).await;
        let mut changed = config.clone();
        changed.azimuth_samples = 8;
        changed.range_in_bins = 16;
        changed.range_gain = 0.5;
        assert_eq!(
            conn.handshake(&changed).await,
            21,
            "start is sent again, as Navtech's SDK does"
        );
        send_ffts(&mut conn, &changed, 100..103).await;
        let az = take_async(rx.azimuths.as_ref().unwrap(), 8).await;
        assert_eq!(az[4].geometry.azimuth_samples, 16);
        assert_eq!(az[5].geometry.azimuth_samples, 8);
        assert_eq!(az[5].geometry.range_gain, 0.5);
        assert_eq!(az[5].encoder, encoder_of(&changed, 100));
        assert_eq!(az[5].bin_count(), 16);
        // The rotation in progress under the old geometry was closed as partial.
        let partial = rx.rotations.as_ref().unwrap().recv_timeout(STEP).unwrap();
        assert_eq!((partial.azimuths.len(), partial.complete), (5, false));
        let exit = handle.stop().await.unwrap();
        assert_eq!(exit.metrics.configurations, 2);
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn dropping_the_handle_stops_the_driver_cleanly() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (driver, rx) = Driver::new(test_settings(radar.addr));
        let handle = driver.spawn();
        let mut conn = radar.accept().await;
        conn.handshake(&small_configuration()).await;
        drop(handle);
        assert_eq!(conn.recv().await.map(|m| m.id()), Some(22));
        assert!(conn.closed_by_client().await);
        // The driver is gone: its channels disconnect.
        let az = rx.azimuths.unwrap();
        let gone = tokio::task::spawn_blocking(move || az.recv_timeout(STEP))
            .await
            .unwrap();
        assert_eq!(gone, Err(crossbeam_channel::RecvTimeoutError::Disconnected));
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_configuration_with_a_zero_range_gain_is_refused_with_a_clear_error() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let mut settings = test_settings(radar.addr);
        settings.max_attempts = std::num::NonZeroU32::new(1);
        let (driver, _receivers) = Driver::new(settings);
        let metrics = driver.metrics();
        let handle = driver.spawn();
        let mut conn = radar.accept().await;
        let mut config = small_configuration();
        config.range_gain = 0.0;
        conn.send_message(&protocol::Message::Configuration(Box::new(config)))
            .await;
        // No data is requested: the driver closes the connection instead.
        assert_eq!(conn.recv().await.map(|m| m.id()), None);
        let err = handle.join().await.unwrap_err();
        assert!(
            matches!(
                &err,
                radar_driver::DriverError::GaveUp {
                    last: radar_driver::SessionError::BadConfiguration(
                        protocol::GeometryError::NonPositiveRangeGain { .. }
                    ),
                    ..
                }
            ),
            "{err:?}"
        );
        let text = radar_driver::ErrorChain(&err).to_string();
        assert!(
            text.ends_with("the radar's configuration is unusable: range gain 0 is not positive"),
            "{text}"
        );
        let m = metrics.snapshot();
        assert_eq!((m.configurations, m.configurations_refused), (1, 1));
    })
    .await
    .expect("bounded");
}
