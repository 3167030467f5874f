//! `[model]`: the radar model's choices and constants (spreading form, receiver
//! compensation, beam, noise) as `radar-model` and the filter use them.

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::values::{FiniteF64, PositiveF64, ValueError};

/// Most points a compensation gain table may hold.
pub const MAX_GAIN_POINTS: usize = 4096;
/// Highest roll-off filter order accepted.
pub const MAX_ROLLOFF_ORDER: u64 = 16;

/// How power spreads with range for targets behind other targets (see `radar-model.md` §3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Spreading {
    /// The paper's eq. 13: spreading over the separations `(R_{j+1} - R_j)^4`.
    Paper,
    /// The textbook radar equation: `R_i^4` with `tau_j^2` for every target in front.
    Textbook,
}

/// The receiver compensation, as written: `compensation = "40db" | "60db" | "table"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, Serialize)]
pub enum CompensationKind {
    /// 40 dB per decade: ideal for the radar equation's R^-4.
    #[serde(rename = "40db")]
    Slope40,
    /// 60 dB per decade: the paper's model of its unit's filter.
    #[serde(rename = "60db")]
    Slope60,
    /// A measured gain curve, from `compensation_table`.
    #[serde(rename = "table")]
    Table,
}

/// One point of a measured receiver gain curve.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RawGainPoint {
    /// Range, m.
    pub range_m: f64,
    /// Receiver gain at that range, dB.
    pub gain_db: f64,
}

/// A validated gain point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GainPoint {
    /// Range, m (> 0).
    pub range_m: PositiveF64,
    /// Gain, dB.
    pub gain_db: FiniteF64,
}

/// A measured gain curve: at least two points, ranges strictly increasing.
#[derive(Debug, Clone, PartialEq)]
pub struct GainTable(Vec<GainPoint>);

impl GainTable {
    /// Checks the table's shape (each point's values are checked by the caller).
    pub fn new(points: Vec<GainPoint>) -> Result<Self, ValueError> {
        if points.len() < 2 || points.len() > MAX_GAIN_POINTS {
            return Err(ValueError::Rule(format!(
                "must hold between 2 and {MAX_GAIN_POINTS} points, got {}",
                points.len()
            )));
        }
        for pair in points.windows(2) {
            if let [before, after] = pair {
                if after.range_m.get() <= before.range_m.get() {
                    return Err(ValueError::Rule(format!(
                        "ranges must increase strictly, got {} m then {} m",
                        before.range_m, after.range_m
                    )));
                }
            }
        }
        Ok(Self(points))
    }
    /// The points, ranges strictly increasing.
    pub fn points(&self) -> &[GainPoint] {
        &self.0
    }
}

/// Receiver range compensation, validated.
#[derive(Debug, Clone, PartialEq)]
pub enum Compensation {
    /// 40 dB per decade.
    Slope40DbPerDecade,
    /// 60 dB per decade (the paper's).
    Slope60DbPerDecade,
    /// Interpolated measured gain.
    Table(GainTable),
}

/// `[model]` as written in the file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawModel {
    /// `"paper"` or `"textbook"`. Default `"paper"`.
    pub spreading: Spreading,
    /// `"40db"`, `"60db"` or `"table"`. Default `"60db"` (the paper's).
    pub compensation: CompensationKind,
    /// With `compensation = "table"`: `[{ range_m = .., gain_db = .. }, ..]`.
    pub compensation_table: Option<Vec<RawGainPoint>>,
    /// Beam width, degrees in `(0, 360)`. Default 1.8.
    pub beam_width_deg: f64,
    /// Range resolution c / 2B, m > 0. Default 0.25 (600 MHz sweep).
    pub range_resolution_m: f64,
    /// Bearing noise, degrees > 0. Default 1.0 (book chapter).
    pub sigma_bearing_deg: f64,
    /// Low-pass roll-off corner (3 dB point), m > 0. Default 200 (the paper's unit).
    pub rolloff_corner_m: f64,
    /// Low-pass roll-off order, `[0, 16]`; 0 means no roll-off. Default 4.
    pub rolloff_order: i64,
    /// Range noise (phase noise of a peak's centre), m > 0. Default 0.1, as `radar-model`'s
    /// `RangeSpread` (the paper gives no figure).
    pub sigma_range_m: f64,
    /// Target-present power noise, dB > 0. Default 2.02 (variance 4.07 dB^2, book chapter).
    pub sigma_power_db: f64,
    /// Target-absent noise close in: mean power, dB. Default -14.8 (book chapter, 10 m).
    pub noise_floor_near_mean_db: f64,
    /// Target-absent noise close in: variance, dB^2 > 0. Default 0.35.
    pub noise_floor_near_variance_db2: f64,
    /// Range of the close-in target-absent fit, m > 0. Default 10 (book chapter).
    pub noise_floor_near_range_m: f64,
    /// Range beyond which target-absent noise is Weibull, m > 0. Default 45.
    pub noise_floor_transition_m: f64,
    /// Target-absent Weibull scale, > 0. Default 26.706 (book chapter, 100 m).
    pub noise_floor_weibull_scale: f64,
    /// Target-absent Weibull shape, > 0. Default 5.333.
    pub noise_floor_weibull_shape: f64,
    /// FMCW range-Doppler coupling, s in `[-1, 1]`: a return closing on the radar at `v` m/s
    /// reads `v` times this many metres short, so each detection's range is corrected by
    /// it with the vehicle's speed along the beam. Default 0 (the paper's unit); a Navtech
    /// CTS350-X's sawtooth chirp gives about 0.049 (Burnett et al., 2021, on the Oxford Radar
    /// RobotCar scans). Against the embedded simulator the scene radar's own value is used.
    pub doppler_range_coupling_s: f64,
}

impl Default for RawModel {
    fn default() -> Self {
        Self {
            spreading: Spreading::Paper,
            compensation: CompensationKind::Slope60,
            compensation_table: None,
            beam_width_deg: 1.8,
            range_resolution_m: 0.25,
            sigma_bearing_deg: 1.0,
            rolloff_corner_m: 200.0,
            rolloff_order: 4,
            sigma_range_m: 0.1,
            sigma_power_db: 4.07_f64.sqrt(),
            noise_floor_near_mean_db: -14.8,
            noise_floor_near_variance_db2: 0.35,
            noise_floor_near_range_m: 10.0,
            noise_floor_transition_m: 45.0,
            noise_floor_weibull_scale: 26.706,
            noise_floor_weibull_shape: 5.333,
            doppler_range_coupling_s: 0.0,
        }
    }
}

/// Target-absent noise floor parameters (book chapter figures by default).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseFloor {
    /// Mean power close in, dB.
    pub near_mean_db: FiniteF64,
    /// Variance close in, dB^2.
    pub near_variance_db2: PositiveF64,
    /// Range of the close-in fit, m.
    pub near_range_m: PositiveF64,
    /// Range beyond which the Weibull applies, m.
    pub transition_m: PositiveF64,
    /// Weibull scale.
    pub weibull_scale: PositiveF64,
    /// Weibull shape.
    pub weibull_shape: PositiveF64,
}

/// Low-pass roll-off: `-10 log10(1 + (R / corner_m)^(2 order))` dB.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RollOff {
    /// Corner (3 dB) range, m.
    pub corner_m: PositiveF64,
    /// Filter order.
    pub order: std::num::NonZeroU8,
}

/// `[model]`, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelSettings {
    /// Spreading form.
    pub spreading: Spreading,
    /// Receiver compensation.
    pub compensation: Compensation,
    /// Low-pass roll-off near the end of range; `None` for none.
    pub rolloff: Option<RollOff>,
    /// Beam width, degrees.
    pub beam_width_deg: PositiveF64,
    /// Range resolution, m.
    pub range_resolution_m: PositiveF64,
    /// Bearing noise, degrees.
    pub sigma_bearing_deg: PositiveF64,
    /// Range noise, m.
    pub sigma_range_m: PositiveF64,
    /// Target-present power noise, dB.
    pub sigma_power_db: PositiveF64,
    /// Target-absent noise floor.
    pub noise_floor: NoiseFloor,
    /// FMCW range-Doppler coupling, s: a return closing at `v` m/s reads `v` times this
    /// short.
    pub doppler_range_coupling_s: FiniteF64,
}

impl ModelSettings {
    /// Beam width in radians.
    pub fn beam_width_rad(&self) -> f64 {
        self.beam_width_deg.get().to_radians()
    }
    /// Bearing noise in radians.
    pub fn sigma_bearing_rad(&self) -> f64 {
        self.sigma_bearing_deg.get().to_radians()
    }
}

impl Default for ModelSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let settings = RawModel::default().check(&mut c);
        debug_assert!(c.is_clean(), "the [model] defaults must be valid");
        settings
    }
}

impl RawModel {
    /// Validates this section alone; errors name `model.<field>`.
    pub fn validate(&self) -> Result<ModelSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c);
        c.finish(settings)
    }

    fn check_table(&self, c: &mut Checker) -> Compensation {
        let Some(raw) = &self.compensation_table else {
            c.fail(
                "model.compensation_table",
                ValueError::Rule("is required with model.compensation = \"table\"".into()),
            );
            return Compensation::Slope60DbPerDecade;
        };
        if raw.len() > MAX_GAIN_POINTS {
            c.fail(
                "model.compensation_table",
                ValueError::Rule(format!("must hold at most {MAX_GAIN_POINTS} points")),
            );
            return Compensation::Slope60DbPerDecade;
        }
        let points = raw
            .iter()
            .enumerate()
            .map(|(i, p)| GainPoint {
                range_m: c.check(
                    &format!("model.compensation_table[{i}].range_m"),
                    PositiveF64::new(p.range_m),
                ),
                gain_db: c.check(
                    &format!("model.compensation_table[{i}].gain_db"),
                    FiniteF64::new(p.gain_db),
                ),
            })
            .collect();
        match GainTable::new(points) {
            Ok(table) => Compensation::Table(table),
            Err(problem) => {
                c.fail("model.compensation_table", problem);
                Compensation::Slope60DbPerDecade
            }
        }
    }

    pub(crate) fn check(&self, c: &mut Checker) -> ModelSettings {
        let compensation = match self.compensation {
            CompensationKind::Slope40 | CompensationKind::Slope60
                if self.compensation_table.is_some() =>
            {
                c.fail(
                    "model.compensation_table",
                    ValueError::Rule(
                        "is only used with model.compensation = \"table\"; remove it".into(),
                    ),
                );
                Compensation::Slope60DbPerDecade
            }
            CompensationKind::Slope40 => Compensation::Slope40DbPerDecade,
            CompensationKind::Slope60 => Compensation::Slope60DbPerDecade,
            CompensationKind::Table => self.check_table(c),
        };
        let beam = c.check(
            "model.beam_width_deg",
            PositiveF64::new(self.beam_width_deg),
        );
        let beam_width_deg = if beam.get() >= 360.0 {
            c.fail(
                "model.beam_width_deg",
                ValueError::OutOfRange {
                    range: "(0, 360)".into(),
                    got: beam.to_string(),
                },
            );
            PositiveF64::ONE
        } else {
            beam
        };
        let corner_m = c.check(
            "model.rolloff_corner_m",
            PositiveF64::new(self.rolloff_corner_m),
        );
        let order = c.check(
            "model.rolloff_order",
            crate::values::count(self.rolloff_order, MAX_ROLLOFF_ORDER),
        );
        let rolloff = u8::try_from(order)
            .ok()
            .and_then(std::num::NonZeroU8::new)
            .map(|order| RollOff { corner_m, order });
        ModelSettings {
            spreading: self.spreading,
            compensation,
            rolloff,
            beam_width_deg,
            range_resolution_m: c.check(
                "model.range_resolution_m",
                PositiveF64::new(self.range_resolution_m),
            ),
            sigma_bearing_deg: c.check(
                "model.sigma_bearing_deg",
                PositiveF64::new(self.sigma_bearing_deg),
            ),
            sigma_range_m: c.check("model.sigma_range_m", PositiveF64::new(self.sigma_range_m)),
            sigma_power_db: c.check(
                "model.sigma_power_db",
                PositiveF64::new(self.sigma_power_db),
            ),
            noise_floor: self.check_noise_floor(c),
            doppler_range_coupling_s: self.check_doppler(c),
        }
    }

    /// The range-Doppler coupling: finite and at most 1 s either way (a CTS350-X's is 0.049).
    fn check_doppler(&self, c: &mut Checker) -> FiniteF64 {
        let v = c.check(
            "model.doppler_range_coupling_s",
            FiniteF64::new(self.doppler_range_coupling_s),
        );
        if v.get().abs() > 1.0 {
            c.fail(
                "model.doppler_range_coupling_s",
                ValueError::OutOfRange {
                    range: "[-1, 1]".into(),
                    got: v.get().to_string(),
                },
            );
            return FiniteF64::ZERO;
        }
        v
    }

    /// The target-absent floor; the close-in fit must end before the Weibull starts.
    fn check_noise_floor(&self, c: &mut Checker) -> NoiseFloor {
        let floor = NoiseFloor {
            near_mean_db: c.check(
                "model.noise_floor_near_mean_db",
                FiniteF64::new(self.noise_floor_near_mean_db),
            ),
            near_variance_db2: c.check(
                "model.noise_floor_near_variance_db2",
                PositiveF64::new(self.noise_floor_near_variance_db2),
            ),
            near_range_m: c.check(
                "model.noise_floor_near_range_m",
                PositiveF64::new(self.noise_floor_near_range_m),
            ),
            transition_m: c.check(
                "model.noise_floor_transition_m",
                PositiveF64::new(self.noise_floor_transition_m),
            ),
            weibull_scale: c.check(
                "model.noise_floor_weibull_scale",
                PositiveF64::new(self.noise_floor_weibull_scale),
            ),
            weibull_shape: c.check(
                "model.noise_floor_weibull_shape",
                PositiveF64::new(self.noise_floor_weibull_shape),
            ),
        };
        let (near, transition) = (self.noise_floor_near_range_m, self.noise_floor_transition_m);
        let both_valid = PositiveF64::new(near).is_ok() && PositiveF64::new(transition).is_ok();
        if both_valid && near >= transition {
            c.fail(
                "model.noise_floor_near_range_m",
                ValueError::OutOfRange {
                    range: format!(
                        "(0, noise_floor_transition_m = {})",
                        floor.transition_m.get()
                    ),
                    got: floor.near_range_m.get().to_string(),
                },
            );
        }
        floor
    }
}

impl From<&ModelSettings> for RawModel {
    /// The settings written back out.
    fn from(s: &ModelSettings) -> Self {
        let (compensation, compensation_table) = match &s.compensation {
            Compensation::Slope40DbPerDecade => (CompensationKind::Slope40, None),
            Compensation::Slope60DbPerDecade => (CompensationKind::Slope60, None),
            Compensation::Table(table) => (
                CompensationKind::Table,
                Some(
                    table
                        .points()
                        .iter()
                        .map(|p| RawGainPoint {
                            range_m: p.range_m.get(),
                            gain_db: p.gain_db.get(),
                        })
                        .collect(),
                ),
            ),
        };
        let defaults = RawModel::default();
        Self {
            spreading: s.spreading,
            compensation,
            compensation_table,
            rolloff_corner_m: s
                .rolloff
                .map_or(defaults.rolloff_corner_m, |r| r.corner_m.get()),
            rolloff_order: s.rolloff.map_or(0, |r| i64::from(r.order.get())),
            beam_width_deg: s.beam_width_deg.get(),
            range_resolution_m: s.range_resolution_m.get(),
            sigma_bearing_deg: s.sigma_bearing_deg.get(),
            sigma_range_m: s.sigma_range_m.get(),
            sigma_power_db: s.sigma_power_db.get(),
            noise_floor_near_mean_db: s.noise_floor.near_mean_db.get(),
            noise_floor_near_variance_db2: s.noise_floor.near_variance_db2.get(),
            noise_floor_near_range_m: s.noise_floor.near_range_m.get(),
            noise_floor_transition_m: s.noise_floor.transition_m.get(),
            noise_floor_weibull_scale: s.noise_floor.weibull_scale.get(),
            noise_floor_weibull_shape: s.noise_floor.weibull_shape.get(),
            doppler_range_coupling_s: s.doppler_range_coupling_s.get(),
        }
    }
}
