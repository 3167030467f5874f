//! The daemon's detectors scored on the simulator's shipped scenes against the targets
//! really in each beam (`evaluation::detections`): probability of detection (targets of
//! 10 dB and more over the mean floor, a hit within 0.5 m), false alarms per rotation, and
//! the beams with two or more such targets in which every one was found.
//!
//! Run: `cargo run --release -p evaluation --bin detection_scoring [-- TABLE]`, TABLE one of
//! `sweep`, `learned` or `all` (the default; about 15 s in release together).
//!
//! - `sweep`: CA-CFAR, OS-CFAR and TPP, each in the measured and the uncompensated domain,
//!   over thresholds of 12 to 28 dB, on `outdoor-field`, `penetration-wood` and
//!   `dense-clutter` (12 rotations, seed 7).
//! - `learned`: the front end for current units (`[detector] kind = "learned"`) over the
//!   same thresholds (its floor's `min_snr_db`) against the default TPP, on `long-loop`
//!   (the CTS350-X preset) and `outdoor-field` (the paper's unit) (8 rotations, seed 7).

use clap::{Parser, ValueEnum};
use evaluation::detections::{score_detector, score_learned, DetectionScore};
use slam_node::detect::{DetectionDomain, DetectorKind, DetectorSettings};

/// Threshold sweep, dB over each detector's noise estimate.
const THRESHOLDS_DB: [f64; 5] = [12.0, 16.0, 20.0, 24.0, 28.0];
/// Simulator seed of every run.
const SEED: u64 = 7;

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Table {
    /// Both tables.
    All,
    /// CA-CFAR, OS-CFAR and TPP over a sweep of thresholds.
    Sweep,
    /// The learned front end against TPP.
    Learned,
}

#[derive(Debug, Parser)]
#[command(about = "Scores the daemon's detectors against the simulator's truth")]
struct Args {
    /// Which table to print.
    #[arg(value_enum, default_value = "all")]
    table: Table,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    if matches!(args.table, Table::All | Table::Sweep) {
        sweep()?;
    }
    if args.table == Table::All {
        println!();
    }
    if matches!(args.table, Table::All | Table::Learned) {
        learned()?;
    }
    Ok(())
}

/// `Pd`, false alarms per rotation and complete multi-target beams, as the tables print them.
fn columns(s: &DetectionScore) -> String {
    format!(
        "{:>8} {:>8.3} {:>10.2} {:>7}/{:<5}",
        s.targets,
        s.pd(),
        s.fa_per_rotation(),
        s.multi_target_complete,
        s.multi_target_beams
    )
}

fn with(kind: DetectorKind, domain: DetectionDomain, scale_db: f64) -> DetectorSettings {
    let mut s = DetectorSettings {
        kind,
        domain,
        ca_scale_db: scale_db,
        os_scale_db: scale_db,
        ..DetectorSettings::default()
    };
    s.tpp.snr_threshold_db = scale_db;
    s
}

fn sweep() -> anyhow::Result<()> {
    println!(
        "{:<20} {:<8} {:<14} {:>6} {:>8} {:>8} {:>10} {:>12}",
        "scene", "detector", "domain", "thr_dB", "targets", "Pd", "FA/rot", "multi-beam"
    );
    for scene in ["outdoor-field", "penetration-wood", "dense-clutter"] {
        for kind in [
            DetectorKind::CaCfar,
            DetectorKind::OsCfar,
            DetectorKind::Tpp,
        ] {
            for domain in [DetectionDomain::Measured, DetectionDomain::Uncompensated] {
                for thr in THRESHOLDS_DB {
                    let s = score_detector(scene, with(kind, domain, thr), 12, SEED)?;
                    println!(
                        "{:<20} {:<8} {:<14} {:>6.1} {}",
                        scene,
                        format!("{kind:?}"),
                        format!("{domain:?}"),
                        thr,
                        columns(&s)
                    );
                }
            }
        }
    }
    Ok(())
}

fn learned() -> anyhow::Result<()> {
    println!(
        "{:<14} {:<8} {:>9} {:>8} {:>8} {:>10} {:>12}",
        "scene", "detector", "thr_dB", "targets", "Pd", "FA/rot", "multi-beam"
    );
    for scene in ["long-loop", "outdoor-field"] {
        let tpp = score_detector(scene, DetectorSettings::default(), 8, SEED)?;
        println!(
            "{:<14} {:<8} {:>9} {}",
            scene,
            "Tpp",
            "default",
            columns(&tpp)
        );
        for thr in THRESHOLDS_DB {
            let mut s = DetectorSettings {
                kind: DetectorKind::Learned,
                ..DetectorSettings::default()
            };
            s.floor.min_snr_db = thr;
            let r = score_learned(scene, s, 8, SEED)?;
            println!(
                "{:<14} {:<8} {:>9.1} {}",
                scene,
                "Learned",
                thr,
                columns(&r)
            );
        }
    }
    Ok(())
}
