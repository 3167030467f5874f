//! Rendering one azimuth's spectrum from a scene: which features the beam sees from the pose
//! at that azimuth's timestamp, their powers by the paper's eq. 13, and a noisy spectrum by
//! radar-model's synthesis, quantised into an FFT frame.
//!
//! Cost per azimuth does not grow with the scene: [`beams`] picks the features a beam sees
//! from per-rotation candidates gathered with a grid ([`GridIndex`]).
//!
//! Every random draw is a pure function of the scene's seed and the azimuth's (or
//! rotation's) index, so all clients see identical spectra and a run is reproducible.

use std::cell::OnceCell;
use std::sync::Arc;

use bytes::BytesMut;
use protocol::{encode_fft_frame, encode_fft_frame_from_db, BinWidth, Timestamp};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use radar_model::compensation::Compensation;
use radar_model::geometry::Pose2;
use radar_model::material::Material;
use radar_model::noise::{NoiseModel, RangeSpread, TargetAbsentNoise, TargetPresentNoise};
use radar_model::power::{PowerModel, PowerTarget, RadarConstants, SpreadingForm};
use radar_model::spectrum::{
    beam_spectrum_targets, SpectrumGeometry, SpectrumModel, SpectrumTarget,
};

use crate::error::SimError;
use crate::index::GridIndex;
pub use crate::radar::{azimuth_in_rotation, offset_ns};
use crate::radar::{DataWidth, RadarParams};
use crate::realism::objects::World;
use crate::realism::render::{RealisticCursor, RealisticModel};
use crate::scene::{Feature, MotionSpec, Scene, Spreading};
use crate::trajectory::{Trajectory, TrajectoryCursor};

pub mod beams;
mod occlusion;
mod scans;

pub use scans::render_scans;

use beams::BeamSelector;

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
    realistic: Option<RealisticModel>,
    occluders: Option<occlusion::Occluders>,
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
        let realistic = match &scene.realism {
            Some(spec) => {
                let world = World::build(&scene.features, &scene.objects, scene.seed)?;
                Some(RealisticModel::new(world, spec.clone(), &scene.radar)?)
            }
            None => None,
        };
        // The realistic renderer draws objects itself; the point-target renderer only lets
        // opaque ones hide features.
        let occluders = if realistic.is_none() {
            occlusion::Occluders::new(&scene.objects)
        } else {
            None
        };
        Ok(SceneRenderer {
            realistic,
            occluders,
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

    /// The realistic model, when the scene asks for it (`[realism]`).
    pub fn realistic(&self) -> Option<&RealisticModel> {
        self.realistic.as_ref()
    }

    /// A per-client rendering state.
    pub fn cursor(self: &Arc<Self>) -> RenderCursor {
        RenderCursor {
            renderer: Arc::clone(self),
            trajectory: self.trajectory.cursor(),
            beams: BeamSelector::default(),
            targets: Vec::new(),
            spectrum_targets: Vec::new(),
            power_db: vec![0.0; usize::from(self.radar.range_bins)],
            wire: Vec::new(),
            realistic: Box::default(),
            realistic_db: OnceCell::new(),
        }
    }
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
    beams: BeamSelector,
    targets: Vec<PowerTarget>,
    spectrum_targets: Vec<SpectrumTarget>,
    power_db: Vec<f64>,
    /// The realistic renderer's bins as the wire carries them.
    wire: Vec<u8>,
    realistic: Box<RealisticCursor>,
    /// The realistic renderer's last levels in dB, computed when first asked for.
    realistic_db: OnceCell<Vec<f64>>,
}

impl RenderCursor {
    /// The true pose at `offset_ns` after azimuth 0.
    pub fn pose_at(&mut self, offset_ns: u64) -> Result<Pose2, SimError> {
        self.renderer
            .trajectory
            .pose_with(&mut self.trajectory, offset_ns)
    }

    /// Features inside the beam of azimuth `index`, sorted by true range, as `(range_m,
    /// feature id)`; the apparent (bearing-perturbed) positions are used, as for rendering,
    /// and the range is the one the return is rendered at (less the radar's range-Doppler
    /// shift, [`RadarParams::doppler_range_coupling_s`]).
    pub fn features_in_beam(&mut self, index: u64) -> Result<Vec<(f64, u32)>, SimError> {
        self.beams
            .select(&self.renderer, &mut self.trajectory, index)?;
        Ok(self
            .beams
            .hits
            .iter()
            .map(|h| {
                (
                    h.rendered_range_m(),
                    self.renderer.ids.get(h.index).copied().unwrap_or(u32::MAX),
                )
            })
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
        let r = &*self.renderer;
        if let Some(model) = &r.realistic {
            let width = bin_width(r.radar.data_width);
            let (pose, counts) = self.realistic.render(
                model,
                &r.trajectory,
                &mut self.trajectory,
                &r.radar,
                r.seed,
                index,
                width,
                self.power_db.len(),
                &mut self.wire,
            )?;
            // The levels in dB only when asked for (`last_power_db`).
            self.realistic_db = OnceCell::new();
            let encoder = r.radar.encoder_of(azimuth_in_rotation(&r.radar, index));
            encode_fft_frame(dst, width, sweep_counter, encoder, timestamp, &self.wire)
                .map_err(|e| SimError::Model(format!("encoding azimuth {index}: {e}")))?;
            return Ok(Rendered {
                pose,
                targets: counts.deposited,
            });
        }
        let pose = self
            .beams
            .select(&self.renderer, &mut self.trajectory, index)?;
        let r = &*self.renderer;
        self.targets.clear();
        let mut shifts = false;
        for h in &self.beams.hits {
            if let Some(material) = r.materials.get(h.index) {
                self.targets.push(PowerTarget {
                    range_m: h.range_m,
                    material: *material,
                });
                shifts |= h.doppler_shift_m != 0.0;
            }
        }
        beam_spectrum_targets(
            &r.power,
            &self.targets,
            r.loss_db,
            &mut self.spectrum_targets,
        )
        .map_err(|e| SimError::Model(e.to_string()))?;
        // The power is the true range's; the peak sits where the range-Doppler coupling
        // puts it.
        if shifts {
            let with_material = self
                .beams
                .hits
                .iter()
                .filter(|h| r.materials.get(h.index).is_some());
            for (t, h) in self.spectrum_targets.iter_mut().zip(with_material) {
                t.range_m -= h.doppler_shift_m;
            }
        }
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
            targets: self.beams.hits.len(),
        })
    }

    /// Tests only: the realistic renderer tests every candidate on every azimuth.
    #[cfg(test)]
    pub(crate) fn test_every_candidate(&mut self) {
        self.realistic.test_every_candidate();
    }

    /// The last rendered spectrum in dB (before quantisation; the realistic renderer's
    /// output levels).
    pub fn last_power_db(&self) -> &[f64] {
        match &self.renderer.realistic {
            Some(model) => self.realistic_db.get_or_init(|| {
                let mut db = vec![0.0; self.power_db.len()];
                self.realistic.levels_db(&model.receiver, &mut db);
                db
            }),
            None => &self.power_db,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::shipped;
    use radar_model::geometry::{range_bearing, wrap_angle, Beam};

    /// Point targets 20 m dead ahead of azimuth 0, abeam to the right of azimuth 100 and
    /// behind azimuth 200 (a 400-azimuth radar at 4 Hz) of a vehicle driving along +x from
    /// the origin at `speed` (x = 0.5 m at azimuth 100 and 1 m at 200 for 8 m/s), noise
    /// off; `radar` is the `[radar]` section.
    fn three_targets(radar: &str, speed: f64) -> Scene {
        let x = |t: f64| speed * t;
        Scene::from_toml_str(
            "doppler",
            &format!(
                "[radar]\n{radar}\n[noise]\nenabled = false\n\
                 [[control]]\nt_s = 0.0\nspeed_mps = {speed}\nsteer_rad = 0.0\n\
                 [[features]]\nkind = \"reflector\"\nx_m = 20.0\ny_m = 0.0\n\
                 [[features]]\nkind = \"reflector\"\nx_m = {}\ny_m = -20.0\n\
                 [[features]]\nkind = \"reflector\"\nx_m = {}\ny_m = 0.0\n",
                x(0.0625),
                x(0.125) - 20.0
            ),
        )
        .expect("scene")
    }

    /// Renders azimuths 0, 100 and 200: each one's spectrum (dB) and its targets' ranges.
    fn render_three(scene: &Scene) -> Vec<(Vec<f64>, Vec<f64>)> {
        let renderer = Arc::new(SceneRenderer::new(scene, None, 10.0).expect("renderer"));
        let mut cursor = renderer.cursor();
        let mut frame = BytesMut::new();
        [0u64, 100, 200]
            .into_iter()
            .map(|k| {
                let ranges = cursor
                    .features_in_beam(k)
                    .expect("beam")
                    .into_iter()
                    .map(|(r, _)| r)
                    .collect();
                frame.clear();
                cursor
                    .render(k, 0, Timestamp::EPOCH, &mut frame)
                    .expect("render");
                (cursor.last_power_db().to_vec(), ranges)
            })
            .collect()
    }

    /// Where the spectrum peaks within 2 m of `range_m`, metres (three-point interpolation).
    fn peak_m(db: &[f64], bin_m: f64, range_m: f64) -> f64 {
        let c = (range_m / bin_m).round() as usize;
        let reach = (2.0 / bin_m) as usize;
        let b = (c - reach..=c + reach)
            .max_by(|&i, &j| db[i].total_cmp(&db[j]))
            .expect("bins");
        let (l, m, r) = (db[b - 1], db[b], db[b + 1]);
        let d = 0.5 * (l - r) / (l - 2.0 * m + r);
        (b as f64 + d) * bin_m
    }

    #[test]
    fn the_cts350x_renders_point_targets_ahead_short_behind_long_and_abeam_unmoved() {
        let with = render_three(&three_targets("preset = \"cts350x-400\"", 8.0));
        let without = render_three(&three_targets(
            "preset = \"cts350x-400\"\ndoppler_range_coupling_s = 0.0",
            8.0,
        ));
        let moved: Vec<f64> = with
            .iter()
            .zip(&without)
            .map(|(w, o)| peak_m(&w.0, 0.0438, 20.0) - peak_m(&o.0, 0.0438, 20.0))
            .collect();
        println!("peaks moved by the coupling (ahead, abeam, behind): {moved:?} m");
        // 0.049 s x 8 m/s = 0.392 m.
        assert!((moved[0] + 0.392).abs() < 0.01, "{moved:?}");
        assert!(moved[1].abs() < 1e-9, "{moved:?}");
        assert!((moved[2] - 0.392).abs() < 0.01, "{moved:?}");
        // The targets in the beam are reported where they are rendered.
        let reported: Vec<f64> = with.iter().map(|w| w.1[0]).collect();
        for (r, expected) in reported.iter().zip([20.0 - 0.392, 20.0, 20.0 + 0.392]) {
            assert!((r - expected).abs() < 1e-6, "{reported:?}");
        }
    }

    #[test]
    fn a_still_vehicle_and_the_paper_unit_render_no_range_doppler_shift() {
        let still = render_three(&three_targets("preset = \"cts350x-400\"", 0.0));
        let still_without = render_three(&three_targets(
            "preset = \"cts350x-400\"\ndoppler_range_coupling_s = 0.0",
            0.0,
        ));
        assert_eq!(still, still_without);
        // The paper's unit: no coupling; its targets sit at their true ranges while moving.
        assert_eq!(
            crate::radar::RadarPreset::Paper200
                .params()
                .doppler_range_coupling_s,
            0.0
        );
        let paper = three_targets(
            "preset = \"paper-200\"\nazimuths = 400\nrotation_hz = 4.0",
            8.0,
        );
        for (_, ranges) in render_three(&paper) {
            assert!((ranges[0] - 20.0).abs() < 1e-9, "{ranges:?}");
        }
    }

    #[test]
    fn the_coupling_is_overridable_and_validated_in_a_scene_file() {
        let s = three_targets(
            "preset = \"paper-200\"\ndoppler_range_coupling_s = 0.03",
            1.0,
        );
        assert_eq!(s.radar.doppler_range_coupling_s, 0.03);
        for bad in ["1.5", "-1.01", "nan", "inf"] {
            let err = Scene::from_toml_str(
                "bad",
                &format!("[radar]\npreset = \"cts350x-400\"\ndoppler_range_coupling_s = {bad}\n"),
            )
            .expect_err(bad);
            assert!(
                err.to_string().contains("radar.doppler_range_coupling_s"),
                "{bad}: {err}"
            );
        }
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
