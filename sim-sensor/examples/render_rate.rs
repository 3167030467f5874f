//! Renders whole rotations with the realistic renderer and prints the time per rotation
//! and a checksum of the frames: the plain loop of `benches/realistic.rs`, small enough to
//! run under `valgrind --tool=callgrind --toggle-collect='*RenderCursor*render*'`.
//!
//! ```sh
//! cargo run --release -p sim-sensor --example render_rate -- [grid|SHIPPED|SCENE_FILE] [ROTATIONS]
//! ```
//!
//! `grid` (the default) is the benchmark's 4 x 4-block street grid (117,751 scatterers, 12
//! moving vehicles) from a car at 9 m/s; rotations from the fifth (1 s into the drive).

use std::sync::Arc;
use std::time::Instant;

use bytes::BytesMut;
use protocol::Timestamp;
use sim_sensor::render::SceneRenderer;
use sim_sensor::scene::{shipped, Scene};

/// The benchmark's grid (`benches/realistic.rs`).
const GRID: &str = include_str!("../benches/street-grid-100k.toml");

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let which = args.next().unwrap_or_else(|| "grid".into());
    let rotations: u64 = args.next().map_or(Ok(3), |s| s.parse())?;
    let scene = if which == "grid" {
        Scene::from_toml_str("street-grid-100k", GRID)?
    } else if which.contains('/') || which.contains('.') {
        Scene::load(std::path::Path::new(&which))?
    } else {
        shipped::load(&which)?
    };
    let renderer = Arc::new(SceneRenderer::new(&scene, None, 120.0)?);
    let n = u64::from(scene.radar.azimuths);
    let scatterers = renderer.realistic().map_or(0, |m| m.world.scatterers.len());
    let mut cursor = renderer.cursor();
    let mut frame = BytesMut::new();
    let mut checksum = 0u64;
    let mut deposited = 0usize;
    let started = Instant::now();
    for k in 4 * n..(4 + rotations) * n {
        frame.clear();
        let out = cursor.render(k, 0, Timestamp::EPOCH, &mut frame)?;
        deposited += out.targets;
        checksum = frame.iter().fold(checksum, |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
        });
    }
    let ms = started.elapsed().as_secs_f64() * 1e3 / rotations as f64;
    println!(
        "{which}: {scatterers} scatterers, {rotations} rotations, {ms:.1} ms a rotation, \
         {:.0} deposits an azimuth, frames' checksum {checksum:016x}",
        deposited as f64 / (rotations * n) as f64
    );
    Ok(())
}
