//! `evaluate`: runs the evaluation and writes the report (see `evaluation/README.md`).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use clap::Parser;
use evaluation::report::{Budget, Options};

/// Measures the radar SLAM system and writes a Markdown report with SVG figures.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// Report folder (README.md and figures are written here).
    #[arg(long, default_value = "docs/evaluation")]
    out: PathBuf,
    /// Smoke-test budget: every section, a minute or two in release.
    #[arg(long)]
    quick: bool,
    /// The smallest budget that exercises every code path (seconds even in debug).
    #[arg(long, conflicts_with = "quick")]
    tiny: bool,
    /// Oxford Radar RobotCar folder (default: ../shared/data/oxford-radar-robotcar beside
    /// the workspace).
    #[arg(long)]
    oxford: Option<PathBuf>,
    /// Run only these sections (comma-separated): consistency, accuracy, association,
    /// association-sweep, spectra, sweep, oxford, realistic-city, stability.
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Worker threads for independent runs (timed runs always run alone).
    #[arg(long)]
    jobs: Option<usize>,
}

fn main() -> ExitCode {
    match run() {
        Ok(code) => code,
        Err(e) => {
            eprintln!("evaluate: {e:#}");
            ExitCode::from(2)
        }
    }
}

fn run() -> anyhow::Result<ExitCode> {
    let args = Args::parse();
    let mut budget = if args.quick {
        Budget::quick()
    } else if args.tiny {
        Budget::tiny()
    } else {
        Budget::full()
    };
    if let Some(j) = args.jobs {
        budget.jobs = j.max(1);
    }
    // Quoted in the report as the documented, equivalent cargo command.
    let rest: Vec<String> = std::env::args().skip(1).collect();
    let command = format!("cargo run --release -p evaluation -- {}", rest.join(" "));
    let opts = Options {
        out_dir: args.out,
        budget,
        oxford_dir: Some(
            args.oxford
                .unwrap_or_else(evaluation::sections::oxford::default_dir),
        ),
        command,
        only: args.only,
    };
    let outcome = evaluation::evaluate(&opts).context("evaluation")?;
    for (key, secs) in &outcome.timings {
        println!("{key:<12} {secs:8.1} s");
    }
    println!("report: {}", outcome.report_path.display());
    if outcome.failed.is_empty() {
        Ok(ExitCode::SUCCESS)
    } else {
        for (key, e) in &outcome.failed {
            eprintln!("section {key} failed: {e}");
        }
        Ok(ExitCode::FAILURE)
    }
}
