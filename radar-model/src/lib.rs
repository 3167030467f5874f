//! The paper's power-range physics. No IO, no clock.
