//! The place descriptor on small synthetic places: the same place seen from a rotated and
//! shifted pose, with jitter, missed points and clutter, matches and gives back the rotation;
//! other places do not; the ring-key index retrieves the place; bad input is refused.

use radar_odometry::{PlaceDescriptor, PlaceError, PlaceIndex, PlaceQuery, PlaceSettings};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A street-like place: two rows of poles along a 12 m wide street through the origin, a
/// cross street, scattered corners; `seed` decides where each stands.
fn place(seed: u64) -> Vec<[f64; 2]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut p = Vec::new();
    let mut x = -90.0;
    while x < 90.0 {
        x += rng.gen_range(4.0..12.0);
        p.push([x, 6.0 + rng.gen_range(-0.5..0.5)]);
        p.push([
            x + rng.gen_range(-2.0..2.0),
            -6.0 + rng.gen_range(-0.5..0.5),
        ]);
    }
    let cross = rng.gen_range(-60.0..60.0);
    let mut y = -90.0;
    while y < 90.0 {
        y += rng.gen_range(5.0..15.0);
        p.push([cross + 6.0, y]);
    }
    for _ in 0..15 {
        p.push([rng.gen_range(-80.0..80.0), rng.gen_range(-80.0..80.0)]);
    }
    p
}

/// `points` (world) seen from `pose` (x, y, heading), each jittered, a share missed, some
/// clutter added.
fn seen_from(points: &[[f64; 2]], pose: [f64; 3], seed: u64) -> Vec<[f64; 2]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (s, c) = pose[2].sin_cos();
    let mut out: Vec<[f64; 2]> = Vec::new();
    for p in points {
        if !rng.gen_bool(0.85) {
            continue;
        }
        let (dx, dy) = (p[0] - pose[0], p[1] - pose[1]);
        out.push([
            c * dx + s * dy + rng.gen_range(-0.3..0.3),
            -s * dx + c * dy + rng.gen_range(-0.3..0.3),
        ]);
    }
    for _ in 0..8 {
        out.push([rng.gen_range(-70.0..70.0), rng.gen_range(-70.0..70.0)]);
    }
    out
}

fn descriptor(points: &[[f64; 2]]) -> PlaceDescriptor {
    PlaceDescriptor::new(points.iter().copied(), &PlaceSettings::default()).unwrap()
}

fn yaw_error(a: f64, b: f64) -> f64 {
    radar_model::geometry::wrap_angle(a - b).abs()
}

#[test]
fn the_same_place_from_a_rotated_and_shifted_pose_matches_and_gives_the_transform() {
    let settings = PlaceSettings::default();
    for seed in 0..4u64 {
        let world = place(seed);
        let a = descriptor(&seen_from(&world, [0.0, 0.0, 0.0], 100 + seed));
        for (i, pose) in [
            [0.0, 0.0, 0.3],
            [3.0, -2.0, 1.7],
            [-5.0, 6.0, -2.6],
            [8.0, 1.0, 3.1],
        ]
        .into_iter()
        .enumerate()
        {
            let q = PlaceQuery::new(
                &seen_from(&world, pose, 200 + 10 * seed + i as u64),
                &settings,
            )
            .unwrap();
            let m = q.compare(&a).unwrap();
            let other =
                PlaceQuery::new(&seen_from(&place(1000 + seed), pose, 300 + seed), &settings)
                    .unwrap();
            let d = other.compare(&a).unwrap();
            assert!(
                m.place.distance < 0.5,
                "seed {seed} {pose:?}: same place at {m:?}"
            );
            assert!(
                d.place.distance > m.place.distance + 0.02,
                "seed {seed} {pose:?}: another place at {} vs the same at {}",
                d.place.distance,
                m.place.distance
            );
            assert!(
                yaw_error(m.place.yaw_rad, pose[2]) < 0.06,
                "seed {seed}: yaw {} recovered for {}",
                m.place.yaw_rad,
                pose[2]
            );
            let t = m.transform;
            assert!(
                (t[0] - pose[0]).hypot(t[1] - pose[1]) < 2.6,
                "seed {seed}: translation {t:?} for {pose:?}"
            );
        }
    }
}

#[test]
fn the_ring_key_index_retrieves_the_place_among_others() {
    let mut index = PlaceIndex::new();
    let mut places = Vec::new();
    for seed in 0..40u64 {
        let d = descriptor(&seen_from(&place(seed), [0.0, 0.0, 0.0], seed));
        index.insert(seed, &d);
        places.push(d);
    }
    assert_eq!(index.len(), 40);
    let settings = PlaceSettings::default();
    for seed in [3u64, 17, 29, 35] {
        let q = PlaceQuery::new(
            &seen_from(&place(seed), [-2.0, 4.0, 2.0], 900 + seed),
            &settings,
        )
        .unwrap();
        let near = index.nearest(&q.shifted[0].1, 8);
        assert_eq!(near.len(), 8);
        assert!(near.windows(2).all(|w| w[0].1 <= w[1].1), "nearest first");
        let near = index.nearest_to_query(&q, 16);
        assert!(near.len() <= 16);
        assert!(
            near.iter().any(|(id, _)| *id == seed),
            "place {seed} retrieved: {near:?}"
        );
        // The full comparison over the retrieved places picks the true one.
        let best = near
            .iter()
            .filter_map(|(id, _)| Some((*id, q.compare(&places[*id as usize])?.place.distance)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|b| b.0);
        assert_eq!(best, Some(seed));
    }
    assert!(PlaceIndex::new().nearest(&places[0], 5).is_empty());
}

#[test]
fn bounded_memory_and_bad_input() {
    // A million points make a descriptor of the same fixed size; cells stay in [0, 1].
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let many = (0..1_000_000).map(|_| [rng.gen_range(-100.0..100.0), rng.gen_range(-100.0..100.0)]);
    let d = PlaceDescriptor::new(many, &PlaceSettings::default()).unwrap();
    assert_eq!(PlaceDescriptor::heap_bytes(), 20 * 60 * 4);
    assert!(d.ring_key().iter().all(|k| (0.0..=1.0).contains(k)));
    // Non-finite and far points are left out, and too few points is an error.
    let few = [
        [f64::NAN, 1.0],
        [f64::INFINITY, 0.0],
        [500.0, 0.0],
        [1.0, 1.0],
    ];
    assert_eq!(
        PlaceDescriptor::new(few, &PlaceSettings::default()).unwrap_err(),
        PlaceError::TooFewPoints {
            found: 1,
            needed: 12
        }
    );
    for bad in [
        PlaceSettings {
            blur_m: f64::NAN,
            ..PlaceSettings::default()
        },
        PlaceSettings {
            search_step_m: 0.01,
            ..PlaceSettings::default()
        },
    ] {
        assert!(matches!(
            PlaceDescriptor::new([[1.0, 1.0]], &bad),
            Err(PlaceError::BadSettings { .. })
        ));
        assert!(PlaceQuery::new(&[[1.0, 1.0]], &bad).is_err());
    }
    assert_eq!(PlaceSettings::default().shifts().unwrap().len(), 81);
}
