//! Finding where the vehicle is in the map's scans without a prior.
//!
//! The query is the **local scan**: the radar odometry's clouds of the last stretch of
//! driving, placed by the local filter's poses in the vehicle's frame and thinned as the
//! map's scans are (one point per metre cell seen in at least two rotations,
//! [`slam_graph::ScanAccumulator`]). An attempt:
//!
//! 1. describes the local scan around shifted origins and compares it with the
//!    [`NEIGHBOURS`] nearest map places by ring key ([`super::scan_map::ScanMap`]); each
//!    close match gives a guess of the vehicle's pose in the map, to within a few metres
//!    and a descriptor sector, and is tried both ways round (a street looks much the same
//!    driven either way);
//! 2. scores each guess by correlative scan matching (slam-graph's `correlate`: every
//!    shift and heading of a window around the guess, the local scan's points laid on the
//!    map's score grid); the best must reach [`MIN_SCORE`] and beat every guess elsewhere
//!    by [`MIN_MARGIN`];
//! 3. verifies the winner as loop closure verifies two submaps' scans
//!    ([`slam_graph::align_scans`]: ICP, a large share of the local scan on the map's
//!    surfaces, a small residual, every direction pinned, no second basin nearly as good),
//!    then scores the map's own look-alikes of the verified place (the map's scan there
//!    described and looked up among its places, both ways round): one within
//!    [`MIN_MARGIN`] of the winner is a rival, and nothing is taken;
//! 4. fixes only when the same transform of the local frame into the map's verifies at two
//!    attempts in a row.
//!
//! The outcome speaks of the local frame ([`super::search::Verified`]), as the feature
//! search's does, so the caller treats both alike. No IO.

use std::sync::Arc;

use nalgebra::{Matrix3, Vector3};
use radar_model::geometry::{wrap_angle, Pose2};
use radar_odometry::{PlaceIndex, PlaceQuery};
use slam_graph::correlate::{correlate, Peak, ScoreGrid, Window};
use slam_graph::se2::{compose, inverse};
use slam_graph::{align_scans, reference_scan, AlignSettings, ScanAccumulator, ScanAlignSettings};

use super::scan_map::ScanMap;
use super::search::{confirm, same, vehicle_at, Attempt, Verified, SAME_M, SAME_RAD};

/// Map places compared in full per attempt (nearest by ring key).
const NEIGHBOURS: usize = 40;
/// Descriptor matches verified per attempt at most (best first).
const MAX_CANDIDATES: usize = 20;
/// Matches further than this descriptor distance are not verified.
const MAX_DISTANCE: f64 = 0.6;
/// Map points within this of a guess (m) are the verifier's reference.
const VERIFY_RADIUS_M: f64 = 100.0;
/// The correlative search's window around a descriptor's guess: half-widths (m, rad). A
/// guess is within a shift step and a place spacing along the street, and a sector (6
/// degrees) in heading.
const GUESS_HALF_M: f64 = 10.0;
const GUESS_HALF_RAD: f64 = 0.12;
/// Around a look-alike place of the map (m).
const RIVAL_HALF_M: f64 = 8.0;
/// The score grids' cells at most (a 100 m radius at 1 m cells is 40,000).
const MAX_SCORE_CELLS: usize = 1 << 20;
/// The correlative score (the mean kernel value under the local scan's points, in [0, 1])
/// a place must reach: a city's scans are dense (a wall every few metres), so the local
/// scan laid anywhere in a street scores 0.55-0.70; laid on its own place, 0.80-0.83
/// (`realistic-city-return`, measured over 60 attempts).
pub const MIN_SCORE: f64 = 0.7;
/// A place elsewhere scoring within this of the winner is a rival: nothing is taken.
pub const MIN_MARGIN: f64 = 0.1;
/// Look-alike places tried as rivals at most (nearest by descriptor).
const MAX_RIVAL_CHECKS: usize = 16;
/// A rival is a pose further than this from the winner's (m), or turned more than
/// [`RIVAL_MIN_TURN_RAD`].
const RIVAL_MIN_SEPARATION_M: f64 = 10.0;
const RIVAL_MIN_TURN_RAD: f64 = 0.2;
/// Fewest local scan points for an attempt.
pub const MIN_LOCAL_POINTS: usize = 800;

/// One rotation's cloud kept for the local scan: the vehicle's pose in the local frame
/// then, and the cloud in the vehicle's frame.
pub type KeptCloud = (Pose2, Arc<Vec<[f64; 2]>>);

/// The local scan around `vehicle` (in the local frame), in the vehicle's frame: every
/// kept cloud placed and thinned as the map's scans are.
pub fn local_scan(clouds: &[KeptCloud], vehicle: &Pose2, s: &ScanAlignSettings) -> Vec<[f64; 2]> {
    let to_vehicle = inverse(vehicle);
    let mut acc = ScanAccumulator::new(s);
    for (pose, cloud) in clouds {
        acc.add(&compose(&to_vehicle, pose), cloud);
    }
    acc.take()
}

/// The scan search's state: the map and a pending candidate.
#[derive(Debug)]
pub struct ScanSearcher {
    map: Arc<ScanMap>,
    index: PlaceIndex,
    scan: ScanAlignSettings,
    align: AlignSettings,
    pending: Option<Verified>,
}

impl ScanSearcher {
    /// A search over `map`'s places.
    pub fn new(map: Arc<ScanMap>) -> Self {
        Self {
            index: map.index(),
            map,
            scan: ScanAlignSettings::default(),
            align: AlignSettings::default(),
            pending: None,
        }
    }

    /// The scan settings the local scan is thinned with.
    pub fn scan_settings(&self) -> &ScanAlignSettings {
        &self.scan
    }

    /// The local frame restarted at `origin` (in the old one).
    pub fn reframe(&mut self, origin: &Pose2) {
        if let Some(p) = self.pending.as_mut() {
            p.transform = compose(&p.transform, origin);
        }
    }

    /// Forgets a pending candidate.
    pub fn forget(&mut self) {
        self.pending = None;
    }

    /// The best transform of `sample` (local scan points in the vehicle's frame) onto the
    /// map's scans in a window around `guess` (the vehicle in the map): the correlative
    /// search's peak and its score (the mean kernel value under the points, in [0, 1]).
    fn correlate_at(
        &self,
        guess: &Pose2,
        sample: &[[f64; 2]],
        half_m: f64,
        half_rad: f64,
    ) -> Option<Peak> {
        let points = self.map.near([guess.x, guess.y], VERIFY_RADIUS_M);
        let grid = ScoreGrid::new(
            &points,
            self.scan.search_cell_m,
            self.scan.search_sigma_m,
            MAX_SCORE_CELLS,
        )?;
        let window = Window {
            half_m,
            half_rad,
            step_rad: self.scan.search_step_rad,
        };
        correlate(
            &grid,
            sample,
            guess,
            &window,
            self.scan.rival_separation_m,
            0,
        )
        .map(|(best, _)| best)
    }

    /// One attempt with the local scan `local` (in the vehicle's frame), the vehicle at
    /// `vehicle` in the local frame.
    pub fn attempt(&mut self, local: &[[f64; 2]], vehicle: &Pose2) -> Attempt {
        if local.len() < MIN_LOCAL_POINTS {
            return Attempt::TooFewFeatures;
        }
        let Ok(query) = PlaceQuery::new(local, &self.map.settings) else {
            return Attempt::TooFewFeatures;
        };
        let map = Arc::clone(&self.map);
        // Vehicle poses in the map the descriptors suggest, nearest first.
        let mut matches: Vec<(f64, Pose2)> = self
            .index
            .nearest_to_query(&query, NEIGHBOURS)
            .into_iter()
            .filter_map(|(id, _)| {
                let (place, d) = map.places.get(usize::try_from(id).ok()?)?;
                let m = query.compare(d)?;
                Some((m.place.distance, vehicle_at(place, &m)))
            })
            .collect();
        matches.sort_by(|a, b| a.0.total_cmp(&b.0));
        let best_distance = matches.first().map(|m| m.0);
        // The best few, each both ways round (a street looks much the same driven either
        // way, and the descriptor often takes one for the other).
        let mut guesses: Vec<(Pose2, f64, f64)> = Vec::new();
        for (_, g) in matches.iter().filter(|m| m.0 <= MAX_DISTANCE) {
            if guesses.len() >= 2 * MAX_CANDIDATES {
                break;
            }
            for turn in [0.0, std::f64::consts::PI] {
                let g = Pose2::new(g.x, g.y, wrap_angle(g.theta + turn));
                if !guesses
                    .iter()
                    .any(|(h, _, _)| same(h, &g, SAME_M, SAME_RAD))
                {
                    guesses.push((g, GUESS_HALF_M, GUESS_HALF_RAD));
                }
            }
        }
        if let Some(p) = self.pending {
            guesses.push((compose(&p.transform, vehicle), 2.0, 0.05));
        }
        let stride = local.len().div_ceil(self.scan.search_points.max(1)).max(1);
        let sample: Vec<[f64; 2]> = local.iter().step_by(stride).copied().collect();
        let mut scored: Vec<Peak> = guesses
            .iter()
            .filter_map(|(g, m, r)| self.correlate_at(g, &sample, *m, *r))
            .collect();
        scored.sort_by(|a, b| b.score.total_cmp(&a.score));
        let Some(best) = scored.first().copied() else {
            self.pending = None;
            return Attempt::NothingVerified { best_distance };
        };
        let runner_up = scored
            .iter()
            .filter(|p| {
                !same(
                    &p.pose,
                    &best.pose,
                    RIVAL_MIN_SEPARATION_M,
                    RIVAL_MIN_TURN_RAD,
                )
            })
            .map(|p| p.score)
            .fold(0.0, f64::max);
        tracing::debug!(
            x_m = best.pose.x,
            y_m = best.pose.y,
            heading_rad = best.pose.theta,
            score = best.score,
            runner_up,
            guesses = scored.len(),
            local_points = local.len(),
            "the scan search's best place"
        );
        if best.score < MIN_SCORE {
            self.pending = None;
            return Attempt::NothingVerified { best_distance };
        }
        if runner_up > best.score - MIN_MARGIN {
            self.pending = None;
            return Attempt::Ambiguous(2);
        }
        // The winner refined and checked as loop closure checks two scans.
        let tight = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 0.03f64.powi(2)));
        let reference = reference_scan(
            map.near([best.pose.x, best.pose.y], VERIFY_RADIUS_M),
            &self.scan,
        );
        let al = match align_scans(
            &reference,
            local,
            &best.pose,
            &tight,
            &self.align,
            &self.scan,
        ) {
            Ok(al) => al,
            Err(refusal) => {
                tracing::debug!(
                    ?refusal,
                    "the scan search's best place refused by the scan verifier"
                );
                self.pending = None;
                return Attempt::NothingVerified { best_distance };
            }
        };
        let here = al.transform;
        let rivals = self.rivals(&sample, &here, best.score);
        if rivals > 0 {
            self.pending = None;
            return Attempt::Ambiguous(1 + rivals);
        }
        // The local frame in the map's.
        let v = Verified {
            transform: compose(&here, &inverse(vehicle)),
            covariance: al.covariance,
            matches: al.matches.len(),
        };
        confirm(&mut self.pending, v)
    }

    /// Places of the map where it looks as it does around the verified pose `here` (the
    /// map's own scan there, described around shifted origins and looked up among all its
    /// places), each tried both ways round: one where the local scan scores within
    /// [`MIN_MARGIN`] of `best` (the winner's score) is a rival.
    fn rivals(&mut self, sample: &[[f64; 2]], here: &Pose2, best: f64) -> usize {
        let map = Arc::clone(&self.map);
        let mut offered: Vec<Pose2> = Vec::new();
        if let Ok(query) = PlaceQuery::new(&map.around(here), &map.settings) {
            for (id, _) in self.index.nearest_to_query(&query, MAX_RIVAL_CHECKS) {
                let Some((place, d)) = usize::try_from(id).ok().and_then(|i| map.places.get(i))
                else {
                    continue;
                };
                if let Some(m) = query.compare(d) {
                    offered.push(vehicle_at(place, &m));
                }
            }
        }
        let mut rivals: Vec<Pose2> = Vec::new();
        for there in offered {
            for turn in [0.0, std::f64::consts::PI] {
                let start = Pose2::new(there.x, there.y, wrap_angle(there.theta + turn));
                if same(&start, here, RIVAL_MIN_SEPARATION_M, RIVAL_MIN_TURN_RAD) {
                    continue;
                }
                let Some(peak) = self.correlate_at(&start, sample, RIVAL_HALF_M, GUESS_HALF_RAD)
                else {
                    continue;
                };
                tracing::debug!(
                    x_m = peak.pose.x,
                    y_m = peak.pose.y,
                    heading_rad = peak.pose.theta,
                    score = peak.score,
                    best,
                    "a look-alike place of the map tried as a rival (scans)"
                );
                if peak.score > best - MIN_MARGIN
                    && !same(&peak.pose, here, RIVAL_MIN_SEPARATION_M, RIVAL_MIN_TURN_RAD)
                    && !rivals.iter().any(|x| same(x, &peak.pose, SAME_M, SAME_RAD))
                {
                    rivals.push(peak.pose);
                }
            }
        }
        rivals.len()
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::pipeline::localise::known::MapFeatures;
    use slam_graph::se2::transform_point;

    use crate::pipeline::localise::repeated_tests::Lcg;

    /// A street along x from 0 to 400 m with fronts either side (set back irregularly,
    /// with gaps), cross streets every 100 m and posts: points every 0.5 m, as a scan sees
    /// them, shifted by `dx` along x.
    pub(crate) fn street(rng: &mut Lcg, dx: f64) -> Vec<[f64; 2]> {
        let mut out = Vec::new();
        for side in [-1.0, 1.0] {
            let mut x = 0.0;
            while x < 400.0 {
                let width = 6.0 + 15.0 * rng.next();
                let setback = 2.0 * rng.next();
                let gap = rng.next() < 0.3;
                let mut u = 0.0;
                while u < width {
                    let px = x + u;
                    // Cross streets every 100 m (12 m wide) have no fronts.
                    if !gap && px % 100.0 > 12.0 {
                        out.push([px + dx, side * (8.0 + setback)]);
                    }
                    u += 0.5;
                }
                x += width;
            }
            // The cross streets' fronts.
            for k in 0..4 {
                let cx = 100.0 * f64::from(k) + dx;
                let mut y = 10.0;
                while y < 60.0 {
                    out.push([cx, side * y]);
                    out.push([cx + 12.0, side * y]);
                    y += 0.5;
                }
            }
            // Buildings further back: rectangles 8-20 m wide, 20-50 m from the centre line.
            for _ in 0..40 {
                let (x0, y0) = (400.0 * rng.next(), 20.0 + 20.0 * rng.next());
                let (w, h) = (8.0 + 12.0 * rng.next(), 5.0 + 10.0 * rng.next());
                let mut u = 0.0;
                while u < w {
                    out.push([x0 + u + dx, side * y0]);
                    out.push([x0 + u + dx, side * (y0 + h)]);
                    u += 0.5;
                }
                let mut v = 0.0;
                while v < h {
                    out.push([x0 + dx, side * (y0 + v)]);
                    out.push([x0 + w + dx, side * (y0 + v)]);
                    v += 0.5;
                }
            }
            // Posts.
            for _ in 0..30 {
                out.push([400.0 * rng.next() + dx, side * (5.0 + rng.next())]);
            }
        }
        out
    }

    /// The map's drive: one submap along the street, from x = 0 to x = 400 (plus `dx`).
    fn drive(dxs: &[f64]) -> MapFeatures {
        let id = Matrix3::identity() * 1e-4;
        MapFeatures {
            features: Vec::new(),
            frames: dxs
                .iter()
                .map(|dx| (Pose2::new(*dx, 0.0, 0.0), id))
                .collect(),
            ends: dxs
                .iter()
                .map(|dx| Pose2::new(dx + 400.0, 0.0, 0.0))
                .collect(),
            end_local: dxs
                .iter()
                .map(|_| (Pose2::new(400.0, 0.0, 0.0), id))
                .collect(),
            paths: Vec::new(),
        }
    }

    /// What a vehicle at `pose` sees of `world` within 80 m, in its frame, with 0.1 m of
    /// jitter, thinned to one point per metre cell as the local scan is.
    fn seen(world: &[[f64; 2]], pose: &Pose2, rng: &mut Lcg) -> Vec<[f64; 2]> {
        let inv = inverse(pose);
        let local: Vec<[f64; 2]> = world
            .iter()
            .map(|p| transform_point(&inv, *p))
            .filter(|p| p[0].hypot(p[1]) <= 80.0 && p[0].hypot(p[1]) >= 4.0)
            .map(|p| {
                [
                    p[0] + 0.1 * (rng.next() - 0.5),
                    p[1] + 0.1 * (rng.next() - 0.5),
                ]
            })
            .collect();
        let s = ScanAlignSettings::default();
        let mut acc = ScanAccumulator::new(&s);
        // Two rotations of the same view: every cell is seen twice.
        acc.add(&Pose2::new(0.0, 0.0, 0.0), &local);
        acc.add(&Pose2::new(0.0, 0.0, 0.0), &local);
        acc.take()
    }

    #[test]
    fn a_place_of_a_street_is_found_and_confirmed_from_no_prior() {
        let mut rng = Lcg(7);
        let world = street(&mut rng, 0.0);
        let map = Arc::new(ScanMap::from_points(world.clone(), &drive(&[0.0])).unwrap());
        let mut search = ScanSearcher::new(map);
        // The local frame: the vehicle started at (150, 1) heading east; it is now 20 m on.
        let origin = Pose2::new(150.0, 1.0, 0.02);
        let vehicle_local = Pose2::new(20.0, -0.5, -0.01);
        let truth = compose(&origin, &vehicle_local);
        let local = seen(&world, &truth, &mut rng);
        let first = search.attempt(&local, &vehicle_local);
        assert!(matches!(first, Attempt::Candidate(_)), "{first:?}");
        let second = search.attempt(&local, &vehicle_local);
        let Attempt::Fix(v) = second else {
            panic!("{second:?}");
        };
        // The local frame's origin in the map, to the cell's size and better.
        assert!((v.transform.x - origin.x).abs() < 0.3, "{v:?}");
        assert!((v.transform.y - origin.y).abs() < 0.3, "{v:?}");
        assert!(
            wrap_angle(v.transform.theta - origin.theta).abs() < 0.01,
            "{v:?}"
        );
        assert!(v.covariance.cholesky().is_some());
    }

    #[test]
    fn a_map_that_holds_the_street_twice_never_gives_a_fix() {
        let mut rng = Lcg(7);
        let mut world = street(&mut rng, 0.0);
        let mut copy = Lcg(7);
        world.extend(street(&mut copy, 1000.0));
        let map = Arc::new(ScanMap::from_points(world.clone(), &drive(&[0.0, 1000.0])).unwrap());
        let mut search = ScanSearcher::new(map);
        let vehicle_local = Pose2::new(0.0, 0.0, 0.0);
        let truth = Pose2::new(170.0, 0.5, 0.01);
        let local = seen(&world, &truth, &mut rng);
        for _ in 0..3 {
            let a = search.attempt(&local, &vehicle_local);
            // The two copies score alike: places alike, never a candidate.
            assert!(matches!(a, Attempt::Ambiguous(_)), "{a:?}");
        }
    }

    /// The tracker on the same street: a prediction 0.3 m and 0.01 rad off is pulled onto
    /// the truth by one rotation's registration, with a covariance that shrinks and stays
    /// symmetric positive definite; a registration 2 m from the confident prediction is
    /// outside the gate and not fused, until four in a row agree on it.
    #[test]
    fn tracking_registers_each_rotation_against_the_map_and_gates_a_jump() {
        use super::super::scan_track::{ScanTracker, TrackSettings, Update};
        let mut rng = Lcg(11);
        let world = street(&mut rng, 0.0);
        let map = ScanMap::from_points(world.clone(), &drive(&[0.0])).unwrap();
        let truth = Pose2::new(200.0, 0.5, 0.0);
        let start = Pose2::new(200.3, 0.3, 0.01);
        let cov = Matrix3::from_diagonal(&Vector3::new(0.25, 0.25, 0.02f64.powi(2)));
        let mut t = ScanTracker::new(TrackSettings::default(), start, cov, start);
        let cloud = seen(&world, &truth, &mut rng);
        let u = t.update(&map, &cloud);
        assert!(matches!(u, Update::Fused { .. }), "{u:?}");
        let (p, c) = t.estimate();
        assert!((p.x - truth.x).hypot(p.y - truth.y) < 0.05, "{p:?}");
        assert!(wrap_angle(p.theta - truth.theta).abs() < 0.002, "{p:?}");
        assert!(c[(0, 0)] < 0.25 && c[(1, 1)] < 0.25, "{c}");
        assert!((c - c.transpose()).norm() < 1e-12 && c.cholesky().is_some());
        // The vehicle is in fact 2 m further on than the (now confident) prediction: the
        // registration finds it there, far outside the prediction's gate, and is not fused.
        let ahead = seen(&world, &Pose2::new(202.0, 0.5, 0.0), &mut rng);
        let u = t.update(&map, &ahead);
        assert!(matches!(u, Update::Gated { .. }), "{u:?}");
        assert!((t.estimate().0.x - truth.x).abs() < 0.05);
        // The registrations keep agreeing on that offset: after four in a row the pose is
        // taken from them (the prediction was wrong, not the map).
        for _ in 0..2 {
            let u = t.update(&map, &ahead);
            assert!(matches!(u, Update::Gated { .. }), "{u:?}");
        }
        let u = t.update(&map, &ahead);
        assert!(matches!(u, Update::Reanchored { .. }), "{u:?}");
        let (p, c) = t.estimate();
        assert!(
            (p.x - 202.0).abs() < 0.05 && (p.y - 0.5).abs() < 0.05,
            "{p:?}"
        );
        assert!(
            c.cholesky().is_some() && c[(0, 0)] > 1.0,
            "grown by the offset: {c}"
        );
        assert!(!t.lost());
    }

    #[test]
    fn too_small_a_local_scan_is_no_attempt() {
        let mut rng = Lcg(3);
        let world = street(&mut rng, 0.0);
        let map = Arc::new(ScanMap::from_points(world, &drive(&[0.0])).unwrap());
        let mut search = ScanSearcher::new(map);
        let a = search.attempt(&[[10.0, 8.0]; 20], &Pose2::new(0.0, 0.0, 0.0));
        assert_eq!(a, Attempt::TooFewFeatures);
    }
}
