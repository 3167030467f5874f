//! The saved map (slam-map's `.slmap`) as the pipeline builds it: the frozen submaps with
//! their frames in the world, the current submap as it stands, the loop closures and the
//! radar the run used. Built at the end of the run, every `[map] save_every_s` of the
//! run's clock, and when asked ([`request_save`], SIGUSR1); the writer thread writes it,
//! atomically. No IO here besides reading the
//! wall clock for the map's creation time.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use nalgebra::Matrix3;
use radar_model::geometry::Pose2;
use serde::Serialize;
use slam_filter::FrozenSubmap;
use slam_graph::LoopClosure;
use slam_map::{Map, MapMeta, MapProfile};
use tracing::warn;

use super::ekf::DaemonEkf;
pub use super::map_save::MapSaveSettings;
use super::submaps::SubmapRun;

/// A save asked for from outside the pipeline (SIGUSR1), for the process's pipeline.
static SAVE_REQUESTED: AtomicBool = AtomicBool::new(false);

/// Asks the process's pipeline to save its map after the rotation it is in (the daemon's
/// SIGUSR1 handler calls it), whatever `[map] save` says.
pub fn request_save() {
    SAVE_REQUESTED.store(true, Ordering::Relaxed);
}

/// Whether a save was asked for since the last call.
pub(crate) fn take_save_request() -> bool {
    SAVE_REQUESTED.swap(false, Ordering::Relaxed)
}

/// What went into the last saved map.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct SavedMapCounts {
    /// Submaps (the current one included).
    pub submaps: usize,
    /// Features.
    pub features: usize,
    /// Loop closures.
    pub loops: usize,
    /// Drives (more than one when the run extended a saved map) and their joins.
    pub drives: usize,
    /// Joins.
    pub joins: usize,
    /// Submaps whose scan the map keeps, and the scans' points.
    pub scans: usize,
    /// Scan points.
    pub scan_points: usize,
    /// Features left out for a value that is not finite.
    pub dropped_features: usize,
    /// The longest time building a saved map took on the pipeline thread over the run (ms;
    /// the writer thread encodes and writes it).
    pub max_build_ms: f64,
}

/// The radar's geometry as it announced it, under the profile's name.
fn map_profile(name: &str, geometry: Option<&protocol::Geometry>) -> Option<MapProfile> {
    let a = super::derive::announced(geometry?);
    Some(MapProfile {
        name: name.to_owned(),
        azimuths: a.azimuths,
        encoder_size: a.encoder_size,
        range_bins: a.range_bins,
        bin_size_m: a.bin_size_m,
    })
}

/// The saved map of the run so far: with submaps, the frozen ones through their frames and
/// the current one (`FrozenSubmap::from_state`: its end pose is the vehicle's pose now);
/// without, the dense map as submap 0. `loops` replaces the loop closures the submap stage
/// gathered (the finished global layer's, at the end of the run). `None` (logged) before
/// the radar's geometry is known or when the map breaks the format's rules.
pub fn build(
    settings: &MapSaveSettings,
    geometry: Option<&protocol::Geometry>,
    ekf: &DaemonEkf,
    submaps: Option<&SubmapRun>,
    loops: Option<&[LoopClosure]>,
    source: String,
) -> Option<(Map, SavedMapCounts)> {
    let profile = map_profile(&settings.profile, geometry)?;
    let current = FrozenSubmap::from_state(ekf.state());
    let origin = (Pose2::new(0.0, 0.0, 0.0), Matrix3::zeros());
    let meta = MapMeta {
        profile,
        source,
        created_unix_s: SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_secs()),
    };
    let built = match submaps {
        Some(run) => {
            let p = run.parts();
            let frame = |k: usize| {
                (
                    p.frames.get(k).copied().unwrap_or(origin.0),
                    p.frame_covs.get(k).copied().unwrap_or(origin.1),
                )
            };
            let parts = p
                .frozen
                .iter()
                .map(|s| s.as_ref())
                .chain(std::iter::once(&current))
                .enumerate()
                .map(|(k, s)| {
                    let (f, c) = frame(k);
                    (s, f, c)
                });
            let drives = slam_map::Drives {
                starts: p.drive_starts.to_vec(),
                joins: p.joins.to_vec(),
            };
            Map::from_drives(meta, parts, loops.unwrap_or(p.loops), &drives).and_then(
                |(map, report)| {
                    let scans = p
                        .scans
                        .iter()
                        .enumerate()
                        .filter_map(|(k, s)| s.as_deref().map(|v| (k, &v[..])));
                    let paths = run.paths();
                    let paths = paths.iter().map(|v| &v[..]).enumerate();
                    Ok((map.with_scans(scans)?.with_paths(paths)?, report))
                },
            )
        }
        None => Map::from_parts(meta, std::iter::once((&current, origin.0, origin.1)), &[]),
    };
    match built {
        Ok((map, report)) => {
            if report.dropped_features > 0 || report.dropped_loops > 0 {
                warn!(
                    features = report.dropped_features,
                    loops = report.dropped_loops,
                    "values that are not finite were left out of the saved map"
                );
            }
            let counts = SavedMapCounts {
                submaps: map.submaps.len(),
                features: map.feature_count(),
                loops: map.loops.len(),
                drives: map.drive_starts.len() + 1,
                joins: map.joins.len(),
                scans: map.scans.len(),
                scan_points: map.scan_point_count(),
                dropped_features: report.dropped_features,
                max_build_ms: 0.0,
            };
            Some((map, counts))
        }
        Err(e) => {
            warn!(error = %e, "the saved map could not be built");
            None
        }
    }
}
