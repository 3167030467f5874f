//! The shipped city scenes (`city-drive`, `repeated-blocks`): what issue 14's evaluation
//! relies on, checked on the ground-truth trajectory the simulator integrates.

use sim_sensor::scene::city::CityLayout;
use sim_sensor::scene::{shipped, Scene};
use sim_sensor::visits::{drive_samples, look_alikes, revisits, DriveSample};

fn load(name: &str) -> (Scene, CityLayout, Vec<DriveSample>) {
    let scene = shipped::load(name).expect("shipped scene");
    let layout = scene.city.clone().expect("a [city] scene");
    let samples = drive_samples(&scene, layout.drive_duration_s + 5.0, 0.1).expect("samples");
    (scene, layout, samples)
}

/// Every 5th sample (0.5 s): enough for revisits, 25 times cheaper.
fn coarse(samples: &[DriveSample]) -> Vec<DriveSample> {
    samples.iter().step_by(5).copied().collect()
}

fn assert_on_the_road(name: &str, layout: &CityLayout, samples: &[DriveSample]) {
    let (mut off_line, mut off_road) = (0.0_f64, 0.0_f64);
    for s in samples {
        let p = [s.pose.x_m, s.pose.y_m];
        let d = layout.distance_to_centre_line(p);
        off_road = off_road.max(d);
        if !layout.in_junction(p) {
            off_line = off_line.max(d);
        }
    }
    println!("{name}: at most {off_line:.2} m from a centre line outside junctions, {off_road:.2} m inside");
    assert!(off_line <= 1.5, "{name}: {off_line} m off the centre line");
    // Through a junction the car cuts the corner but stays on the carriageway with its
    // half-width (0.9 m) to spare.
    assert!(
        off_road <= layout.carriageway_half_m - 0.9,
        "{name}: {off_road} m"
    );
}

#[test]
fn the_city_drive_is_over_3_km_with_thousands_of_landmarks_at_urban_speed() {
    let (scene, layout, samples) = load("city-drive");
    let driven = samples.last().map_or(0.0, |s| s.travelled_m);
    let top_speed = scene
        .schedule
        .keys()
        .iter()
        .map(|k| k.speed_mps)
        .fold(0.0, f64::max);
    println!(
        "city-drive: {} landmarks, route {:.0} m, driven {driven:.0} m in {:.1} s ({:.2} m/s mean, {top_speed} m/s top)",
        scene.features.len(),
        layout.route_length_m,
        layout.drive_duration_s,
        driven / layout.drive_duration_s
    );
    assert!(layout.route_length_m >= 3000.0);
    assert!(driven >= 3000.0, "{driven}");
    assert!(
        (2000..10_000).contains(&scene.features.len()),
        "{}",
        scene.features.len()
    );
    assert!((8.0..=12.0).contains(&top_speed), "{top_speed}");
    assert_eq!(scene.preset, sim_sensor::radar::RadarPreset::Cts350x400);
    // At rest once the route is done.
    let last = scene.schedule.keys().last().expect("keys");
    assert_eq!(last.speed_mps, 0.0);
    let end = samples.last().expect("samples");
    let corner = layout.route_corners.last().expect("corners");
    assert!((end.pose.x_m - corner[0]).hypot(end.pose.y_m - corner[1]) < 1.0);
}

#[test]
fn the_city_drive_stays_on_the_road() {
    let (_, layout, samples) = load("city-drive");
    assert_on_the_road("city-drive", &layout, &samples);
}

#[test]
fn the_city_drive_returns_to_mapped_places_after_long_excursions() {
    let (_, _, samples) = load("city-drive");
    let found = revisits(&coarse(&samples), 10.0, 300.0);
    for r in &found {
        println!(
            "revisit {:6.1}-{:6.1} s near ({:6.1}, {:6.1}), there first at {:6.1} s, heading {:+4.0} deg",
            r.start_s, r.end_s, r.at[0], r.at[1], r.earlier_s, r.heading_change_deg
        );
    }
    // Each return a stretch of street (not a brush past a junction) after 300 m or more.
    let long: Vec<_> = found
        .iter()
        .filter(|r| r.end_s - r.start_s >= 10.0)
        .collect();
    assert!(long.len() >= 2, "{found:?}");
    // One of them driven the same way as the first time.
    assert!(
        found.iter().any(|r| r.heading_change_deg.abs() < 20.0),
        "{found:?}"
    );
}

#[test]
fn the_city_scenes_are_the_same_from_the_same_seed() {
    for name in ["city-drive", "repeated-blocks"] {
        let a = shipped::load(name).expect("scene");
        let b = shipped::load(name).expect("scene");
        assert_eq!(a, b, "{name}");
        let text = shipped::text(name).expect("text");
        let reseeded = text.replacen("[city]\nseed = ", "[city]\nseed = 1", 1);
        let c = Scene::from_toml_str(name, &reseeded).expect("reseeded");
        assert_ne!(a.features, c.features, "{name}");
    }
}

#[test]
fn the_repeated_blocks_stay_on_the_road_and_come_back_to_the_start_once() {
    let (scene, layout, samples) = load("repeated-blocks");
    assert!(layout.repeated);
    assert!(scene.features.len() >= 2000, "{}", scene.features.len());
    assert_on_the_road("repeated-blocks", &layout, &samples);
    let found = revisits(&coarse(&samples), 10.0, 300.0);
    println!("repeated-blocks: {found:?}");
    assert_eq!(found.len(), 1, "{found:?}");
    let start = layout.route_corners[0];
    let r = found[0];
    assert!(
        r.earlier_s < 30.0 && r.heading_change_deg.abs() < 20.0,
        "{r:?}"
    );
    assert!((r.at[0] - start[0]).abs() < 250.0 && (r.at[1] - start[1]).abs() < 10.0);
}

#[test]
fn the_repeated_blocks_look_like_each_other_along_most_of_the_drive() {
    let (_, layout, samples) = load("repeated-blocks");
    let alikes = look_alikes(&coarse(&samples), layout.pitch_m, 3.0, 10.0, 50.0);
    let seconds: f64 = alikes.iter().map(|a| a.end_s - a.start_s).sum();
    for a in &alikes {
        println!(
            "look-alike {:6.1}-{:6.1} s: {:6.1} s shifted by {:?} blocks",
            a.start_s, a.end_s, a.earlier_s, a.shift_blocks
        );
    }
    println!(
        "{seconds:.0} s of {:.0} s look like somewhere else",
        layout.drive_duration_s
    );
    assert!(seconds > 0.5 * layout.drive_duration_s, "{seconds}");
    assert!(alikes.iter().all(|a| a.shift_blocks != [0, 0]));
}
