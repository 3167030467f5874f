//! Detections per rotation with the daemon's detector (`slam_node::detect`) on the real
//! Oxford scans and on the simulated `urban-street` scene (the realistic renderer), the
//! same detector settings and the same per-bin gain (none removed) for both: the
//! detection figure of the realism comparison (`cargo run --release -p sim-sensor
//! --example realism` gives the others).
//!
//! Run: `cargo run --release -p evaluation --bin realism_detections`
//!
//! The detector's default (TPP) keeps a per-bin minimum over scans, so the first two
//! rotations of each set are warm-up and are not counted.

use sim_sensor::realism::calibrate::{default_oxford_dir, load_polar_dir};
use sim_sensor::realism::render_scans;
use sim_sensor::realism::stats::Scans;
use sim_sensor::scene::shipped;
use slam_node::detect::{BeamDetector, DetectorKind, DetectorSettings, RangeAxis};

/// Mean detections per rotation over the rotations after `warmup`.
fn per_rotation(scans: &Scans, settings: DetectorSettings, warmup: usize) -> f64 {
    let mut detector = BeamDetector::new(settings, scans.azimuths);
    let gain = vec![0.0; scans.bins];
    let axis = RangeAxis {
        first_bin_m: 0.0,
        bin_m: scans.bin_m,
    };
    let mut out = Vec::new();
    let mut counted = 0usize;
    let mut total = 0usize;
    let mut row_db = vec![0.0; scans.bins];
    for (r, rot) in scans.rotations.iter().enumerate() {
        for (a, row) in rot.chunks_exact(scans.bins).enumerate() {
            for (d, &v) in row_db.iter_mut().zip(row) {
                *d = f64::from(v) / 2.0;
            }
            out.clear();
            detector.detect(a, &row_db, &gain, None, &axis, &mut out);
            if r >= warmup {
                total += out.len();
            }
        }
        if r >= warmup {
            counted += 1;
        }
    }
    total as f64 / counted.max(1) as f64
}

fn main() -> anyhow::Result<()> {
    let dir = default_oxford_dir();
    if !dir.is_dir() {
        println!("no real scans at {}: nothing to compare", dir.display());
        return Ok(());
    }
    let real = load_polar_dir(&dir)?;
    let scene = shipped::load("urban-street")?;
    let sim = render_scans(&scene, None, 4, real.rotations.len() as u64)?;
    println!("| detector | real detections / rotation | simulated | sim / real |");
    println!("|---|---|---|---|");
    // The daemon's default detector (TPP); two rotations of warm-up.
    let settings = DetectorSettings {
        kind: DetectorKind::Tpp,
        ..DetectorSettings::default()
    };
    let (r, s) = (
        per_rotation(&real, settings, 2),
        per_rotation(&sim, settings, 2),
    );
    println!(
        "| TPP (the daemon's default) | {r:.0} | {s:.0} | {:.2} |",
        s / r
    );
    Ok(())
}
