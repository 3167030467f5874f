//! Detection, association, the augmented-state EKF, map management and outputs; the daemon.

pub mod filter;
