//! The `radar-driver` binary against the in-test fake radar.

mod common;

use std::process::Stdio;
use std::time::Duration;

use common::*;
use tokio::process::Command;

const BOUND: Duration = Duration::from_secs(60);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_cli_prints_the_configuration_and_rates_and_records_the_stream() {
    tokio::time::timeout(BOUND, async {
        let dir = tempfile::tempdir().unwrap();
        let record = dir.path().join("cli.colossus");
        let radar = FakeRadar::bind().await;
        let child = Command::new(env!("CARGO_BIN_EXE_radar-driver"))
            .args([
                "--address",
                &radar.addr.to_string(),
                "--duration-s",
                "1",
                "--interval-s",
                "0.25",
                "--record",
            ])
            .arg(&record)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .kill_on_drop(true)
            .spawn()
            .unwrap();
        let config = small_configuration();
        let mut conn = radar.accept().await;
        assert_eq!(conn.handshake(&config).await, 21);
        send_ffts(&mut conn, &config, 0..100).await;
        // The CLI stops by itself and sends stop (22) first.
        assert_eq!(conn.recv().await.map(|m| m.id()), Some(22));
        let out = child.wait_with_output().await.unwrap();
        assert!(out.status.success());
        let text = String::from_utf8(out.stdout).unwrap();
        assert!(text.contains("azimuth samples     16"), "{text}");
        assert!(text.contains("az/s"), "{text}");
        assert!(text.contains("100 azimuths (0 dropped)"), "{text}");
        let recorded = std::fs::read(&record).unwrap();
        let expected_len = frame(&protocol::Message::Configuration(Box::new(config.clone()))).len()
            + (0..100).map(|s| fft_frame(&config, s).len()).sum::<usize>();
        assert_eq!(recorded.len(), expected_len);
    })
    .await
    .expect("bounded");
}

#[tokio::test]
async fn bad_arguments_exit_with_an_error_and_a_message() {
    let out = Command::new(env!("CARGO_BIN_EXE_radar-driver"))
        .args(["--address", "not-an-address"])
        .output()
        .await
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--address"));
    let out = Command::new(env!("CARGO_BIN_EXE_radar-driver"))
        .args(["--address", "127.0.0.1:1", "--interval-s", "0"])
        .output()
        .await
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("interval"));
}
