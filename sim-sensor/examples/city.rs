//! Prints a city scene's plan: landmarks, route length, the drive's length and duration, how
//! far the vehicle strays from the street centre lines, its true revisits and (on a grid of
//! identical blocks) its look-alike places.
//!
//! ```sh
//! cargo run --release -p sim-sensor --example city [-- SCENE]   # default city-drive
//! ```

use sim_sensor::scene::{shipped, Scene};
use sim_sensor::visits::{drive_samples, look_alikes, revisits};

fn main() -> anyhow::Result<()> {
    let name = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "city-drive".into());
    let scene = if name.contains('/') || name.contains('.') {
        Scene::load(std::path::Path::new(&name))?
    } else {
        shipped::load(&name)?
    };
    let layout = scene
        .city
        .clone()
        .ok_or_else(|| anyhow::anyhow!("{name} has no [city]"))?;
    let samples = drive_samples(&scene, layout.drive_duration_s + 2.0, 0.1)?;
    let driven = samples.last().map_or(0.0, |s| s.travelled_m);
    let (mut worst_off_line, mut worst_off_road) = (0.0_f64, 0.0_f64);
    for s in &samples {
        let d = layout.distance_to_centre_line([s.pose.x_m, s.pose.y_m]);
        worst_off_road = worst_off_road.max(d);
        if !layout.in_junction([s.pose.x_m, s.pose.y_m]) {
            worst_off_line = worst_off_line.max(d);
        }
    }
    println!(
        "{}: {} landmarks, {} building fronts; route {:.0} m junction to junction, path {:.0} m, driven {:.0} m in {:.1} s (mean {:.2} m/s)",
        scene.name,
        scene.features.len(),
        scene.objects.len(),
        layout.route_length_m,
        layout.path_length_m,
        driven,
        layout.drive_duration_s,
        driven / layout.drive_duration_s.max(1e-9)
    );
    println!(
        "farthest from a centre line: {worst_off_line:.2} m outside junctions, {worst_off_road:.2} m anywhere (carriageway half-width {} m)",
        layout.carriageway_half_m
    );
    for r in revisits(&samples, 10.0, 300.0) {
        println!(
            "revisit {:7.1}-{:7.1} s at ({:7.1}, {:6.1}) first seen at {:7.1} s, heading change {:4.0} deg",
            r.start_s, r.end_s, r.at[0], r.at[1], r.earlier_s, r.heading_change_deg
        );
    }
    if layout.repeated {
        let alikes = look_alikes(&samples, layout.pitch_m, 3.0, 10.0, 50.0);
        let total: f64 = alikes.iter().map(|a| a.end_s - a.start_s).sum();
        println!(
            "{} look-alike stretches ({total:.0} s of driving), e.g.:",
            alikes.len()
        );
        for a in alikes.iter().take(12) {
            println!(
                "  {:7.1}-{:7.1} s looks like {:7.1} s shifted by {:?} blocks",
                a.start_s, a.end_s, a.earlier_s, a.shift_blocks
            );
        }
    }
    Ok(())
}
