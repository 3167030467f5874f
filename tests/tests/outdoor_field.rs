//! The whole daemon against the simulator over loopback on the outdoor field: it maps the
//! scene's features, associates correctly, and its estimates move toward the scene's values.
//! Figures measured with these tests are quoted in `slam-node/README.md`.

use std::time::Duration;

use e2e_tests::{print, run, Run};

const LIMIT: Duration = Duration::from_secs(300);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_daemon_maps_the_outdoor_field_and_its_materials_move_toward_the_scene() {
    let out = tempfile::tempdir().unwrap();
    let report = run(&Run::new("outdoor-field", 30.0), out.path(), LIMIT)
        .await
        .unwrap();
    print(&report);
    let s = &report.run.summary;
    let map = s.map.as_ref().expect("truth is known");
    // Most features the vehicle came within range of are in the map.
    let found = map.distinct_scene_features_matched as f64 / map.scene_features_in_range as f64;
    assert!(
        found >= 0.8,
        "only {found:.2} of the features in range were mapped"
    );
    // Few associations pair an observation with another feature's estimate.
    let wrong = s.association_errors as f64 / s.associations.max(1) as f64;
    assert!(wrong < 0.05, "association error rate {wrong:.3}");
    // Received power fixes 10 log10 rho - L only: with that offset removed, rho has moved
    // from the initial guess toward the scene's values.
    let fixed = map.mean_rho_error_gauge_fixed.expect("true loss known");
    assert!(
        fixed < 0.5 * map.initial_rho_error,
        "rho error {fixed:.3} vs initial {:.3}",
        map.initial_rho_error
    );
    // The predicted spectra agree with the measured ones inside the paper's bound.
    let inside = s.spectrum.in_bound_fraction().expect("beams compared");
    assert!(inside > 0.9, "in-bound fraction {inside:.3}");
    // The daemon takes azimuths from the driver and asks for no rotations, so none is
    // counted as dropped.
    let driver = report.driver.as_ref().expect("driver counters");
    assert_eq!(
        driver.rotation_drops, 0,
        "rotations counted as dropped: {}",
        driver.rotation_drops
    );
    // Outputs are on disk.
    for f in &report.writer.files {
        assert!(f.exists(), "{} missing", f.display());
    }
    assert!(out.path().join("ground-truth.jsonl").exists());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn range_bearing_slam_keeps_its_pose_error_inside_its_own_three_sigma_bounds() {
    let out = tempfile::tempdir().unwrap();
    let mut r = Run::new("outdoor-field", 30.0);
    r.use_power = false;
    let report = run(&r, out.path(), LIMIT).await.unwrap();
    print(&report);
    let pose = report.run.summary.pose.as_ref().expect("truth is known");
    assert!(pose.samples > 50);
    assert!(
        pose.inside_fraction() >= 0.95,
        "pose inside its 3-sigma bounds in only {:.3} of rotations",
        pose.inside_fraction()
    );
}

/// Runs `seeds` and returns per-run (inside-3-sigma fraction, time-averaged pose NEES).
async fn consistency(use_power: bool, seeds: std::ops::RangeInclusive<u64>) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for seed in seeds {
        let dir = tempfile::tempdir().unwrap();
        let mut r = Run::new("outdoor-field", 30.0);
        r.use_power = use_power;
        r.seed = Some(seed);
        let report = run(&r, dir.path(), LIMIT).await.unwrap();
        let pose = report.run.summary.pose.clone().expect("truth is known");
        let nees = pose.nees_sum / pose.samples.max(1) as f64;
        println!(
            "power {use_power} seed {seed}: inside 3-sigma {:.3}, mean NEES {nees:.2}, RMS {:.3} m",
            pose.inside_fraction(),
            pose.rms_position_m()
        );
        out.push((pose.inside_fraction(), nees));
    }
    out
}

/// Average pose NEES over 5 runs of 3 dof must lie below chi2(0.975, 15) / 5 = 5.50 for
/// a consistent filter (the upper end of the two-sided 95 % interval).
const NEES_UPPER_5_RUNS: f64 = 5.50;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "five end-to-end runs: run by hand, README.md 'Tests'"]
async fn over_five_seeds_range_bearing_slam_is_consistent() {
    let runs = consistency(false, 1..=5).await;
    let mean = runs.iter().map(|r| r.1).sum::<f64>() / runs.len() as f64;
    println!("range-bearing: mean NEES over runs {mean:.2}");
    assert!(mean <= NEES_UPPER_5_RUNS, "mean NEES {mean:.2}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "five end-to-end runs: run by hand, README.md 'Tests'"]
async fn over_five_seeds_the_paper_filter_with_power_is_consistent() {
    let runs = consistency(true, 1..=5).await;
    let mean = runs.iter().map(|r| r.1).sum::<f64>() / runs.len() as f64;
    println!("with power: mean NEES over runs {mean:.2}");
    assert!(mean <= NEES_UPPER_5_RUNS, "mean NEES {mean:.2}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_odometry_the_daemon_refuses_to_update_the_map() {
    let out = tempfile::tempdir().unwrap();
    let mut r = Run::new("outdoor-field", 5.0);
    r.odometry = false;
    let report = run(&r, out.path(), LIMIT).await.unwrap();
    print(&report);
    let s = &report.run.summary;
    assert!(s.detections > 0, "detection still runs");
    assert!(
        s.refused.no_odometry > 0,
        "beams were refused for want of odometry"
    );
    assert_eq!(s.beams, 0, "no beam reached the filter");
    assert_eq!(s.map_size, 0, "nothing was mapped from fabricated motion");
}
