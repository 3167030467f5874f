//! Loop closure without a usable prior: a 400 m square driven once and then some, chained by
//! switch poses whose heading is biased far beyond their stated covariance, so that on the
//! return the pose prior puts the vehicle tens of metres from where it is and claims to
//! know it to a few. The uncertainty search finds nothing; the place descriptors find the
//! return, and the verifier accepts the closure with the true transform (every closure is
//! checked against the truth).

use std::sync::Arc;

use nalgebra::{Matrix2, Matrix3, Vector3};
use radar_model::geometry::{wrap_angle, Pose2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam_filter::{FeatureId, FrozenSubmap, SubmapFeature};
use slam_graph::se2::{between, inverse, transform_point};
use slam_graph::{GlobalMap, GlobalSettings, PlaceSearch};

const SIDE_M: f64 = 400.0;
const STEP_M: f64 = 50.0;

/// True frames every 50 m around the square, then three more along the first side.
fn true_frames() -> Vec<Pose2> {
    true_frames_then(4)
}

/// True frames every 50 m around the square, then `then - 1` more around it again.
fn true_frames_then(then: usize) -> Vec<Pose2> {
    let per_side = (SIDE_M / STEP_M) as usize;
    let mut out = Vec::new();
    for n in 0..(4 * per_side + then) {
        let side = (n / per_side) % 4;
        let d = STEP_M * (n % per_side) as f64;
        let (x, y) = match side {
            0 => (d, 0.0),
            1 => (SIDE_M, d),
            2 => (SIDE_M - d, SIDE_M),
            _ => (0.0, SIDE_M - d),
        };
        out.push(Pose2::new(
            x,
            y,
            wrap_angle(side as f64 * std::f64::consts::FRAC_PI_2),
        ));
    }
    out
}

/// Submaps seeing the posts within 60 m of their frame, chained with a heading bias of
/// `bias_rad` per submap and a covariance that knows nothing of it.
fn submaps(bias_rad: f64, seed: u64) -> (Vec<FrozenSubmap>, Vec<Pose2>) {
    submaps_along(true_frames(), bias_rad, seed)
}

/// [`submaps`] along `frames`.
fn submaps_along(frames: Vec<Pose2>, bias_rad: f64, seed: u64) -> (Vec<FrozenSubmap>, Vec<Pose2>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let posts: Vec<[f64; 2]> = (0..1400)
        .map(|_| [rng.gen_range(-70.0..470.0), rng.gen_range(-70.0..470.0)])
        .collect();
    let noise = Normal::new(0.0, 0.1).unwrap();
    let mut out = Vec::new();
    for k in 0..frames.len() - 1 {
        let inv = inverse(&frames[k]);
        let features = posts
            .iter()
            .enumerate()
            .filter(|(_, p)| (p[0] - frames[k].x).hypot(p[1] - frames[k].y) < 60.0)
            .map(|(i, p)| {
                let q = transform_point(&inv, *p);
                SubmapFeature {
                    id: FeatureId(i as u64),
                    xy: [q[0] + noise.sample(&mut rng), q[1] + noise.sample(&mut rng)],
                    xy_cov: Matrix2::from_diagonal_element(0.01),
                    uv: [0.0, 0.0],
                    uv_cov: Matrix2::from_diagonal_element(0.1),
                    hits: 10,
                }
            })
            .collect();
        let mut end = between(&frames[k], &frames[k + 1]);
        end.theta += bias_rad;
        out.push(FrozenSubmap {
            end_pose: end,
            end_cov: Matrix3::from_diagonal(&Vector3::new(0.04, 0.04, 2.5e-5)),
            features,
            loss_db: 0.0,
            end_s: k as f64,
        });
    }
    (out, frames)
}

/// Loops found (and how many came from places), every one checked against the truth.
fn run(place: bool) -> (usize, u64) {
    let (maps, frames) = submaps(0.02, 4);
    let mut g = GlobalMap::new(GlobalSettings {
        place: PlaceSearch {
            enabled: place,
            ..PlaceSearch::default()
        },
        ..GlobalSettings::default()
    });
    for m in maps {
        g.add_submap(Arc::new(m));
    }
    for l in g.loops() {
        let truth = between(&frames[l.from], &frames[l.to]);
        let (dx, dy) = (truth.x - l.transform.x, truth.y - l.transform.y);
        assert!(
            dx.hypot(dy) < 0.5 && wrap_angle(truth.theta - l.transform.theta).abs() < 0.01,
            "loop {} -> {}: {:?} against the true {truth:?}",
            l.from,
            l.to,
            l.transform
        );
    }
    (g.loops().len(), g.stats().place_loops)
}

#[test]
fn places_close_the_loop_the_drifted_prior_cannot_reach() {
    // The prior at the return is far off: 32 submaps of 0.02 rad heading bias.
    let (maps, frames) = submaps(0.02, 4);
    let mut chained = Pose2::new(0.0, 0.0, 0.0);
    for m in &maps[..32] {
        chained = slam_graph::se2::compose(&chained, &m.end_pose);
    }
    let off = (chained.x - frames[32].x).hypot(chained.y - frames[32].y);
    assert!(
        off > 100.0,
        "the return is {off:.0} m from its chained estimate"
    );

    let (without, _) = run(false);
    assert_eq!(without, 0, "the uncertainty search cannot reach the return");
    let (with, from_places) = run(true);
    assert!(with >= 1, "the place descriptors close the loop");
    // The first closure comes from a place; once it has pulled the frames back, the pose
    // prior is good again and the uncertainty search finds the next submaps' returns.
    assert!(from_places >= 1, "{from_places} of {with} from places");
}

/// The square driven once and then once more (the chain's heading biased as in [`run`]),
/// submap 32 (back at the start) seeing what submap `alias` saw, in its own frame: a
/// street that looks, once, like one 200 m away. Every closure is
/// returned with its error against the truth (m).
fn run_with_an_alias(alias: usize, confirm: bool) -> (Vec<(usize, usize, f64)>, u64) {
    let (mut maps, frames) = submaps_along(true_frames_then(12), 0.02, 4);
    maps[32].features = maps[alias].features.clone();
    let settings = GlobalSettings {
        confirm_place_jumps: confirm,
        ..GlobalSettings::default()
    };
    closures_against_truth(maps, &frames, settings)
}

/// The square driven once and then once more on an exact chain, submap 31 (the first to
/// see the start again, where the chain's uncertainty has grown over the whole square)
/// seeing its posts 6 m along the street from where they are, as a street whose parked
/// cars repeat every 6 m may fit: every closure with its error against the truth (m), and
/// the closures held and not confirmed.
fn run_with_a_slide(confirm: bool) -> (Vec<(usize, usize, f64)>, u64) {
    let (mut maps, frames) = submaps_along(true_frames_then(12), 0.0, 4);
    for f in &mut maps[31].features {
        f.xy[0] -= 6.0;
    }
    let settings = GlobalSettings {
        confirm_prior_slides: confirm,
        ..GlobalSettings::default()
    };
    closures_against_truth(maps, &frames, settings)
}

/// The closures a layer with `settings` finds over `maps`, each with its error against the
/// true `frames` (m), and the closures it held and did not confirm.
fn closures_against_truth(
    maps: Vec<FrozenSubmap>,
    frames: &[Pose2],
    settings: GlobalSettings,
) -> (Vec<(usize, usize, f64)>, u64) {
    let mut g = GlobalMap::new(settings);
    for m in maps {
        g.add_submap(Arc::new(m));
    }
    let loops = g
        .loops()
        .iter()
        .map(|l| {
            let truth = between(&frames[l.from], &frames[l.to]);
            let error = (truth.x - l.transform.x).hypot(truth.y - l.transform.y);
            (l.from, l.to, error)
        })
        .collect();
    (loops, g.stats().unconfirmed)
}

/// What a held false closure leaves (`loops` with their errors against the truth, and the
/// closures not confirmed): it was held and dropped, no false closure entered the graph,
/// and the true return closes at a submap after `after`.
fn assert_held_and_dropped(
    loops: &[(usize, usize, f64)],
    unconfirmed: u64,
    after: usize,
    what: &str,
) {
    assert!(unconfirmed >= 1, "the {what} was not held: {loops:?}");
    assert!(
        loops.iter().all(|l| l.2 < 0.5),
        "a false closure entered the graph: {loops:?}"
    );
    assert!(
        loops.iter().any(|l| l.1 > after),
        "the true return after the {what} closes: {loops:?}"
    );
}

#[test]
fn a_prior_closure_sliding_along_the_street_waits_for_the_next_submap_to_confirm_it() {
    // Held for confirmation, the slide is dropped: the next submap is where it is.
    let (loops, unconfirmed) = run_with_a_slide(true);
    assert_held_and_dropped(&loops, unconfirmed, 31, "slide");
    // Taken at once, it enters the graph.
    let (taken, _) = run_with_a_slide(false);
    assert!(
        taken.iter().any(|l| l.1 == 31 && l.2 > 5.0),
        "the slide was not even found: {taken:?}"
    );
}

#[test]
fn a_place_closure_jumping_from_the_chain_waits_for_the_next_submap_to_confirm_it() {
    // Held for confirmation, the alias is dropped: the next submap is not where it says.
    let (loops, unconfirmed) = run_with_an_alias(4, true);
    assert_held_and_dropped(&loops, unconfirmed, 32, "alias");
    // Taken at once, it enters the graph.
    let (taken, _) = run_with_an_alias(4, false);
    assert!(
        taken.iter().any(|l| l.2 > 50.0),
        "the alias was not even found: {taken:?}"
    );
}
