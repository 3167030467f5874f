//! Scene files: the world the simulated radar looks at, the radar itself, the noise, the
//! vehicle's start and its control schedule. Parsing and validation only (no IO here except
//! [`Scene::load`], which reads one file).
//!
//! The format is documented with examples in `sim-sensor/README.md`; the shipped scenes in
//! `sim-sensor/scenes/` are embedded in the binary ([`shipped`]).

pub mod kinds;
pub mod shipped;

use std::path::Path;

use serde::Deserialize;

pub use kinds::FeatureKind;

use crate::error::SceneError;
use crate::radar::{DataWidth, RadarParams, RadarPreset};
use crate::schedule::{ControlKey, ControlSchedule, Interpolation};

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
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    #[serde(default)]
    name: Option<String>,
    #[serde(default)]
    description: String,
    #[serde(default)]
    seed: u64,
    #[serde(default)]
    radar: RawRadar,
    #[serde(default)]
    noise: NoiseSpec,
    #[serde(default)]
    receiver: ReceiverSpec,
    #[serde(default)]
    loss_db: f64,
    #[serde(default)]
    motion: MotionSpec,
    #[serde(default)]
    start: RawStart,
    #[serde(default)]
    interpolation: Interpolation,
    #[serde(default)]
    control: Vec<ControlKey>,
    #[serde(default)]
    features: Vec<RawFeature>,
    #[serde(default)]
    lines: Vec<RawLine>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRadar {
    preset: RadarPreset,
    azimuths: Option<u16>,
    encoder_size: Option<u16>,
    range_bins: Option<u16>,
    bin_size_m: Option<f64>,
    rotation_hz: Option<f64>,
    range_gain: Option<f32>,
    range_offset_m: Option<f32>,
    data_width: Option<u32>,
    beam_width_deg: Option<f64>,
}

impl Default for RawRadar {
    fn default() -> Self {
        Self {
            preset: RadarPreset::Paper200,
            azimuths: None,
            encoder_size: None,
            range_bins: None,
            bin_size_m: None,
            rotation_hz: None,
            range_gain: None,
            range_offset_m: None,
            data_width: None,
            beam_width_deg: None,
        }
    }
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStart {
    #[serde(default)]
    x_m: f64,
    #[serde(default)]
    y_m: f64,
    #[serde(default)]
    theta_deg: f64,
    #[serde(default)]
    unix_time_s: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFeature {
    kind: FeatureKind,
    x_m: f64,
    y_m: f64,
    rho: Option<f64>,
    alpha: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLine {
    kind: FeatureKind,
    from: [f64; 2],
    to: [f64; 2],
    spacing_m: f64,
    rho: Option<f64>,
    alpha: Option<f64>,
}

/// Most point features one scene may hold (after line expansion).
pub const MAX_FEATURES: usize = 200_000;

fn invalid(field: String, reason: impl Into<String>) -> SceneError {
    SceneError::Invalid {
        field,
        reason: reason.into(),
    }
}

fn material(
    field: &str,
    kind: FeatureKind,
    rho: Option<f64>,
    alpha: Option<f64>,
) -> Result<(f64, f64), SceneError> {
    let (rho0, alpha0) = kind.default_material();
    let rho = rho.unwrap_or(rho0);
    let alpha = alpha.unwrap_or(alpha0);
    if !(rho.is_finite() && rho > 0.0 && rho < 1.0) {
        return Err(invalid(
            format!("{field}.rho"),
            format!("must be in (0, 1), got {rho}"),
        ));
    }
    if !(alpha.is_finite() && alpha > 0.0 && alpha < 1.0) {
        return Err(invalid(
            format!("{field}.alpha"),
            format!("must be in (0, 1), got {alpha}"),
        ));
    }
    if rho + alpha >= 1.0 {
        return Err(invalid(
            format!("{field}.alpha"),
            format!(
                "rho + alpha must be < 1 (some power must pass), got {}",
                rho + alpha
            ),
        ));
    }
    Ok((rho, alpha))
}

fn finite_coord(field: String, value: f64) -> Result<f64, SceneError> {
    if value.is_finite() && value.abs() <= 1e6 {
        Ok(value)
    } else {
        Err(invalid(
            field,
            format!("must be finite and within 1000 km, got {value}"),
        ))
    }
}

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
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
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

    /// The largest distance of any feature from the start position, metres.
    pub fn extent_m(&self) -> f64 {
        self.features
            .iter()
            .map(|f| (f.x_m - self.start[0]).hypot(f.y_m - self.start[1]))
            .fold(0.0, f64::max)
    }
}

impl RawRadar {
    fn build(&self) -> Result<RadarParams, SceneError> {
        let mut p = self.preset.params();
        if let Some(v) = self.azimuths {
            p.azimuths = v;
        }
        if let Some(v) = self.encoder_size {
            p.encoder_size = v;
        }
        if let Some(v) = self.range_bins {
            p.range_bins = v;
        }
        if let Some(v) = self.bin_size_m {
            let tenths = (v * 10_000.0).round();
            if !(tenths.is_finite() && (1.0..=f64::from(u16::MAX)).contains(&tenths)) {
                return Err(invalid(
                    "radar.bin_size_m".into(),
                    format!("must be in [0.0001, 6.5535] m, got {v}"),
                ));
            }
            p.bin_size_tenth_mm = tenths as u16;
        }
        if let Some(v) = self.rotation_hz {
            let mhz = (v * 1000.0).round();
            if !(mhz.is_finite() && (1.0..=f64::from(u16::MAX)).contains(&mhz)) {
                return Err(invalid(
                    "radar.rotation_hz".into(),
                    format!("must be in [0.001, 65.535] Hz, got {v}"),
                ));
            }
            p.rotation_mhz = mhz as u16;
        }
        if let Some(v) = self.range_gain {
            p.range_gain = v;
        }
        if let Some(v) = self.range_offset_m {
            p.range_offset_m = v;
        }
        if let Some(bits) = self.data_width {
            p.data_width = DataWidth::from_bits(bits).ok_or_else(|| {
                invalid(
                    "radar.data_width".into(),
                    format!("must be 8 or 16, got {bits}"),
                )
            })?;
        }
        if let Some(deg) = self.beam_width_deg {
            p.beam_width_rad = deg.to_radians();
        }
        p.validate()?;
        Ok(p)
    }
}

impl RawScene {
    fn validate(self, fallback_name: &str) -> Result<Scene, SceneError> {
        let radar = self.radar.build()?;
        let noise = self.noise;
        let check_nonneg = |field: &str, v: f64, max: f64| {
            if v.is_finite() && (0.0..=max).contains(&v) {
                Ok(())
            } else {
                Err(invalid(
                    format!("noise.{field}"),
                    format!("must be in [0, {max}], got {v}"),
                ))
            }
        };
        check_nonneg(
            "target_power_variance_db2",
            noise.target_power_variance_db2,
            1000.0,
        )?;
        check_nonneg("bearing_sigma_deg", noise.bearing_sigma_deg, 45.0)?;
        check_nonneg("range_sigma_m", noise.range_sigma_m, 100.0)?;
        let slope = self.receiver.compensation_db_per_decade;
        if !(slope.is_finite() && (0.0..=120.0).contains(&slope)) {
            return Err(invalid(
                "receiver.compensation_db_per_decade".into(),
                format!("must be in [0, 120], got {slope}"),
            ));
        }
        if !(self.loss_db.is_finite() && self.loss_db.abs() <= 300.0) {
            return Err(invalid(
                "loss_db".into(),
                format!("must be within +/-300 dB, got {}", self.loss_db),
            ));
        }
        match self.motion {
            MotionSpec::Paper { step_s } if !(step_s.is_finite() && step_s > 0.0) => {
                return Err(invalid(
                    "motion.step_s".into(),
                    format!("must be > 0, got {step_s}"),
                ));
            }
            MotionSpec::Bicycle { wheelbase_m }
                if !(wheelbase_m.is_finite() && wheelbase_m > 0.0) =>
            {
                return Err(invalid(
                    "motion.wheelbase_m".into(),
                    format!("must be > 0, got {wheelbase_m}"),
                ));
            }
            _ => {}
        }
        let start = [
            finite_coord("start.x_m".into(), self.start.x_m)?,
            finite_coord("start.y_m".into(), self.start.y_m)?,
            finite_coord("start.theta_deg".into(), self.start.theta_deg)?.to_radians(),
        ];
        let start_time_ns = match self.start.unix_time_s {
            None => None,
            Some(t) if t.is_finite() && (0.0..4.0e9).contains(&t) => Some((t * 1e9).round() as u64),
            Some(t) => {
                return Err(invalid(
                    "start.unix_time_s".into(),
                    format!("must be in [0, 4e9) seconds, got {t}"),
                ))
            }
        };
        let schedule = ControlSchedule::new(self.control, self.interpolation)?;

        let mut features = Vec::with_capacity(self.features.len());
        for (i, f) in self.features.iter().enumerate() {
            let field = format!("features[{i}]");
            let (rho, alpha) = material(&field, f.kind, f.rho, f.alpha)?;
            features.push(Feature {
                id: 0,
                kind: f.kind,
                x_m: finite_coord(format!("{field}.x_m"), f.x_m)?,
                y_m: finite_coord(format!("{field}.y_m"), f.y_m)?,
                rho,
                alpha,
            });
        }
        for (i, line) in self.lines.iter().enumerate() {
            let field = format!("lines[{i}]");
            let (rho, alpha) = material(&field, line.kind, line.rho, line.alpha)?;
            let from = [
                finite_coord(format!("{field}.from"), line.from[0])?,
                finite_coord(format!("{field}.from"), line.from[1])?,
            ];
            let to = [
                finite_coord(format!("{field}.to"), line.to[0])?,
                finite_coord(format!("{field}.to"), line.to[1])?,
            ];
            if !(line.spacing_m.is_finite() && line.spacing_m >= 0.05) {
                return Err(invalid(
                    format!("{field}.spacing_m"),
                    format!("must be >= 0.05 m, got {}", line.spacing_m),
                ));
            }
            let length = (to[0] - from[0]).hypot(to[1] - from[1]);
            let steps = (length / line.spacing_m).floor();
            if steps > MAX_FEATURES as f64 {
                return Err(invalid(
                    format!("{field}.spacing_m"),
                    format!("expands to more than {MAX_FEATURES} features"),
                ));
            }
            let steps = steps as usize;
            for k in 0..=steps {
                let w = if steps == 0 {
                    0.0
                } else {
                    k as f64 / steps as f64
                };
                features.push(Feature {
                    id: 0,
                    kind: line.kind,
                    x_m: from[0] + w * (to[0] - from[0]),
                    y_m: from[1] + w * (to[1] - from[1]),
                    rho,
                    alpha,
                });
                if features.len() > MAX_FEATURES {
                    return Err(invalid(
                        "lines".into(),
                        format!("the scene expands to more than {MAX_FEATURES} features"),
                    ));
                }
            }
        }
        for (id, f) in features.iter_mut().enumerate() {
            f.id = u32::try_from(id).unwrap_or(u32::MAX);
        }
        Ok(Scene {
            name: self.name.unwrap_or_else(|| fallback_name.to_string()),
            description: self.description,
            seed: self.seed,
            preset: self.radar.preset,
            radar,
            noise,
            receiver: self.receiver,
            loss_db: self.loss_db,
            motion: self.motion,
            start,
            start_time_ns,
            schedule,
            features,
        })
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
