//! Rendering one azimuth's spectrum from a scene: which features the beam sees from the pose
//! at that azimuth's timestamp, their powers by the paper's eq. 13, and a noisy spectrum by
//! radar-model's synthesis, quantised into an FFT frame.
//!
//! Cost per azimuth does not grow with the scene: once per rotation the features within
//! range of the rotation's middle pose are gathered from a grid ([`GridIndex`]) and sorted
//! by bearing; each azimuth then tests only the features whose bearing lies within the beam
//! plus a margin that bounds how far the vehicle's motion during the rotation can move a
//! bearing (features closer than [`NEAR_RANGE_M`]-ish, whose bearing can swing widely,
//! are tested on every azimuth).
//!
//! Every random draw is a pure function of the scene's seed and the azimuth's (or
//! rotation's) index, so all clients see identical spectra and a run is reproducible.

use std::sync::Arc;

use bytes::BytesMut;
use protocol::{encode_fft_frame_from_db, BinWidth, Timestamp};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use radar_model::compensation::Compensation;
use radar_model::geometry::{range_bearing, wrap_angle, Beam, Pose2};
use radar_model::material::Material;
use radar_model::noise::{NoiseModel, RangeSpread, TargetAbsentNoise, TargetPresentNoise};
use radar_model::power::{PowerModel, PowerTarget, RadarConstants, SpreadingForm};
use radar_model::spectrum::{
    beam_spectrum_targets, SpectrumGeometry, SpectrumModel, SpectrumTarget,
};

use crate::error::SimError;
use crate::index::GridIndex;
use crate::radar::{DataWidth, RadarParams};
use crate::scene::{Feature, MotionSpec, Scene, Spreading};
use crate::trajectory::{Trajectory, TrajectoryCursor};

/// Features nearer than this to a rotation's middle pose (plus twice the distance travelled)
/// are tested on every azimuth of that rotation.
pub const NEAR_RANGE_M: f64 = 5.0;
/// Random stream reserved for the per-rotation bearing errors (azimuth streams use the
/// azimuth index, which never reaches it).
const BEARING_STREAM_BASE: u64 = 1 << 63;
/// Poses sampled per rotation to bound the vehicle's motion during it.
const MOTION_SAMPLES: u64 = 8;

/// Converts the wire width.
pub fn bin_width(width: DataWidth) -> BinWidth {
    match width {
        DataWidth::Bits8 => BinWidth::Eight,
        DataWidth::Bits16 => BinWidth::Sixteen,
    }
}

/// Everything about a scene that does not change while it is served (shared by clients).
#[derive(Debug)]
pub struct SceneRenderer {
    name: String,
    motion: MotionSpec,
    features: Vec<Feature>,
    radar: RadarParams,
    seed: u64,
    loss_db: f64,
    noise_enabled: bool,
    bearing_sigma_rad: f64,
    positions: Vec<[f64; 2]>,
    materials: Vec<Material>,
    ids: Vec<u32>,
    grid: GridIndex,
    power: PowerModel,
    spectrum: SpectrumModel,
    trajectory: Trajectory,
}

/// The radar-model settings a scene renders with.
pub fn physics(scene: &Scene) -> (PowerModel, Compensation, NoiseModel, SpectrumGeometry) {
    let constants = RadarConstants::default();
    let radar = &scene.radar;
    let bin_size_m = f64::from(radar.range_gain) * radar.bin_size_m();
    let power = PowerModel {
        form: match scene.receiver.spreading {
            Spreading::Paper => SpreadingForm::Paper,
            Spreading::Textbook => SpreadingForm::Textbook,
        },
        constants,
        range_resolution_m: bin_size_m,
    };
    let compensation =
        Compensation::calibrated(scene.receiver.compensation_db_per_decade, &constants);
    let noise = NoiseModel {
        absent: TargetAbsentNoise::default(),
        present: TargetPresentNoise {
            variance_db2: scene.noise.target_power_variance_db2,
        },
        range: RangeSpread {
            resolution_fwhm_m: bin_size_m,
            phase_noise_sigma_m: scene.noise.range_sigma_m,
        },
        bearing_sigma_rad: scene.noise.bearing_sigma_deg.to_radians(),
    };
    let geometry = SpectrumGeometry {
        bins: usize::from(radar.range_bins),
        bin_size_m,
        range_offset_m: f64::from(radar.range_offset_m),
    };
    (power, compensation, noise, geometry)
}

impl SceneRenderer {
    /// Prepares a scene: integrates its trajectory to `horizon_s`, indexes its features and
    /// builds the spectrum tables. `seed` overrides the scene's.
    pub fn new(
        scene: &Scene,
        seed: Option<u64>,
        horizon_s: f64,
    ) -> Result<SceneRenderer, SimError> {
        scene.radar.validate()?;
        let (power, compensation, noise, geometry) = physics(scene);
        power.check().map_err(|e| SimError::Model(e.to_string()))?;
        let spectrum = SpectrumModel::new(geometry, &compensation, noise)
            .map_err(|e| SimError::Model(e.to_string()))?;
        let positions: Vec<[f64; 2]> = scene.features.iter().map(|f| [f.x_m, f.y_m]).collect();
        let materials = scene
            .features
            .iter()
            .map(|f| {
                Material::from_rho_alpha(f.rho, f.alpha)
                    .map_err(|e| SimError::Model(format!("feature {}: {e}", f.id)))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let ids = scene.features.iter().map(|f| f.id).collect();
        let cell_m = (scene.radar.max_range_m() / 8.0).clamp(2.0, 50.0);
        Ok(SceneRenderer {
            name: scene.name.clone(),
            motion: scene.motion,
            features: scene.features.clone(),
            radar: scene.radar.clone(),
            seed: seed.unwrap_or(scene.seed),
            loss_db: scene.loss_db,
            noise_enabled: scene.noise.enabled,
            bearing_sigma_rad: if scene.noise.enabled {
                scene.noise.bearing_sigma_deg.to_radians()
            } else {
                0.0
            },
            grid: GridIndex::new(&positions, cell_m),
            positions,
            materials,
            ids,
            power,
            spectrum,
            trajectory: Trajectory::new(scene, horizon_s)?,
        })
    }

    /// The scene's name.
    pub fn scene_name(&self) -> &str {
        &self.name
    }

    /// The scene's process model.
    pub fn motion(&self) -> MotionSpec {
        self.motion
    }

    /// The scene's features.
    pub fn features(&self) -> &[Feature] {
        &self.features
    }

    /// The radar loss L, dB.
    pub fn loss_db(&self) -> f64 {
        self.loss_db
    }

    /// The radar.
    pub fn radar(&self) -> &RadarParams {
        &self.radar
    }

    /// The true trajectory.
    pub fn trajectory(&self) -> &Trajectory {
        &self.trajectory
    }

    /// The seed in use.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Nanoseconds from azimuth 0 to azimuth `index`.
    pub fn offset_ns(&self, index: u64) -> u64 {
        offset_ns(&self.radar, index)
    }

    /// A per-client rendering state.
    pub fn cursor(self: &Arc<Self>) -> RenderCursor {
        RenderCursor {
            renderer: Arc::clone(self),
            trajectory: self.trajectory.cursor(),
            rotation: None,
            candidates: Vec::new(),
            near: Vec::new(),
            margin_rad: 0.0,
            hits: Vec::new(),
            targets: Vec::new(),
            spectrum_targets: Vec::new(),
            power_db: vec![0.0; usize::from(self.radar.range_bins)],
        }
    }
}

/// Nanoseconds from azimuth 0 to azimuth `index` at the radar's rate (exact integer maths).
pub fn offset_ns(radar: &RadarParams, index: u64) -> u64 {
    let per_s = u128::from(radar.azimuths) * u128::from(radar.rotation_mhz);
    if per_s == 0 {
        return 0;
    }
    let ns = u128::from(index) * 1_000_000_000_000 / per_s;
    u64::try_from(ns).unwrap_or(u64::MAX)
}

#[derive(Debug, Clone, Copy)]
struct Candidate {
    bearing_mid: f64,
    index: usize,
    apparent: [f64; 2],
}

/// What [`RenderCursor::render`] produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rendered {
    /// The pose the azimuth was rendered from.
    pub pose: Pose2,
    /// Features inside the beam.
    pub targets: usize,
}

/// One client's rendering state: its position on the trajectory, the current rotation's
/// candidate features and its buffers (no allocation per azimuth once warm).
#[derive(Debug)]
pub struct RenderCursor {
    renderer: Arc<SceneRenderer>,
    trajectory: TrajectoryCursor,
    rotation: Option<u64>,
    candidates: Vec<Candidate>,
    near: Vec<Candidate>,
    margin_rad: f64,
    hits: Vec<(f64, usize)>,
    targets: Vec<PowerTarget>,
    spectrum_targets: Vec<SpectrumTarget>,
    power_db: Vec<f64>,
}

impl RenderCursor {
    /// The true pose at `offset_ns` after azimuth 0.
    pub fn pose_at(&mut self, offset_ns: u64) -> Result<Pose2, SimError> {
        self.renderer
            .trajectory
            .pose_with(&mut self.trajectory, offset_ns)
    }

    /// Features inside the beam of azimuth `index`, sorted by range, as `(range_m, feature
    /// id)`; the apparent (bearing-perturbed) positions are used, as for rendering.
    pub fn features_in_beam(&mut self, index: u64) -> Result<Vec<(f64, u32)>, SimError> {
        self.collect_hits(index)?;
        Ok(self
            .hits
            .iter()
            .map(|&(r, i)| (r, self.renderer.ids.get(i).copied().unwrap_or(u32::MAX)))
            .collect())
    }

    /// Renders azimuth `index` (counted from azimuth 0 of the scene) as an FFT frame
    /// appended to `dst`.
    pub fn render(
        &mut self,
        index: u64,
        sweep_counter: u16,
        timestamp: Timestamp,
        dst: &mut BytesMut,
    ) -> Result<Rendered, SimError> {
        let pose = self.collect_hits(index)?;
        let r = &*self.renderer;
        self.targets.clear();
        for &(range_m, i) in &self.hits {
            if let Some(material) = r.materials.get(i) {
                self.targets.push(PowerTarget {
                    range_m,
                    material: *material,
                });
            }
        }
        beam_spectrum_targets(
            &r.power,
            &self.targets,
            r.loss_db,
            &mut self.spectrum_targets,
        )
        .map_err(|e| SimError::Model(e.to_string()))?;
        if r.noise_enabled {
            let mut rng = ChaCha8Rng::seed_from_u64(r.seed);
            rng.set_stream(index);
            r.spectrum
                .synthesize_into(&self.spectrum_targets, &mut rng, &mut self.power_db)
        } else {
            r.spectrum
                .predict_into(&self.spectrum_targets, &mut self.power_db)
        }
        .map_err(|e| SimError::Model(e.to_string()))?;
        let encoder = r.radar.encoder_of(azimuth_in_rotation(&r.radar, index));
        encode_fft_frame_from_db(
            dst,
            bin_width(r.radar.data_width),
            sweep_counter,
            encoder,
            timestamp,
            self.power_db.iter().copied(),
        )
        .map_err(|e| SimError::Model(format!("encoding azimuth {index}: {e}")))?;
        Ok(Rendered {
            pose,
            targets: self.hits.len(),
        })
    }

    /// The last rendered spectrum in dB (before quantisation).
    pub fn last_power_db(&self) -> &[f64] {
        &self.power_db
    }

    fn collect_hits(&mut self, index: u64) -> Result<Pose2, SimError> {
        let n = u64::from(self.renderer.radar.azimuths);
        let rotation = index / n;
        if self.rotation != Some(rotation) {
            self.prepare_rotation(rotation)?;
        }
        let r = &*self.renderer;
        let pose = r
            .trajectory
            .pose_with(&mut self.trajectory, r.offset_ns(index))?;
        let bearing = r
            .radar
            .angle_of_encoder(r.radar.encoder_of(azimuth_in_rotation(&r.radar, index)));
        let beam = Beam {
            bearing_rad: wrap_angle(bearing),
            width_rad: r.radar.beam_width_rad,
            min_range_m: 0.0,
            max_range_m: r.radar.max_range_m(),
        };
        self.hits.clear();
        let half = 0.5 * beam.width_rad + self.margin_rad;
        let test = |c: &Candidate, hits: &mut Vec<(f64, usize)>| {
            let rb = range_bearing(&pose, c.apparent);
            if beam.contains(&rb) {
                hits.push((rb.range_m, c.index));
            }
        };
        for c in &self.near {
            test(c, &mut self.hits);
        }
        for_each_in_window(&self.candidates, beam.bearing_rad, half, |c| {
            test(c, &mut self.hits)
        });
        self.hits
            .sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        Ok(pose)
    }

    fn prepare_rotation(&mut self, rotation: u64) -> Result<(), SimError> {
        let r = &*self.renderer;
        let n = u64::from(r.radar.azimuths);
        let first = rotation.saturating_mul(n);
        let mid_offset = r.offset_ns(first + n / 2);
        let mid = r.trajectory.pose_with(&mut self.trajectory, mid_offset)?;
        // Bound the motion during the rotation from a few sampled poses.
        let mut travel_m: f64 = 0.0;
        let mut turn_rad: f64 = 0.0;
        for s in 0..=MOTION_SAMPLES {
            let k = first + (n.saturating_sub(1)) * s / MOTION_SAMPLES;
            let p = r
                .trajectory
                .pose_with(&mut self.trajectory, r.offset_ns(k))?;
            travel_m = travel_m.max((p.x - mid.x).hypot(p.y - mid.y));
            turn_rad = turn_rad.max(wrap_angle(p.theta - mid.theta).abs());
        }
        // Samples can miss the extremes between them: pad generously.
        travel_m = travel_m * 1.25 + 0.05;
        turn_rad = turn_rad * 1.25 + 1e-3;
        let near_m = NEAR_RANGE_M + 2.0 * travel_m;
        let bearing_pad = 4.0 * r.bearing_sigma_rad;
        self.margin_rad = turn_rad + (travel_m / near_m).min(1.0).asin() + 1e-6;

        let mut rng = ChaCha8Rng::seed_from_u64(r.seed);
        rng.set_stream(BEARING_STREAM_BASE | rotation);
        self.candidates.clear();
        self.near.clear();
        let reach = r.radar.max_range_m() + travel_m;
        let mut found: Vec<usize> = Vec::new();
        r.grid
            .for_each_near([mid.x, mid.y], reach, |i| found.push(i));
        found.sort_unstable();
        for i in found {
            let Some(&p) = r.positions.get(i) else {
                continue;
            };
            let range_mid = (p[0] - mid.x).hypot(p[1] - mid.y);
            if range_mid > reach {
                continue;
            }
            let apparent = if r.bearing_sigma_rad > 0.0 {
                let n: f64 = StandardNormal.sample(&mut rng);
                let delta = (n * r.bearing_sigma_rad).clamp(-bearing_pad, bearing_pad);
                rotate_about([mid.x, mid.y], p, delta)
            } else {
                p
            };
            let c = Candidate {
                bearing_mid: range_bearing(&mid, apparent).bearing_rad,
                index: i,
                apparent,
            };
            if range_mid < near_m {
                self.near.push(c);
            } else {
                self.candidates.push(c);
            }
        }
        self.candidates.sort_by(|a, b| {
            a.bearing_mid
                .total_cmp(&b.bearing_mid)
                .then(a.index.cmp(&b.index))
        });
        self.rotation = Some(rotation);
        Ok(())
    }
}

/// Index of azimuth `index` within its rotation.
pub fn azimuth_in_rotation(radar: &RadarParams, index: u64) -> u16 {
    u16::try_from(index % u64::from(radar.azimuths.max(1))).unwrap_or(0)
}

/// Rotates `p` about `centre` by `-delta` radians (counter-clockwise negative), which adds
/// `delta` to its bearing as eq. 4 measures it (clockwise).
fn rotate_about(centre: [f64; 2], p: [f64; 2], delta: f64) -> [f64; 2] {
    let (s, c) = (-delta).sin_cos();
    let dx = p[0] - centre[0];
    let dy = p[1] - centre[1];
    [centre[0] + c * dx - s * dy, centre[1] + s * dx + c * dy]
}

/// Visits the candidates (sorted by `bearing_mid` in (-pi, pi]) whose bearing lies within
/// `half` of `bearing`, across the +/-pi seam.
fn for_each_in_window(
    candidates: &[Candidate],
    bearing: f64,
    half: f64,
    mut visit: impl FnMut(&Candidate),
) {
    if half >= std::f64::consts::PI {
        candidates.iter().for_each(visit);
        return;
    }
    let lo = bearing - half;
    let hi = bearing + half;
    let range = |a: f64, b: f64, visit: &mut dyn FnMut(&Candidate)| {
        let start = candidates.partition_point(|c| c.bearing_mid < a);
        let end = candidates.partition_point(|c| c.bearing_mid <= b);
        if let Some(slice) = candidates.get(start..end.max(start)) {
            slice.iter().for_each(&mut *visit);
        }
    };
    let pi = std::f64::consts::PI;
    range(lo.max(-pi), hi.min(pi), &mut visit);
    if lo < -pi {
        range(lo + 2.0 * pi, pi, &mut visit);
    }
    if hi > pi {
        range(-pi, hi - 2.0 * pi, &mut visit);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::shipped;

    #[test]
    fn the_window_finds_candidates_across_the_pi_seam() {
        let mk = |b: f64, i: usize| Candidate {
            bearing_mid: b,
            index: i,
            apparent: [0.0, 0.0],
        };
        let cands = vec![mk(-3.1, 0), mk(-1.0, 1), mk(0.0, 2), mk(3.1, 3)];
        let mut seen = Vec::new();
        for_each_in_window(&cands, 3.13, 0.1, |c| seen.push(c.index));
        seen.sort_unstable();
        assert_eq!(seen, vec![0, 3]);
    }

    #[test]
    fn rotating_a_point_adds_to_its_clockwise_bearing() {
        let pose = Pose2::new(1.0, 2.0, 0.3);
        let p = [11.0, 4.0];
        let before = range_bearing(&pose, p);
        let after = range_bearing(&pose, rotate_about([1.0, 2.0], p, 0.05));
        assert!((after.bearing_rad - before.bearing_rad - 0.05).abs() < 1e-12);
        assert!((after.range_m - before.range_m).abs() < 1e-12);
    }

    #[test]
    fn the_windowed_search_finds_exactly_what_a_full_scan_finds_on_a_moving_vehicle() {
        let mut scene = shipped::load("dense-clutter").expect("scene");
        scene.noise.enabled = false;
        let renderer = Arc::new(SceneRenderer::new(&scene, None, 120.0).expect("renderer"));
        let mut cursor = renderer.cursor();
        let n = u64::from(scene.radar.azimuths);
        for index in (0..n * 3).chain(n * 40..n * 41) {
            let fast: Vec<u32> = cursor
                .features_in_beam(index)
                .expect("hits")
                .into_iter()
                .map(|(_, id)| id)
                .collect();
            let pose = renderer
                .trajectory()
                .pose_at(renderer.offset_ns(index))
                .expect("pose");
            let bearing = scene.radar.angle_of_encoder(
                scene
                    .radar
                    .encoder_of(azimuth_in_rotation(&scene.radar, index)),
            );
            let beam = Beam {
                bearing_rad: wrap_angle(bearing),
                width_rad: scene.radar.beam_width_rad,
                min_range_m: 0.0,
                max_range_m: scene.radar.max_range_m(),
            };
            let mut slow: Vec<(f64, u32)> = scene
                .features
                .iter()
                .filter_map(|f| {
                    let rb = range_bearing(&pose, [f.x_m, f.y_m]);
                    beam.contains(&rb).then_some((rb.range_m, f.id))
                })
                .collect();
            slow.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let slow: Vec<u32> = slow.into_iter().map(|(_, id)| id).collect();
            assert_eq!(fast, slow, "azimuth {index}");
        }
    }
}
