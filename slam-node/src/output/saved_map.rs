//! Writes the saved map (slam-map's `.slmap`, `docs/map-format.md`) on the writer thread:
//! atomically, so a crash mid-write leaves the previous map whole. A failed write is logged
//! and recorded; the other outputs go on.

use std::path::Path;

use slam_map::Map;
use tracing::{info, warn};

use super::summary::WriterSummary;

/// Saves `map` at `path` and records the outcome in `summary`.
pub fn save(map: &Map, path: &Path, summary: &mut WriterSummary) {
    match map.save(path) {
        Ok(bytes) => {
            if summary.saved_maps == 0 {
                summary.files.push(path.to_path_buf());
            }
            summary.saved_maps += 1;
            summary.saved_map_bytes = Some(bytes);
            summary.saved_map_error = None;
            info!(
                path = %path.display(),
                bytes,
                submaps = map.submaps.len(),
                features = map.feature_count(),
                loops = map.loops.len(),
                "map saved"
            );
        }
        Err(e) => {
            warn!(error = %e, "the map could not be saved");
            summary.saved_map_error = Some(e.to_string());
        }
    }
}
