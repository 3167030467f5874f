//! Detections per rotation with the daemon's detector (`slam_node::detect`) on the real
//! Oxford scans and on the simulated `urban-street` scene (the realistic renderer), the
//! same detector settings and the same per-bin gain (none removed) for both: the
//! detection figure of the realism comparison (`cargo run --release -p sim-sensor
//! --example realism` gives the others).
//!
//! Run: `cargo run --release -p evaluation --bin realism_detections`
//!
//! Rows: the daemon's default detector (TPP), and the front end for current units
//! (`[detector] kind = "learned"`, with the settings `slam-node --replay-dir` uses):
//! every target it finds, and the point-like ones.
//!
//! The detector's default (TPP) keeps a per-bin minimum over scans, so the first two
//! rotations of each set are warm-up and are not counted.

use sim_sensor::realism::calibrate::{default_oxford_dir, load_polar_dir};
use sim_sensor::realism::render_scans;
use sim_sensor::realism::stats::Scans;
use sim_sensor::scene::shipped;
use slam_node::detect::{
    BeamDetector, DetectorKind, DetectorSettings, LearnedFloor, LineDetector, LineSettings,
    RangeAxis,
};

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

/// Mean targets per rotation found by the learned front end (`[detector] kind =
/// "learned"`: the floor learned from the stream, the line-rate detector) over the
/// rotations after `warmup`, all of them and the point-like ones (at most the landmark
/// extent in range, the others being what the daemon keeps out of the map as extended).
fn learned_per_rotation(scans: &Scans, settings: &DetectorSettings, warmup: usize) -> (f64, f64) {
    let mut floor = LearnedFloor::new(settings.floor, scans.bins);
    let mut line = LineDetector::new();
    let axis = RangeAxis {
        first_bin_m: 0.0,
        bin_m: scans.bin_m,
    };
    let line_settings = LineSettings {
        merge_gap_bins: settings.peaks.merge_gap_bins,
        max_peaks: settings.peaks.max_peaks,
        min_range_m: settings.min_range_m,
        max_range_m: settings.max_range_m,
    };
    let mut peaks = Vec::new();
    let (mut all, mut points, mut counted) = (0usize, 0usize, 0usize);
    for (r, rot) in scans.rotations.iter().enumerate() {
        for row in rot.chunks_exact(scans.bins) {
            line.detect(row, &mut floor, &axis, &line_settings, &mut peaks);
            if r >= warmup {
                all += peaks.len();
                points += peaks
                    .iter()
                    .filter(|p| {
                        p.extent_bins as f64 * scans.bin_m <= settings.landmarks.max_extent_m
                    })
                    .count();
            }
        }
        if r >= warmup {
            counted += 1;
        }
    }
    let n = counted.max(1) as f64;
    (all as f64 / n, points as f64 / n)
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
    // The front end for current units, with the settings the replay runs it with.
    let shipped = evaluation::daemon::shipped_settings()?;
    let learned = |scans: &Scans| {
        let settings = slam_node::daemon::replay::recorded_settings_for(
            shipped.clone(),
            scans.bins as f64 * scans.bin_m,
            scans.bin_m,
        );
        learned_per_rotation(scans, &settings.detector, 2)
    };
    let ((ra, rp), (sa, sp)) = (learned(&real), learned(&sim));
    println!(
        "| learned front end (current units), every target | {ra:.0} | {sa:.0} | {:.2} |",
        sa / ra
    );
    println!(
        "| learned front end, point-like targets (extent <= 0.5 m) | {rp:.0} | {sp:.0} | {:.2} |",
        sp / rp
    );
    Ok(())
}
