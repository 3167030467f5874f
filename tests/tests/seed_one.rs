//! What makes the README's first command (outdoor field, config seed 1) over-confident
//! (issue 15, finding C): measurements, ignored by default, run in release with
//! `cargo test --release -p e2e-tests --test seed_one -- --ignored --nocapture`.
//!
//! `odometry_heading_excursions` prints, per seed, the heading error the simulator's steering
//! noise alone puts into dead reckoning over the first seconds of the drive (1 m/s, 2.7 m
//! wheelbase, 20 Hz records), against its standard deviation. `seed_one_without_each_noise`
//! runs seed 1 (60 s, as the harness of `ensemble_consistency`) with the shipped filter, then
//! with one noise source or one filter feature removed at a time, and prints the mean NEES,
//! the wrong associations and the cross-track and heading errors along the run.

use std::path::Path;
use std::time::Duration;

use e2e_tests::{run, Run};
use sim_sensor::odometry::OdometryGenerator;
use sim_sensor::OdometryNoise;

const LIMIT: Duration = Duration::from_secs(600);

#[test]
#[ignore = "a measurement: prints the steering noise's heading excursions per seed"]
fn odometry_heading_excursions() {
    let noise = OdometryNoise::default();
    let per_record_mrad = 1e3 * noise.sigma_steer_rad / 2.7 / noise.rate_hz;
    for seed in 1..=20u64 {
        let g = OdometryGenerator::new(noise, seed, 0);
        let heading = |records: u64| {
            (0..records)
                .map(|j| g.record(j, (1.0, 0.0)).steer_rad)
                .sum::<f64>()
                * 1e3
                / 2.7
                / noise.rate_hz
        };
        let line: Vec<String> = [24u64, 96, 200]
            .iter()
            .map(|&n| {
                let sd = per_record_mrad * (n as f64).sqrt();
                format!(
                    "{:.1} s {:+.2} mrad ({:+.1} sigma)",
                    n as f64 / noise.rate_hz,
                    heading(n),
                    heading(n) / sd
                )
            })
            .collect();
        println!("seed {seed:>2}: {}", line.join(", "));
    }
}

/// `(cross-track error m, heading error mrad, heading sigma mrad)` at these rotations.
fn along(dir: &Path, rotations: &[usize]) -> String {
    let text = std::fs::read_to_string(dir.join("diagnostics.csv")).expect("diagnostics");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).expect(name);
    let (ey, eth, sth) = (
        col("pose_error_y_m"),
        col("pose_error_theta_rad"),
        col("pose_sigma_theta_rad"),
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    rotations
        .iter()
        .filter_map(|&k| {
            let row = rows.get(k)?;
            let num = |i: usize| row.get(i).and_then(|c| c.parse::<f64>().ok());
            Some(format!(
                "r{k} {:+.3} m {:+.2}/{:.2} mrad",
                num(ey)?,
                1e3 * num(eth)?,
                1e3 * num(sth)?
            ))
        })
        .collect::<Vec<_>>()
        .join(", ")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "a measurement: seven 60 s runs of seed 1"]
async fn seed_one_without_each_noise() {
    let quiet = |f: fn(&mut OdometryNoise)| {
        let mut n = OdometryNoise::default();
        f(&mut n);
        Some(n)
    };
    let variants: Vec<(&str, Run)> = vec![
        ("shipped", Run::new("outdoor-field", 60.0)),
        ("no steering noise", {
            let mut r = Run::new("outdoor-field", 60.0);
            r.odometry_noise = quiet(|n| n.sigma_steer_rad = 0.0);
            r
        }),
        ("no speed noise", {
            let mut r = Run::new("outdoor-field", 60.0);
            r.odometry_noise = quiet(|n| n.sigma_speed_mps = 0.0);
            r
        }),
        ("no bearing noise", {
            let mut r = Run::new("outdoor-field", 60.0);
            r.bearing_sigma_deg = Some(0.0);
            r
        }),
        ("no FEJ", {
            let mut r = Run::new("outdoor-field", 60.0);
            r.first_estimate_jacobians = false;
            r
        }),
        ("no repeat-look", {
            let mut r = Run::new("outdoor-field", 60.0);
            r.repeat_look_decorrelation = false;
            r
        }),
        ("no power row", {
            let mut r = Run::new("outdoor-field", 60.0);
            r.use_power = false;
            r
        }),
    ];
    for (label, mut r) in variants {
        r.seed = Some(1);
        let dir = tempfile::tempdir().unwrap();
        let report = run(&r, dir.path(), LIMIT).await.unwrap();
        let s = &report.run.summary;
        let pose = s.pose.as_ref().expect("scored");
        println!(
            "seed 1, {label:<18} mean NEES {:5.2}, wrong associations {:3}; {}",
            pose.nees_sum / pose.samples.max(1) as f64,
            s.association_errors,
            along(dir.path(), &[3, 8, 12, 40, 80, 140])
        );
    }
}
