//! Fits the realistic receiver (the CTS350-X-like unit's floor, output scale, clip, peak
//! shapes and signal gain with range) to real Oxford Radar RobotCar scans, and prints the
//! fitted values as the `FITTED_*` constants of `sim-sensor/src/realism/calibrate.rs` and
//! as a scene's `[realism]` table.
//!
//! Run: `cargo run --release -p sim-sensor --example calibrate [-- DIR]`
//! (DIR defaults to `../shared/data/oxford-radar-robotcar`; without it the command says so
//! and stops).
//!
//! Steps 1-4 of the module doc of `calibrate.rs` fit on the real scans alone; step 5 (gain
//! and slope) and the width corrections iterate: render the shipped `urban-street` scene
//! (8 rotations, as many as there are real ones), measure it the same way, correct.

use sim_sensor::realism::calibrate::{
    default_oxford_dir, fit_floor, fit_gain_correction, fit_log_scale, load_polar_dir,
};
use sim_sensor::realism::stats::scan_stats;
use sim_sensor::realism::RealismSpec;
use sim_sensor::render::render_scans;
use sim_sensor::scene::shipped;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::args()
        .nth(1)
        .map(std::path::PathBuf::from)
        .unwrap_or_else(default_oxford_dir);
    if !dir.is_dir() {
        println!("no real scans at {}: nothing to fit", dir.display());
        return Ok(());
    }
    let real = load_polar_dir(&dir)?;
    println!(
        "{} real rotations from {}",
        real.rotations.len(),
        dir.display()
    );
    let real_stats = scan_stats(&real);
    let mut pooled = [0u64; 256];
    for h in &real_stats.histograms {
        for (p, v) in pooled.iter_mut().zip(h) {
            *p += v;
        }
    }
    let c = fit_log_scale(&pooled);
    let floor = fit_floor(&real, c);
    let top = real
        .rotations
        .iter()
        .flat_map(|r| r.iter())
        .copied()
        .max()
        .unwrap_or(0);
    println!(
        "output scale c = {c:.4}; floor shape {:.2} (error {:.4})",
        floor.shape, floor.error
    );
    for (r, m) in &floor.means {
        println!("  floor mean at {r:6.2} m: {m:7.3}");
    }
    println!(
        "clip {:.1} dB; real peak widths: {:.3} m in range, {:.2} deg in azimuth ({} peaks)",
        f64::from(top) / 2.0,
        real_stats.widths.range_fwhm_m,
        real_stats.widths.azimuth_fwhm_deg,
        real_stats.widths.peaks
    );

    let mut spec = RealismSpec {
        floor_mean: floor.means.iter().map(|&(r, m)| [r, m]).collect(),
        floor_shape: floor.shape,
        log_scale: c,
        saturation_db: f64::from(top) / 2.0,
        ..RealismSpec::default()
    };
    if real_stats.widths.range_fwhm_m.is_finite() {
        spec.range_fwhm_m = real_stats.widths.range_fwhm_m;
    }
    if real_stats.widths.azimuth_fwhm_deg.is_finite() {
        spec.beam_fwhm_deg = real_stats.widths.azimuth_fwhm_deg;
    }
    let iterations: usize = std::env::var("CALIBRATE_ITERATIONS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    // The high-pass corner by grid search; gain, slope and widths by iteration for each.
    let mut best: Option<(f64, RealismSpec)> = None;
    for highpass_m in [0.0, 3.0, 6.0, 9.0, 12.0, 15.0, 18.0] {
        let mut trial = RealismSpec {
            highpass_m,
            ..spec.clone()
        };
        let mut err = f64::INFINITY;
        for it in 0..=iterations {
            let mut scene = shipped::load("urban-street")?;
            scene.realism = Some(trial.clone());
            let sim = render_scans(&scene, None, 4, real.rotations.len().max(1) as u64)?;
            let s = scan_stats(&sim);
            err = real_stats
                .bands
                .iter()
                .zip(&s.bands)
                .map(|(r, s)| (r.p99_db - s.p99_db).powi(2) + (r.p90_db - s.p90_db).powi(2))
                .sum::<f64>();
            println!(
                "high-pass {highpass_m:.1} m, iteration {it}: gain {:.2} dB slope {:.2} dB/dec range FWHM {:.3} m beam {:.2} deg -> sim widths {:.3} m {:.2} deg, above floor {:.4} (real {:.4}), p90/p99 squared error {err:.1}",
                trial.signal_gain_db,
                trial.signal_slope_db_per_decade,
                trial.range_fwhm_m,
                trial.beam_fwhm_deg,
                s.widths.range_fwhm_m,
                s.widths.azimuth_fwhm_deg,
                s.above_floor,
                real_stats.above_floor,
            );
            if it == iterations {
                break;
            }
            let (dg, ds) = fit_gain_correction(&real_stats.bands, &s.bands);
            trial.signal_gain_db += dg;
            trial.signal_slope_db_per_decade += ds;
            if s.widths.range_fwhm_m.is_finite() && real_stats.widths.range_fwhm_m.is_finite() {
                trial.range_fwhm_m = (trial.range_fwhm_m * real_stats.widths.range_fwhm_m
                    / s.widths.range_fwhm_m)
                    .clamp(0.02, 2.0);
            }
            if s.widths.azimuth_fwhm_deg.is_finite()
                && real_stats.widths.azimuth_fwhm_deg.is_finite()
            {
                trial.beam_fwhm_deg = (trial.beam_fwhm_deg * real_stats.widths.azimuth_fwhm_deg
                    / s.widths.azimuth_fwhm_deg)
                    .clamp(0.3, 10.0);
            }
        }
        if best.as_ref().is_none_or(|(e, _)| err < *e) {
            best = Some((err, trial));
        }
    }
    let Some((_, spec)) = best else {
        return Ok(());
    };
    println!("\n// fitted constants for sim-sensor/src/realism/calibrate.rs");
    println!("pub const FITTED_FLOOR_MEAN: &[(f64, f64)] = &[");
    for (r, m) in &floor.means {
        println!("    ({r:.2}, {m:.3}),");
    }
    println!("];");
    println!("pub const FITTED_FLOOR_SHAPE: f64 = {:.2};", floor.shape);
    println!("pub const FITTED_LOG_SCALE: f64 = {c:.4};");
    println!(
        "pub const FITTED_SATURATION_DB: f64 = {:.1};",
        f64::from(top) / 2.0
    );
    println!(
        "pub const FITTED_RANGE_FWHM_M: f64 = {:.3};",
        spec.range_fwhm_m
    );
    println!(
        "pub const FITTED_BEAM_FWHM_DEG: f64 = {:.2};",
        spec.beam_fwhm_deg
    );
    println!(
        "pub const FITTED_SIGNAL_GAIN_DB: f64 = {:.2};",
        spec.signal_gain_db
    );
    println!(
        "pub const FITTED_SIGNAL_SLOPE_DB_PER_DECADE: f64 = {:.2};",
        spec.signal_slope_db_per_decade
    );
    println!("pub const FITTED_HIGHPASS_M: f64 = {:.1};", spec.highpass_m);
    Ok(())
}
