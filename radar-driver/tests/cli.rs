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
    // A radar on 127.0.0.1:0, held for the test's life: the refusal must come at parsing,
    // before any connection.
    let radar = FakeRadar::bind().await;
    let out = Command::new(env!("CARGO_BIN_EXE_radar-driver"))
        .args(["--address", &radar.addr.to_string(), "--interval-s", "0"])
        .output()
        .await
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("interval"));
}

#[tokio::test]
async fn out_of_range_values_are_refused_when_parsing_not_with_a_panic() {
    let cases: [&[&str]; 8] = [
        &["--duration-s", "1e20"],
        &["--duration-s", "NaN"],
        &["--duration-s", "inf"],
        &["--duration-s", "0"],
        &["--duration-s=-1"],
        &["--interval-s", "1e9"],
        &["--interval-s", "0"],
        &["--watchdog-ms", "0"],
    ];
    let radar = FakeRadar::bind().await;
    let address = radar.addr.to_string();
    for args in cases {
        let out = Command::new(env!("CARGO_BIN_EXE_radar-driver"))
            .args(["--address", &address])
            .args(args)
            .output()
            .await
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        let flag = args[0].split('=').next().unwrap_or_default();
        assert!(stderr.contains(flag), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_cli_ends_at_its_duration_not_at_the_next_rate_line() {
    use tokio::io::{AsyncBufReadExt, BufReader};
    tokio::time::timeout(BOUND, async {
        let radar = FakeRadar::bind().await;
        let mut child = Command::new(env!("CARGO_BIN_EXE_radar-driver"))
            .args(["--address", &radar.addr.to_string()])
            .args(["--duration-s", "1", "--interval-s", "5"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .kill_on_drop(true)
            .spawn()
            .unwrap();
        let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
        // Printed just before the driver starts (and the duration with it).
        let first = lines.next_line().await.unwrap().unwrap();
        let started = std::time::Instant::now();
        assert!(first.starts_with("connecting to"), "{first}");
        let config = small_configuration();
        let mut conn = radar.accept().await;
        assert_eq!(conn.handshake(&config).await, 21);
        send_ffts(&mut conn, &config, 0..10).await;
        assert_eq!(conn.recv().await.map(|m| m.id()), Some(22));
        let status = child.wait().await.unwrap();
        let took = started.elapsed();
        assert!(status.success());
        // 1 s, not the 5 s of the next rate line; the margin is for a loaded machine.
        assert!(
            took >= Duration::from_secs(1) && took < Duration::from_millis(1400),
            "took {took:?}"
        );
        while let Ok(Some(_)) = lines.next_line().await {}
    })
    .await
    .expect("bounded");
}
