//! Extend mode (`[map] mode = "extend"`, `--map FILE`): the run localises in a saved map as
//! localise mode does (no pose in the map's frame before the fix), tracks in it for
//! [`TRACK_BEFORE_MAPPING`] rotations, then maps on: the tracking filter's pose and its
//! covariance against the map's features there become the join of a new drive to the
//! nearest saved submap, the global layer is resumed from the saved graph
//! ([`slam_graph::GlobalMap::resume`]) with the saved submaps as its first nodes, and the
//! filter starts the new drive's first submap at the vehicle. From then on the run is a
//! mapping run whose frames are the map's: new submaps join the saved graph, the layer's
//! loop-closure search offers the saved submaps to the verifier, and the map saved is the
//! merged one (`slam_map::Map::drive_starts`, `joins`).
//!
//! Before the fix nothing is mapped into the merged map: the search's own local map is
//! thrown away at the fix (it is by construction the part of the drive the saved map
//! already holds, or the drive before it reached the map).
//!
//! No IO.

use std::sync::Arc;

use nalgebra::Matrix3;
use radar_model::geometry::Pose2;
use serde::Serialize;
use slam_filter::{Ekf, FilterError};
use slam_graph::{GlobalMap, LoopClosure, ResumeError, SavedGraph};
use slam_map::model::unpack3;
use slam_map::Map;
use tracing::{info, warn};

use super::localise::Localiser;
use super::settings::{PipelineSettings, SubmapOptions};
use super::submaps::{Resumed, SubmapRun};
use super::DaemonEkf;

/// Rotations tracked in the map after the fix before mapping starts: the join is the
/// tracking filter's pose once it has used the map's features for a while, not the
/// search's first estimate.
pub const TRACK_BEFORE_MAPPING: u64 = 8;

/// Why mapping could not start at the fix.
#[derive(Debug, thiserror::Error)]
pub enum ExtendError {
    /// The saved graph and the join do not make a graph.
    #[error("the saved map's graph cannot be extended: {0}")]
    Resume(#[from] ResumeError),
    /// No pose in the map's frame to join at.
    #[error("no fix in the map to join the new drive at")]
    NoFix,
    /// The pose is not near any saved submap (a map without submaps).
    #[error("no saved submap to join the new drive to")]
    NoSubmap,
    /// The global layer's thread could not start.
    #[error("the global layer's thread could not start: {0}")]
    Thread(#[source] std::io::Error),
    /// The mapping filter could not start.
    #[error("the mapping filter could not start: {0}")]
    Filter(#[from] FilterError),
}

/// What extending did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ExtendSummary {
    /// The saved map's submaps, loop closures and drives.
    pub saved_submaps: usize,
    /// Loop closures.
    pub saved_loops: usize,
    /// Drives.
    pub saved_drives: usize,
    /// Stream time from the first rotation to the start of mapping (s); `None`: never.
    pub mapping_after_s: Option<f64>,
    /// The saved submap the new drive was joined to.
    pub joined_to: Option<usize>,
    /// The join: the new drive's first frame in that submap's frame `[x m, y m, rad]`.
    pub join: Option<[f64; 3]>,
    /// Its standard deviations.
    pub join_sigma: Option<[f64; 3]>,
    /// Why mapping could not start, when it could not.
    pub error: Option<String>,
}

/// The extend stage: waits for the localiser's fix, then starts the mapping.
#[derive(Debug)]
pub struct Extension {
    options: SubmapOptions,
    map: Arc<Map>,
    mapping: bool,
    failed: bool,
    summary: ExtendSummary,
}

impl Extension {
    /// For `map`, mapping with `options` once localised.
    pub fn new(options: SubmapOptions, map: Arc<Map>) -> Self {
        let summary = ExtendSummary {
            saved_submaps: map.submaps.len(),
            saved_loops: map.loops.len(),
            saved_drives: map.drive_starts.len() + 1,
            ..ExtendSummary::default()
        };
        Self {
            options,
            map,
            mapping: false,
            failed: false,
            summary,
        }
    }

    /// Whether the run maps (after the fix).
    pub fn mapping(&self) -> bool {
        self.mapping
    }

    /// Whether mapping should start now.
    pub fn due(&self, l: &Localiser) -> bool {
        !self.mapping && !self.failed && l.tracked_rotations() >= TRACK_BEFORE_MAPPING
    }

    /// The summary.
    pub fn summary(&self) -> &ExtendSummary {
        &self.summary
    }

    /// Starts mapping at the tracking filter's pose: the join, the resumed global layer and
    /// a mapping filter at the new drive's first frame (which replaces `ekf`). On an error
    /// the run goes on localising (logged; nothing is saved).
    pub fn start(
        &mut self,
        l: &Localiser,
        ekf: &mut DaemonEkf,
        settings: &PipelineSettings,
        since_start_s: f64,
    ) -> Option<SubmapRun> {
        match self.try_start(l, ekf, settings) {
            Ok((run, new_ekf)) => {
                *ekf = new_ekf;
                self.mapping = true;
                self.summary.mapping_after_s = Some(since_start_s);
                info!(
                    after_s = since_start_s,
                    joined_to = self.summary.joined_to,
                    saved_submaps = self.summary.saved_submaps,
                    "extending the map: mapping from here in the map's frame, new submaps joined to its graph"
                );
                Some(run)
            }
            Err(e) => {
                self.failed = true;
                self.summary.error = Some(e.to_string());
                warn!(error = %e, "extending the map could not start: localising only, nothing is saved");
                None
            }
        }
    }

    fn try_start(
        &mut self,
        l: &Localiser,
        ekf: &DaemonEkf,
        settings: &PipelineSettings,
    ) -> Result<(SubmapRun, DaemonEkf), ExtendError> {
        // By scans the filter carries only the motion in a frame of its own: the pose in
        // the map is the scan tracker's.
        let (pose, cov) = l.map_estimate(ekf).ok_or(ExtendError::NoFix)?;
        let (from, transform, covariance) = l
            .map_features()
            .in_nearest_submap(&pose, &cov)
            .ok_or(ExtendError::NoSubmap)?;
        let join = LoopClosure {
            from,
            to: 0,
            transform,
            covariance,
            // What the join rests on: the map features the tracking filter holds, or by
            // scans the rotations registered against the map since the fix.
            matches: if l.tracks_by_scans() {
                usize::try_from(l.tracked_rotations()).unwrap_or(usize::MAX)
            } else {
                ekf.feature_count()
            },
            nis: 0.0,
            dof: 3,
            rival_matches: 0,
            from_place: false,
        };
        let map = &self.map;
        let n = map.submaps.len();
        let frozen: Vec<Arc<slam_filter::FrozenSubmap>> =
            map.frozen_submaps().into_iter().map(Arc::new).collect();
        // The saved scans, read from the file's 32-bit points once: the layer's copy and
        // the stage's (for the merged map) share them.
        let scans: Vec<Option<Arc<Vec<[f64; 2]>>>> =
            (0..n).map(|k| map.scan_points(k).map(Arc::new)).collect();
        let saved = SavedGraph {
            submaps: frozen.clone(),
            frames: map.submaps.iter().map(|s| s.frame_pose()).collect(),
            covariances: map.submaps.iter().map(|s| unpack3(&s.frame_cov)).collect(),
            drives: (0..n).map(|k| map.drive_of(k)).collect(),
            loops: map.loop_closures(),
            joins: map.join_closures(),
            scans: scans.iter().map(|s| s.as_deref().cloned()).collect(),
        };
        let layer = GlobalMap::resume(self.options.global, saved, join)?;
        let sol = layer.solution(0.0);
        let frames: Vec<(Pose2, Matrix3<f64>)> = sol
            .frames
            .iter()
            .copied()
            .zip(sol.covariances.iter().copied())
            .collect();
        let mut drive_starts: Vec<usize> = map.drive_starts.iter().map(|&s| s as usize).collect();
        drive_starts.push(n);
        let run = SubmapRun::resumed(
            self.options,
            Resumed {
                layer,
                frozen,
                frames,
                drive_starts,
                scans,
                paths: (0..n)
                    .map(|k| map.path_points(k).unwrap_or_default())
                    .collect(),
            },
        )
        .map_err(ExtendError::Thread)?;
        // The mapping filter adds features whatever the localising one did (by the map's
        // scans the local filter maps none).
        let mut fresh = Ekf::new(
            slam_filter::FilterSettings {
                add_features: true,
                ..settings.filter.clone()
            },
            Pose2::new(0.0, 0.0, 0.0),
            Matrix3::zeros(),
            ekf.state().time_s(),
            settings.motion,
            slam_filter::RadarBeamModel {
                power: settings.power,
            },
        )?;
        if let Some(held) = ekf.held_odometry() {
            fresh.apply_odometry(held)?;
        }
        // The new drive's features are numbered past the saved map's: ids stay unique.
        let next = map
            .submaps
            .iter()
            .flat_map(|s| s.features.iter().map(|f| f.id))
            .max()
            .map_or(0, |m| m.saturating_add(1));
        fresh.number_features_from(next);
        let sd = |v: f64| v.max(0.0).sqrt();
        self.summary.joined_to = Some(from);
        self.summary.join = Some([transform.x, transform.y, transform.theta]);
        self.summary.join_sigma = Some([
            sd(covariance[(0, 0)]),
            sd(covariance[(1, 1)]),
            sd(covariance[(2, 2)]),
        ]);
        Ok((run, fresh))
    }
}
