//! What makes the README's first command (outdoor field, configuration seed 1)
//! over-confident (issue 15, finding C).
//!
//! Run: `cargo run --release -p evaluation --bin seed_one` (about 10 s in release).
//!
//! First, per seed, the heading error the simulator's steering noise alone puts into dead
//! reckoning over the first seconds of the drive (1 m/s, 2.7 m wheelbase, 20 Hz records),
//! against its standard deviation. Then seed 1 run for 60 s through the whole daemon
//! against the simulator over loopback (the harness of the end-to-end tests,
//! `e2e_tests::run`) with the shipped filter, and again with one noise source or one filter
//! feature removed at a time: the mean NEES, the wrong associations, and the cross-track and
//! heading errors (with the heading's standard deviation) at six rotations along the run.
//!
//! IO: sockets on 127.0.0.1:0 and the daemon's outputs in a temporary folder.

use std::path::Path;
use std::time::Duration;

use anyhow::Context;
use e2e_tests::{run, Run};
use sim_sensor::odometry::OdometryGenerator;
use sim_sensor::OdometryNoise;

/// Wall-time limit of one daemon run.
const LIMIT: Duration = Duration::from_secs(600);
/// The wheelbase the excursions are computed for (m).
const WHEELBASE_M: f64 = 2.7;
/// Rotations at which the errors along the run are printed.
const ALONG: [usize; 6] = [3, 8, 12, 40, 80, 140];

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    heading_excursions();
    println!();
    without_each_noise().await
}

/// The steering noise's heading excursions per seed.
fn heading_excursions() {
    let noise = OdometryNoise::default();
    let per_record_mrad = 1e3 * noise.sigma_steer_rad / WHEELBASE_M / noise.rate_hz;
    println!("heading error of dead reckoning from the steering noise alone, per seed:");
    for seed in 1..=20u64 {
        let g = OdometryGenerator::new(noise, seed, 0);
        let heading = |records: u64| {
            (0..records)
                .map(|j| g.record(j, (1.0, 0.0)).steer_rad)
                .sum::<f64>()
                * 1e3
                / WHEELBASE_M
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

/// Seed 1 with the shipped filter, then with one noise or one filter feature removed.
async fn without_each_noise() -> anyhow::Result<()> {
    let quiet = |f: fn(&mut OdometryNoise)| {
        let mut n = OdometryNoise::default();
        f(&mut n);
        Some(n)
    };
    let shipped = || Run::new("outdoor-field", 60.0);
    let variants: Vec<(&str, Run)> = vec![
        ("shipped", shipped()),
        ("no steering noise", {
            let mut r = shipped();
            r.odometry_noise = quiet(|n| n.sigma_steer_rad = 0.0);
            r
        }),
        ("no speed noise", {
            let mut r = shipped();
            r.odometry_noise = quiet(|n| n.sigma_speed_mps = 0.0);
            r
        }),
        ("no bearing noise", {
            let mut r = shipped();
            r.bearing_sigma_deg = Some(0.0);
            r
        }),
        ("no FEJ", {
            let mut r = shipped();
            r.first_estimate_jacobians = false;
            r
        }),
        ("no repeat-look", {
            let mut r = shipped();
            r.repeat_look_decorrelation = false;
            r
        }),
        ("no power row", {
            let mut r = shipped();
            r.use_power = false;
            r
        }),
    ];
    for (label, mut r) in variants {
        r.seed = Some(1);
        let dir = tempfile::tempdir().context("a temporary folder for the daemon's outputs")?;
        let report = run(&r, dir.path(), LIMIT)
            .await
            .with_context(|| format!("the daemon's run of seed 1, {label}"))?;
        let s = &report.run.summary;
        let pose = s
            .pose
            .as_ref()
            .context("the run was not scored against the truth")?;
        println!(
            "seed 1, {label:<18} mean NEES {:5.2}, wrong associations {:3}; {}",
            pose.nees_sum / pose.samples.max(1) as f64,
            s.association_errors,
            along(dir.path(), &ALONG)?
        );
    }
    Ok(())
}

/// `(cross-track error m, heading error mrad, heading sigma mrad)` at these rotations, from
/// the run's `diagnostics.csv`.
fn along(dir: &Path, rotations: &[usize]) -> anyhow::Result<String> {
    let path = dir.join("diagnostics.csv");
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .with_context(|| format!("{} is empty", path.display()))?
        .split(',')
        .collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .with_context(|| format!("{} has no column {name}", path.display()))
    };
    let (ey, eth, sth) = (
        col("pose_error_y_m")?,
        col("pose_error_theta_rad")?,
        col("pose_sigma_theta_rad")?,
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    Ok(rotations
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
        .join(", "))
}
