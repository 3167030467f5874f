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
use sim_sensor::realism::stats::{ks_distance, quantile_db, scan_stats, Scans};
use sim_sensor::render::render_scans;
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
    // Where the returns are around the radar: the street's layout relative to the vehicle.
    println!("\n| each azimuth's median level (dB), mean per 45-degree sector from azimuth 0 | 1 | 2 | 3 | 4 | 5 | 6 | 7 | 8 |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for band in [(10.0, 20.0), (60.0, 80.0)] {
        for (who, scans) in [("real", &real), ("simulated", &sim)] {
            let cells: Vec<String> = sector_levels(scans, band)
                .iter()
                .map(|v| format!("{v:.1}"))
                .collect();
            println!(
                "| {who}, {:.0}-{:.0} m | {} |",
                band.0,
                band.1,
                cells.join(" | ")
            );
        }
    }
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

/// The mean over rotations of each azimuth's median level (dB) over the range band
/// `band_m`, averaged per 45-degree sector counted from azimuth 0 (0 where a sector has no
/// azimuths or the band no bins).
fn sector_levels(scans: &Scans, band_m: (f64, f64)) -> [f64; 8] {
    let mut sum = [0.0; 8];
    let mut count = [0usize; 8];
    if scans.bin_m <= 0.0 || scans.azimuths == 0 {
        return sum;
    }
    let first = ((band_m.0 / scans.bin_m) as usize).min(scans.bins);
    let last = ((band_m.1 / scans.bin_m) as usize).min(scans.bins);
    for rotation in &scans.rotations {
        for a in 0..scans.azimuths {
            let row = a * scans.bins;
            let Some(values) = rotation.get(row + first..row + last) else {
                continue;
            };
            let mut histogram = [0u64; 256];
            for &v in values {
                histogram[usize::from(v)] += 1;
            }
            let median = quantile_db(&histogram, 0.5);
            let sector = a * 8 / scans.azimuths;
            if let (false, Some(s), Some(c)) =
                (median.is_nan(), sum.get_mut(sector), count.get_mut(sector))
            {
                *s += median;
                *c += 1;
            }
        }
    }
    for (s, &c) in sum.iter_mut().zip(&count) {
        if c > 0 {
            *s /= c as f64;
        }
    }
    sum
}
