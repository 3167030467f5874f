//! The realistic city (`scenes/realistic-city.toml` and its check layout): the route's
//! length, returns and directions from the layout alone and on the ground truth, what the
//! generator lines the streets with, determinism from the seed, and the renderer's spatial
//! index against a brute-force search over the whole city. No rendering.

use std::path::PathBuf;

use sim_sensor::realism::objects::World;
use sim_sensor::scene::objects::ObjectKind;
use sim_sensor::scene::{FeatureKind, Scene};
use sim_sensor::visits::{drive_samples, revisits};

fn scene_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(format!("{name}.toml"))
}

fn load(name: &str) -> Scene {
    Scene::load(&scene_path(name)).expect("scene")
}

#[test]
fn the_route_is_over_4_km_and_comes_back_three_times_once_the_other_way_once_after_1_5_km() {
    for name in ["realistic-city", "realistic-city-check"] {
        let scene = load(name);
        let layout = scene.city.clone().expect("a [city] scene");
        let returns = layout.street_returns();
        for r in &returns {
            println!(
                "{name}: return at {:.0} m along the route from {:?}: {:.0} m over {} edges, {:.0} m driven since, {}",
                r.at_m,
                r.from,
                r.length_m,
                r.edges,
                r.driven_since_m,
                if r.opposite { "the other way" } else { "the same way" }
            );
        }
        assert!(layout.route_length_m >= 4000.0, "{}", layout.route_length_m);
        assert!(layout.path_length_m >= 4000.0, "{}", layout.path_length_m);
        assert!(returns.len() >= 3, "{name}: {} returns", returns.len());
        assert!(
            returns.iter().any(|r| r.opposite),
            "{name}: none the other way"
        );
        assert!(
            returns.iter().any(|r| r.driven_since_m > 1500.0),
            "{name}: none after 1.5 km"
        );
        assert!(
            layout.route_junctions() >= 30,
            "{}",
            layout.route_junctions()
        );
    }
}

#[test]
fn the_ground_truth_drives_over_4_km_and_finds_the_same_returns() {
    let scene = load("realistic-city");
    let layout = scene.city.clone().expect("a [city] scene");
    let samples = drive_samples(&scene, layout.drive_duration_s + 2.0, 0.5).expect("samples");
    let driven = samples.last().map_or(0.0, |s| s.travelled_m);
    assert!(driven >= 4000.0, "{driven} m");
    let found = revisits(&samples, 10.0, 300.0);
    println!("{found:?}");
    assert!(found.len() >= 3, "{} revisits", found.len());
    assert!(found
        .iter()
        .any(|r| (r.heading_change_deg.abs() - 180.0).abs() < 20.0));
    // One comes back more than 1.5 km of driving after the place was first driven.
    let travelled_at = |t: f64| {
        samples
            .iter()
            .find(|s| s.t_s >= t)
            .map_or(driven, |s| s.travelled_m)
    };
    assert!(found
        .iter()
        .any(|r| travelled_at(r.start_s) - travelled_at(r.earlier_s) > 1500.0));
}

#[test]
fn the_streets_are_lined_with_everything_the_urban_street_has_and_fences() {
    let scene = load("realistic-city");
    let count = |kind: ObjectKind| scene.objects.iter().filter(|o| o.kind == kind).count();
    let fronts = count(ObjectKind::BuildingFront);
    let parked = scene
        .objects
        .iter()
        .filter(|o| o.kind == ObjectKind::Vehicle && o.speed_mps == 0.0)
        .count();
    let moving = scene
        .objects
        .iter()
        .filter(|o| o.kind == ObjectKind::Vehicle && o.speed_mps != 0.0)
        .count();
    let trees = scene
        .features
        .iter()
        .filter(|f| f.kind == FeatureKind::Tree)
        .count();
    let poles = scene
        .features
        .iter()
        .filter(|f| f.kind == FeatureKind::LampPost)
        .count();
    println!(
        "fronts {fronts}, hedges {}, fences {}, crowns {}, clutter patches {}, parked {parked}, moving {moving}, trunks {trees}, poles {poles}",
        count(ObjectKind::Hedge),
        count(ObjectKind::Fence),
        count(ObjectKind::Foliage),
        count(ObjectKind::Clutter)
    );
    assert!(
        fronts > 1000 && parked > 1000 && moving == 60,
        "{fronts} {parked} {moving}"
    );
    assert!(count(ObjectKind::Hedge) > 50 && count(ObjectKind::Fence) > 50);
    assert_eq!(count(ObjectKind::Foliage), trees);
    assert!(trees > 500 && poles > 500, "{trees} {poles}");
    // Set-backs: fronts off the building line; gaps: a block side not covered end to end.
    let layout = scene.city.clone().expect("city");
    let half = layout.carriageway_half_m + layout.pavement_m;
    let set_back = scene
        .objects
        .iter()
        .filter(|o| o.kind == ObjectKind::BuildingFront)
        .filter_map(|o| o.from)
        .filter(|p| layout.distance_to_centre_line(*p) > half + 1.0)
        .count();
    assert!(set_back > fronts / 3, "{set_back} of {fronts} set back");
    // Nothing stands on the carriageway but vehicles and ground clutter.
    for o in &scene.objects {
        if matches!(o.kind, ObjectKind::Vehicle | ObjectKind::Clutter) {
            continue;
        }
        for p in [o.from, o.to, o.at].into_iter().flatten() {
            let d = layout.distance_to_centre_line(p);
            assert!(
                d >= layout.carriageway_half_m,
                "{:?} at {p:?}, {d} m",
                o.kind
            );
        }
    }
}

#[test]
fn the_layout_is_the_same_from_the_same_seed_and_another_from_another() {
    let text = std::fs::read_to_string(scene_path("realistic-city")).expect("text");
    let a = Scene::from_toml_str("a", &text).expect("scene");
    let b = Scene::from_toml_str("b", &text).expect("scene");
    assert_eq!(a.objects, b.objects);
    assert_eq!(a.features, b.features);
    let check = load("realistic-city-check");
    assert_ne!(a.objects, check.objects);
    // The same route and drive, another layout.
    assert_eq!(a.schedule, check.schedule);
    assert_eq!(
        a.city.as_ref().map(|c| &c.route_corners),
        check.city.as_ref().map(|c| &c.route_corners)
    );
}

#[test]
fn a_rotations_gather_through_the_grid_finds_exactly_what_a_brute_force_search_finds() {
    let scene = load("realistic-city");
    let world = World::build(&scene.features, &scene.objects, scene.seed).expect("world");
    let layout = scene.city.clone().expect("city");
    let reach = scene.radar.max_range_m() + 3.0;
    let statics: Vec<[f64; 2]> = world
        .static_scatterers
        .iter()
        .map(|&i| world.scatterers[i as usize].pos)
        .collect();
    assert!(statics.len() > 500_000, "{}", statics.len());
    for c in layout.route_corners.iter().take(5) {
        let centre = [c[0] + 3.0, c[1] - 2.0];
        let inside = |p: &[f64; 2]| (p[0] - centre[0]).hypot(p[1] - centre[1]) <= reach;
        let mut grid: Vec<usize> = Vec::new();
        world
            .scatterer_grid
            .for_each_near(centre, reach, |i| grid.push(i));
        grid.retain(|&i| statics.get(i).is_some_and(inside));
        grid.sort_unstable();
        let brute: Vec<usize> = (0..statics.len())
            .filter(|&i| inside(&statics[i]))
            .collect();
        assert!(brute.len() > 10_000, "{}", brute.len());
        assert_eq!(grid, brute, "at {centre:?}");
    }
}
