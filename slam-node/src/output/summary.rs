//! What the output writer wrote, shared by the writer and the saved-map step. No IO.

use std::path::PathBuf;

use super::foxglove::FoxgloveSummary;
use super::live::LiveSummary;
use super::recording::RecordingSummary;

/// What the writer wrote.
#[derive(Debug, Clone, Default)]
pub struct WriterSummary {
    /// Poses written.
    pub poses: u64,
    /// Rotations written.
    pub rotations: u64,
    /// Map snapshots written.
    pub maps: u64,
    /// Spectrum comparisons written.
    pub spectra: u64,
    /// Figures drawn.
    pub figures: Vec<PathBuf>,
    /// The data files written.
    pub files: Vec<PathBuf>,
    /// The MCAP recording, when one was made.
    pub recording: Option<RecordingSummary>,
    /// Why the recording stopped early, if it did (the other outputs went on).
    pub recording_error: Option<String>,
    /// The live Zenoh output, when there was one.
    pub live: Option<LiveSummary>,
    /// Saved maps written (`[map]`).
    pub saved_maps: u64,
    /// The last saved map's size (bytes).
    pub saved_map_bytes: Option<u64>,
    /// Why the last saved map could not be written, if it could not (the previous file
    /// stays whole; the other outputs went on).
    pub saved_map_error: Option<String>,
    /// The Foxglove output, when there was one.
    pub foxglove: Option<FoxgloveSummary>,
}
