//! The association sweep on its own (`evaluation::sections::association_sweep`): the
//! paper's claim that power aids association, over spacing x contrast with noisy odometry,
//! then on the realistic street; prints the Markdown tables.
//!
//! Run: `cargo run --release -p evaluation --bin association_sweep -- [--seeds N]
//! [--seconds S] [--street-seconds S] [--no-street] [--jobs N] [--noise 5,20] [--no-pairs] [--street-noise-scale K]
//! [--street-static-only]`

use clap::Parser;
use evaluation::sections::association_sweep::{sweep, SweepBudget, NOISE_MULTIPLES};

/// Sweeps the association claim and prints the tables.
#[derive(Debug, Parser)]
#[command(about)]
struct Args {
    /// Seeds per cell and innovation (the same seeds with and without power).
    #[arg(long, default_value_t = 6)]
    seeds: usize,
    /// Simulated seconds per pair-scene run.
    #[arg(long, default_value_t = 20.0)]
    seconds: f64,
    /// Simulated seconds per street run.
    #[arg(long, default_value_t = 20.0)]
    street_seconds: f64,
    /// Skip the realistic street.
    #[arg(long)]
    no_street: bool,
    /// Worker threads.
    #[arg(long, default_value_t = 2)]
    jobs: usize,
    /// Skip the pair scenes (the street only).
    #[arg(long)]
    no_pairs: bool,
    /// Multiply the street filter's observation noise (range, bearing, power) by this.
    #[arg(long, default_value_t = 1.0)]
    street_noise_scale: f64,
    /// Remove the street's moving vehicles.
    #[arg(long)]
    street_static_only: bool,
    /// Multiples of the simulator's default odometry noise to sweep (comma-separated;
    /// default 5,20).
    #[arg(long, value_delimiter = ',')]
    noise: Vec<f64>,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let noise_multiples = if args.noise.is_empty() {
        NOISE_MULTIPLES.to_vec()
    } else {
        args.noise.clone()
    };
    for m in &noise_multiples {
        anyhow::ensure!(
            m.is_finite() && *m >= 0.0 && *m <= 100.0,
            "--noise {m}: a multiple in [0, 100]"
        );
    }
    let budget = SweepBudget {
        seeds: args.seeds.max(1),
        seconds: args.seconds,
        street_seeds: args.seeds.max(1),
        street_seconds: args.street_seconds,
        skip_street: args.no_street,
        jobs: args.jobs.max(1),
        noise_multiples,
        skip_pairs: args.no_pairs,
        street_noise_scale: args.street_noise_scale,
        street_static_only: args.street_static_only,
    };
    let started = std::time::Instant::now();
    println!("{}", sweep(&budget)?);
    println!("(took {:.0} s)", started.elapsed().as_secs_f64());
    Ok(())
}
