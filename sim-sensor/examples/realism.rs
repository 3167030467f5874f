//! The realism measurement: the shipped `urban-street` scene rendered by the realistic
//! renderer against the real Oxford Radar RobotCar scans, on the same statistics (floor
//! level and spread per range band, two-sample Kolmogorov-Smirnov distance per band, share
//! of bins above the floor, peak widths in range and azimuth), printed as a side-by-side
//! Markdown table with each figure's ratio to the real one, and a Cartesian picture of a
//! real and a simulated scan (`realism.png`, real on the left).
//!
//! Run: `cargo run --release -p sim-sensor --example realism [-- OUT_DIR [SCENE]]`
//! (OUT_DIR defaults to `out/realism`; SCENE to `urban-street`, any shipped scene name or a
//! scene file). Detections per rotation with the daemon's detector are measured by the
//! evaluation (`evaluation/`), which links the daemon; this command does not.

use std::path::PathBuf;

use sim_sensor::realism::calibrate::{default_oxford_dir, load_polar_dir};
use sim_sensor::realism::picture::{cartesian, write_side_by_side};
use sim_sensor::realism::render_scans;
use sim_sensor::realism::stats::{ks_distance, scan_stats};
use sim_sensor::scene::{shipped, Scene};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().unwrap_or_else(|| "out/realism".into()));
    let scene_name = args.next().unwrap_or_else(|| "urban-street".into());
    let dir = default_oxford_dir();
    if !dir.is_dir() {
        println!("no real scans at {}: nothing to compare", dir.display());
        return Ok(());
    }
    let real = load_polar_dir(&dir)?;
    let scene = if shipped::NAMES.contains(&scene_name.as_str()) {
        shipped::load(&scene_name)?
    } else {
        Scene::load(std::path::Path::new(&scene_name))?
    };
    let rotations = real.rotations.len().max(1) as u64;
    let started = std::time::Instant::now();
    let sim = render_scans(&scene, None, 4, rotations)?;
    let render_s = started.elapsed().as_secs_f64();
    let (r, s) = (scan_stats(&real), scan_stats(&sim));
    println!(
        "real: {} rotations from {}; simulated: {} rotations of {} ({:.2} s to render)\n",
        real.rotations.len(),
        dir.display(),
        sim.rotations.len(),
        scene.name,
        render_s
    );
    println!("| band (m) | floor real / sim (dB) | spread (IQR) real / sim (dB) | p90 real / sim | p99 real / sim | above floor real / sim | KS |");
    println!("|---|---|---|---|---|---|---|");
    let mut ks_max: f64 = 0.0;
    for (k, (br, bs)) in r.bands.iter().zip(&s.bands).enumerate() {
        let ks = ks_distance(&r.histograms[k], &s.histograms[k]);
        ks_max = ks_max.max(ks);
        println!(
            "| {:.0}-{:.0} | {:.1} / {:.1} | {:.1} / {:.1} | {:.1} / {:.1} | {:.1} / {:.1} | {:.3} / {:.3} | {:.3} |",
            br.range_m.0,
            br.range_m.1,
            br.median_db,
            bs.median_db,
            br.iqr_db,
            bs.iqr_db,
            br.p90_db,
            bs.p90_db,
            br.p99_db,
            bs.p99_db,
            br.above_floor,
            bs.above_floor,
            ks
        );
    }
    let ratio = |a: f64, b: f64| b / a;
    println!("\n| figure | real | simulated | sim / real | target |");
    println!("|---|---|---|---|---|");
    println!(
        "| share of bins above the floor (+{} dB) | {:.4} | {:.4} | {:.2} | 0.75-1.25 |",
        sim_sensor::realism::stats::ABOVE_FLOOR_DB,
        r.above_floor,
        s.above_floor,
        ratio(r.above_floor, s.above_floor)
    );
    println!(
        "| peak width in range (m, median of {} / {} peaks) | {:.3} | {:.3} | {:.2} | 0.75-1.25 |",
        r.widths.peaks,
        s.widths.peaks,
        r.widths.range_fwhm_m,
        s.widths.range_fwhm_m,
        ratio(r.widths.range_fwhm_m, s.widths.range_fwhm_m)
    );
    println!(
        "| peak width in azimuth (deg) | {:.2} | {:.2} | {:.2} | 0.75-1.25 |",
        r.widths.azimuth_fwhm_deg,
        s.widths.azimuth_fwhm_deg,
        ratio(r.widths.azimuth_fwhm_deg, s.widths.azimuth_fwhm_deg)
    );
    println!("| largest KS distance over the bands | | | {ks_max:.3} | <= 0.1 |");
    std::fs::create_dir_all(&out)?;
    let size = 800;
    let images = vec![
        cartesian(&real, 0, size, 80.0, 60.0),
        cartesian(&sim, 0, size, 80.0, 60.0),
    ];
    let path = out.join("realism.png");
    write_side_by_side(&path, &images, size)?;
    println!(
        "\npicture (real left, simulated right, +/-80 m, forward up): {}",
        path.display()
    );
    Ok(())
}
