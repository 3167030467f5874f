//! Rendering rate of the realistic city on one core: whole rotations (the CTS350-X-like
//! unit, 400 azimuths x 3768 bins, 4 Hz) rendered at places spread over the whole drive,
//! with the rotations a second and the real-time factor (rotations a second / 4 Hz) printed.
//! Target: at least 10x real time (a rotation in at most 25 ms).
//!
//! ```sh
//! cargo bench -p sim-sensor --bench city_render [-- [SCENE_FILE] [ROTATIONS]]
//! ```
//!
//! SCENE_FILE (relative to the workspace root) defaults to
//! `sim-sensor/scenes/realistic-city.toml`, ROTATIONS to 64: groups of 4 consecutive
//! rotations at 16 places evenly spaced in time over the drive. A plain release binary (no criterion): one pass, the
//! figures of each rotation timed on their own, so the median and the slowest are shown too.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use bytes::BytesMut;
use protocol::Timestamp;
use sim_sensor::render::SceneRenderer;
use sim_sensor::scene::Scene;

/// Consecutive rotations rendered at each place.
const GROUP: u64 = 4;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // `cargo bench` passes `--bench`; anything starting with `--` is not ours.
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    // `cargo bench` runs in the package's folder: a relative path that is not there is
    // taken from the workspace root.
    let path = args.first().map_or_else(
        || root.join("sim-sensor/scenes/realistic-city.toml"),
        |a| {
            let p = PathBuf::from(a);
            if p.is_relative() && !p.exists() {
                root.join(p)
            } else {
                p
            }
        },
    );
    let rotations: u64 = args.get(1).map_or(Ok(64), |s| s.parse())?.max(GROUP);
    let scene = Scene::load(&path)?;
    let drive_s = scene.city.as_ref().map_or(20.0, |c| c.drive_duration_s);
    let built = Instant::now();
    let renderer = Arc::new(SceneRenderer::new(&scene, None, drive_s + 5.0)?);
    let build_s = built.elapsed().as_secs_f64();
    let scatterers = renderer.realistic().map_or(0, |m| m.world.scatterers.len());
    let n = u64::from(scene.radar.azimuths);
    let hz = scene.radar.rotation_hz();
    let groups = rotations / GROUP;
    let last_rotation = ((drive_s * hz) as u64).saturating_sub(GROUP + 1).max(1);
    let mut cursor = renderer.cursor();
    let mut frame = BytesMut::new();
    let mut times_ms = Vec::new();
    let mut deposits = 0usize;
    let started = Instant::now();
    for g in 0..groups {
        let first = 1 + last_rotation * g / groups.max(1);
        for rot in first..first + GROUP {
            let t0 = Instant::now();
            for k in rot * n..(rot + 1) * n {
                frame.clear();
                deposits += cursor.render(k, 0, Timestamp::EPOCH, &mut frame)?.targets;
            }
            times_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        }
    }
    let total_s = started.elapsed().as_secs_f64();
    let done = times_ms.len();
    times_ms.sort_by(f64::total_cmp);
    let per_s = done as f64 / total_s;
    println!(
        "{}: {scatterers} scatterers (world built in {build_s:.2} s), {done} rotations at {groups} places over the {drive_s:.0} s drive",
        scene.name
    );
    println!(
        "{:.1} ms a rotation (median {:.1}, slowest {:.1}), {per_s:.1} rotations/s, real-time factor {:.1}x at {hz} Hz (target 10x), {:.0} deposits an azimuth",
        1e3 * total_s / done as f64,
        times_ms[done / 2],
        times_ms[done - 1],
        per_s / hz,
        deposits as f64 / (done as u64 * n) as f64
    );
    Ok(())
}
