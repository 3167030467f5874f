//! The global layer over the filter's local submaps (Jose and Adams' augmented-state EKF,
//! run on bounded pieces of the drive by `slam_filter::submap`).
//!
//! - [`se2`]: rigid transforms of the plane, their Jacobians.
//! - [`graph`]: the pose graph of submap frames; Levenberg-Marquardt with a sparse Cholesky
//!   factorisation (faer) per step; marginal covariances.
//! - [`align`]: loop-closure verification by jointly compatible, unambiguous association of
//!   many features, with their reflectivity and absorption.
//! - [`places`]: loop-closure candidates from place descriptors (radar-odometry's
//!   [`radar_odometry::PlaceDescriptor`]), for returns the pose uncertainty does not reach.
//! - [`resume`]: a layer that goes on from a saved graph, a new drive joined to it (extend
//!   mode).
//! - [`revisits`]: closures scored over every true revisit of a ground truth (recall and
//!   precision).
//! - [`layer`]: [`GlobalMap`] (synchronous, deterministic) and [`GlobalLayer`] (the same on a
//!   thread of its own, never blocking the caller).
//!
//! No IO and no clock besides the solve timings.

pub mod align;
pub mod correlate;
pub mod graph;
pub mod layer;
pub mod places;
pub mod resume;
pub mod revisits;
pub mod scans;
pub mod se2;

pub use align::{align, AlignSettings, Alignment, Refusal};
pub use graph::{Edge, EdgeKind, GraphError, PoseGraph, Solution, SolveSettings};
pub use layer::{
    AddReport, GlobalLayer, GlobalMap, GlobalSettings, GlobalSolution, GlobalStats, LoopClosure,
};
pub use places::{PlaceCandidate, PlaceSearch};
pub use resume::{ResumeError, SavedGraph};
pub use revisits::{score_path_revisits, score_revisits, PathSample, RevisitRule, RevisitScore};
pub use scans::{align_scans, reference_scan, ScanAccumulator, ScanAlignSettings, ScanReference};
