use super::*;
use crate::scene::Scene;

fn spec(route: &[&str]) -> CitySpec {
    CitySpec {
        blocks_x: 3,
        blocks_y: 2,
        start: [0, 0],
        route: route.iter().map(|s| s.to_string()).collect(),
        ..CitySpec::default()
    }
}

#[test]
fn the_same_seed_gives_the_same_city_and_another_seed_another() {
    let a = spec(&["E2", "N1"]).generate(2.7).expect("city");
    let b = spec(&["E2", "N1"]).generate(2.7).expect("city");
    assert_eq!(a, b);
    let c = CitySpec {
        seed: 2,
        ..spec(&["E2", "N1"])
    }
    .generate(2.7)
    .expect("city");
    assert_ne!(a.landmarks, c.landmarks);
    // The drive depends on the route, not on the layout's seed.
    assert_eq!(a.control, c.control);
}

#[test]
fn no_two_landmarks_are_closer_than_the_minimum_spacing() {
    let city = CitySpec {
        blocks_x: 4,
        blocks_y: 4,
        kerb_spacing_m: 3.0,
        ..CitySpec::default()
    }
    .generate(2.7)
    .expect("city");
    let n = city.landmarks.len();
    assert!(n > 500, "{n}");
    for (i, a) in city.landmarks.iter().enumerate() {
        for b in &city.landmarks[i + 1..] {
            let d = (a.x_m - b.x_m).hypot(a.y_m - b.y_m);
            assert!(d >= 4.0 - 1e-9, "{a:?} and {b:?} are {d} m apart");
        }
    }
}

#[test]
fn landmarks_stand_off_the_carriageway_and_outside_the_buildings() {
    let s = CitySpec::default();
    let city = s.generate(2.7).expect("city");
    let layout = &city.layout;
    for l in &city.landmarks {
        let d = layout.distance_to_centre_line([l.x_m, l.y_m]);
        // Parked cars' street-side corners stand in the parking lane, 1.8 m out from the
        // kerb; everything else on the pavement or the building line.
        assert!(d >= s.carriageway_half_m - 1.8 - 1e-9, "{l:?} at {d} m");
        assert!(
            d <= s.carriageway_half_m + s.pavement_m - 0.25 + 1e-9
                || l.class == LandmarkClass::BuildingCorner,
            "{l:?} at {d} m"
        );
    }
}

#[test]
fn repeated_blocks_have_the_same_landmarks_relative_to_their_corner() {
    let s = CitySpec {
        repeated: true,
        ..CitySpec::default()
    };
    let city = s.generate(2.7).expect("city");
    let [px, py] = s.pitch_m();
    let block_of = |l: &Landmark| {
        // Landmarks stand within the pavement of their block, so the nearest block
        // centre names it.
        (
            ((l.x_m - 0.5 * px) / px).round() as i64,
            ((l.y_m - 0.5 * py) / py).round() as i64,
        )
    };
    let mut by_block: std::collections::BTreeMap<(i64, i64), Vec<(i64, i64)>> =
        std::collections::BTreeMap::new();
    for l in &city.landmarks {
        let (i, j) = block_of(l);
        let local = (
            ((l.x_m - i as f64 * px) * 1e6).round() as i64,
            ((l.y_m - j as f64 * py) * 1e6).round() as i64,
        );
        by_block.entry((i, j)).or_default().push(local);
    }
    assert_eq!(by_block.len(), (s.blocks_x * s.blocks_y) as usize);
    let first = by_block.values().next().cloned().unwrap_or_default();
    assert!(first.len() > 30, "{}", first.len());
    for (block, local) in &by_block {
        assert_eq!(local, &first, "block {block:?}");
    }
    // Without `repeated` two blocks differ.
    let varied = CitySpec::default().generate(2.7).expect("city");
    assert_ne!(varied.landmarks.len(), 0);
    let first_block: Vec<&Landmark> = varied
        .landmarks
        .iter()
        .filter(|l| block_of(l) == (0, 0))
        .collect();
    let second_block: Vec<&Landmark> = varied
        .landmarks
        .iter()
        .filter(|l| block_of(l) == (1, 0))
        .collect();
    assert!(
        first_block.len() != second_block.len()
            || first_block
                .iter()
                .zip(&second_block)
                .any(|(a, b)| (a.x_m + px - b.x_m).abs() > 1e-6),
        "two varied blocks are identical"
    );
}

#[test]
fn a_route_that_leaves_the_grid_or_turns_back_is_a_named_error() {
    let err = spec(&["E4"]).generate(2.7).expect_err("off the grid");
    assert!(err.to_string().contains("city.route[0]"), "{err}");
    assert!(err.to_string().contains("leaves the grid"), "{err}");
    let err = spec(&["E2", "W1"]).generate(2.7).expect_err("U-turn");
    assert!(err.to_string().contains("city.route[1]"), "{err}");
    let err = spec(&["X2"]).generate(2.7).expect_err("bad leg");
    assert!(err.to_string().contains("city.route[0]"), "{err}");
    let err = spec(&["E0"]).generate(2.7).expect_err("no blocks");
    assert!(err.to_string().contains("city.route[0]"), "{err}");
}

#[test]
fn a_turn_the_car_cannot_make_within_the_carriageway_is_refused() {
    let err = CitySpec {
        turn_mps: 12.0,
        cruise_mps: 12.0,
        turn_radius_m: 2.0,
        steer_rate_rad_s: 0.05,
        ..spec(&["E1", "N1"])
    }
    .generate(2.7)
    .expect_err("too fast for the corner");
    assert!(err.to_string().contains("leaves the carriageway"), "{err}");
}

#[test]
fn a_city_scene_refuses_a_hand_written_schedule_start_or_another_motion_model() {
    let city = "[city]\nroute = [\"E1\"]\n";
    for (extra, field) in [
        (
            "[[control]]\nt_s = 0.0\nspeed_mps = 1.0\nsteer_rad = 0.0\n",
            "control",
        ),
        ("[start]\nx_m = 3.0\n", "start"),
        (
            "[motion]\nmodel = \"paper\"\nstep_s = 0.05\n",
            "motion.model",
        ),
    ] {
        let err = Scene::from_toml_str("c", &format!("{extra}{city}")).expect_err(field);
        assert!(err.to_string().contains(field), "{err}");
    }
    // The start time alone is allowed.
    let scene =
        Scene::from_toml_str("c", &format!("[start]\nunix_time_s = 1.0e9\n{city}")).expect("valid");
    assert_eq!(scene.start_time_ns, Some(1_000_000_000_000_000_000));
    assert!(scene.city.is_some());
}

#[test]
fn the_vehicle_stands_still_at_the_start_without_a_route() {
    let scene = Scene::from_toml_str("c", "[city]\nstart = [1, 1]\n").expect("valid");
    let layout = scene.city.clone().expect("layout");
    assert_eq!(layout.route_length_m, 0.0);
    let t = crate::trajectory::Trajectory::new(&scene, 5.0).expect("trajectory");
    let p = t.pose_at(4_000_000_000).expect("pose");
    assert_eq!((p.x, p.y), (layout.pitch_m[0], layout.pitch_m[1]));
}

#[test]
fn buildings_hide_the_landmarks_behind_them_from_the_point_target_renderer() {
    // A vehicle at junction (1, 1) of a 3 x 3 grid sees down its four streets; the
    // landmarks on the far side of a block are hidden.
    let text = "[radar]\npreset = \"cts350x-400\"\n[noise]\nenabled = false\n\
                [city]\nblocks_x = 3\nblocks_y = 3\nstart = [1, 1]\n";
    let with = Scene::from_toml_str("c", text).expect("valid");
    let without = Scene::from_toml_str("c", &format!("{text}buildings = false\n")).expect("valid");
    assert_eq!(with.features, without.features);
    let seen = |scene: &Scene| {
        let renderer = std::sync::Arc::new(
            crate::render::SceneRenderer::new(scene, None, 5.0).expect("renderer"),
        );
        let mut cursor = renderer.cursor();
        let mut ids = std::collections::BTreeSet::new();
        for k in 0..u64::from(scene.radar.azimuths) {
            for (_, id) in cursor.features_in_beam(k).expect("beam") {
                ids.insert(id);
            }
        }
        ids
    };
    let (a, b) = (seen(&with), seen(&without));
    println!(
        "seen from junction (1, 1): {} with buildings, {} without",
        a.len(),
        b.len()
    );
    assert!(a.is_subset(&b));
    assert!(a.len() * 2 < b.len(), "{} of {}", a.len(), b.len());
    // What is seen lies along the four streets through the junction, or at a corner.
    let layout = with.city.clone().expect("layout");
    let [px, py] = layout.pitch_m;
    for id in &a {
        let f = &with.features[*id as usize];
        let off_street = (f.x_m - px).abs().min((f.y_m - py).abs());
        assert!(off_street <= 8.5, "{f:?} seen through a building");
    }
}

#[test]
fn the_realistic_city_needs_realism_and_dressing_together_and_names_a_bad_dressing_value() {
    let base = r#"
        [motion]
        model = "bicycle"
        wheelbase_m = 2.7
        [city]
        blocks_x = 2
        blocks_y = 2
        route = ["E1"]
    "#;
    let err = Scene::from_toml_str("x", &format!("[realism]\n{base}")).expect_err("no dressing");
    assert!(err.to_string().contains("city.dressing"), "{err}");
    let err =
        Scene::from_toml_str("x", &format!("{base}[city.dressing]\n")).expect_err("no realism");
    assert!(err.to_string().contains("city.dressing"), "{err}");
    let err = Scene::from_toml_str(
        "x",
        &format!("[realism]\n{base}[city.dressing]\nparked_fraction = 1.5\n"),
    )
    .expect_err("out of range");
    assert!(
        err.to_string().contains("city.dressing.parked_fraction"),
        "{err}"
    );
    let scene = Scene::from_toml_str("x", &format!("[realism]\n{base}[city.dressing]\n"))
        .expect("a small realistic city");
    assert!(scene.objects.len() > 50 && !scene.features.is_empty());
    assert!(scene.realism.is_some() && scene.city.is_some());
}
