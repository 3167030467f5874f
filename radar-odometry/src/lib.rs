//! Radar odometry, without IO: a spinning radar's returns, one azimuth at a time, placed in
//! the vehicle's frame; each rotation's cloud registered against the previous rotation's by
//! robust point-to-line ICP (then, where [`ScanMatchSettings::soft_kernel_m`] asks, once more
//! without hard pairs: [`register_soft`]); the motion between the two with a covariance that
//! grows along any direction the scene does not pin (an open field, a long bare wall), so that a filter
//! driven by it grows its uncertainty there instead of being confidently wrong.
//!
//! The pieces stand alone: [`register`] two clouds you already have; [`ScanMatcher`] for a
//! stream of azimuths; [`KStrongest`] to take returns from raw power profiles when you have
//! no detector. `cargo run --release -p radar-odometry --example register_two_scans` registers
//! two recorded Oxford scans. [`place`] describes a place (the points around it) for loop
//! closure without a pose prior. slam-node's pipeline uses it to measure motion for the filter
//! and, with `[odometry] source = "none"`, to drive the filter's prediction on the radar alone.
//!
//! No IO, no clock, no threads: time and motion estimates come in as arguments.

pub mod cloud;
pub mod extract;
pub mod grid;
pub mod matcher;
pub mod place;
pub mod register;

pub use cloud::ReferenceCloud;
pub use extract::KStrongest;
pub use grid::PointGrid;
pub use matcher::{
    MatcherCounts, RadarReturn, Return, RotationEnd, RotationMotion, ScanMatchSettings,
    ScanMatcher, MAX_POINTS,
};
pub use place::{
    PlaceDescriptor, PlaceError, PlaceIndex, PlaceMatch, PlaceQuery, PlaceSettings, QueryMatch,
};
pub use register::{
    covariance, in_frame_of, register, register_soft, Constraint, Registration, HEADING_LENGTH_M,
};
