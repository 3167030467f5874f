//! Real recorded radar data end to end: the Oxford Radar RobotCar scans (read from
//! `../shared/data/oxford-radar-robotcar`, skipped with a message when absent), served by
//! sim-sensor's replay on the Colossus protocol over loopback and received by radar-driver,
//! arrive bin for bin, with every encoder value and timestamp, exactly as the PNG reader
//! gives them. This is the equivalence the evaluation relies on when it reads the scans
//! with the PNG reader directly.

use std::path::{Path, PathBuf};
use std::time::Duration;

use radar_driver::{Azimuth, BinWidth, Driver, DriverSettings, DropPolicy, HandoffSettings};
use sim_sensor::replay::png::read_polar_png;
use sim_sensor::scene::shipped;
use sim_sensor::{SimOptions, SimServer, SourceSpec};

fn oxford_radar_dir() -> Option<PathBuf> {
    let dir =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/oxford-radar-robotcar/radar");
    if dir.is_dir() {
        Some(dir)
    } else {
        println!(
            "SKIPPED: the Oxford Radar RobotCar scans are not at {} (they live in ../shared beside the workspace)",
            dir.display()
        );
        None
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn oxford_scans_replayed_by_the_simulator_reach_the_driver_bin_for_bin() {
    let Some(dir) = oxford_radar_dir() else {
        return;
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("the scans folder")
        .map(|e| e.expect("an entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    files.sort();
    let expected: Vec<_> = files
        .iter()
        .flat_map(|f| read_polar_png(f).expect("a polar scan").rows)
        .collect();
    assert_eq!(expected.len(), files.len() * 400);

    let mut options = SimOptions::for_tests(shipped::load("penetration-wood").expect("scene"));
    options.source = SourceSpec::OxfordPng(dir);
    options.odometry_bind = None;
    let sim = SimServer::spawn(options)
        .await
        .expect("the simulator starts");

    let mut settings = DriverSettings::new(sim.local_addr());
    settings.handoff = HandoffSettings {
        azimuth_capacity: Some(expected.len() + 16),
        rotation_capacity: None,
        drop_policy: DropPolicy::DropNewest,
    };
    let (driver, receivers) = Driver::new(settings);
    let handle = driver.spawn();
    let azimuths = receivers.azimuths.expect("the per-azimuth channel");
    let n = expected.len();
    let received: Vec<Azimuth> = tokio::task::spawn_blocking(move || {
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            match azimuths.recv_timeout(Duration::from_secs(20)) {
                Ok(a) => out.push(a),
                Err(_) => break,
            }
        }
        out
    })
    .await
    .expect("the collector");
    let exit = handle.stop().await.expect("the driver stops cleanly");
    sim.shutdown().await.expect("the simulator stops");

    assert_eq!(received.len(), n, "every recorded azimuth arrived");
    assert_eq!(exit.metrics.azimuth_drops, 0);
    for (k, (az, row)) in received.iter().zip(&expected).enumerate() {
        let (scan, r) = (k / 400, k % 400);
        assert_eq!(az.encoder, row.encoder, "scan {scan} row {r}: encoder");
        let us = (az.timestamp_s * 1e6).round() as i64;
        assert_eq!(us, row.timestamp_us, "scan {scan} row {r}: timestamp");
        assert_eq!(az.width, BinWidth::Eight);
        assert_eq!(
            az.bins.as_ref(),
            row.bins.as_slice(),
            "scan {scan} row {r}: bins"
        );
        let angle = f64::from(row.encoder) * std::f64::consts::TAU / 5600.0;
        assert!(
            (az.angle_rad - angle).abs() < 1e-12,
            "scan {scan} row {r}: angle"
        );
    }
    // The geometry the driver took from the replay's configuration message.
    let g = &received[0].geometry;
    assert_eq!(
        (g.azimuth_samples, g.range_in_bins, g.encoder_size),
        (400, 3768, 5600)
    );
    assert!(
        (g.bin_size_m - 0.0438).abs() < 1e-12,
        "bin size {}",
        g.bin_size_m
    );
}
