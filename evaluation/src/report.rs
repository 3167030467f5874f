//! The report: settings of a run of the evaluation (budgets, paths), Markdown helpers, and
//! the sections' common shape.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::error::EvalError;

/// How much work each section does.
#[derive(Debug, Clone, PartialEq)]
pub struct Budget {
    /// Monte Carlo runs for the consistency figures.
    pub mc_runs: usize,
    /// Simulated seconds per Monte Carlo run.
    pub mc_seconds: f64,
    /// Monte Carlo runs of the whole pipeline (spectra, detection).
    pub mc_pipeline_runs: usize,
    /// Longest simulated time per scene in the accuracy table (s).
    pub scene_seconds: f64,
    /// Seeds per setting in the association comparison.
    pub association_seeds: usize,
    /// Simulated seconds per association run.
    pub association_seconds: f64,
    /// Seeds per cell of the association sweep (and per setting on the street).
    pub association_sweep_seeds: usize,
    /// Simulated seconds per run of the association sweep's pair scenes.
    pub association_sweep_seconds: f64,
    /// Simulated seconds per run of the association sweep on the realistic street.
    pub association_sweep_street_seconds: f64,
    /// Simulated seconds per point of the speed/error sweep.
    pub sweep_seconds: f64,
    /// Rotations compared per scene in the spectra section.
    pub spectra_rotations: usize,
    /// Filter steps (azimuths) of the long stability run.
    pub stability_steps: u64,
    /// Longest detection run on the CTS350-X-like scene (s).
    pub heavy_scene_seconds: f64,
    /// Oxford scans used (at most the 8 recorded).
    pub oxford_scans: usize,
    /// Simulated seconds of the realistic city's drive on the radar alone (at most the
    /// route's; 470 is the whole 4.3 km drive).
    pub city_seconds: f64,
    /// Skip the runs that take minutes in a debug build (the CTS350-X-like scene's
    /// detection runs, the filter over the Oxford scans, the dense-clutter sweep).
    pub skip_heavy: bool,
    /// Worker threads for independent runs (timed runs always run alone).
    pub jobs: usize,
}

impl Budget {
    /// The documented full evaluation.
    pub fn full() -> Self {
        Self {
            mc_runs: 50,
            mc_seconds: 40.0,
            mc_pipeline_runs: 10,
            scene_seconds: 20.0,
            association_seeds: 3,
            association_seconds: 20.0,
            association_sweep_seeds: 6,
            association_sweep_seconds: 20.0,
            association_sweep_street_seconds: 20.0,
            sweep_seconds: 6.0,
            spectra_rotations: 3,
            stability_steps: 1_000_000,
            heavy_scene_seconds: 2.5,
            oxford_scans: 8,
            city_seconds: 470.0,
            skip_heavy: false,
            jobs: 2,
        }
    }

    /// A smoke test of every section in a minute or two (release).
    pub fn quick() -> Self {
        Self {
            mc_runs: 6,
            mc_seconds: 8.0,
            mc_pipeline_runs: 2,
            scene_seconds: 6.0,
            association_seeds: 1,
            association_seconds: 6.0,
            association_sweep_seeds: 2,
            association_sweep_seconds: 6.0,
            association_sweep_street_seconds: 5.0,
            sweep_seconds: 4.0,
            spectra_rotations: 1,
            stability_steps: 20_000,
            heavy_scene_seconds: 1.0,
            oxford_scans: 8,
            city_seconds: 60.0,
            skip_heavy: false,
            jobs: 2,
        }
    }

    /// The smallest budget that still exercises every code path (tests, debug builds).
    pub fn tiny() -> Self {
        Self {
            mc_runs: 2,
            mc_seconds: 0.8,
            mc_pipeline_runs: 1,
            scene_seconds: 0.8,
            association_seeds: 1,
            association_seconds: 0.8,
            association_sweep_seeds: 1,
            association_sweep_seconds: 0.8,
            association_sweep_street_seconds: 0.8,
            sweep_seconds: 0.8,
            spectra_rotations: 1,
            stability_steps: 400,
            heavy_scene_seconds: 0.5,
            oxford_scans: 2,
            city_seconds: 3.0,
            skip_heavy: true,
            jobs: 2,
        }
    }
}

/// Where to read and write, and how much to do.
#[derive(Debug, Clone)]
pub struct Options {
    /// Report folder (created if absent).
    pub out_dir: PathBuf,
    /// Work per section.
    pub budget: Budget,
    /// The Oxford Radar RobotCar scans (`None`: that section says so and is skipped).
    pub oxford_dir: Option<PathBuf>,
    /// The command that produced the report, quoted beside every figure.
    pub command: String,
    /// Sections to run (by key); empty runs all.
    pub only: Vec<String>,
}

/// One section of the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    /// Heading.
    pub title: String,
    /// Markdown body.
    pub body: String,
}

/// A Markdown table.
pub fn table(headers: &[&str], rows: &[Vec<String>]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "| {} |", headers.join(" | "));
    let _ = writeln!(s, "|{}", headers.iter().map(|_| "---|").collect::<String>());
    for r in rows {
        let _ = writeln!(s, "| {} |", r.join(" | "));
    }
    s
}

/// A number with `digits` decimals; "n/a" when not finite.
pub fn num(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "n/a".to_string()
    }
}

/// A percentage of a fraction with one decimal; "n/a" when not finite.
pub fn pct(fraction: f64) -> String {
    if fraction.is_finite() {
        format!("{:.1} %", 100.0 * fraction)
    } else {
        "n/a".to_string()
    }
}

/// Writes `text` to `path`.
pub fn write_file(path: &Path, text: &str) -> Result<(), EvalError> {
    std::fs::write(path, text).map_err(|source| EvalError::Io {
        path: path.to_path_buf(),
        source,
    })
}
