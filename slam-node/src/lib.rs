//! Detection, association, the augmented-state EKF, map management and outputs; the daemon.

pub mod angles;
pub mod daemon;
pub mod detect;
pub mod filter;
pub mod output;
pub mod pipeline;
pub mod synth;
