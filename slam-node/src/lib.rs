//! Detection, association, the augmented-state EKF, map management and outputs; the daemon.
//!
//! - [`detect`]: every target down each beam (CA/OS-CFAR, TPP), peaks, grouping across
//!   azimuths. No IO.
//! - [`filter`]: the augmented-state EKF. No IO, no clock.
//! - [`pipeline`]: per-azimuth processing at each azimuth's own time, spectrum
//!   prediction vs measurement, truth scoring ([`pipeline::core`] does no IO; its thread
//!   loop [`pipeline::run`] reads channels).
//! - [`output`]: trajectory, map, diagnostics, figures, MCAP; the writer thread writes
//!   files; with the `zenoh` feature, [`output::live`] publishes ROS 2 messages over Zenoh.
//! - [`daemon`]: driver, odometry, simulator, pipeline and writer wired together (sockets,
//!   threads).
//!
//! IO happens only in `daemon`, `pipeline::run` (channels), `output::writer` (files) and
//! `output::live` (the network, feature `zenoh`).

pub mod daemon;
pub mod detect;
pub mod output;
pub mod pipeline;
pub mod source;
