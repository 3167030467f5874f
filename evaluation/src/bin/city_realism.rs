//! The realistic city's realism per kilometre of its route, against the real Oxford Radar
//! RobotCar scans in `../shared/data/oxford-radar-robotcar`: for each kilometre, groups of
//! consecutive rotations spread evenly over it are rendered by the realistic renderer and
//! measured as the real scans are (`evaluation::city_realism`), one table row a kilometre
//! and one for the whole drive, with the target band; then the route's returns to mapped
//! streets, and an SVG map of the layout and the route (with the daemon's trajectories over
//! it when given).
//!
//! Run: `cargo run --release -p evaluation --bin city_realism [-- [SCENE_FILE] [--out DIR]
//! [--groups N] [--group-rotations M] [--groups-too] [--trajectory out/trajectory.tum
//! --trajectory out/trajectory-online.tum]]` (SCENE_FILE: `sim-sensor/scenes/realistic-city.toml`
//! by default; the check layout is `sim-sensor/scenes/realistic-city-check.toml`; DIR:
//! `out/city-realism`). Skips with a message when the real scans are absent.
//!
//! Targets: every ratio to the real scans within 25 % (0.75-1.25) on every kilometre; the
//! largest KS distance over the range bands at most 0.1 (the realism comparison's target:
//! a distance, so it has no ratio).

use std::path::PathBuf;
use std::sync::Arc;

use clap::Parser;
use evaluation::city_realism::{
    figures, kilometres, read_tum_xy, render_rotations, write_map, Figures,
};
use sim_sensor::realism::calibrate::{default_oxford_dir, load_polar_dir};
use sim_sensor::render::SceneRenderer;
use sim_sensor::scene::Scene;
use sim_sensor::visits::drive_samples;

#[derive(Debug, Parser)]
#[command(about = "Realism of the realistic city per kilometre against the real scans")]
struct Args {
    /// The scene file (a realistic city).
    scene: Option<PathBuf>,
    /// Where the map goes.
    #[arg(long, default_value = "out/city-realism")]
    out: PathBuf,
    /// Groups of consecutive rotations per kilometre.
    #[arg(long, default_value_t = 4)]
    groups: u64,
    /// Rotations in a group (the first two warm the detectors up).
    #[arg(long, default_value_t = 8)]
    group_rotations: u64,
    /// Also a row for each group (where it is, its figures).
    #[arg(long)]
    groups_too: bool,
    /// A trajectory in the TUM format to draw over the map (the daemon's
    /// `trajectory.tum`, `trajectory-online.tum`); may be given more than once.
    #[arg(long)]
    trajectory: Vec<PathBuf>,
}

/// `value / real`, marked in bold outside 0.75-1.25.
fn ratio(value: f64, real: f64) -> String {
    let r = value / real;
    if (0.75..=1.25).contains(&r) {
        format!("{r:.2}")
    } else {
        format!("**{r:.2}**")
    }
}

fn row(name: &str, f: &Figures, real: &Figures) -> String {
    let ks = if f.ks_max <= 0.1 {
        format!("{:.3}", f.ks_max)
    } else {
        format!("**{:.3}**", f.ks_max)
    };
    format!(
        "| {name} | {} | {ks} ({:.0}-{:.0} m) | {:.4} ({}) | {:.3} ({}) | {:.2} ({}) | {:.0} ({}) | {:.0} ({}) |",
        f.rotations,
        f.ks_band_m.0,
        f.ks_band_m.1,
        f.above_floor,
        ratio(f.above_floor, real.above_floor),
        f.range_fwhm_m,
        ratio(f.range_fwhm_m, real.range_fwhm_m),
        f.azimuth_fwhm_deg,
        ratio(f.azimuth_fwhm_deg, real.azimuth_fwhm_deg),
        f.tpp_per_rotation,
        ratio(f.tpp_per_rotation, real.tpp_per_rotation),
        f.learned_per_rotation,
        ratio(f.learned_per_rotation, real.learned_per_rotation),
    )
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let path = args
        .scene
        .unwrap_or_else(|| root.join("sim-sensor/scenes/realistic-city.toml"));
    let scene = Scene::load(&path)?;
    let layout = scene
        .city
        .clone()
        .ok_or_else(|| anyhow::anyhow!("{} has no [city]", path.display()))?;
    let samples = drive_samples(&scene, layout.drive_duration_s, 0.25)?;
    std::fs::create_dir_all(&args.out)?;
    let map = args.out.join(format!("{}.svg", scene.name));
    let mut trajectories = Vec::new();
    for p in &args.trajectory {
        let name = p
            .file_name()
            .map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into());
        trajectories.push((name, read_tum_xy(p)?));
    }
    write_map(&map, &scene, &samples, &trajectories)?;
    println!("map of the layout and route: {}", map.display());
    println!(
        "\n{}: route {:.0} m junction to junction, {:.0} m driven in {:.0} s, {} junctions passed; returns to mapped streets:",
        scene.name,
        layout.route_length_m,
        samples.last().map_or(0.0, |s| s.travelled_m),
        layout.drive_duration_s,
        layout.route_junctions()
    );
    for r in layout.street_returns() {
        println!(
            "- at {:.0} m along the route from ({:.0}, {:.0}): {:.0} m, {}, {:.0} m of driving since it was last driven",
            r.at_m,
            r.from[0],
            r.from[1],
            r.length_m,
            if r.opposite { "the other way" } else { "the same way" },
            r.driven_since_m
        );
    }
    let dir = default_oxford_dir();
    if !dir.is_dir() {
        println!(
            "\nno real scans at {}: nothing to compare against",
            dir.display()
        );
        return Ok(());
    }
    let real_scans = load_polar_dir(&dir)?;
    let real = figures(std::slice::from_ref(&real_scans), None);
    let renderer = Arc::new(SceneRenderer::new(
        &scene,
        None,
        layout.drive_duration_s + 5.0,
    )?);
    let hz = scene.radar.rotation_hz();
    let m = args.group_rotations.max(3);
    let groups = args.groups.max(1);
    let started = std::time::Instant::now();
    let mut all = Vec::new();
    let mut rows = Vec::new();
    for (k, &(t0, t1, length_m)) in kilometres(&samples).iter().enumerate() {
        // Group starts evenly spread over the kilometre (whole rotations inside it).
        let (r0, r1) = ((t0 * hz).ceil() as u64, (t1 * hz).floor() as u64);
        let room = r1.saturating_sub(r0 + m);
        let mut km = Vec::new();
        for g in 0..groups {
            let first = r0 + room * (2 * g + 1) / (2 * groups);
            let scans = render_rotations(&renderer, first, m)?;
            if args.groups_too {
                let t = first as f64 / hz;
                let at = samples
                    .iter()
                    .find(|s| s.t_s >= t)
                    .map_or([0.0; 2], |s| [s.pose.x_m, s.pose.y_m]);
                let f = figures(std::slice::from_ref(&scans), Some(&real_scans));
                rows.push(row(
                    &format!(
                        "km {} group at {t:.0} s, ({:.0}, {:.0})",
                        k + 1,
                        at[0],
                        at[1]
                    ),
                    &f,
                    &real,
                ));
            }
            km.push(scans);
        }
        let f = figures(&km, Some(&real_scans));
        rows.push(row(
            &format!("km {} ({:.0} m, {:.0}-{:.0} s)", k + 1, length_m, t0, t1),
            &f,
            &real,
        ));
        all.extend(km);
    }
    let whole = figures(&all, Some(&real_scans));
    println!(
        "\n{} real rotations from {}; simulated: {} groups of {m} consecutive rotations a kilometre ({} rotations rendered and measured in {:.1} s)\n",
        real.rotations,
        dir.display(),
        groups,
        whole.rotations,
        started.elapsed().as_secs_f64()
    );
    println!("| stretch | rotations | largest KS over the bands (band) | share 10 dB above the floor (sim / real) | range peak width, m | azimuth peak width, deg | TPP detections / rotation | learned front end targets / rotation |");
    println!("|---|---|---|---|---|---|---|---|");
    println!(
        "| real Oxford scans | {} | | {:.4} | {:.3} | {:.2} | {:.0} | {:.0} |",
        real.rotations,
        real.above_floor,
        real.range_fwhm_m,
        real.azimuth_fwhm_deg,
        real.tpp_per_rotation,
        real.learned_per_rotation
    );
    for r in &rows {
        println!("{r}");
    }
    println!("{}", row("whole drive", &whole, &real));
    println!(
        "\ntarget: every ratio in 0.75-1.25 (bold: outside), the largest KS at most 0.1 (bold: above), on every kilometre"
    );
    Ok(())
}
