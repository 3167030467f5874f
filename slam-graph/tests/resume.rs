//! A layer resumed from a saved graph (extend mode): a first drive along two sides of a
//! square of posts is mapped and its graph kept; a second drive starts in its middle, joined
//! there, re-drives part of it and goes on around the square. The second drive's submaps
//! close loops to the first drive's (whatever the travel between them), the saved frames
//! move within their uncertainty, and no chain edge joins the two drives.

use std::sync::Arc;

use nalgebra::{Matrix2, Matrix3, Vector3};
use radar_model::geometry::Pose2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam_filter::{FeatureId, FrozenSubmap, SubmapFeature};
use slam_graph::se2::{between, inverse, transform_point};
use slam_graph::{EdgeKind, GlobalMap, GlobalSettings, LoopClosure, ResumeError, SavedGraph};

/// True frames every 25 m around a 100 m square.
fn true_frames() -> Vec<Pose2> {
    let mut out = Vec::new();
    for side in 0..4 {
        for step in 0..4 {
            let d = 25.0 * step as f64;
            let (x, y) = match side {
                0 => (d, 0.0),
                1 => (100.0, d),
                2 => (100.0 - d, 100.0),
                _ => (0.0, 100.0 - d),
            };
            out.push(Pose2::new(x, y, side as f64 * std::f64::consts::FRAC_PI_2));
        }
    }
    out
}

/// Submaps at `frames[from..to]` (each seeing the posts within 45 m), chained with a
/// heading bias of `bias_rad` per submap.
fn drive(
    posts: &[[f64; 2]],
    frames: &[Pose2],
    bias_rad: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Arc<FrozenSubmap>> {
    let noise = Normal::new(0.0, 0.1).unwrap();
    (0..frames.len() - 1)
        .map(|k| {
            let inv = inverse(&frames[k]);
            let features = posts
                .iter()
                .enumerate()
                .filter(|(_, p)| (p[0] - frames[k].x).hypot(p[1] - frames[k].y) < 45.0)
                .map(|(i, p)| {
                    let q = transform_point(&inv, *p);
                    SubmapFeature {
                        id: FeatureId(i as u64),
                        xy: [q[0] + noise.sample(rng), q[1] + noise.sample(rng)],
                        xy_cov: Matrix2::from_diagonal_element(0.01),
                        uv: [0.0, 0.0],
                        uv_cov: Matrix2::from_diagonal_element(0.1),
                        hits: 10,
                    }
                })
                .collect();
            let mut end = between(&frames[k], &frames[k + 1]);
            end.theta += bias_rad;
            Arc::new(FrozenSubmap {
                end_pose: end,
                end_cov: Matrix3::from_diagonal(&Vector3::new(0.04, 0.04, 1e-4)),
                features,
                loss_db: 0.0,
                end_s: k as f64,
            })
        })
        .collect()
}

fn saved(first: &GlobalMap) -> SavedGraph {
    let sol = first.solution(0.0);
    let n = first.submaps().len();
    SavedGraph {
        submaps: first.submaps().to_vec(),
        frames: sol.frames[..n].to_vec(),
        covariances: sol.covariances[..n].to_vec(),
        drives: vec![0; n],
        loops: first.loops().to_vec(),
        joins: Vec::new(),
        scans: Vec::new(),
    }
}

fn join(from: usize, transform: Pose2) -> LoopClosure {
    LoopClosure {
        from,
        to: 0,
        transform,
        covariance: Matrix3::from_diagonal(&Vector3::new(0.01, 0.01, 1e-4)),
        matches: 20,
        nis: 0.0,
        dof: 0,
        rival_matches: 0,
        from_place: false,
    }
}

#[test]
fn a_second_drive_joins_the_saved_graph_and_closes_loops_to_it() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let posts: Vec<[f64; 2]> = (0..400)
        .map(|_| [rng.gen_range(-40.0..140.0), rng.gen_range(-40.0..140.0)])
        .collect();
    let frames = true_frames();
    // First drive: frames 0..=8 (sides 0 and 1), 8 submaps.
    let mut first = GlobalMap::new(GlobalSettings::default());
    for s in drive(&posts, &frames[..9], 0.004, &mut rng) {
        first.add_submap(s);
    }
    let saved = saved(&first);
    let n = saved.submaps.len();
    assert_eq!(n, 8);
    let before = saved.frames.clone();
    let covs = saved.covariances.clone();
    // The second drive starts at true frame 2, found in saved submap 2's frame where the
    // first drive put it (the fix), and drives frames 2..=15.
    let fix = between(&before[2], &before[2]);
    let mut second = GlobalMap::resume(GlobalSettings::default(), saved, join(2, fix)).unwrap();
    second.describe_saved_places();
    // The join and no chain edge between the drives.
    let into_new: Vec<EdgeKind> = second
        .graph()
        .edges()
        .iter()
        .filter(|e| e.to == n)
        .map(|e| e.kind)
        .collect();
    assert_eq!(into_new, vec![EdgeKind::Join]);
    assert_eq!(second.joins().len(), 1);
    assert_eq!(second.joins()[0].to, n);
    let mut cross = 0;
    for s in drive(&posts, &frames[2..], 0.004, &mut rng) {
        let r = second.add_submap(s);
        cross += r.accepted.iter().filter(|l| l.from < n).count();
    }
    assert!(
        cross >= 2,
        "loops from the second drive to the first: {cross}"
    );
    assert_eq!(second.submaps().len(), n + 13);
    assert_eq!(second.drives()[n - 1], 0);
    assert_eq!(second.drives()[n], 1);
    // The saved frames move, within 3 sigma of their saved uncertainty (frame 0 is fixed).
    let after = second.graph().nodes();
    for k in 1..n {
        let d = (after[k].x - before[k].x).hypot(after[k].y - before[k].y);
        let sigma = (covs[k][(0, 0)] + covs[k][(1, 1)]).sqrt();
        assert!(
            d <= 3.0 * sigma + 1e-6,
            "saved frame {k} moved {d:.3} m, sigma {sigma:.3} m"
        );
    }
    // The new frames sit where the truth puts them, relative to frame 0 (the bias drifts
    // them without the loops to the saved drive).
    for (j, t) in frames[2..].iter().enumerate() {
        let e = after[n + j];
        let d = (e.x - t.x).hypot(e.y - t.y);
        assert!(d < 2.0, "new frame {j} is {d:.2} m off");
    }
}

#[test]
fn a_saved_graph_that_does_not_hold_together_is_refused() {
    let empty = GlobalMap::resume(
        GlobalSettings::default(),
        SavedGraph::default(),
        join(0, Pose2::new(0.0, 0.0, 0.0)),
    );
    assert_eq!(empty.unwrap_err(), ResumeError::Empty);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let posts: Vec<[f64; 2]> = (0..100)
        .map(|_| [rng.gen_range(-40.0..140.0), rng.gen_range(-40.0..140.0)])
        .collect();
    let mut first = GlobalMap::new(GlobalSettings::default());
    for s in drive(&posts, &true_frames()[..3], 0.0, &mut rng) {
        first.add_submap(s);
    }
    let ok = saved(&first);
    let far = GlobalMap::resume(
        GlobalSettings::default(),
        ok.clone(),
        join(9, Pose2::new(0.0, 0.0, 0.0)),
    );
    assert!(matches!(
        far.unwrap_err(),
        ResumeError::BadEdge { from: 9, .. }
    ));
    let mut bad = join(0, Pose2::new(0.0, 0.0, 0.0));
    bad.covariance[(0, 0)] = f64::NAN;
    let nan = GlobalMap::resume(GlobalSettings::default(), ok.clone(), bad);
    assert_eq!(nan.unwrap_err(), ResumeError::NotFinite);
    let mut short = ok;
    short.drives.pop();
    let e = GlobalMap::resume(
        GlobalSettings::default(),
        short,
        join(0, Pose2::new(0.0, 0.0, 0.0)),
    );
    assert!(matches!(e.unwrap_err(), ResumeError::Lengths { .. }));
}

#[test]
fn saved_scans_come_back_with_their_submaps_and_a_map_without_them_has_none() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let posts: Vec<[f64; 2]> = (0..200)
        .map(|_| [rng.gen_range(-40.0..140.0), rng.gen_range(-40.0..140.0)])
        .collect();
    // Two long walls, a point every 0.25 m: each submap's scan, in its frame.
    let walls: Vec<[f64; 2]> = (0..800)
        .flat_map(|i| {
            let t = -50.0 + 0.25 * f64::from(i);
            [[t, -20.0], [t, 30.0]]
        })
        .collect();
    let frames = true_frames();
    let mut first = GlobalMap::new(GlobalSettings::default());
    for (k, s) in drive(&posts, &frames[..4], 0.0, &mut rng)
        .into_iter()
        .enumerate()
    {
        let inv = inverse(&frames[k]);
        let scan = walls.iter().map(|p| transform_point(&inv, *p)).collect();
        first.add_submap_with_scan(s, Some(scan));
    }
    let n = first.submaps().len();
    assert!((0..n).all(|k| first.scan(k).is_some()));
    let mut kept = saved(&first);
    kept.scans = (0..n).map(|k| first.scan(k).map(<[_]>::to_vec)).collect();
    kept.scans[1] = None;
    let resumed = GlobalMap::resume(
        GlobalSettings::default(),
        kept.clone(),
        join(0, Pose2::new(0.0, 0.0, 0.0)),
    )
    .unwrap();
    for k in 0..n {
        assert_eq!(
            resumed.scan(k),
            kept.scans[k].as_deref(),
            "saved submap {k}'s scan"
        );
    }
    // An older map (no scans): the saved submaps are verified by their features.
    let mut none = kept;
    none.scans.clear();
    let resumed = GlobalMap::resume(
        GlobalSettings::default(),
        none,
        join(0, Pose2::new(0.0, 0.0, 0.0)),
    )
    .unwrap();
    assert!((0..n).all(|k| resumed.scan(k).is_none()));
}
