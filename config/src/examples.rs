//! The shipped example files, compiled in, so binaries can run on shipped settings with no
//! file on disk.

use crate::Preset;

/// `examples/vehicle.toml`: on the vehicle, against a real radar at 192.168.0.1:6317.
pub const VEHICLE: &str = include_str!("../examples/vehicle.toml");
/// `examples/sim.toml`: against the simulator on loopback.
pub const SIM: &str = include_str!("../examples/sim.toml");
/// `examples/test.toml`: integration tests (127.0.0.1:0 binds, as fast as possible).
pub const TEST: &str = include_str!("../examples/test.toml");

/// A preset's text and the name its errors carry.
pub fn text(preset: Preset) -> (&'static str, &'static str) {
    match preset {
        Preset::Vehicle => (VEHICLE, "config/examples/vehicle.toml"),
        Preset::Sim => (SIM, "config/examples/sim.toml"),
        Preset::Test => (TEST, "config/examples/test.toml"),
    }
}
