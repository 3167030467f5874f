//! Prints the straight-ahead spectrum of the paper's penetration scenes (its fig. 2): the
//! sheet at 8.5 m and the 177 m^2 reflector at 14 m behind it, expected (noise-free) and one
//! noisy look, with the floor around them.
//!
//! Run: `cargo run --release -p sim-sensor --example penetration`

use std::sync::Arc;

use bytes::BytesMut;
use protocol::Timestamp;
use sim_sensor::render::SceneRenderer;
use sim_sensor::scene::shipped;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    for name in ["penetration-wood", "penetration-perspex"] {
        for noisy in [false, true] {
            let mut scene = shipped::load(name)?;
            scene.noise.enabled = noisy;
            scene.noise.bearing_sigma_deg = 0.0; // keep both targets in azimuth 0
            let renderer = Arc::new(SceneRenderer::new(&scene, None, 10.0)?);
            let mut cursor = renderer.cursor();
            let mut frame = BytesMut::new();
            cursor.render(0, 0, Timestamp::EPOCH, &mut frame)?;
            let db = cursor.last_power_db();
            let peak = |lo: usize, hi: usize| db[lo..=hi].iter().copied().fold(f64::MIN, f64::max);
            let mut floor: Vec<f64> = db[80..200].to_vec();
            floor.sort_by(f64::total_cmp);
            println!(
                "{name:20} {:9} sheet (8.5 m, bin 34) {:6.1} dB  reflector (14 m, bin 56) {:6.1} dB  floor 20-50 m median {:5.1} dB",
                if noisy { "one look" } else { "expected" },
                peak(32, 36),
                peak(54, 58),
                floor[floor.len() / 2]
            );
        }
    }
    Ok(())
}
