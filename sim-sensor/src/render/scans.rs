//! Whole rotations rendered into polar scans ([`Scans`], the 8-bit wire's values), for the
//! realism statistics and the evaluations that compare simulated scans with real ones.
//! IO: none.

use std::sync::Arc;

use super::SceneRenderer;
use crate::error::SimError;
use crate::realism::stats::Scans;
use crate::scene::Scene;

/// Renders `rotations` whole rotations of `scene` from rotation `first` (seed `seed`, or
/// the scene's) and returns them as 8-bit scans, quantised as the wire does.
pub fn render_scans(
    scene: &Scene,
    seed: Option<u64>,
    first: u64,
    rotations: u64,
) -> Result<Scans, SimError> {
    let radar = &scene.radar;
    let n = u64::from(radar.azimuths);
    let horizon_s = (first + rotations + 1) as f64 / radar.rotation_hz() + 1.0;
    let renderer = Arc::new(SceneRenderer::new(scene, seed, horizon_s)?);
    let mut cursor = renderer.cursor();
    let mut scans = Scans::new(
        usize::from(radar.azimuths),
        usize::from(radar.range_bins),
        f64::from(radar.range_gain) * radar.bin_size_m(),
    );
    let mut frame = bytes::BytesMut::new();
    let mut rows = Vec::with_capacity(usize::from(radar.azimuths) * usize::from(radar.range_bins));
    for rot in first..first + rotations {
        rows.clear();
        for k in 0..n {
            frame.clear();
            cursor.render(rot * n + k, 0, protocol::Timestamp::EPOCH, &mut frame)?;
            rows.extend_from_slice(cursor.last_power_db());
        }
        scans.push_db(&rows);
    }
    Ok(scans)
}
