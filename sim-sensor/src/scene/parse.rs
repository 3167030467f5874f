//! Stage one of reading a scene: the file's own shape (serde structs with
//! `deny_unknown_fields`), and its validation into [`Scene`].

use serde::Deserialize;

use super::city::CitySpec;
use super::objects::ObjectSpec;
use super::realism_spec::RealismSpec;
use super::street::StreetSpec;
use super::{Feature, FeatureKind, MotionSpec, NoiseSpec, ReceiverSpec, Scene, MAX_FEATURES};
use crate::error::SceneError;
use crate::radar::{DataWidth, RadarParams, RadarPreset};
use crate::schedule::{ControlKey, ControlSchedule, Interpolation};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawScene {
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
    #[serde(default)]
    realism: Option<RealismSpec>,
    #[serde(default)]
    objects: Vec<ObjectSpec>,
    #[serde(default)]
    street: Option<StreetSpec>,
    #[serde(default)]
    city: Option<CitySpec>,
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
    doppler_range_coupling_s: Option<f64>,
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
            doppler_range_coupling_s: None,
        }
    }
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStart {
    #[serde(default)]
    x_m: Option<f64>,
    #[serde(default)]
    y_m: Option<f64>,
    #[serde(default)]
    theta_deg: Option<f64>,
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
        if let Some(v) = self.doppler_range_coupling_s {
            p.doppler_range_coupling_s = v;
        }
        p.validate()?;
        Ok(p)
    }
}

impl RawScene {
    pub(super) fn validate(self, fallback_name: &str) -> Result<Scene, SceneError> {
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
        let mut start = [
            finite_coord("start.x_m".into(), self.start.x_m.unwrap_or(0.0))?,
            finite_coord("start.y_m".into(), self.start.y_m.unwrap_or(0.0))?,
            finite_coord(
                "start.theta_deg".into(),
                self.start.theta_deg.unwrap_or(0.0),
            )?
            .to_radians(),
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
        // A city makes its own start pose and control schedule from its route.
        let city = match &self.city {
            None => None,
            Some(spec) => {
                if self.street.is_some() {
                    return Err(invalid(
                        "city".into(),
                        "[city] makes its own streets: remove [street]",
                    ));
                }
                match (self.realism.is_some(), spec.dressing.is_some()) {
                    (true, false) => {
                        return Err(invalid(
                            "city".into(),
                            "[city] with [realism] is the realistic city: add [city.dressing] (or remove [realism] for the point-landmark city)",
                        ))
                    }
                    (false, true) => {
                        return Err(invalid(
                            "city.dressing".into(),
                            "the dressed city renders only with the realistic renderer: add [realism]",
                        ))
                    }
                    _ => {}
                }
                if !self.control.is_empty() {
                    return Err(invalid(
                        "control".into(),
                        "[city] makes the control schedule from its route: remove [[control]]",
                    ));
                }
                if self.start.x_m.is_some()
                    || self.start.y_m.is_some()
                    || self.start.theta_deg.is_some()
                {
                    return Err(invalid(
                        "start".into(),
                        "[city] starts at its route's first junction: [start] may set only unix_time_s",
                    ));
                }
                let MotionSpec::Bicycle { wheelbase_m } = self.motion else {
                    return Err(invalid(
                        "motion.model".into(),
                        "[city] drives the bicycle model: set model = \"bicycle\"",
                    ));
                };
                Some(spec.generate(wheelbase_m)?)
            }
        };
        let schedule = match &city {
            Some(city) => {
                start = city.start;
                ControlSchedule::new(city.control.clone(), Interpolation::Linear)?
            }
            None => ControlSchedule::new(self.control, self.interpolation)?,
        };

        if self.features.len() > MAX_FEATURES {
            return Err(invalid(
                "features".into(),
                format!(
                    "{} features; a scene holds at most {MAX_FEATURES}",
                    self.features.len()
                ),
            ));
        }
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
        if let Some(realism) = &self.realism {
            realism.validate()?;
        } else if !self.objects.is_empty() || self.street.is_some() {
            return Err(invalid(
                "objects".into(),
                "objects and [street] render only with the realistic renderer: add [realism]",
            ));
        }
        let mut objects = self.objects;
        if let Some(street) = &self.street {
            let generated = street.generate()?;
            for (kind, x, y) in generated.features {
                let (rho, alpha) = kind.default_material();
                features.push(Feature {
                    id: 0,
                    kind,
                    x_m: x,
                    y_m: y,
                    rho,
                    alpha,
                });
            }
            if features.len() > MAX_FEATURES {
                return Err(invalid(
                    "street".into(),
                    format!("the scene expands to more than {MAX_FEATURES} features"),
                ));
            }
            objects.extend(generated.objects);
        }
        let mut layout = None;
        if let Some(city) = city {
            for landmark in &city.landmarks {
                let (kind, rho, alpha) = landmark.class.material();
                features.push(Feature {
                    id: 0,
                    kind,
                    x_m: landmark.x_m,
                    y_m: landmark.y_m,
                    rho,
                    alpha,
                });
            }
            if features.len() > MAX_FEATURES {
                return Err(invalid(
                    "city".into(),
                    format!("the scene expands to more than {MAX_FEATURES} features"),
                ));
            }
            for (kind, x, y) in city.features {
                let (rho, alpha) = kind.default_material();
                features.push(Feature {
                    id: 0,
                    kind,
                    x_m: x,
                    y_m: y,
                    rho,
                    alpha,
                });
            }
            if features.len() > MAX_FEATURES {
                return Err(invalid(
                    "city".into(),
                    format!("the scene expands to more than {MAX_FEATURES} features"),
                ));
            }
            objects.extend(city.objects);
            layout = Some(city.layout);
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
            realism: self.realism,
            objects,
            city: layout,
        })
    }
}
