//! Does the data set's ground truth agree with what the radar itself sees, scan to scan?
//! (`evaluation::truth_agreement`: a dense, power-weighted registration of each pair of
//! consecutive recorded Oxford scans, none of the daemon's code, set against
//! `radar_odometry.csv`.)
//!
//! Run: `cargo run --release -p evaluation --bin truth_agreement -- [--dir DIR]
//! [--threshold-db 15] [--max-range-m 60] [--blur-m 0.15] [--bin-m 0.0438] [--no-deskew]
//! [--simulated ROTATIONS [--scene urban-street]]`. `--simulated` checks the method where
//! the truth is exact: the simulator's street rendered as the daemon receives it.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Parser;
use evaluation::sections::oxford::{default_dir, read_scans};
use evaluation::truth_agreement::{agreement, simulated, DenseSettings, SUBSETS};
use sim_sensor::replay::truth::read_oxford_odometry;
use sim_sensor::scene::{shipped, Scene};

/// Largest `--max-range-m`: the image is `(2 (range + 5 m) / 5 cm)^2` pixels (about 150 MB
/// at 150 m, twice that while it is blurred).
const MAX_RANGE_M: f64 = 150.0;
/// Largest `--simulated`: a CTS350-X rotation held in dB is about 12 MB.
const MAX_SIMULATED: u64 = 30;

/// Registers consecutive recorded scans densely and prints them against the ground truth.
#[derive(Debug, Parser)]
#[command(about)]
struct Args {
    /// The recorded folder (`radar/*.png`, `radar_odometry.csv`).
    #[arg(long)]
    dir: Option<PathBuf>,
    /// A bin enters a scan's cloud this far above its azimuth's median (dB).
    #[arg(long, default_value_t = DenseSettings::default().threshold_db)]
    threshold_db: f64,
    /// Bins further than this are left out (m, at most 150).
    #[arg(long, default_value_t = DenseSettings::default().max_range_m)]
    max_range_m: f64,
    /// The Cartesian image's blur (m, at most 2).
    #[arg(long, default_value_t = DenseSettings::default().blur_m)]
    blur_m: f64,
    /// Bin size (m): the daemon's 0.0438, or the data set's SDK's 0.0432.
    #[arg(long, default_value_t = DenseSettings::default().bin_m)]
    bin_m: f64,
    /// Leave each rotation's points where they were measured (no motion taken out).
    #[arg(long)]
    no_deskew: bool,
    /// Check the method instead where the truth is exact: render this many rotations (2 to
    /// 30) of the simulator's `--scene` and register them the same way.
    #[arg(long)]
    simulated: Option<u64>,
    /// The scene for `--simulated`: a shipped scene's name or a scene file.
    #[arg(long, default_value = "urban-street")]
    scene: String,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let dir = args.dir.unwrap_or_else(default_dir);
    let settings = DenseSettings {
        threshold_db: args.threshold_db,
        max_range_m: args.max_range_m,
        blur_m: args.blur_m,
        bin_m: args.bin_m,
        deskew: !args.no_deskew,
        ..DenseSettings::default()
    };
    anyhow::ensure!(
        [
            settings.threshold_db,
            settings.max_range_m,
            settings.blur_m,
            settings.bin_m
        ]
        .iter()
        .all(|v| v.is_finite() && *v >= 0.0)
            && settings.max_range_m > settings.min_range_m
            && settings.bin_m > 0.0
            && settings.max_range_m <= MAX_RANGE_M
            && settings.blur_m <= 2.0,
        "settings out of range: {settings:?}"
    );
    let (scans, truth, source, settings) = match args.simulated {
        Some(rotations) => {
            anyhow::ensure!(
                (2..=MAX_SIMULATED).contains(&rotations),
                "--simulated takes 2 to {MAX_SIMULATED} rotations, got {rotations}"
            );
            let scene = if shipped::NAMES.contains(&args.scene.as_str()) {
                shipped::load(&args.scene)?
            } else {
                Scene::load(Path::new(&args.scene))?
            };
            let (scans, truth) = simulated(&scene, rotations)?;
            let source = format!("the simulator's {} (exact truth)", args.scene);
            (scans, truth, source, settings.for_radar(&scene.radar))
        }
        None => {
            let scans = read_scans(&dir).with_context(|| {
                format!(
                    "reading the recorded scans in {} (the Oxford excerpt lives in ../shared/data/oxford-radar-robotcar)",
                    dir.display()
                )
            })?;
            let truth_path = dir.join("radar_odometry.csv");
            let truth = read_oxford_odometry(&truth_path)
                .with_context(|| format!("reading {}", truth_path.display()))?;
            let scans = scans.into_iter().map(|s| (s.time_us, s.scan)).collect();
            (scans, truth, dir.display().to_string(), settings)
        }
    };
    let timed: Vec<(i64, &evaluation::scan::Scan)> = scans.iter().map(|(t, s)| (*t, s)).collect();
    let pairs = agreement(&timed, &truth, &settings);
    anyhow::ensure!(
        !pairs.is_empty(),
        "no consecutive pair of scans in {source} has a ground-truth row"
    );

    println!(
        "Dense registration against the ground truth, {} pairs of {} scans in {} \
         (threshold {} dB above each azimuth's median, {}-{} m, bins of {} m, blur {} m, \
         Doppler coupling {} s, {}).\n",
        pairs.len(),
        scans.len(),
        source,
        settings.threshold_db,
        settings.min_range_m,
        settings.max_range_m,
        settings.bin_m,
        settings.blur_m,
        settings.doppler_coupling_s,
        if settings.deskew {
            "motion during the rotation taken out with the ground truth's velocity"
        } else {
            "no motion taken out"
        }
    );
    println!("| pair | truth: forward, left (m), turn (mrad) | speed truth / radar (m/s) | radar - truth: forward, left (mm), turn (mrad) | forward (mm) from: left half, right half, near, far | points |");
    println!("|---|---|---|---|---|---|");
    let mut diffs = Vec::new();
    for (k, p) in pairs.iter().enumerate() {
        let g = p.truth.pose;
        let d = [
            (p.dense.x - g.x) * 1e3,
            (p.dense.y - g.y) * 1e3,
            (p.dense.theta - g.theta) * 1e3,
        ];
        diffs.push(d);
        let halves: Vec<String> = p
            .subsets
            .iter()
            .map(|s| s.map_or("-".into(), |s| format!("{:+.0}", (s.x - g.x) * 1e3)))
            .collect();
        println!(
            "| {} -> {} | {:.3}, {:+.3}, {:+.2} | {:.2} / {:.2} | {:+.0}, {:+.0}, {:+.2} | {} | {} |",
            k,
            k + 1,
            g.x,
            g.y,
            g.theta * 1e3,
            g.x / p.dt_s,
            p.dense.x / p.dt_s,
            d[0],
            d[1],
            d[2],
            halves.join(", "),
            p.points
        );
    }
    let n = diffs.len() as f64;
    let mean = |c: usize| diffs.iter().map(|d| d[c]).sum::<f64>() / n;
    let sd = |c: usize| {
        let m = mean(c);
        (diffs.iter().map(|d| (d[c] - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt()
    };
    println!(
        "\nradar - truth over {} pairs, mean +- sd: forward {:+.1} +- {:.1} mm, left {:+.1} +- {:.1} mm, turn {:+.2} +- {:.2} mrad",
        diffs.len(),
        mean(0),
        sd(0),
        mean(1),
        sd(1),
        mean(2),
        sd(2)
    );
    let total_truth: f64 = pairs.iter().map(|p| p.truth.pose.x).sum();
    let total_radar: f64 = pairs.iter().map(|p| p.dense.x).sum();
    println!(
        "distance forward, summed: truth {total_truth:.3} m, radar {total_radar:.3} m ({:+.2} %)",
        (total_radar / total_truth - 1.0) * 100.0
    );
    println!(
        "subsets: {}",
        SUBSETS
            .iter()
            .map(|(name, _)| *name)
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}
