//! Detection, association, the augmented-state EKF, map management and outputs; the daemon.
//!
//! - [`detect`]: every target down each beam (CA/OS-CFAR, TPP), peaks, grouping across
//!   azimuths. No IO.
//! - [`filter`]: the augmented-state EKF. No IO, no clock.
//! - [`pipeline`]: per-azimuth processing at each azimuth's own time, spectrum
//!   prediction vs measurement, truth scoring ([`pipeline::core`] does no IO; its thread
//!   loop [`pipeline::run`] reads channels).
//! - [`output`]: trajectory, map, diagnostics, figures; the writer thread writes files.
//! - [`daemon`]: driver, odometry, simulator, pipeline and writer wired together (sockets,
//!   threads).
//!
//! IO happens only in `daemon`, `pipeline::run` (channels) and `output::writer` (files).

pub mod daemon;
pub mod detect;
pub mod output;
pub mod pipeline;
