//! Monte Carlo consistency over several runs of one drive (`evaluation::nees_ensemble`):
//! `cargo run --release -p evaluation --bin nees_ensemble -- RUN_DIR RUN_DIR...`, each
//! RUN_DIR the output folder of one daemon run with ground truth (its `diagnostics.csv`).
//! Exits 1 with the reason when a table cannot be read or no rotation is common to all.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::Parser;
use evaluation::nees_ensemble::{ensemble, read_run};
use slam_filter::health::POSE_NEES_BAND_95;
use slam_node::pipeline::scores::NeesBand;

/// The ensemble pose NEES of several runs against its 95 % band, and each run's own.
#[derive(Parser)]
struct Args {
    /// The runs' output folders (each with a diagnostics.csv).
    #[arg(required = true)]
    runs: Vec<PathBuf>,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let runs = args
        .runs
        .iter()
        .map(|d| Ok(read_run(&d.join("diagnostics.csv"))?))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let e = ensemble(&runs).context("no rotation has a pose NEES in every run")?;
    let [below, inside, above] = e.counts.shares().map(|s| 100.0 * s);
    let mean = e.means.iter().sum::<f64>() / e.means.len() as f64;
    println!(
        "ensemble NEES {mean:.2} over {} rotations of {} runs; band [{:.2}, {:.2}]: inside at {inside:.1}% of rotations, below (conservative) {below:.1}%, above (optimistic) {above:.1}% (consistent: 95 / 2.5 / 2.5)",
        e.means.len(),
        runs.len(),
        e.band.0,
        e.band.1
    );
    let tenths: Vec<String> = (0..10)
        .map(|i| &e.means[e.means.len() * i / 10..e.means.len() * (i + 1) / 10])
        .filter(|c| !c.is_empty())
        .map(|c| {
            let n = NeesBand::of(c.iter().copied(), e.band);
            format!(
                "{:.2} ({}/{})",
                c.iter().sum::<f64>() / c.len() as f64,
                n.below,
                n.above
            )
        })
        .collect();
    println!(
        "  by tenth of the rotations, ensemble NEES (rotations below / above the band): {}",
        tenths.join("  ")
    );
    let (lo, hi) = POSE_NEES_BAND_95;
    for (dir, run) in args.runs.iter().zip(&runs) {
        let [below, inside, above] = NeesBand::of(run.values().copied(), (lo, hi))
            .shares()
            .map(|s| 100.0 * s);
        println!(
            "  {}: mean NEES {:.2} over {} rotations; single-rotation band [{lo:.2}, {hi:.2}]: inside {inside:.1}%, below {below:.1}%, above {above:.1}%",
            dir.display(),
            run.values().sum::<f64>() / run.len().max(1) as f64,
            run.len()
        );
    }
    Ok(())
}
