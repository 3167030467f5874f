//! Replaying recordings over the protocol: Oxford/Boreas polar PNG scans ([`png`]) and raw
//! Colossus byte streams ([`raw`]). Both keep the recording's own encoder values and
//! timestamps.

pub mod png;
pub mod raw;
pub mod truth;
