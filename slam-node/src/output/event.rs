//! What the pipeline hands the writer (and the live outputs): one event per pose, rotation,
//! map snapshot, spectrum pair, input or trajectory. A leaf: it names the outputs' data
//! types and nothing that writes them.

use radar_driver::Azimuth;
use slam_filter::OdometrySample;

use super::detections::RotationDetections;
use super::diagnostics::{RotationDiagnostics, SpectrumComparison};
use super::figures::TruthOverlay;
use super::map::MapSnapshot;
use super::trajectory::PoseSample;

/// Something for the writer.
#[derive(Debug, Clone)]
pub enum OutputEvent {
    /// One trajectory pose.
    Pose(PoseSample),
    /// On submaps, with each pose: the vehicle chained by the filter's motion and the
    /// submaps' switch poses alone, the global layer's corrections left out (the odometry):
    /// written as `trajectory-odometry.tum` and, in the Boreas benchmark's odometry format,
    /// as `odometry-boreas.txt`.
    OdometryPose(PoseSample),
    /// One rotation's diagnostics.
    Rotation(Box<RotationDiagnostics>),
    /// A map snapshot (rewrites the map file).
    Map(MapSnapshot),
    /// A predicted/measured spectrum pair.
    Spectrum(SpectrumComparison),
    /// Ground truth for the final figure.
    Truth(TruthOverlay),
    /// One radar azimuth as received (sent only when a recording wants it).
    Azimuth(Azimuth),
    /// One odometry sample the pipeline received (sent only when a recording wants it).
    Odometry(OdometrySample),
    /// The detections of one rotation that reached the filter.
    Detections(RotationDetections),
    /// The whole trajectory re-expressed with the global layer's final submap frames (end
    /// of a run on submaps): the trajectory file is rewritten with it, and the poses as
    /// published during the run are kept beside it as `<name>-online.<ext>`.
    Trajectory(Vec<PoseSample>),
    /// The saved map (`[map]`, slam-map's file), written atomically over the previous one.
    SavedMap(Box<slam_map::Map>),
}
