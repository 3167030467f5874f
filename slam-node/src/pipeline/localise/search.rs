//! Finding where the vehicle is in the map without a prior: place recognition over the
//! map, then the loop-closure verifier.
//!
//! While searching, the filter maps in a frame of its own (the vehicle starts at its
//! origin). The map is described beforehand by places every [`PLACE_SPACING_M`] along its
//! drive (radar-odometry's polar descriptor of every map feature within the descriptor's
//! range, axes of the map's frame). Every few metres of driving the local map around the
//! vehicle is described (in the vehicle's frame, around shifted origins), the nearest map
//! places by ring key are compared under every rotation, and each match below the distance
//! threshold gives a guess of the local frame in the map's, refined by a vote over feature
//! offsets (slam-graph's `places::refine`) and offered to the verifier (`slam_graph::align`:
//! jointly compatible, unambiguous association of many features with their material).
//!
//! A fix is taken only when, at two attempts in a row, exactly one transform verified
//! (several verified transforms further apart than [`SAME_M`] / [`SAME_RAD`] are places
//! alike: nothing is taken, and the search waits for the local map to tell them apart) and
//! the second agrees with the first. The winner must also clearly beat every other place of
//! the map that could fit ([`PlaceSearcher::rivals`]): the places the attempt matched by
//! descriptor, and those where the map looks like the winner's place (the map's own
//! features around the verified pose, looked up among all its places), each scored by the
//! local features it explains ([`super::support::MapGrid`]); one explaining
//! [`RIVAL_SHARE`] of the winner's is a rival, and nothing is taken. A street of identical
//! blocks is never fixed on until the local map reaches something that tells the
//! blocks apart. No IO.

use nalgebra::Matrix3;
use radar_model::geometry::{wrap_angle, Pose2};
use radar_odometry::{PlaceDescriptor, PlaceIndex, PlaceQuery, PlaceSettings, QueryMatch};
use slam_filter::{FrozenSubmap, SubmapFeature};
use slam_graph::places::{refine, PlaceSearch};
use slam_graph::se2::{compose, inverse, transform_point};
use slam_graph::{align, AlignSettings};

use super::known::MapFeatures;
use super::support::MapGrid;

/// Places of the map every this many metres along its drive.
pub const PLACE_SPACING_M: f64 = 10.0;
/// Two verified transforms within this distance (m) and heading (rad) are one place.
pub const SAME_M: f64 = 2.0;
/// See [`SAME_M`].
pub const SAME_RAD: f64 = 0.05;
/// A fix needs the second verification within this of the first (m, rad).
const CONFIRM_M: f64 = 1.0;
const CONFIRM_RAD: f64 = 0.03;
/// Map places compared in full per attempt (nearest by ring key).
const NEIGHBOURS: usize = 12;
/// Matches below this descriptor distance are verified, at most this many.
const MAX_DISTANCE: f64 = 0.5;
const MAX_CANDIDATES: usize = 6;
/// Fewest features matched for a fix.
pub const MIN_FIX_MATCHES: usize = 8;
/// Map features within this of a guess (m) are offered to the verifier.
const VERIFY_RADIUS_M: f64 = 120.0;
/// A look-alike place of the map that the local map fits with at least this share of the
/// best place's matches makes the fix ambiguous.
pub const RIVAL_SHARE: f64 = 0.6;
/// A place of the map elsewhere whose descriptor is this close to the map's around a
/// verified pose is a copy of it: no fix there.
pub const SELF_SIMILAR_DISTANCE: f64 = 0.15;
/// Local features within this of the vehicle (m) are scored apart too: near the vehicle a
/// place the map holds twice fits twice even where the map is bent further out.
pub const NEAR_M: f64 = 60.0;
/// A rival's translation is voted within this of its look-alike's guess (m).
const RIVAL_REACH_M: f64 = 45.0;
/// Look-alike places of the map scored as rivals at most per check (nearest by
/// descriptor), besides the places the attempt matched.
const MAX_RIVAL_CHECKS: usize = 24;
/// A look-alike place nearer than this to the verified pose (m), and turned less than
/// [`RIVAL_MIN_TURN_RAD`], is the same place.
const RIVAL_MIN_SEPARATION_M: f64 = 10.0;
/// See [`RIVAL_MIN_SEPARATION_M`].
const RIVAL_MIN_TURN_RAD: f64 = 0.2;

/// A transform of the local frame into the map's, verified.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Verified {
    /// The local frame in the map's.
    pub transform: Pose2,
    /// Its covariance.
    pub covariance: Matrix3<f64>,
    /// Features matched.
    pub matches: usize,
}

/// What one attempt found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Attempt {
    /// Too few local features to describe the place yet.
    TooFewFeatures,
    /// No map place was close enough, or none verified.
    NothingVerified {
        /// The nearest descriptor distance found.
        best_distance: Option<f64>,
    },
    /// More than one place verified: the map does not tell them apart yet.
    Ambiguous(usize),
    /// One place verified; a fix needs it confirmed at the next attempt.
    Candidate(Verified),
    /// Confirmed: the fix.
    Fix(Verified),
}

/// The map's places and the search's state.
#[derive(Debug)]
pub struct PlaceSearcher {
    settings: PlaceSettings,
    places: Vec<(Pose2, PlaceDescriptor)>,
    index: PlaceIndex,
    grid: MapGrid,
    pending: Option<Verified>,
    align: AlignSettings,
}

/// Points along the drive of the map: each submap's frame to its end, every `spacing` m.
pub fn drive_points(map: &MapFeatures, spacing: f64) -> Vec<[f64; 2]> {
    let mut out = Vec::new();
    for k in 0..map.frames.len() {
        out.extend(super::known::path_samples(&map.path_of(k), spacing));
    }
    if let Some(end) = map.ends.last() {
        out.push([end.x, end.y]);
    }
    out
}

impl PlaceSearcher {
    /// Describes the map's places.
    pub fn new(map: &MapFeatures, min_hits: u64) -> Self {
        let settings = PlaceSettings::default();
        let mut places = Vec::new();
        let mut index = PlaceIndex::new();
        let r2 = settings.max_range_m * settings.max_range_m;
        for p in drive_points(map, PLACE_SPACING_M) {
            let points: Vec<[f64; 2]> = map
                .features
                .iter()
                .filter(|f| f.hits >= min_hits)
                .map(|f| [f.xy[0] - p[0], f.xy[1] - p[1]])
                .filter(|d| d[0] * d[0] + d[1] * d[1] <= r2)
                .collect();
            if let Ok(d) = PlaceDescriptor::new(points, &settings) {
                index.insert(places.len() as u64, &d);
                places.push((Pose2::new(p[0], p[1], 0.0), d));
            }
        }
        let grid = MapGrid::new(
            map.features
                .iter()
                .filter(|f| f.hits >= min_hits)
                .map(|f| f.xy),
        );
        Self {
            settings,
            places,
            index,
            grid,
            pending: None,
            align: AlignSettings {
                min_hits,
                ..AlignSettings::default()
            },
        }
    }

    /// The local frame restarted at `origin` (in the old one): a pending candidate is
    /// re-expressed in the new frame.
    pub fn reframe(&mut self, origin: &Pose2) {
        if let Some(p) = self.pending.as_mut() {
            p.transform = compose(&p.transform, origin);
        }
    }

    /// Forgets a pending candidate (the search starts again).
    pub fn forget(&mut self) {
        self.pending = None;
    }

    /// Places described.
    pub fn places(&self) -> usize {
        self.places.len()
    }

    /// One attempt with the local map `local` (the filter's features in its own frame) and
    /// the vehicle at `vehicle` in it.
    pub fn attempt(&mut self, map: &MapFeatures, local: &FrozenSubmap, vehicle: &Pose2) -> Attempt {
        let min_hits = self.align.min_hits;
        let to_vehicle = inverse(vehicle);
        let r = self.settings.max_range_m;
        let query_points: Vec<[f64; 2]> = local
            .features
            .iter()
            .filter(|f| f.hits >= min_hits)
            .map(|f| transform_point(&to_vehicle, f.xy))
            .filter(|p| p[0].hypot(p[1]) <= r)
            .collect();
        let Ok(query) = PlaceQuery::new(&query_points, &self.settings) else {
            return Attempt::TooFewFeatures;
        };
        let mut matches: Vec<(f64, Pose2)> = self
            .index
            .nearest_to_query(&query, NEIGHBOURS)
            .into_iter()
            .filter_map(|(id, _)| {
                let (place, d) = self.places.get(usize::try_from(id).ok()?)?;
                let m = query.compare(d)?;
                // The vehicle in the map, then the local frame in the map.
                let vehicle_in_map = vehicle_at(place, &m);
                Some((m.place.distance, compose(&vehicle_in_map, &to_vehicle)))
            })
            .collect();
        matches.sort_by(|a, b| a.0.total_cmp(&b.0));
        let best_distance = matches.first().map(|m| m.0);
        let mut guesses: Vec<(Pose2, Matrix3<f64>)> = Vec::new();
        // Every place that matched by descriptor, verified or not, is a place the winner
        // must beat.
        let mut alike: Vec<Pose2> = Vec::new();
        let loose = loose_prior();
        for (_, g) in matches.into_iter().filter(|m| m.0 <= MAX_DISTANCE) {
            if !alike.iter().any(|h| same(h, &g, SAME_M, SAME_RAD)) {
                alike.push(g);
            }
            if guesses.len() < MAX_CANDIDATES
                && !guesses.iter().any(|(h, _)| same(h, &g, SAME_M, SAME_RAD))
            {
                guesses.push((g, loose));
            }
        }
        if let Some(p) = self.pending {
            let tight = Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, 0.02f64.powi(2)));
            guesses.push((p.transform, tight));
        }
        let b_xy: Vec<[f64; 2]> = local
            .features
            .iter()
            .filter(|f| f.hits >= min_hits)
            .map(|f| f.xy)
            .collect();
        let mut verified: Vec<Verified> = Vec::new();
        for (guess, cov) in guesses {
            if let Some(v) = self.verify(map, local, &b_xy, vehicle, guess, &cov) {
                match verified
                    .iter_mut()
                    .find(|w| same(&w.transform, &v.transform, SAME_M, SAME_RAD))
                {
                    Some(w) if w.matches < v.matches => *w = v,
                    Some(_) => {}
                    None => verified.push(v),
                }
            }
        }
        match verified.as_slice() {
            [] => {
                self.pending = None;
                Attempt::NothingVerified { best_distance }
            }
            [v] if v.matches >= MIN_FIX_MATCHES => {
                let v = *v;
                let rivals = self.rivals(map, &b_xy, vehicle, &v, &alike);
                if rivals > 0 {
                    self.pending = None;
                    return Attempt::Ambiguous(1 + rivals);
                }
                confirm(&mut self.pending, v)
            }
            [_] => {
                self.pending = None;
                Attempt::NothingVerified { best_distance }
            }
            many => {
                self.pending = None;
                Attempt::Ambiguous(many.len())
            }
        }
    }
}

/// Where a descriptor match puts the vehicle in the map: the query's frame in `place`'s.
pub(super) fn vehicle_at(place: &Pose2, m: &QueryMatch) -> Pose2 {
    compose(
        place,
        &Pose2::new(m.transform[0], m.transform[1], m.transform[2]),
    )
}

/// A place verified alone and without rivals: confirmed (the fix) when it agrees with the
/// attempt before ([`CONFIRM_M`], [`CONFIRM_RAD`]), else the candidate the next attempt must
/// confirm.
pub(super) fn confirm(pending: &mut Option<Verified>, v: Verified) -> Attempt {
    let confirmed =
        pending.is_some_and(|p| same(&p.transform, &v.transform, CONFIRM_M, CONFIRM_RAD));
    if confirmed {
        *pending = None;
        Attempt::Fix(v)
    } else {
        *pending = Some(v);
        Attempt::Candidate(v)
    }
}

/// The prior the verifier is given with a place's guess.
fn loose_prior() -> Matrix3<f64> {
    let search = PlaceSearch::default();
    Matrix3::from_diagonal(&nalgebra::Vector3::new(
        search.prior_sigma_m.powi(2),
        search.prior_sigma_m.powi(2),
        search.prior_sigma_rad.powi(2),
    ))
}

impl PlaceSearcher {
    /// Offers the local map (`local`, its well-seen points `b_xy`, the vehicle at `vehicle`
    /// in it) to the verifier against the map's features around `guess` (the local frame
    /// in the map's), with that prior and covariance.
    fn verify(
        &self,
        map: &MapFeatures,
        local: &FrozenSubmap,
        b_xy: &[[f64; 2]],
        vehicle: &Pose2,
        guess: Pose2,
        cov: &Matrix3<f64>,
    ) -> Option<Verified> {
        let centre = compose(&guess, vehicle);
        let a: Vec<SubmapFeature> = map
            .features
            .iter()
            .enumerate()
            .filter(|(_, f)| (f.xy[0] - centre.x).hypot(f.xy[1] - centre.y) <= VERIFY_RADIUS_M)
            .map(|(k, f)| f.as_submap_feature(k as u64))
            .collect();
        let a_xy: Vec<[f64; 2]> = a
            .iter()
            .filter(|f| f.hits >= self.align.min_hits)
            .map(|f| f.xy)
            .collect();
        let prior = refine(&a_xy, b_xy, guess, &PlaceSearch::default());
        let al = align(&a, &local.features, &prior, cov, &self.align).ok()?;
        Some(Verified {
            transform: al.transform,
            covariance: al.covariance,
            matches: al.matches.len(),
        })
    }

    /// The map's well-seen features within [`VERIFY_RADIUS_M`] of `centre`.
    fn map_points_near(&self, map: &MapFeatures, centre: &Pose2) -> Vec<[f64; 2]> {
        map.features
            .iter()
            .filter(|f| f.hits >= self.align.min_hits)
            .filter(|f| (f.xy[0] - centre.x).hypot(f.xy[1] - centre.y) <= VERIFY_RADIUS_M)
            .map(|f| f.xy)
            .collect()
    }

    /// Places of the map the local map (its well-seen points `b_xy`, the vehicle at
    /// `vehicle` in it) fits nearly as well as the verified `v`: rivals of the fix.
    ///
    /// The places offered are those the attempt matched by descriptor (`alike`, the local
    /// frame in the map's) and every place of the map that looks like the one `v` puts the
    /// vehicle in (the map's own features around that pose, compared with all the map's
    /// places: where the map repeats itself). Each is refined (a vote over feature offsets,
    /// then nearest-neighbour fits) and scored by the local features it explains
    /// ([`MapGrid::fit`]), as `v` is; a place elsewhere explaining at least
    /// [`RIVAL_SHARE`] of what `v` explains is a rival. The verifier is not asked: it
    /// refuses a place where the map holds a street twice, a metre or two apart, which is
    /// still a place the local map fits (the wrong fix on `repeated-blocks`).
    pub fn rivals(
        &mut self,
        map: &MapFeatures,
        b_xy: &[[f64; 2]],
        vehicle: &Pose2,
        v: &Verified,
        alike: &[Pose2],
    ) -> usize {
        let here = compose(&v.transform, vehicle);
        let Some(mut offered) = self.look_alikes(map, &here) else {
            // The map itself has a near copy of this place elsewhere: whatever the local
            // map fits, the place is not told apart (repeated blocks).
            return 1;
        };
        let to_vehicle = inverse(vehicle);
        offered.extend(alike.iter().map(|g| compose(g, vehicle)));
        let near = |t: &Pose2| -> Vec<[f64; 2]> {
            let v = compose(t, vehicle);
            b_xy.iter()
                .copied()
                .filter(|p| {
                    let q = transform_point(t, *p);
                    (q[0] - v.x).hypot(q[1] - v.y) <= NEAR_M
                })
                .collect()
        };
        let (polished, best) = self.grid.fit(b_xy, v.transform);
        let near_local = near(&polished);
        let best_near = self.grid.inliers(&near_local, &polished);
        let here = compose(&polished, vehicle);
        // A look-alike's pose is known to tens of metres along a street of repeated
        // blocks: the vote reaches that far.
        let search = PlaceSearch {
            prior_sigma_m: RIVAL_REACH_M / 3.0,
            ..PlaceSearch::default()
        };
        let mut rivals: Vec<Pose2> = Vec::new();
        for there in offered {
            // A street looks much the same driven either way: the descriptor's heading and
            // the opposite one are both tried.
            for turn in [0.0, std::f64::consts::PI] {
                let there = Pose2::new(there.x, there.y, wrap_angle(there.theta + turn));
                if same(&there, &here, RIVAL_MIN_SEPARATION_M, RIVAL_MIN_TURN_RAD) {
                    continue;
                }
                let guess = compose(&there, &to_vehicle);
                let a_xy = self.map_points_near(map, &there);
                let refined = refine(&a_xy, b_xy, guess, &search);
                let (t, n) = self.grid.fit(b_xy, refined);
                let n_near = self.grid.inliers(&near_local, &t);
                let at = compose(&t, vehicle);
                tracing::debug!(
                    x_m = at.x,
                    y_m = at.y,
                    heading_rad = at.theta,
                    explained = n,
                    best,
                    near = n_near,
                    best_near,
                    "a place of the map alike offered as a rival"
                );
                let strong = n as f64 >= RIVAL_SHARE * best as f64
                    || n_near as f64 >= RIVAL_SHARE * best_near as f64;
                if strong
                    && !same(&at, &here, RIVAL_MIN_SEPARATION_M, RIVAL_MIN_TURN_RAD)
                    && !rivals.iter().any(|x| same(x, &at, SAME_M, SAME_RAD))
                {
                    rivals.push(at);
                }
            }
        }
        rivals.len()
    }

    /// Vehicle poses in the map where the map looks as it does around `here` (its own
    /// features there described and compared with every place of the map), nearest by
    /// descriptor first, at most [`MAX_RIVAL_CHECKS`]; `None` when one is a near copy
    /// ([`SELF_SIMILAR_DISTANCE`]).
    fn look_alikes(&self, map: &MapFeatures, here: &Pose2) -> Option<Vec<Pose2>> {
        let to_here = inverse(here);
        let r = self.settings.max_range_m;
        let points: Vec<[f64; 2]> = map
            .features
            .iter()
            .filter(|f| f.hits >= self.align.min_hits)
            .map(|f| transform_point(&to_here, f.xy))
            .filter(|p| p[0].hypot(p[1]) <= r)
            .collect();
        // Every place of the map is compared with the map around the pose (one descriptor,
        // cheap); those alike are compared again around shifted origins for where the pose
        // would be there.
        let Ok(described) = PlaceDescriptor::new(points.iter().copied(), &self.settings) else {
            return Some(Vec::new());
        };
        let Ok(query) = PlaceQuery::new(&points, &self.settings) else {
            return Some(Vec::new());
        };
        let mut alternatives: Vec<(f64, Pose2)> = Vec::new();
        for (place, d) in &self.places {
            if (place.x - here.x).hypot(place.y - here.y) < RIVAL_MIN_SEPARATION_M
                || d.compare(&described).distance > MAX_DISTANCE
            {
                continue;
            }
            let Some(m) = query.compare(d) else {
                continue;
            };
            if m.place.distance > MAX_DISTANCE {
                continue;
            }
            let there = vehicle_at(place, &m);
            if (there.x - here.x).hypot(there.y - here.y) < RIVAL_MIN_SEPARATION_M {
                continue;
            }
            // Look-alikes within a few metres of one another are one place: the nearest
            // by descriptor stands for them.
            match alternatives
                .iter_mut()
                .find(|(_, a)| same(a, &there, RIVAL_MIN_SEPARATION_M, RIVAL_MIN_TURN_RAD))
            {
                Some(a) if a.0 > m.place.distance => *a = (m.place.distance, there),
                Some(_) => {}
                None => alternatives.push((m.place.distance, there)),
            }
        }
        alternatives.sort_by(|a, b| a.0.total_cmp(&b.0));
        if alternatives
            .first()
            .is_some_and(|(d, _)| *d <= SELF_SIMILAR_DISTANCE)
        {
            return None;
        }
        alternatives.truncate(MAX_RIVAL_CHECKS);
        Some(alternatives.into_iter().map(|(_, p)| p).collect())
    }
}

/// Whether two transforms are within `m` metres and `rad` radians.
/// Whether two poses are within `m` metres and `rad` of each other.
pub(super) fn same(a: &Pose2, b: &Pose2, m: f64, rad: f64) -> bool {
    (a.x - b.x).hypot(a.y - b.y) <= m && wrap_angle(a.theta - b.theta).abs() <= rad
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drive_points_are_spaced_along_each_submap() {
        let map = MapFeatures {
            features: Vec::new(),
            frames: vec![
                (Pose2::new(0.0, 0.0, 0.0), Matrix3::zeros()),
                (Pose2::new(25.0, 0.0, 0.0), Matrix3::zeros()),
            ],
            ends: vec![Pose2::new(25.0, 0.0, 0.0), Pose2::new(25.0, 20.0, 0.0)],
            end_local: Vec::new(),
            paths: Vec::new(),
        };
        let p = drive_points(&map, 10.0);
        // 25 m in 3 steps, 20 m in 2, and the end.
        assert_eq!(p.len(), 6);
        assert_eq!(p[0], [0.0, 0.0]);
        assert_eq!(p[3], [25.0, 0.0]);
        assert_eq!(p[5], [25.0, 20.0]);
    }

    /// With the map's paths (format version 4) the places follow where the vehicle drove:
    /// the first submap's frame is the map's origin, 100 m from where the drive began, and
    /// the drive turned; the line from frame to end would put places where no vehicle was.
    #[test]
    fn drive_points_follow_the_saved_path() {
        let map = MapFeatures {
            features: Vec::new(),
            frames: vec![(Pose2::new(0.0, 0.0, 0.0), Matrix3::zeros())],
            ends: vec![Pose2::new(120.0, 20.0, 1.5)],
            end_local: Vec::new(),
            paths: vec![vec![[100.0, 0.0], [120.0, 0.0], [120.0, 20.0]]],
        };
        let p = drive_points(&map, 10.0);
        assert_eq!(
            p,
            vec![
                [100.0, 0.0],
                [110.0, 0.0],
                [120.0, 0.0],
                [120.0, 10.0],
                [120.0, 20.0]
            ]
        );
        // The submap nearest a point of the path, and how far.
        assert_eq!(map.nearest_submap([119.0, 12.0]), Some(0));
        let d = crate::pipeline::localise::known::polyline_distance([60.0, 10.0], &map.path_of(0));
        assert!((d - 41.231).abs() < 1e-3, "{d}");
    }

    /// A saved path holds a vertex every 2 m: the places still fall every `spacing` along
    /// it (one per vertex made the places five times as dense, and the search's nearest 40
    /// descriptors all came from a few stretches of the map).
    #[test]
    fn drive_points_are_spaced_along_a_densely_sampled_path() {
        let path: Vec<[f64; 2]> = (0..=20).map(|i| [2.0 * f64::from(i), 0.0]).collect();
        let map = MapFeatures {
            features: Vec::new(),
            frames: vec![(Pose2::new(0.0, 0.0, 0.0), Matrix3::zeros())],
            ends: vec![Pose2::new(40.0, 0.0, 0.0)],
            end_local: Vec::new(),
            paths: vec![path],
        };
        let p = drive_points(&map, 10.0);
        let xs: Vec<f64> = p.iter().map(|q| q[0]).collect();
        assert_eq!(xs.len(), 5, "{xs:?}");
        for (x, want) in xs.iter().zip([0.0, 10.0, 20.0, 30.0, 40.0]) {
            assert!((x - want).abs() < 1e-9, "{xs:?}");
        }
        // Across a corner the spacing runs on: 10 m along the path, not from the corner.
        let bent = vec![[0.0, 0.0], [4.0, 0.0], [4.0, 30.0]];
        let q = crate::pipeline::localise::known::path_samples(&bent, 10.0);
        assert_eq!(q.len(), 4, "{q:?}");
        assert!(
            (q[1][1] - 6.0).abs() < 1e-9 && (q[3][1] - 26.0).abs() < 1e-9,
            "{q:?}"
        );
        // A map file's far-flung but finite vertices cost a bounded number of places.
        use crate::pipeline::localise::known::{path_samples, MAX_PATH_SAMPLES};
        let far: Vec<[f64; 2]> = (0..4096)
            .map(|i| [f64::from(i) * 3e37, if i % 2 == 0 { 0.0 } else { 1e37 }])
            .collect();
        let n = path_samples(&far, 10.0).len();
        assert!(n > 0 && n <= MAX_PATH_SAMPLES + 1, "{n}");
        let n = path_samples(&[[0.0, 0.0], [f64::MAX, f64::MAX]], 10.0).len();
        assert!(n <= MAX_PATH_SAMPLES + 1, "{n}");
    }
}
