//! Scene files: the world the simulated radar looks at, the radar itself, the noise, the
//! vehicle's start and its control schedule. Parsing and validation only (no IO here except
//! [`Scene::load`], which reads one file).
//!
//! The format is documented with examples in `sim-sensor/README.md`; the shipped scenes in
//! `sim-sensor/scenes/` are embedded in the binary ([`shipped`]).

pub mod city;
pub mod kinds;
pub mod objects;
mod parse;
pub mod realism_spec;
pub mod shipped;
pub mod street;

use std::path::Path;

use serde::Deserialize;

use parse::RawScene;

pub use kinds::FeatureKind;

use crate::error::SceneError;
use crate::radar::{DataWidth, RadarParams, RadarPreset};
use crate::schedule::ControlSchedule;

/// One point feature of the world, as the paper models it: a position and a material.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Feature {
    /// Stable id: the feature's order in the scene after line expansion.
    pub id: u32,
    /// What it is.
    pub kind: FeatureKind,
    /// World x, metres.
    pub x_m: f64,
    /// World y, metres.
    pub y_m: f64,
    /// Normalised reflectivity (the paper's Upsilon_R), in (0, 1).
    pub rho: f64,
    /// Normalised absorption (the paper's Upsilon_a), in (0, 1); `rho + alpha < 1`.
    pub alpha: f64,
}

/// The vehicle's process model, as the scene asks for it (mapped onto radar-model's
/// `MotionModel`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(tag = "model", rename_all = "kebab-case", deny_unknown_fields)]
pub enum MotionSpec {
    /// The paper's eq. 2 with `a' = steer dt / step_s`.
    Paper {
        /// The step the steering input refers to, seconds.
        step_s: f64,
    },
    /// Heading rate `v tan(steer) / wheelbase`.
    Bicycle {
        /// Wheelbase, metres.
        wheelbase_m: f64,
    },
}

impl Default for MotionSpec {
    fn default() -> Self {
        MotionSpec::Bicycle { wheelbase_m: 2.7 }
    }
}

/// Noise settings of the rendered spectra.
///
/// Defaults are the figures in `docs/radar-model.md`: target-present power noise with a
/// variance of 4.07 dB^2, a 1 degree bearing standard deviation, and radar-model's
/// target-absent noise floor (exponential close in, Weibull beyond about 45 m).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NoiseSpec {
    /// `false` renders the expected (noise-free) spectrum.
    pub enabled: bool,
    /// Variance of a target's power about its prediction, dB^2.
    pub target_power_variance_db2: f64,
    /// Standard deviation of a feature's apparent bearing, degrees. One error is drawn per
    /// feature per rotation (the feature is seen rotated by it about the rotation's middle
    /// pose); within a rotation, the beam width decides which azimuths see it.
    pub bearing_sigma_deg: f64,
    /// Standard deviation of a peak's centre between looks (phase noise), metres.
    pub range_sigma_m: f64,
}

/// How power spreads between targets down one beam (radar-model's `SpreadingForm`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Spreading {
    /// The paper's eq. 13.
    #[default]
    Paper,
    /// The textbook two-way radar equation.
    Textbook,
}

/// The simulated receiver: the physics the spectra are rendered with.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReceiverSpec {
    /// Spreading form of eq. 13.
    pub spreading: Spreading,
    /// Slope of the receiver's range compensation, dB per decade (40 ideal; the paper
    /// models its unit as 60).
    pub compensation_db_per_decade: f64,
}

impl Default for ReceiverSpec {
    fn default() -> Self {
        Self {
            spreading: Spreading::Paper,
            compensation_db_per_decade: 40.0,
        }
    }
}

impl Default for NoiseSpec {
    fn default() -> Self {
        Self {
            enabled: true,
            target_power_variance_db2: 4.07,
            bearing_sigma_deg: 1.0,
            range_sigma_m: 0.1,
        }
    }
}

/// The whole scene, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Its name (file stem or shipped name).
    pub name: String,
    /// Free text.
    pub description: String,
    /// Seed of every random draw the simulator makes for this scene.
    pub seed: u64,
    /// The radar.
    pub radar: RadarParams,
    /// Which preset the radar started from.
    pub preset: RadarPreset,
    /// Spectrum noise.
    pub noise: NoiseSpec,
    /// Receiver physics.
    pub receiver: ReceiverSpec,
    /// Radar loss L, dB (subtracted from every target's power).
    pub loss_db: f64,
    /// The vehicle's process model.
    pub motion: MotionSpec,
    /// Start pose: x, y (m), theta (rad, counter-clockwise from +x).
    pub start: [f64; 3],
    /// Unix time of the start, nanoseconds; `None` = the moment the server starts.
    pub start_time_ns: Option<u64>,
    /// Speed and steering over time.
    pub schedule: ControlSchedule,
    /// Every point feature (lines already expanded).
    pub features: Vec<Feature>,
    /// The realistic renderer's settings (`[realism]`); `None` renders point targets with
    /// radar-model's synthesis, as the project's figures were made.
    pub realism: Option<realism_spec::RealismSpec>,
    /// Extended objects (`[[objects]]` and the `[street]` generator's), drawn only by the
    /// realistic renderer; the `[city]` generator's building fronts, which the point-target
    /// renderer uses as occluders.
    pub objects: Vec<objects::ObjectSpec>,
    /// The `[city]` generator's geometry (streets, route, drive length and duration).
    pub city: Option<city::CityLayout>,
}

/// Most point features one scene may hold (after line expansion).
pub const MAX_FEATURES: usize = 200_000;

/// Largest scene file read (bytes): far above any hand-written or generated scene of the
/// feature limit, far below what would exhaust memory.
pub const MAX_SCENE_BYTES: u64 = 16 << 20;

impl Scene {
    /// Parses and validates a scene from TOML text; `name` is used in errors and when the
    /// file names none.
    pub fn from_toml_str(name: &str, text: &str) -> Result<Scene, SceneError> {
        let raw: RawScene = toml::from_str(text).map_err(|source| SceneError::Parse {
            name: name.to_string(),
            source,
        })?;
        raw.validate(name)
    }

    /// Reads and parses a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        use std::io::Read as _;
        let io = |source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        };
        // Read at most one byte past the limit: a larger file (or /dev/zero) is refused
        // without reading it all.
        let mut text = String::new();
        std::fs::File::open(path)
            .map_err(io)?
            .take(MAX_SCENE_BYTES + 1)
            .read_to_string(&mut text)
            .map_err(io)?;
        if text.len() as u64 > MAX_SCENE_BYTES {
            return Err(SceneError::TooLarge {
                path: path.to_path_buf(),
                limit: MAX_SCENE_BYTES,
            });
        }
        let stem = path.file_stem().map_or_else(
            || path.display().to_string(),
            |s| s.to_string_lossy().into_owned(),
        );
        Scene::from_toml_str(&stem, &text)
    }

    /// Replaces the radar with a preset, keeping everything else.
    pub fn with_preset(mut self, preset: RadarPreset) -> Scene {
        let width = self.radar.data_width;
        self.radar = preset.params();
        self.radar.data_width = width;
        self.preset = preset;
        self
    }

    /// Sets the wire's data width.
    pub fn with_data_width(mut self, width: DataWidth) -> Scene {
        self.radar.data_width = width;
        self
    }

    /// The scene reflected about the world's x axis: every feature's and the start's y, the
    /// start heading and every steering input negated, so the vehicle turns the other way
    /// past the mirror image of the same features (a check for handedness in the radar, the
    /// filter or the simulator: the radar still sweeps clockwise). Point-feature scenes
    /// only: a scene with extended objects or a generated city is refused.
    pub fn mirrored(&self) -> Result<Scene, SceneError> {
        if !self.objects.is_empty() || self.city.is_some() || self.realism.is_some() {
            return Err(SceneError::Invalid {
                field: "objects".into(),
                reason: format!(
                    "scene {:?}: only point-feature scenes can be mirrored",
                    self.name
                ),
            });
        }
        let mut m = self.clone();
        m.name = format!("{}-mirrored", self.name);
        m.start = [self.start[0], -self.start[1], -self.start[2]];
        for f in &mut m.features {
            f.y_m = -f.y_m;
        }
        m.schedule = self.schedule.with_steer_negated();
        Ok(m)
    }

    /// The largest distance of any feature from the start position, metres.
    pub fn extent_m(&self) -> f64 {
        self.features
            .iter()
            .map(|f| (f.x_m - self.start[0]).hypot(f.y_m - self.start[1]))
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = r#"
        [[features]]
        kind = "reflector"
        x_m = 14.0
        y_m = 0.0
    "#;

    #[test]
    fn a_mirrored_scene_drives_the_mirror_image_past_the_mirrored_features() {
        let scene = shipped::load("outdoor-field").expect("shipped");
        let mirrored = scene.mirrored().expect("point features only");
        let a = crate::trajectory::Trajectory::new(&scene, 60.0).expect("trajectory");
        let b = crate::trajectory::Trajectory::new(&mirrored, 60.0).expect("trajectory");
        for t_s in [0.0, 12.5, 30.0, 39.99, 55.0] {
            let t_ns = (t_s * 1e9) as u64;
            let (p, q) = (
                a.pose_at(t_ns).expect("pose"),
                b.pose_at(t_ns).expect("pose"),
            );
            assert!(
                (p.x - q.x).abs() < 1e-9 && (p.y + q.y).abs() < 1e-9,
                "{t_s} s"
            );
            assert!((p.theta + q.theta).abs() < 1e-12, "{t_s} s");
        }
        assert!(
            a.pose_at(30_000_000_000).expect("pose").y.abs() > 1.0,
            "the scene turns"
        );
        for (f, g) in scene.features.iter().zip(&mirrored.features) {
            assert_eq!((f.id, f.x_m, f.y_m), (g.id, g.x_m, -g.y_m));
        }
        assert!(shipped::load("urban-street")
            .expect("shipped")
            .mirrored()
            .is_err());
    }

    #[test]
    fn a_minimal_scene_takes_the_paper_radar_and_default_materials() {
        let scene = Scene::from_toml_str("minimal", MINIMAL).expect("valid");
        assert_eq!(scene.name, "minimal");
        assert_eq!(scene.radar, RadarPreset::Paper200.params());
        assert_eq!(scene.features.len(), 1);
        assert_eq!(
            (scene.features[0].rho, scene.features[0].alpha),
            FeatureKind::Reflector.default_material()
        );
    }

    #[test]
    fn an_unknown_key_is_an_error_naming_the_key() {
        let err = Scene::from_toml_str(
            "typo",
            "[[features]]\nkind = \"tree\"\nx_m = 1\ny_m = 2\nrhoo = 0.2\n",
        )
        .expect_err("unknown key");
        let text = err.to_string();
        assert!(text.contains("rhoo"), "{text}");
        assert!(text.contains("line 5"), "{text}");
    }

    #[test]
    fn a_material_that_leaves_nothing_to_transmit_is_rejected() {
        let err = Scene::from_toml_str(
            "bad",
            "[[features]]\nkind = \"tree\"\nx_m = 1\ny_m = 2\nrho = 0.6\nalpha = 0.4\n",
        )
        .expect_err("rho + alpha = 1");
        assert!(err.to_string().contains("features[0].alpha"), "{err}");
    }

    #[test]
    fn a_line_expands_into_evenly_spaced_point_features_with_ids_in_order() {
        let scene = Scene::from_toml_str(
            "line",
            "[[lines]]\nkind = \"wooden-fence\"\nfrom = [0.0, 10.0]\nto = [4.0, 10.0]\nspacing_m = 1.0\n",
        )
        .expect("valid");
        let xs: Vec<f64> = scene.features.iter().map(|f| f.x_m).collect();
        assert_eq!(xs, vec![0.0, 1.0, 2.0, 3.0, 4.0]);
        let ids: Vec<u32> = scene.features.iter().map(|f| f.id).collect();
        assert_eq!(ids, vec![0, 1, 2, 3, 4]);
    }

    #[test]
    fn a_line_that_would_expand_without_bound_is_rejected() {
        let err = Scene::from_toml_str(
            "huge",
            "[[lines]]\nkind = \"wall\"\nfrom = [0.0, 0.0]\nto = [900000.0, 0.0]\nspacing_m = 0.05\n",
        )
        .expect_err("too many");
        assert!(err.to_string().contains("more than"), "{err}");
    }

    #[test]
    fn radar_overrides_apply_on_top_of_the_preset() {
        let scene = Scene::from_toml_str(
            "ovr",
            "[radar]\npreset = \"cts350x-400\"\ndata_width = 16\nrange_bins = 1000\n",
        )
        .expect("valid");
        assert_eq!(scene.radar.range_bins, 1000);
        assert_eq!(scene.radar.azimuths, 400);
        assert_eq!(scene.radar.data_width, DataWidth::Bits16);
        assert!(
            Scene::from_toml_str("w", "[radar]\npreset = \"paper-200\"\ndata_width = 12\n")
                .is_err()
        );
    }
}

#[cfg(test)]
mod fuzz {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn arbitrary_text_never_panics_the_scene_parser(text in "\\PC{0,400}") {
            let _ = Scene::from_toml_str("fuzz", &text);
        }

        #[test]
        fn arbitrary_numbers_in_a_well_formed_scene_are_accepted_or_named_errors(
            x in proptest::num::f64::ANY,
            rho in proptest::num::f64::ANY,
            spacing in proptest::num::f64::ANY,
            bins in proptest::num::i64::ANY,
        ) {
            let text = format!(
                "[radar]\npreset = \"paper-200\"\nrange_bins = {bins}\n\
                 [[features]]\nkind = \"tree\"\nx_m = {x:?}\ny_m = 0.0\nrho = {rho:?}\n\
                 [[lines]]\nkind = \"wall\"\nfrom = [0.0, 0.0]\nto = [10.0, 0.0]\nspacing_m = {spacing:?}\n"
            );
            match Scene::from_toml_str("fuzz", &text) {
                Ok(scene) => {
                    prop_assert!(scene.features.iter().all(|f| f.x_m.is_finite() && f.rho > 0.0 && f.rho < 1.0));
                    prop_assert!(scene.features.len() <= MAX_FEATURES);
                }
                Err(e) => prop_assert!(!e.to_string().is_empty()),
            }
        }
    }
}
