//! The daemon's outputs: trajectory (TUM), map (JSON), per-rotation diagnostics (JSONL),
//! spectrum comparisons (CSV), SVG figures, and on request an MCAP recording in ROS 2
//! encodings ([`recording`]). The formats are documented in
//! `slam-node/README.md`.
//!
//! The file writers are generic over `std::io::Write`; [`writer`] runs them on their own
//! thread behind a channel so the filter never waits for a disk. The live outputs ([`live`]
//! over Zenoh, [`foxglove`] over Foxglove's WebSocket protocol) take the same events
//! through bounded queues of their own and do network IO on their own threads.

pub mod csv;
pub mod detections;
pub mod diagnostics;
pub mod event;
pub mod figures;
pub mod foxglove;
pub mod live;
pub mod live_error;
pub mod map;
pub mod recording;
pub mod ros;
pub mod saved_map;
pub mod summary;
pub mod trajectory;
pub mod writer;
pub mod zenoh_keys;
#[cfg(feature = "zenoh")]
pub mod zenoh_node;

pub use detections::{Detection, RotationDetections};
pub use diagnostics::{RotationDiagnostics, SpectrumComparison};
pub use event::OutputEvent;
pub use foxglove::{FoxgloveError, FoxgloveOutput, FoxgloveSummary};
pub use live::{LiveError, LiveOutput, LiveSummary};
pub use map::{MapFeature, MapSnapshot};
pub use recording::{McapRecorder, RecordingError, RecordingSummary};
pub use trajectory::{PoseSample, TumWriter};
pub use writer::{OutputFiles, OutputHandle, RecordingFile, WriterError};
