//! Loop-closure candidates from place descriptors, for returns the pose prior cannot find
//! (a long stretch of drift makes the chained frames' uncertainty too small or the estimate
//! too far off for the search of [`crate::layer`] to reach the earlier submap).
//!
//! Each submap is described (radar-odometry's [`PlaceDescriptor`]: a polar soft-occupancy
//! grid, see its module for why) around its origin from its own features and the previous
//! submap's, placed in its frame: a submap's features lie ahead of its origin, its
//! predecessor's behind, so a place driven the other way still shares half of its points.
//! The new submap's descriptor is looked up among the earlier submaps that are far enough
//! behind along the drive (a k-d tree of ring keys, then the full comparison under every
//! rotation and shifted origin); a match below the distance threshold gives the relative
//! heading and a rough translation, refined by a vote over feature offsets. The match is
//! offered to the existing verifier ([`crate::align`]) for the matched submap and its two
//! neighbours (the place may lie in either's features), with that transform as the prior.
//! The verifier decides: a descriptor never adds an edge by itself.

use std::collections::HashMap;
use std::sync::Arc;

use nalgebra::Matrix3;
use radar_model::geometry::{wrap_angle, Pose2};
use radar_odometry::{PlaceDescriptor, PlaceIndex, PlaceQuery, PlaceSettings};
use slam_filter::FrozenSubmap;

use crate::se2::{compose, inverse, transform_point};

/// Candidates from place descriptors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaceSearch {
    /// Look for candidates by descriptor at all.
    pub enabled: bool,
    /// The descriptor.
    pub descriptor: PlaceSettings,
    /// Earlier submaps retrieved by ring key for the full comparison.
    pub neighbours: usize,
    /// A full comparison at most this far is a candidate (`PlaceMatch::distance`).
    pub max_distance: f64,
    /// Candidates at most per new submap (the nearest by descriptor).
    pub max_candidates: usize,
    /// An earlier submap is looked up only when the vehicle has moved at least this far
    /// (m, along the chain of submap frames) since it ended.
    pub min_travel_m: f64,
    /// The prior handed to the verifier: standard deviation of the translation (m).
    pub prior_sigma_m: f64,
    /// And of the heading (rad).
    pub prior_sigma_rad: f64,
    /// A verified closure from a descriptor is refused when it puts the new submap's frame
    /// farther from where the chain of submaps puts it than this (m) plus
    /// [`Self::drift_per_m`] of the distance driven between the two plus three standard
    /// deviations of the chain's relative position: no odometry drifts so far, and a place
    /// that matches there is another place that looks the same (a grid city's blocks).
    pub drift_floor_m: f64,
    /// The share of the distance driven between the two submaps the chain may have
    /// drifted by (see [`Self::drift_floor_m`]).
    pub drift_per_m: f64,
    /// The same for the heading (rad) ...
    pub heading_drift_floor_rad: f64,
    /// ... plus this per metre driven between the two (rad/m).
    pub heading_drift_per_m: f64,
}

impl Default for PlaceSearch {
    fn default() -> Self {
        Self {
            enabled: true,
            descriptor: PlaceSettings::default(),
            neighbours: 10,
            max_distance: 0.5,
            max_candidates: 2,
            min_travel_m: 200.0,
            prior_sigma_m: 2.0,
            prior_sigma_rad: 0.05,
            drift_floor_m: 20.0,
            drift_per_m: 0.1,
            heading_drift_floor_rad: 0.35,
            heading_drift_per_m: 0.001,
        }
    }
}

/// A candidate from a descriptor: offer submap `index` with this prior of the new one's
/// frame in its frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaceCandidate {
    /// The earlier submap.
    pub index: usize,
    /// The new submap's frame in the earlier one's.
    pub prior: Pose2,
    /// Its covariance.
    pub covariance: Matrix3<f64>,
    /// The descriptor distance of the match it came from.
    pub distance: f64,
}

/// Descriptors of the submaps joined so far and the index of those far enough behind.
#[derive(Debug, Clone, Default)]
pub(crate) struct Places {
    descriptors: Vec<Option<PlaceDescriptor>>,
    index: PlaceIndex,
    /// Submaps considered for the index so far (in order).
    indexed: usize,
}

/// The points a submap's place is described by: its features and its predecessor's, in its
/// frame (features seen at least `min_hits` times).
pub(crate) fn place_points(
    submaps: &[Arc<FrozenSubmap>],
    k: usize,
    min_hits: u64,
) -> Vec<[f64; 2]> {
    let mut points: Vec<[f64; 2]> = Vec::new();
    if let Some(s) = submaps.get(k) {
        points.extend(
            s.features
                .iter()
                .filter(|f| f.hits >= min_hits)
                .map(|f| f.xy),
        );
    }
    if let Some(prev) = k.checked_sub(1).and_then(|j| submaps.get(j)) {
        let back = inverse(&prev.end_pose);
        points.extend(
            prev.features
                .iter()
                .filter(|f| f.hits >= min_hits)
                .map(|f| transform_point(&back, f.xy)),
        );
    }
    points
}

/// Cells of the translation vote (m): a heading off by 0.01 rad moves a feature 50 m out by
/// 0.5 m, so a few such cells separate the headings tried.
const VOTE_CELL_M: f64 = 0.5;

/// The offset of `b`'s features (turned by `yaw`) onto `a`'s that most pairs agree on,
/// within `reach` of `guess` (m): votes in [`VOTE_CELL_M`] cells, scored over 3 x 3 cells; the mean
/// offset of the winning cells' votes, the votes, and their spread (m^2).
fn vote_translation(
    a: &[[f64; 2]],
    b: &[[f64; 2]],
    yaw: f64,
    guess: [f64; 2],
    reach: f64,
) -> Option<([f64; 2], usize, f64)> {
    let (s, c) = yaw.sin_cos();
    // Per cell: votes, sum of x, y, and of x^2 + y^2.
    let mut cells: HashMap<(i64, i64), [f64; 4]> = HashMap::new();
    for pb in b {
        let rb = [c * pb[0] - s * pb[1], s * pb[0] + c * pb[1]];
        for pa in a {
            let d = [pa[0] - rb[0], pa[1] - rb[1]];
            if (d[0] - guess[0]).abs() > reach || (d[1] - guess[1]).abs() > reach {
                continue;
            }
            let e = cells
                .entry((
                    (d[0] / VOTE_CELL_M).floor() as i64,
                    (d[1] / VOTE_CELL_M).floor() as i64,
                ))
                .or_insert([0.0; 4]);
            e[0] += 1.0;
            e[1] += d[0];
            e[2] += d[1];
            e[3] += d[0] * d[0] + d[1] * d[1];
        }
    }
    let window = |(x, y): (i64, i64)| -> [f64; 4] {
        let mut t = [0.0; 4];
        for dx in -1..=1 {
            for dy in -1..=1 {
                if let Some(v) = cells.get(&(x + dx, y + dy)) {
                    for (ti, vi) in t.iter_mut().zip(v) {
                        *ti += vi;
                    }
                }
            }
        }
        t
    };
    let mut keys: Vec<(i64, i64)> = cells.keys().copied().collect();
    keys.sort_unstable();
    keys.into_iter()
        .map(window)
        .filter(|t| t[0] > 0.0)
        .map(|[n, sx, sy, sq]| {
            let m = [sx / n, sy / n];
            let spread = (sq / n - m[0] * m[0] - m[1] * m[1]).max(0.0);
            (m, n as usize, spread)
        })
        .max_by(|p, q| p.1.cmp(&q.1).then(q.2.total_cmp(&p.2)))
}

/// Which earlier submaps a new one may be matched with, and which are chained to their
/// predecessor (a later drive's first submap is not).
pub(crate) struct SubmapOrder<'a> {
    /// Submap `i` is far enough behind (or of another drive).
    pub eligible: &'a dyn Fn(usize) -> bool,
    /// Submap `j`'s frame is where submap `j - 1` ended.
    pub chained: &'a dyn Fn(usize) -> bool,
}

impl Places {
    /// Submaps described so far.
    pub(crate) fn described(&self) -> usize {
        self.descriptors.len()
    }

    /// Describes the newest submap `k` (the last of `submaps`); its query, when it has
    /// enough points.
    /// `points` are the newest submap's place points (see [`place_points`], or its scan).
    pub(crate) fn describe(
        &mut self,
        points: &[[f64; 2]],
        settings: &PlaceSearch,
    ) -> Option<PlaceQuery> {
        let query = PlaceQuery::new(points, &settings.descriptor).ok();
        let own = query
            .as_ref()
            .and_then(|q| q.shifted.first())
            .filter(|(shift, _)| *shift == [0.0, 0.0])
            .map(|(_, d)| d.clone());
        self.descriptors.push(own);
        query
    }

    /// Describes the newest submap without looking it up (the descriptor is kept for later
    /// submaps to find).
    pub(crate) fn skip(&mut self, points: Vec<[f64; 2]>, settings: &PlaceSearch) {
        let own = PlaceDescriptor::new(points, &settings.descriptor).ok();
        self.descriptors.push(own);
    }

    /// Candidates for the newest submap `k` among the earlier ones `i` with
    /// `eligible(i)` (far enough behind), nearest by descriptor first.
    pub(crate) fn candidates(
        &mut self,
        submaps: &[Arc<FrozenSubmap>],
        query: &PlaceQuery,
        order: &SubmapOrder<'_>,
        min_hits: u64,
        settings: &PlaceSearch,
        refine_by_features: bool,
    ) -> Vec<PlaceCandidate> {
        let eligible = order.eligible;
        let chained = order.chained;
        let k = submaps.len().saturating_sub(1);
        while self.indexed < k && eligible(self.indexed) {
            if let Some(Some(d)) = self.descriptors.get(self.indexed) {
                self.index.insert(self.indexed as u64, d);
            }
            self.indexed += 1;
        }
        let mut matches: Vec<(usize, f64, [f64; 3])> = self
            .index
            .nearest_to_query(query, settings.neighbours)
            .into_iter()
            .filter_map(|(id, _)| {
                let i = usize::try_from(id).ok()?;
                let d = self.descriptors.get(i)?.as_ref()?;
                let m = query.compare(d)?;
                (m.place.distance <= settings.max_distance).then_some((
                    i,
                    m.place.distance,
                    m.transform,
                ))
            })
            .collect();
        matches.sort_by(|a, b| a.1.total_cmp(&b.1));
        matches.truncate(settings.max_candidates);
        let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(
            settings.prior_sigma_m.powi(2),
            settings.prior_sigma_m.powi(2),
            settings.prior_sigma_rad.powi(2),
        ));
        let newest: Vec<[f64; 2]> = submaps
            .get(k)
            .map(|s| {
                s.features
                    .iter()
                    .filter(|f| f.hits >= min_hits)
                    .map(|f| f.xy)
                    .collect()
            })
            .unwrap_or_default();
        let mut out: Vec<PlaceCandidate> = Vec::new();
        for (i, distance, t) in matches {
            let t = Pose2::new(t[0], t[1], t[2]);
            // The place may lie in the matched submap's features or its neighbours': offer
            // each (those far enough behind), with the transform carried along the chain.
            let mut offers: Vec<(usize, Pose2)> = vec![(i, t)];
            if let Some(prev) = i
                .checked_sub(1)
                .filter(|_| chained(i))
                .and_then(|j| submaps.get(j))
            {
                offers.push((i - 1, compose(&prev.end_pose, &t)));
            }
            if i + 1 < k && eligible(i + 1) && chained(i + 1) {
                offers.push((i + 1, compose(&inverse(&submaps[i].end_pose), &t)));
            }
            for (j, prior) in offers {
                if out.iter().any(|c| c.index == j) {
                    continue;
                }
                // With scans the verifier's starts find the translation; with features it
                // is voted again from them.
                let prior = if refine_by_features {
                    let earlier: Vec<[f64; 2]> = submaps[j]
                        .features
                        .iter()
                        .filter(|f| f.hits >= min_hits)
                        .map(|f| f.xy)
                        .collect();
                    refine(&earlier, &newest, prior, settings)
                } else {
                    prior
                };
                out.push(PlaceCandidate {
                    index: j,
                    prior,
                    covariance: cov,
                    distance,
                });
            }
        }
        out
    }
}

/// The prior's translation voted again from the features, under headings around the
/// descriptor's (it is known to a fraction of a 6 degree sector); unchanged when too few
/// features agree.
pub fn refine(a: &[[f64; 2]], b: &[[f64; 2]], prior: Pose2, settings: &PlaceSearch) -> Pose2 {
    let reach = 3.0 * settings.prior_sigma_m;
    let mut best: Option<(Pose2, usize, f64)> = None;
    for step in -4..=4 {
        let yaw = wrap_angle(prior.theta + f64::from(step) * 0.01);
        if let Some((t, n, spread)) = vote_translation(a, b, yaw, [prior.x, prior.y], reach) {
            if best.is_none_or(|(_, m, sm)| n > m || (n == m && spread < sm)) {
                best = Some((Pose2::new(t[0], t[1], yaw), n, spread));
            }
        }
    }
    match best {
        Some((p, n, _)) if n >= 3 => p,
        _ => prior,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_vote_finds_the_offset_shared_by_most_pairs() {
        let a: Vec<[f64; 2]> = (0..30)
            .map(|i| [f64::from(i) * 3.7 % 40.0, f64::from(i * i) % 23.0])
            .collect();
        let (yaw, t) = (0.4f64, [2.3, -1.2]);
        let (s, c) = yaw.sin_cos();
        // b = R^-1 (a - t): a = R b + t.
        let b: Vec<[f64; 2]> = a
            .iter()
            .map(|p| {
                let d = [p[0] - t[0], p[1] - t[1]];
                [c * d[0] + s * d[1], -s * d[0] + c * d[1]]
            })
            .collect();
        let (found, n, _) = vote_translation(&a, &b, yaw, [0.0, 0.0], 9.0).unwrap();
        assert!(n >= 30);
        assert!((found[0] - t[0]).hypot(found[1] - t[1]) < 0.3, "{found:?}");
        let p = refine(
            &a,
            &b,
            Pose2::new(0.5, 0.5, yaw + 0.03),
            &PlaceSearch::default(),
        );
        assert!((p.x - t[0]).hypot(p.y - t[1]) < 0.25, "{p:?}");
        assert!((p.theta - yaw).abs() < 0.015, "{p:?}");
    }
}
