//! A whole frame whose last bytes could begin the next frame's signature (`00 01`) is held
//! by the decoder until more bytes tell a cut frame from a whole one. A radar that sends
//! such a frame and then waits (its configuration, before the client asks for data; its
//! last azimuth before a pause) must not have it held until the watchdog ends the session:
//! the driver takes it after a short wait for more bytes. Both tests use a fake radar on
//! 127.0.0.1:0 that keeps the connection open and silent after the frame.

mod common;

use std::time::Duration;

use bytes::Bytes;
use common::*;
use protocol::{BinWidth, Configuration, ConfigurationData, FftData, Message};
use radar_driver::Driver;

const BOUND: Duration = Duration::from_secs(30);
/// Well inside the tests' 1 s watchdog, well over the driver's wait for more bytes.
const PROMPTLY: Duration = Duration::from_millis(500);

/// `small_configuration` without a protobuf part and with a range offset whose last two
/// bytes, the frame's last two, are `00 01` (-0.25 m and one unit in the last place).
fn configuration_ending_in_00_01() -> Configuration {
    let config = Configuration {
        range_offset_m: f32::from_bits(0xBE80_0001),
        data: ConfigurationData::default(),
        ..small_configuration()
    };
    let bytes = frame(&Message::Configuration(Box::new(config.clone())));
    assert_eq!(bytes[bytes.len() - 2..], [0, 1], "the frame ends in 00 01");
    config
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_configuration_ending_in_the_start_of_a_signature_is_answered_promptly() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (driver, _rx) = Driver::new(test_settings(radar.addr));
        let handle = driver.spawn();
        let mut conn = radar.accept().await;
        conn.send_message(&Message::Configuration(Box::new(
            configuration_ending_in_00_01(),
        )))
        .await;
        let answer = tokio::time::timeout(PROMPTLY, conn.recv()).await;
        assert_eq!(
            answer.ok().flatten().map(|m| m.id()),
            Some(21),
            "the driver asks for FFT data within {PROMPTLY:?} of the configuration"
        );
        let exit = handle.stop().await.unwrap();
        assert_eq!(
            (exit.metrics.configurations, exit.metrics.watchdog_timeouts),
            (1, 0)
        );
    })
    .await
    .expect("bounded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_azimuth_ending_in_the_start_of_a_signature_is_delivered_before_more_bytes_come() {
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let (driver, rx) = Driver::new(test_settings(radar.addr));
        let handle = driver.spawn();
        let mut conn = radar.accept().await;
        let config = small_configuration();
        conn.handshake(&config).await;
        send_ffts(&mut conn, &config, 0..5).await;
        let azimuths = rx.azimuths.as_ref().unwrap();
        assert_eq!(sweeps(&take_async(azimuths, 5).await), [0, 1, 2, 3, 4]);
        // Azimuth 5, its last two bins 0 and 1; then the radar says nothing more.
        let mut bins = bins_for(5, 32).to_vec();
        bins[30..].copy_from_slice(&[0, 1]);
        conn.send_message(&Message::FftData(FftData::new(
            BinWidth::Eight,
            5,
            encoder_of(&config, 5),
            timestamp_for(5),
            Bytes::from(bins.clone()),
        )))
        .await;
        let sent = std::time::Instant::now();
        let rx5 = azimuths.clone();
        let got = tokio::task::spawn_blocking(move || rx5.recv_timeout(PROMPTLY))
            .await
            .unwrap()
            .unwrap_or_else(|_| {
                panic!(
                    "azimuth 5 not delivered {:?} after it was sent",
                    sent.elapsed()
                )
            });
        assert_eq!((got.sweep_counter, &got.bins[..]), (5, &bins[..]));
        // The connection is still open: the next azimuth after the pause is taken too.
        send_ffts(&mut conn, &config, 6..7).await;
        assert_eq!(sweeps(&take_async(azimuths, 1).await), [6]);
        let exit = handle.stop().await.unwrap();
        assert_eq!(exit.metrics.watchdog_timeouts, 0);
    })
    .await
    .expect("bounded");
}
