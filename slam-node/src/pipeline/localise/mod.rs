//! Localisation in a saved map (`--map FILE`, `[map] mode = "localise"`): the vehicle is
//! tracked against the map's features without adding any, and the pose is published in
//! the map's frame with its covariance.
//!
//! - **Tracking** ([`known`]): the map's features nearest the vehicle are put into the
//!   filter as known landmarks with the covariance they were saved with, and taken out
//!   when left behind, so the state stays the size of one submap; the filter maps nothing
//!   (`FilterSettings::add_features` false) and retires nothing. The published covariance
//!   is the filter's plus the nearest submap frame's own uncertainty in the map (a shared
//!   error of its features that averaging them does not reduce).
//! - **With a prior** (`[map] initial_pose`, `initial_sigma`): tracking starts there.
//! - **A prior from a topic** (`[map] initial_pose_topic`, [`PriorPose`]): at any time,
//!   searching or tracking, a prior starts tracking again at its pose, carried from its
//!   stamp to the latest rotation along the local filter's motion (the last
//!   [`RECENT_S`] of it are kept; an older stamp is refused with a WARN).
//! - **Without** ([`search`]): the filter maps in a frame of its own until place
//!   recognition and the loop-closure verifier find that frame in the map, twice in
//!   agreement, never two places at once, and clearly ahead of every other place of the map
//!   that could fit; then tracking starts from there. The search runs on a thread of its
//!   own ([`worker`]); the pipeline thread never waits for it in real time. Until the fix
//!   no pose is published and the log says why (WARN at the 1st, 2nd, 4th... attempt).
//!
//! No IO: the map is loaded by the caller (the command line), and its radar profile is
//! checked here against the run's.

pub mod known;
pub mod scan_map;
pub mod scan_search;
pub mod scan_track;
pub mod score;
pub mod search;
pub mod support;
pub mod worker;

#[cfg(test)]
mod repeated_tests;

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::Arc;

use nalgebra::Matrix3;
use radar_model::geometry::{wrap_angle, Pose2};
use serde::Serialize;
use slam_filter::{Ekf, FilterError, FilterSettings, FrozenSubmap, RadarBeamModel};
use slam_graph::se2::compose_covariance;
use slam_map::{Map, ProfileMismatch};
use tracing::{info, warn};

use super::gate::worth_logging;
use super::settings::PipelineSettings;
use super::DaemonEkf;
use known::{Loaded, MapFeatures, SwapRule};
use scan_map::ScanMap;
use scan_search::{KeptCloud, ScanSearcher};
use scan_track::{ScanTracker, TrackSettings, Update};
pub use score::LocaliseScore;
use search::{Attempt, PlaceSearcher};
use worker::{Outcome, Query, Search, SearchWorker};

/// Features of the map held in the filter at most while tracking.
pub const MAX_LOADED: usize = 100;
/// While searching, the local map keeps features within this of the vehicle (m).
const SEARCH_KEEP_M: f64 = 100.0;
/// While searching, the filter's frame is restarted at the vehicle after this much driving
/// (m), the previous frame's features kept for the place queries.
const SEARCH_WINDOW_M: f64 = 100.0;
/// While searching, an attempt after this much driving (m) or this many rotations.
const ATTEMPT_EVERY_M: f64 = 15.0;
const ATTEMPT_EVERY_ROTATIONS: u64 = 10;
/// Tracking: this many rotations in a row without an update from a map feature lose the
/// fix (off the map, or a fix that was wrong): the search starts again.
const LOST_AFTER_ROTATIONS: u32 = 12;
/// Map features used for places and verification: seen at least this often.
const MIN_HITS: u64 = 3;
/// Local frame restarts remembered to carry a late search outcome into the current frame.
const MAX_RESTARTS_KEPT: usize = 8;
/// Local poses kept to carry a prior from its stamp to the latest rotation (s).
pub const RECENT_S: f64 = 30.0;
/// A prior stamped this far (s) after the latest rotation is taken as of that rotation;
/// later, it is refused (a clock that is not the radar's).
const PRIOR_AHEAD_S: f64 = 1.0;
/// By scans: the local scan a search attempt describes is made of the clouds of the last
/// this many metres of driving, at most [`KEEP_ROTATIONS`] of them.
const KEEP_M: f64 = 60.0;
/// See [`KEEP_M`].
const KEEP_ROTATIONS: usize = 80;

/// The map a run localises in, and how it starts.
#[derive(Debug, Clone, PartialEq)]
pub struct LocaliseSettings {
    /// The file it was read from (for messages).
    pub path: PathBuf,
    /// The map.
    pub map: Arc<Map>,
    /// The prior pose in the map's frame and its standard deviations, when given.
    pub prior: Option<([f64; 3], [f64; 3])>,
    /// The standard deviations a prior from the topic takes when its covariance is all
    /// zero (`[map] initial_sigma`).
    pub prior_sigma: [f64; 3],
    /// Extend mode (`[map] mode = "extend"`): once localised, map on in the map's frame
    /// ([`crate::pipeline::extend`]).
    pub extend: bool,
    /// Localise against the map's scans (`[map] localise_with = "scans"`), extending too.
    pub scans: bool,
}

impl LocaliseSettings {
    /// From `[map]` and the map loaded from `path`.
    pub fn new(path: PathBuf, map: Arc<Map>, c: &config::MapSettings) -> Self {
        Self {
            path,
            map,
            prior: c.initial_pose.map(|p| (p, c.initial_sigma)),
            prior_sigma: c.initial_sigma,
            extend: c.mode == config::MapMode::Extend,
            scans: c.localise_with == config::LocaliseWith::Scans,
        }
    }

    /// What localising changes in the pipeline's settings: no submaps (the map's are the
    /// submaps), nothing saved, the filter started at the prior (or at the origin of a
    /// frame of its own to search from). Extending, the submaps and the saved map stay as
    /// configured: the pipeline starts them at the fix.
    pub fn apply(&self, s: &mut PipelineSettings) {
        if !self.extend {
            s.submaps = None;
            s.map_save.enabled = false;
        }
        let (pose, std) = self.prior.unwrap_or(([0.0; 3], [0.0; 3]));
        s.initial_pose = pose;
        s.initial_pose_std = std;
        if self.by_scans(s) {
            // By scans the local filter only carries the motion from one rotation to the
            // next (radar odometry's, the gyro's): it maps no features, which would cost
            // the pipeline thread most of its time and serve nothing.
            s.filter.add_features = false;
        }
    }

    /// Whether the run localises by the map's scans: asked for, radar odometry on, and a
    /// map that holds scans.
    pub fn by_scans(&self, s: &PipelineSettings) -> bool {
        self.scans && s.scan_match.enabled && self.map.scan_point_count() > 0
    }
}

/// Why localisation could not start.
#[derive(Debug, thiserror::Error)]
pub enum LocaliseError {
    /// The map was made with a radar whose geometry differs from this one's.
    #[error("map file {path}: {mismatch}: its features cannot be matched with this radar's")]
    Profile {
        /// The file.
        path: PathBuf,
        /// The differences.
        mismatch: Box<ProfileMismatch>,
    },
    /// The map holds no feature to localise against.
    #[error("map file {0}: the map holds no feature to localise against")]
    Empty(PathBuf),
    /// The place search's thread could not start.
    #[error("the place search's thread could not start: {0}")]
    Thread(#[source] std::io::Error),
    /// Extend mode without submaps to map in.
    #[error("map file {0}: extending a map needs submaps ([submaps] enabled = true)")]
    ExtendNeedsSubmaps(PathBuf),
}

/// What localisation did over a run.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct LocaliseSummary {
    /// The map file.
    pub path: String,
    /// Its submaps and features.
    pub map_submaps: usize,
    /// Features.
    pub map_features: usize,
    /// Places described for the search.
    pub places: usize,
    /// Started from a prior pose.
    pub prior: bool,
    /// Stream time from the first rotation to the fix (s); `None`: no fix.
    pub time_to_fix_s: Option<f64>,
    /// Rotations before the fix.
    pub rotations_to_fix: u64,
    /// Search attempts, and those that found places alike.
    pub attempts: u64,
    /// Attempts refused as ambiguous.
    pub ambiguous: u64,
    /// Map features put into the filter, taken out, refused.
    pub inserted: u64,
    /// Taken out.
    pub removed: u64,
    /// Refused.
    pub refused: u64,
    /// Rotations published in the map's frame.
    pub published: u64,
    /// Fixes taken (the first and any after a loss).
    pub fixes: u64,
    /// Fixes lost (no map feature seen for a while while tracking).
    pub lost: u64,
    /// What the run localised against: `"scans"` or `"features"`.
    pub by: &'static str,
    /// Scan points of the map (by scans).
    pub map_scan_points: usize,
    /// By scans, while tracking: rotations whose registration against the map was fused,
    /// found none, or was outside the gate.
    pub track_fused: u64,
    /// See `track_fused`.
    pub track_unregistered: u64,
    /// See `track_fused`.
    pub track_gated: u64,
    /// Of those outside the gate, the times the pose was re-anchored on registrations that
    /// agreed with each other.
    pub track_reanchored: u64,
    /// Priors received from the topic (`[map] initial_pose_topic`).
    pub priors_received: u64,
    /// Of those, the ones tracking started from (a later one in the same rotation
    /// replaces an earlier one).
    pub priors_applied: u64,
    /// Of those, the ones refused (stamped outside the poses kept).
    pub priors_refused: u64,
    /// By scans: pairs of submaps of different passes over the same streets compared at
    /// load, aligned, and the offsets between them (m): median and largest; the load's
    /// wall time for it (ms).
    pub map_pairs_compared: usize,
    /// See `map_pairs_compared`.
    pub map_pairs_aligned: usize,
    /// See `map_pairs_compared`.
    pub map_offset_p50_m: f64,
    /// See `map_pairs_compared`.
    pub map_offset_max_m: f64,
    /// See `map_pairs_compared`.
    pub map_check_ms: f64,
    /// Search attempts' wall time on the search's thread (ms): median and largest.
    pub search_ms_p50: f64,
    /// Largest.
    pub search_ms_max: f64,
    /// Against the truth, when it is known.
    pub score: Option<LocaliseScore>,
}

enum Phase {
    Searching {
        /// Where the last attempt was made (the local frame).
        last: Option<Pose2>,
        /// Rotations since.
        since: u64,
        /// Driven in the current local frame (m), and the pose it was counted to.
        driven_m: f64,
        counted_to: Option<Pose2>,
        /// The previous local frame's features, in the current frame.
        previous: Option<Box<FrozenSubmap>>,
    },
    Tracking,
}

impl Phase {
    /// A search from nothing: no attempt yet, nothing driven, no previous window.
    fn searching() -> Self {
        Phase::Searching {
            last: None,
            since: 0,
            driven_m: 0.0,
            counted_to: None,
            previous: None,
        }
    }
}

/// The localisation stage.
pub struct Localiser {
    path: PathBuf,
    features: Arc<MapFeatures>,
    worker: SearchWorker,
    /// The search's local frame (restarted with the window and with a new search), and
    /// the recent restarts: from frame k, the next frame's origin in it (`None`: a new
    /// search, nothing carries over).
    frame: u64,
    restarts: VecDeque<(u64, Option<Pose2>)>,
    loaded: Loaded,
    rule: SwapRule,
    tracking: FilterSettings,
    searching: FilterSettings,
    updates_seen: u64,
    quiet_rotations: u32,
    motion: radar_model::motion::MotionModel,
    observer: RadarBeamModel,
    phase: Phase,
    first_rotation_s: Option<f64>,
    rotations: u64,
    /// The rotation count when the last fix was taken.
    fix_rotation: u64,
    summary: LocaliseSummary,
    /// Localising by scans.
    scans: Option<ByScans>,
    /// The latest prior from the topic, applied at the next rotation's end.
    pending_prior: Option<PriorPose>,
    /// The local filter's pose at each rotation's end over the last [`RECENT_S`]: the
    /// local frame it is in, the time, the pose.
    recent: VecDeque<(u64, f64, Pose2)>,
    /// See [`LocaliseSettings::prior_sigma`].
    prior_sigma: [f64; 3],
}

/// A prior pose from a topic (`[map] initial_pose_topic`): where the vehicle was in the
/// map's frame at `stamp_s` (the radar's clock), and how sure that is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PriorPose {
    /// When (s, the radar's clock); `None`: as of the latest rotation.
    pub stamp_s: Option<f64>,
    /// The pose in the map's frame.
    pub pose: Pose2,
    /// Its covariance over (x, y, heading); `None`: [`LocaliseSettings::prior_sigma`].
    pub covariance: Option<Matrix3<f64>>,
}

/// Localisation by the map's scans: the map, the last stretch's clouds, the tracker.
struct ByScans {
    map: Arc<ScanMap>,
    kept: VecDeque<KeptCloud>,
    settings: TrackSettings,
    tracker: Option<ScanTracker>,
    /// While tracking: driven in the current local frame (m), and the pose it was counted
    /// to (the local frame restarts every [`SEARCH_WINDOW_M`], as while searching).
    driven_m: f64,
    counted_to: Option<Pose2>,
}

impl ByScans {
    /// Keeps this rotation's cloud (the vehicle at `pose` in the local frame), dropping
    /// those beyond [`KEEP_M`] of driving or [`KEEP_ROTATIONS`].
    fn keep(&mut self, pose: Pose2, cloud: &[[f64; 2]]) {
        self.kept.push_back((pose, Arc::new(cloud.to_vec())));
        while self.kept.len() > KEEP_ROTATIONS {
            self.kept.pop_front();
        }
        loop {
            let driven: f64 = self
                .kept
                .iter()
                .zip(self.kept.iter().skip(1))
                .map(|((a, _), (b, _))| (a.x - b.x).hypot(a.y - b.y))
                .sum();
            if driven <= KEEP_M || self.kept.len() <= 2 {
                break;
            }
            self.kept.pop_front();
        }
    }

    /// The local frame restarted at `origin` (in the old one).
    fn reframe(&mut self, origin: &Pose2) {
        let back = slam_graph::se2::inverse(origin);
        for (pose, _) in self.kept.iter_mut() {
            *pose = slam_graph::se2::compose(&back, pose);
        }
        if let Some(t) = self.tracker.as_mut() {
            t.reframe(origin);
        }
    }
}

impl std::fmt::Debug for Localiser {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Localiser")
            .field("path", &self.path)
            .field("summary", &self.summary)
            .finish_non_exhaustive()
    }
}

impl Localiser {
    /// Checks the map against the run's radar profile (refused when the geometry differs,
    /// a warning when only the name does) and describes its places.
    pub fn new(l: &LocaliseSettings, s: &PipelineSettings) -> Result<Self, LocaliseError> {
        let map = &l.map;
        match radar_model::profile::by_name(&s.map_save.profile) {
            Some(profile) => match map.check_profile(profile) {
                Ok(()) => {}
                Err(mismatch) if mismatch.geometry_differs() => {
                    return Err(LocaliseError::Profile {
                        path: l.path.clone(),
                        mismatch: Box::new(mismatch),
                    })
                }
                Err(mismatch) => warn!(
                    file = %l.path.display(),
                    "{mismatch}: the same geometry, localising anyway"
                ),
            },
            None => warn!(
                file = %l.path.display(),
                profile = %s.map_save.profile,
                "the run's radar profile is unknown: the map's ({}) is not checked",
                map.profile.name
            ),
        }
        let features = Arc::new(MapFeatures::new(map));
        let scan_map = if l.scans {
            let built = if l.by_scans(s) {
                ScanMap::new(map, &features)
            } else if s.scan_match.enabled {
                None
            } else {
                warn!(
                    file = %l.path.display(),
                    "localising by scans needs radar odometry ([scan_match] enabled, or [odometry] source = \"none\"): localising by the map's features instead"
                );
                None
            };
            if built.is_none() && s.scan_match.enabled {
                warn!(
                    file = %l.path.display(),
                    "the map holds no scans (a map written before version 3, or with [submaps] scans off): localising by its features instead"
                );
            }
            built.map(Arc::new)
        } else {
            None
        };
        if scan_map.is_none() && map.feature_count() == 0 {
            return Err(LocaliseError::Empty(l.path.clone()));
        }
        let (search, places) = match scan_map.as_ref() {
            Some(m) => (
                Search::Scans(ScanSearcher::new(Arc::clone(m))),
                m.places.len(),
            ),
            None => {
                let searcher = PlaceSearcher::new(&features, MIN_HITS);
                let places = searcher.places();
                (Search::Features(searcher, Arc::clone(&features)), places)
            }
        };
        let worker = SearchWorker::spawn(search).map_err(LocaliseError::Thread)?;
        let tracking = FilterSettings {
            add_features: false,
            retire_unseen_after_s: 0.0,
            retire_unrepeatable_below: 0.0,
            retire_after_misses: u32::MAX,
            max_features: s.filter.max_features.max(MAX_LOADED),
            ..s.filter.clone()
        };
        let summary = LocaliseSummary {
            path: l.path.display().to_string(),
            map_submaps: map.submaps.len(),
            map_features: map.feature_count(),
            places,
            prior: l.prior.is_some(),
            by: if scan_map.is_some() {
                "scans"
            } else {
                "features"
            },
            map_scan_points: scan_map.as_ref().map_or(0, |m| m.len()),
            map_pairs_compared: scan_map
                .as_ref()
                .map_or(0, |m| m.disagreement.pairs_compared),
            map_pairs_aligned: scan_map
                .as_ref()
                .map_or(0, |m| m.disagreement.pairs_aligned),
            map_offset_p50_m: scan_map.as_ref().map_or(0.0, |m| {
                let mut v = m.disagreement.offsets_m.clone();
                v.sort_by(f64::total_cmp);
                v.get(v.len() / 2).copied().unwrap_or(0.0)
            }),
            map_offset_max_m: scan_map.as_ref().map_or(0.0, |m| {
                m.disagreement.offsets_m.iter().copied().fold(0.0, f64::max)
            }),
            map_check_ms: scan_map.as_ref().map_or(0.0, |m| m.disagreement.wall_ms),
            ..LocaliseSummary::default()
        };
        info!(
            file = %l.path.display(),
            submaps = map.submaps.len(),
            features = map.feature_count(),
            scan_points = summary.map_scan_points,
            by = summary.by,
            places,
            prior = l.prior.is_some(),
            "localising in a saved map"
        );
        Ok(Self {
            path: l.path.clone(),
            features,
            worker,
            frame: 0,
            restarts: VecDeque::new(),
            loaded: Loaded::default(),
            rule: SwapRule {
                max_loaded: MAX_LOADED.min(tracking.max_features),
                radius_m: s.filter.max_range_m,
                keep_factor: 1.3,
                every_m: 2.0,
            },
            tracking,
            searching: s.filter.clone(),
            updates_seen: 0,
            quiet_rotations: 0,
            motion: s.motion,
            observer: RadarBeamModel { power: s.power },
            phase: if l.prior.is_some() {
                Phase::Tracking
            } else {
                Phase::searching()
            },
            first_rotation_s: None,
            rotations: 0,
            fix_rotation: 0,
            summary,
            scans: scan_map.map(|map| ByScans {
                map,
                kept: VecDeque::new(),
                settings: TrackSettings::for_turn_source(s.gyro.is_some()),
                tracker: None,
                driven_m: 0.0,
                counted_to: None,
            }),
            pending_prior: None,
            recent: VecDeque::new(),
            prior_sigma: l.prior_sigma,
        })
    }

    /// A prior from the topic: applied at the next rotation's end (the latest wins).
    pub fn prior(&mut self, p: PriorPose) {
        self.summary.priors_received += 1;
        self.pending_prior = Some(p);
    }

    /// The local filter's pose at `stamp_s`, in the current local frame: interpolated
    /// between the rotations' ends kept around it, carried through the frame restarts
    /// since. `None` when the stamp is before the poses kept, or later than the last by
    /// more than [`PRIOR_AHEAD_S`] (then it is taken as of the last), or the restarts in
    /// between are no longer known.
    fn local_at(&self, stamp_s: Option<f64>) -> Option<Pose2> {
        let (last_frame, last_s, last_pose) = *self.recent.back()?;
        let stamp_s = stamp_s.unwrap_or(last_s);
        if stamp_s >= last_s {
            return (stamp_s - last_s <= PRIOR_AHEAD_S)
                .then_some(last_pose)
                .and_then(|p| carry(p, last_frame, self.frame, &self.restarts));
        }
        let k = self.recent.iter().position(|(_, t, _)| *t > stamp_s)?;
        let (fb, tb, b) = self.recent[k];
        let (fa, ta, a) = *self.recent.get(k.checked_sub(1)?)?;
        let a = carry(a, fa, fb, &self.restarts)?;
        let w = if tb > ta {
            (stamp_s - ta) / (tb - ta)
        } else {
            1.0
        };
        let at = Pose2::new(
            a.x + w * (b.x - a.x),
            a.y + w * (b.y - a.y),
            wrap_angle(a.theta + w * wrap_angle(b.theta - a.theta)),
        );
        carry(at, fb, self.frame, &self.restarts)
    }

    /// Starts tracking at the prior `p`, carried to now (`ekf`'s pose) along the local
    /// filter's motion since its stamp.
    fn apply_prior(&mut self, p: PriorPose, ekf: &mut DaemonEkf, since_start_s: f64) {
        let now = ekf.pose();
        let Some(then) = self.local_at(p.stamp_s) else {
            self.summary.priors_refused += 1;
            let held = self.recent.front().zip(self.recent.back());
            warn!(
                file = %self.path.display(),
                stamp_s = p.stamp_s,
                held_from_s = held.map(|(a, _)| a.1),
                held_to_s = held.map(|(_, b)| b.1),
                "prior pose refused: stamped outside the vehicle's poses kept (the last {RECENT_S} s of the radar's clock)"
            );
            return;
        };
        let motion = slam_graph::se2::compose(&slam_graph::se2::inverse(&then), &now);
        let pose = slam_graph::se2::compose(&p.pose, &motion);
        let cov = p.covariance.unwrap_or_else(|| {
            let s = self.prior_sigma;
            Matrix3::from_diagonal(&nalgebra::Vector3::new(
                s[0] * s[0],
                s[1] * s[1],
                s[2] * s[2],
            ))
        });
        let cov = compose_covariance(&p.pose, &cov, &motion, &Matrix3::zeros());
        if self.start_tracking(pose, cov, ekf, since_start_s) {
            self.summary.priors_applied += 1;
            info!(
                file = %self.path.display(),
                x_m = pose.x,
                y_m = pose.y,
                heading_rad = wrap_angle(pose.theta),
                carried_m = motion.x.hypot(motion.y),
                "prior pose from the topic: tracking from it, publishing the pose in the map's frame"
            );
        }
    }

    /// Starts (or restarts) tracking at `pose` in the map's frame with `cov`; whether it
    /// started.
    fn start_tracking(
        &mut self,
        pose: Pose2,
        cov: Matrix3<f64>,
        ekf: &mut DaemonEkf,
        since_start_s: f64,
    ) -> bool {
        let local = ekf.pose();
        let started = match self.scans.as_mut() {
            Some(b) => {
                // By scans the local filter maps on; the tracker starts at the fix.
                b.tracker = Some(ScanTracker::new(b.settings, pose, cov, local));
                b.driven_m = 0.0;
                b.counted_to = None;
                Ok(())
            }
            None => self.tracking_filter(ekf, pose, cov).map(|new| {
                *ekf = new;
                // The filter is now in the map's frame: the local poses kept are not.
                self.recent.clear();
                self.loaded.clear();
                self.loaded
                    .swap(ekf, &self.features, &self.rule, ekf.state().time_s(), true);
            }),
        };
        match started {
            Ok(()) => {
                self.phase = Phase::Tracking;
                self.updates_seen = ekf.stats().updates;
                self.quiet_rotations = 0;
                self.summary.fixes += 1;
                self.fix_rotation = self.rotations;
                if self.summary.time_to_fix_s.is_none() {
                    self.summary.time_to_fix_s = Some(since_start_s);
                    self.summary.rotations_to_fix = self.rotations;
                }
                true
            }
            Err(e) => {
                warn!(error = %e, "the fix could not start the tracking filter");
                false
            }
        }
    }

    /// With a prior, the filter the pipeline built (at the prior) becomes the tracking
    /// filter: it maps nothing and retires nothing.
    pub fn begin(&mut self, ekf: &mut DaemonEkf) -> Result<(), FilterError> {
        if !matches!(self.phase, Phase::Tracking) {
            return Ok(());
        }
        if let Some(b) = self.scans.as_mut() {
            // By scans the filter maps on in its frame (here the map's, at the prior); the
            // tracker follows its motion.
            b.tracker = Some(ScanTracker::new(
                b.settings,
                ekf.pose(),
                ekf.pose_covariance(),
                ekf.pose(),
            ));
            self.summary.time_to_fix_s = Some(0.0);
            self.summary.fixes = 1;
            return Ok(());
        }
        {
            *ekf = self.tracking_filter(ekf, ekf.pose(), ekf.pose_covariance())?;
            self.summary.time_to_fix_s = Some(0.0);
            self.summary.fixes = 1;
        }
        Ok(())
    }

    fn tracking_filter(
        &self,
        old: &DaemonEkf,
        pose: Pose2,
        cov: Matrix3<f64>,
    ) -> Result<DaemonEkf, FilterError> {
        let mut ekf = Ekf::new(
            self.tracking.clone(),
            pose,
            0.5 * (cov + cov.transpose()),
            old.state().time_s(),
            self.motion,
            self.observer,
        )?;
        if let Some(held) = old.held_odometry() {
            ekf.apply_odometry(held)?;
        }
        Ok(ekf)
    }

    /// The map's features and frames in the map's frame.
    pub fn map_features(&self) -> &MapFeatures {
        &self.features
    }

    /// Rotations tracked since the last fix (0 while searching).
    pub fn tracked_rotations(&self) -> u64 {
        if self.has_fix() {
            self.rotations - self.fix_rotation
        } else {
            0
        }
    }

    /// Whether a pose in the map's frame is published.
    pub fn has_fix(&self) -> bool {
        matches!(self.phase, Phase::Tracking)
    }

    /// Once a rotation, after the filter's updates: swaps the map's features while
    /// tracking; while searching, trims the local map and now and then looks for the fix.
    pub fn end_rotation(&mut self, ekf: &mut DaemonEkf, time_s: f64, cloud: Option<&[[f64; 2]]>) {
        self.rotations += 1;
        let first = *self.first_rotation_s.get_or_insert(time_s);
        if let (Some(b), Some(c)) = (self.scans.as_mut(), cloud) {
            b.keep(ekf.pose(), c);
        }
        self.recent.push_back((self.frame, time_s, ekf.pose()));
        while self
            .recent
            .front()
            .is_some_and(|(_, t, _)| *t < time_s - RECENT_S)
        {
            self.recent.pop_front();
        }
        if let Some(p) = self.pending_prior.take() {
            self.apply_prior(p, ekf, time_s - first);
        }
        match &mut self.phase {
            Phase::Tracking if self.scans.is_some() => {
                self.track_scans(ekf, cloud, time_s - first);
            }
            Phase::Tracking => {
                self.loaded
                    .swap(ekf, &self.features, &self.rule, ekf.state().time_s(), false);
                self.summary.published += 1;
                let updates = ekf.stats().updates;
                if updates == self.updates_seen {
                    self.quiet_rotations += 1;
                } else {
                    self.quiet_rotations = 0;
                }
                self.updates_seen = updates;
                if self.quiet_rotations >= LOST_AFTER_ROTATIONS {
                    self.lose_fix(ekf, time_s - first);
                }
            }
            Phase::Searching { since, .. } => {
                *since += 1;
                if let Some(o) = self.worker.poll(time_s) {
                    if let Some(attempt) = carried(o, self.frame, &self.restarts) {
                        self.on_attempt(attempt, ekf, time_s - first);
                        if matches!(self.phase, Phase::Tracking) {
                            self.note_swaps();
                            return;
                        }
                    }
                }
                let Phase::Searching {
                    last,
                    since,
                    driven_m,
                    counted_to,
                    previous,
                } = &mut self.phase
                else {
                    return;
                };
                trim_local_map(ekf, SEARCH_KEEP_M);
                let pose = ekf.pose();
                if let Some(p) = counted_to.replace(pose) {
                    *driven_m += (pose.x - p.x).hypot(pose.y - p.y);
                }
                if *driven_m >= SEARCH_WINDOW_M {
                    // A new local frame at the vehicle: the search's uncertainty in its own
                    // frame stays that of one window; the previous window's features are
                    // kept, moved into the new frame.
                    let closed = ekf.start_submap();
                    if let Some(b) = self.scans.as_mut() {
                        b.reframe(&closed.end_pose);
                    }
                    *previous = Some(Box::new(reframed(&closed)));
                    self.worker.reframe(closed.end_pose);
                    push_restart(&mut self.restarts, &mut self.frame, Some(closed.end_pose));
                    *driven_m = 0.0;
                    *counted_to = Some(ekf.pose());
                    *last = Some(ekf.pose());
                    return;
                }
                let due = last
                    .is_none_or(|p| (p.x - pose.x).hypot(p.y - pose.y) >= ATTEMPT_EVERY_M)
                    || *since >= ATTEMPT_EVERY_ROTATIONS;
                if !due || self.worker.busy() {
                    return;
                }
                let query = match self.scans.as_ref() {
                    Some(b) if b.kept.len() < 2 => return,
                    Some(b) => Query::Scans(b.kept.iter().cloned().collect()),
                    None => {
                        let mut local = FrozenSubmap::from_state(ekf.state());
                        if let Some(prev) = previous.as_ref() {
                            local.features.extend(prev.features.iter().copied());
                        }
                        Query::Features(local)
                    }
                };
                if self.worker.submit(self.frame, query, pose, time_s) {
                    *last = Some(pose);
                    *since = 0;
                    self.summary.attempts += 1;
                }
            }
        }
        self.note_swaps();
    }

    /// Tracking by scans, once a rotation: the tracker predicts by the local filter's
    /// motion and registers the rotation's cloud against the map; the local filter's map
    /// stays bounded (trimmed, its frame restarted every [`SEARCH_WINDOW_M`]).
    fn track_scans(&mut self, ekf: &mut DaemonEkf, cloud: Option<&[[f64; 2]]>, since_start_s: f64) {
        let Some(b) = self.scans.as_mut() else {
            return;
        };
        let Some(t) = b.tracker.as_mut() else {
            return;
        };
        t.predict(&ekf.pose());
        let update = match cloud {
            Some(c) => t.update(&b.map, c),
            None => t.skip(),
        };
        let (pose, cov) = t.estimate();
        tracing::debug!(
            ?update,
            x_m = pose.x,
            y_m = pose.y,
            heading_rad = pose.theta,
            sigma_x_m = cov[(0, 0)].max(0.0).sqrt(),
            sigma_y_m = cov[(1, 1)].max(0.0).sqrt(),
            "tracking by scans"
        );
        self.summary.published += 1;
        // Counted over every fix of the run (a tracker lives from a fix to its loss).
        match update {
            Update::Fused { .. } => self.summary.track_fused += 1,
            Update::NoRegistration | Update::PoorFit { .. } => self.summary.track_unregistered += 1,
            Update::Gated { .. } => self.summary.track_gated += 1,
            Update::Reanchored { .. } => {
                self.summary.track_gated += 1;
                self.summary.track_reanchored += 1;
            }
        }
        let lost = t.lost();
        trim_local_map(ekf, SEARCH_KEEP_M);
        let pose = ekf.pose();
        if let Some(p) = b.counted_to.replace(pose) {
            b.driven_m += (pose.x - p.x).hypot(pose.y - p.y);
        }
        if b.driven_m >= SEARCH_WINDOW_M {
            let closed = ekf.start_submap();
            b.reframe(&closed.end_pose);
            b.driven_m = 0.0;
            b.counted_to = Some(ekf.pose());
            self.worker.reframe(closed.end_pose);
            push_restart(&mut self.restarts, &mut self.frame, Some(closed.end_pose));
        }
        if lost {
            self.summary.lost += 1;
            warn!(
                file = %self.path.display(),
                after_s = since_start_s,
                "localisation lost: the rotations no longer register against the map's scans (off the map, or a wrong fix); no pose is published, searching again"
            );
            if let Some(b) = self.scans.as_mut() {
                b.tracker = None;
            }
            self.worker.forget();
            push_restart(&mut self.restarts, &mut self.frame, None);
            self.phase = Phase::searching();
        }
    }

    fn note_swaps(&mut self) {
        self.summary.inserted = self.loaded.inserted;
        self.summary.removed = self.loaded.removed;
        self.summary.refused = self.loaded.refused;
        let mut ms: Vec<f64> = self.worker.wall_s.iter().map(|s| s * 1e3).collect();
        if !ms.is_empty() {
            ms.sort_by(f64::total_cmp);
            self.summary.search_ms_p50 = ms[ms.len() / 2];
            self.summary.search_ms_max = ms[ms.len() - 1];
        }
    }

    /// No map feature seen for [`LOST_AFTER_ROTATIONS`]: the fix is dropped, nothing more
    /// is published in the map's frame, and the search starts again in a frame of its own.
    fn lose_fix(&mut self, ekf: &mut DaemonEkf, since_start_s: f64) {
        self.summary.lost += 1;
        warn!(
            file = %self.path.display(),
            after_s = since_start_s,
            rotations = self.quiet_rotations,
            "localisation lost: no feature of the map seen for a while (off the map, or a wrong fix); no pose is published, searching again"
        );
        let fresh = Ekf::new(
            self.searching.clone(),
            Pose2::new(0.0, 0.0, 0.0),
            Matrix3::zeros(),
            ekf.state().time_s(),
            self.motion,
            self.observer,
        )
        .and_then(|mut e| {
            if let Some(held) = ekf.held_odometry() {
                e.apply_odometry(held)?;
            }
            Ok(e)
        });
        match fresh {
            Ok(e) => *ekf = e,
            Err(e) => warn!(error = %e, "the search filter could not start"),
        }
        self.loaded.clear();
        self.quiet_rotations = 0;
        self.updates_seen = 0;
        self.worker.forget();
        push_restart(&mut self.restarts, &mut self.frame, None);
        self.phase = Phase::searching();
    }

    fn on_attempt(&mut self, attempt: Attempt, ekf: &mut DaemonEkf, since_start_s: f64) {
        let n = self.summary.attempts;
        match attempt {
            Attempt::Fix(v) => {
                let local = ekf.pose();
                let pose = slam_graph::se2::compose(&v.transform, &local);
                let cov =
                    compose_covariance(&v.transform, &v.covariance, &local, &ekf.pose_covariance());
                if self.start_tracking(pose, cov, ekf, since_start_s) {
                    info!(
                        file = %self.path.display(),
                        after_s = since_start_s,
                        x_m = pose.x,
                        y_m = pose.y,
                        heading_rad = wrap_angle(pose.theta),
                        matches = v.matches,
                        "localised in the map: publishing the pose in the map's frame"
                    );
                }
            }
            Attempt::Candidate(v) => info!(
                matches = v.matches,
                "a place of the map verified: confirming at the next attempt"
            ),
            Attempt::Ambiguous(k) => {
                self.summary.ambiguous += 1;
                if worth_logging(self.summary.ambiguous) {
                    info!(
                        places = k,
                        "places of the map alike verified: waiting until the map tells them apart"
                    );
                }
            }
            Attempt::TooFewFeatures | Attempt::NothingVerified { .. } => {
                if worth_logging(n) {
                    let why = match attempt {
                        Attempt::TooFewFeatures => {
                            "too few features around the vehicle yet".to_owned()
                        }
                        Attempt::NothingVerified {
                            best_distance: Some(d),
                        } => format!(
                            "no place of the map verified (nearest descriptor distance {d:.2})"
                        ),
                        _ => "no place of the map resembles this one".to_owned(),
                    };
                    warn!(
                        file = %self.path.display(),
                        attempts = n,
                        after_s = since_start_s,
                        "not localised in the map yet: {why}; no pose is published, still trying"
                    );
                }
            }
        }
    }

    /// Whether the run tracks by the map's scans (else by its features).
    pub fn tracks_by_scans(&self) -> bool {
        self.scans.is_some()
    }

    /// The pose in the map's frame and its covariance against the map where the vehicle
    /// is (the scan tracker's, or the filter's against the map's features), without what
    /// the map adds of its own; `None` before the fix. Extend mode joins the new drive
    /// there.
    pub fn map_estimate(&self, ekf: &DaemonEkf) -> Option<(Pose2, Matrix3<f64>)> {
        if !self.has_fix() {
            return None;
        }
        match self.scans.as_ref() {
            Some(b) => b.tracker.as_ref().map(|t| t.estimate()),
            None => Some((ekf.pose(), ekf.pose_covariance())),
        }
    }

    /// The pose to publish in the map's frame and its covariance ([`Self::map_estimate`]
    /// plus what the map adds of its own there); `None` before the fix.
    pub fn published(&self, ekf: &DaemonEkf) -> Option<(Pose2, Matrix3<f64>)> {
        let (pose, cov) = self.map_estimate(ekf)?;
        // What the map adds of its own where the vehicle is. By scans: where it disagrees
        // with itself (its passes over the same streets apart: the map's frame is itself
        // uncertain by that much); the map's own error against the world is the map's,
        // reported with it, not added here. By features: the nearest submap frame's.
        let shared = match self.scans.as_ref() {
            Some(b) => b.map.disagreement.at([pose.x, pose.y]),
            None => self.features.frame_covariance_at(&pose),
        };
        let cov = cov + shared;
        Some((pose, 0.5 * (cov + cov.transpose())))
    }

    /// The summary, scored against `online` (each published pose with the true pose).
    pub fn summary(&self, online: &[(crate::output::PoseSample, Pose2)]) -> LocaliseSummary {
        let mut s = self.summary.clone();
        s.score = score::score(online);
        s
    }
}

/// The search's local frame restarts (`origin`: the new frame's origin in the old one;
/// `None`: a new search).
/// `pose` in local frame `from` carried into frame `to` through the restarts between
/// (each new frame's origin in the old); `None` when a new search began in between or the
/// restarts are no longer known.
fn carry(
    mut pose: Pose2,
    from: u64,
    to: u64,
    restarts: &VecDeque<(u64, Option<Pose2>)>,
) -> Option<Pose2> {
    for k in from..to {
        let (_, origin) = restarts.iter().find(|(f, _)| *f == k)?;
        pose = slam_graph::se2::compose(&slam_graph::se2::inverse(&(*origin)?), &pose);
    }
    Some(pose)
}

fn push_restart(
    restarts: &mut VecDeque<(u64, Option<Pose2>)>,
    frame: &mut u64,
    origin: Option<Pose2>,
) {
    restarts.push_back((*frame, origin));
    while restarts.len() > MAX_RESTARTS_KEPT {
        restarts.pop_front();
    }
    *frame += 1;
}

/// A search outcome made in local frame `o.frame`, carried into `current` through the
/// frame restarts since (a fix's transform composed with each new frame's origin); `None`
/// when a new search began in between or the restarts are no longer known.
fn carried(o: Outcome, current: u64, restarts: &VecDeque<(u64, Option<Pose2>)>) -> Option<Attempt> {
    let mut attempt = o.attempt;
    for k in o.frame..current {
        let (_, origin) = restarts.iter().find(|(f, _)| *f == k)?;
        let origin = (*origin)?;
        if let Attempt::Fix(v) | Attempt::Candidate(v) = &mut attempt {
            v.covariance =
                compose_covariance(&v.transform, &v.covariance, &origin, &Matrix3::zeros());
            v.transform = slam_graph::se2::compose(&v.transform, &origin);
        }
    }
    Some(attempt)
}

/// A closed local frame's features in the next frame (the one starting at its end pose):
/// positions moved, covariances turned.
fn reframed(closed: &FrozenSubmap) -> FrozenSubmap {
    let back = slam_graph::se2::inverse(&closed.end_pose);
    let r = slam_graph::se2::rotation(back.theta);
    FrozenSubmap {
        end_pose: Pose2::new(0.0, 0.0, 0.0),
        end_cov: Matrix3::zeros(),
        features: closed
            .features
            .iter()
            .map(|f| slam_filter::SubmapFeature {
                xy: slam_graph::se2::transform_point(&back, f.xy),
                xy_cov: r * f.xy_cov * r.transpose(),
                ..*f
            })
            .collect(),
        loss_db: closed.loss_db,
        end_s: closed.end_s,
    }
}

/// Takes out of the searching filter the features further than `keep_m` from the vehicle
/// (the local map stays bounded however long the search).
fn trim_local_map(ekf: &mut DaemonEkf, keep_m: f64) {
    let pose = ekf.pose();
    let far: Vec<slam_filter::FeatureId> = ekf
        .features()
        .into_iter()
        .filter(|f| (f.x_m - pose.x).hypot(f.y_m - pose.y) > keep_m)
        .map(|f| f.id)
        .collect();
    for id in far {
        let _ = ekf.remove_feature(id);
    }
}
