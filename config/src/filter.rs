//! `[filter]`: the augmented-state EKF's initial state, process noise on the material
//! parameters, gating, association and feature life cycle.

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::values::{
    Capacity, FiniteF64, NonNegativeF64, OpenProbability, PositiveF64, Probability, ValueError,
};

/// Most features the state may be configured to hold.
pub const MAX_FEATURES: usize = 100_000;
/// Most sightings or misses a life-cycle rule may count.
pub const MAX_LIFE_CYCLE_COUNT: usize = 1_000;
/// Default gate probability.
pub const DEFAULT_GATE_PROBABILITY: f64 = 0.99;

/// Data association.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Association {
    /// Nearest neighbour inside the gate.
    NearestNeighbour,
    /// Joint compatibility branch and bound.
    Jcbb,
}

/// The chi-square gate on the innovation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Gate {
    /// Accept innovations inside this probability mass; the threshold follows from the
    /// innovation's dimension (11.34 for 3 at 0.99).
    Probability(OpenProbability),
    /// A fixed chi-square threshold.
    Chi2(PositiveF64),
}

/// `[filter]` as written in the file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawFilter {
    /// Initial x, m. Default 0.
    pub initial_x_m: f64,
    /// Initial y, m. Default 0.
    pub initial_y_m: f64,
    /// Initial heading, rad (wrapped to (-pi, pi]). Default 0.
    pub initial_theta_rad: f64,
    /// Initial x standard deviation, m >= 0. Default 0 (the map frame is the start pose).
    pub initial_sigma_x_m: f64,
    /// Initial y standard deviation, m >= 0. Default 0.
    pub initial_sigma_y_m: f64,
    /// Initial heading standard deviation, rad >= 0. Default 0.
    pub initial_sigma_theta_rad: f64,
    /// Random-walk noise on each feature's `u`, per sqrt(second), >= 0. Default 0.01.
    pub sigma_u: f64,
    /// Random-walk noise on each feature's `v`, per sqrt(second), >= 0. Default 0.01.
    pub sigma_v: f64,
    /// How far each feature's apparent position (x and y) may wander between looks, m >= 0:
    /// a return that is not a true point (a crown, a car body, a patch of clutter) peaks at
    /// a point that moves as the viewpoint moves. Between looks `d` metres of driving apart
    /// its variances grow by `sigma_wander_m^2 (1 - exp(-d / wander_length_m))`. Default 0
    /// (point targets).
    pub sigma_wander_m: f64,
    /// Distance driven over which a feature's apparent position decorrelates, m > 0.
    /// Default 2.
    pub wander_length_m: f64,
    /// Initial radar loss L, dB. Default 0.
    pub initial_loss_db: f64,
    /// Initial loss standard deviation, dB > 0. Default 3.
    pub initial_sigma_loss_db: f64,
    /// Gate probability in `(0, 1)`; set this or `gate_chi2`, not both. Default 0.99.
    pub gate_probability: Option<f64>,
    /// Fixed chi-square gate, > 0; instead of `gate_probability`.
    pub gate_chi2: Option<f64>,
    /// `"nearest-neighbour"` or `"jcbb"`. Default `"nearest-neighbour"`.
    pub association: Association,
    /// Sightings before a tentative feature enters the state, `[1, 1000]`. Default 2.
    pub confirm_after: i64,
    /// Misses (predicted visible, not seen) before a feature is retired, `[1, 1000]`.
    /// Default 5.
    pub retire_after_misses: i64,
    /// A feature in the radar's range that nothing was associated with for this long is
    /// retired, s >= 0 (0 = never). Default 4 (ten rotations of the paper's unit).
    pub retire_unseen_after_s: f64,
    /// A feature re-observed in fewer than this share of the rotations it was in view (once
    /// in view for `repeatability_min_rotations`) is retired as unrepeatable, `[0, 1]` (0 =
    /// never). Default 0.5: a landmark is re-observed in most of the rotations it is in
    /// view; clutter, phantoms and the passing peaks of extended returns are not.
    pub retire_unrepeatable_below: f64,
    /// Rotations in view before a feature's repeatability is judged, `[1, 1000]`. Default 8.
    pub repeatability_min_rotations: i64,
    /// Most features in the state, `[1, 100000]`. Default 1000.
    pub max_features: i64,
    /// Observe power as well as range and bearing. Default true.
    pub use_power_in_observation: bool,
    /// Linearise each feature's observation at its first estimate (the FEJ-EKF), so the
    /// filter does not gain false confidence in the map's global heading. Default true.
    pub first_estimate_jacobians: bool,
    /// Count repeated looks at a feature from an unchanged viewpoint (within one range
    /// resolution cell and one beam width) as correlated: the k-th look of such a run is
    /// used with k times its noise variance. Default true.
    pub repeat_look_decorrelation: bool,
    /// The k-th repeated look is used with `min(k, repeat_look_max_factor)` times its noise
    /// variance: without a cap a vehicle parked for hours is held ever more loosely to its
    /// map (slam-node/README.md, "Hours"). At least 1 (`inf`: no cap). Default 32.
    pub repeat_look_max_factor: f64,
}

impl Default for RawFilter {
    fn default() -> Self {
        Self {
            initial_x_m: 0.0,
            initial_y_m: 0.0,
            initial_theta_rad: 0.0,
            initial_sigma_x_m: 0.0,
            initial_sigma_y_m: 0.0,
            initial_sigma_theta_rad: 0.0,
            sigma_u: 0.01,
            sigma_v: 0.01,
            sigma_wander_m: 0.0,
            wander_length_m: 2.0,
            initial_loss_db: 0.0,
            initial_sigma_loss_db: 3.0,
            gate_probability: None,
            gate_chi2: None,
            association: Association::NearestNeighbour,
            confirm_after: 2,
            retire_after_misses: 5,
            retire_unseen_after_s: 4.0,
            retire_unrepeatable_below: 0.5,
            repeatability_min_rotations: 8,
            max_features: 1000,
            use_power_in_observation: true,
            first_estimate_jacobians: true,
            repeat_look_decorrelation: true,
            repeat_look_max_factor: 32.0,
        }
    }
}

/// The initial pose and its standard deviations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InitialPose {
    /// x, m.
    pub x_m: FiniteF64,
    /// y, m.
    pub y_m: FiniteF64,
    /// Heading, rad, in (-pi, pi].
    pub theta_rad: FiniteF64,
    /// x standard deviation, m.
    pub sigma_x_m: NonNegativeF64,
    /// y standard deviation, m.
    pub sigma_y_m: NonNegativeF64,
    /// Heading standard deviation, rad.
    pub sigma_theta_rad: NonNegativeF64,
}

/// `[filter]`, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterSettings {
    /// Initial pose.
    pub initial_pose: InitialPose,
    /// Noise on `u`, per sqrt(second).
    pub sigma_u: NonNegativeF64,
    /// Noise on `v`, per sqrt(second).
    pub sigma_v: NonNegativeF64,
    /// How far a feature's apparent position may wander between looks, m.
    pub sigma_wander_m: NonNegativeF64,
    /// Distance driven over which it decorrelates, m.
    pub wander_length_m: PositiveF64,
    /// Initial loss, dB.
    pub initial_loss_db: FiniteF64,
    /// Initial loss standard deviation, dB.
    pub initial_sigma_loss_db: PositiveF64,
    /// Gate.
    pub gate: Gate,
    /// Association.
    pub association: Association,
    /// Sightings to confirm.
    pub confirm_after: Capacity,
    /// Misses to retire.
    pub retire_after_misses: Capacity,
    /// Retire features in range unseen for this long, s (0 = never).
    pub retire_unseen_after_s: NonNegativeF64,
    /// Retire features re-observed in fewer than this share of rotations in view (0 = never).
    pub retire_unrepeatable_below: Probability,
    /// Rotations in view before repeatability is judged.
    pub repeatability_min_rotations: Capacity,
    /// Most features.
    pub max_features: Capacity,
    /// Observe power.
    pub use_power_in_observation: bool,
    /// First-estimates Jacobians.
    pub first_estimate_jacobians: bool,
    /// Repeated looks from one viewpoint counted as correlated.
    pub repeat_look_decorrelation: bool,
    /// The cap on a repeated look's variance factor, at least 1 (may be infinite).
    pub repeat_look_max_factor: f64,
}

impl Default for FilterSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let settings = RawFilter::default().check(&mut c);
        debug_assert!(c.is_clean(), "the [filter] defaults must be valid");
        settings
    }
}

/// Wraps an angle to (-pi, pi].
fn wrap_angle(angle: f64) -> f64 {
    use std::f64::consts::PI;
    let wrapped = (angle + PI).rem_euclid(2.0 * PI) - PI;
    if wrapped <= -PI {
        wrapped + 2.0 * PI
    } else {
        wrapped
    }
}

impl RawFilter {
    /// Validates this section alone; errors name `filter.<field>`.
    pub fn validate(&self) -> Result<FilterSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c);
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker) -> FilterSettings {
        let theta = c.check(
            "filter.initial_theta_rad",
            FiniteF64::new(self.initial_theta_rad),
        );
        let initial_pose = InitialPose {
            x_m: c.check("filter.initial_x_m", FiniteF64::new(self.initial_x_m)),
            y_m: c.check("filter.initial_y_m", FiniteF64::new(self.initial_y_m)),
            theta_rad: FiniteF64::new(wrap_angle(theta.get())).unwrap_or(FiniteF64::ZERO),
            sigma_x_m: c.check(
                "filter.initial_sigma_x_m",
                NonNegativeF64::new(self.initial_sigma_x_m),
            ),
            sigma_y_m: c.check(
                "filter.initial_sigma_y_m",
                NonNegativeF64::new(self.initial_sigma_y_m),
            ),
            sigma_theta_rad: c.check(
                "filter.initial_sigma_theta_rad",
                NonNegativeF64::new(self.initial_sigma_theta_rad),
            ),
        };
        let gate = match (self.gate_probability, self.gate_chi2) {
            (Some(_), Some(_)) => {
                c.fail(
                    "filter.gate_chi2",
                    ValueError::Rule("cannot be set together with filter.gate_probability".into()),
                );
                Gate::Probability(OpenProbability::HALF)
            }
            (None, Some(chi2)) => Gate::Chi2(c.check("filter.gate_chi2", PositiveF64::new(chi2))),
            (p, None) => Gate::Probability(c.check(
                "filter.gate_probability",
                OpenProbability::new(p.unwrap_or(DEFAULT_GATE_PROBABILITY)),
            )),
        };
        FilterSettings {
            initial_pose,
            sigma_u: c.check("filter.sigma_u", NonNegativeF64::new(self.sigma_u)),
            sigma_v: c.check("filter.sigma_v", NonNegativeF64::new(self.sigma_v)),
            sigma_wander_m: c.check(
                "filter.sigma_wander_m",
                NonNegativeF64::new(self.sigma_wander_m),
            ),
            wander_length_m: c.check(
                "filter.wander_length_m",
                PositiveF64::new(self.wander_length_m),
            ),
            initial_loss_db: c.check(
                "filter.initial_loss_db",
                FiniteF64::new(self.initial_loss_db),
            ),
            initial_sigma_loss_db: c.check(
                "filter.initial_sigma_loss_db",
                PositiveF64::new(self.initial_sigma_loss_db),
            ),
            gate,
            association: self.association,
            confirm_after: c.check(
                "filter.confirm_after",
                Capacity::new(self.confirm_after, MAX_LIFE_CYCLE_COUNT),
            ),
            retire_after_misses: c.check(
                "filter.retire_after_misses",
                Capacity::new(self.retire_after_misses, MAX_LIFE_CYCLE_COUNT),
            ),
            retire_unseen_after_s: c.check(
                "filter.retire_unseen_after_s",
                NonNegativeF64::new(self.retire_unseen_after_s),
            ),
            retire_unrepeatable_below: c.check(
                "filter.retire_unrepeatable_below",
                Probability::new(self.retire_unrepeatable_below),
            ),
            repeatability_min_rotations: c.check(
                "filter.repeatability_min_rotations",
                Capacity::new(self.repeatability_min_rotations, MAX_LIFE_CYCLE_COUNT),
            ),
            max_features: c.check(
                "filter.max_features",
                Capacity::new(self.max_features, MAX_FEATURES),
            ),
            use_power_in_observation: self.use_power_in_observation,
            first_estimate_jacobians: self.first_estimate_jacobians,
            repeat_look_decorrelation: self.repeat_look_decorrelation,
            repeat_look_max_factor: c.check(
                "filter.repeat_look_max_factor",
                at_least_one(self.repeat_look_max_factor),
            ),
        }
    }
}

/// A variance factor: at least 1, infinity allowed (no cap).
fn at_least_one(v: f64) -> Result<f64, ValueError> {
    if v >= 1.0 {
        Ok(v)
    } else {
        Err(ValueError::Rule(format!(
            "must be at least 1 (inf: no cap), got {v}"
        )))
    }
}

impl From<&FilterSettings> for RawFilter {
    /// The settings written back out.
    fn from(s: &FilterSettings) -> Self {
        let (gate_probability, gate_chi2) = match s.gate {
            Gate::Probability(p) => (Some(p.get()), None),
            Gate::Chi2(x) => (None, Some(x.get())),
        };
        let p = &s.initial_pose;
        Self {
            initial_x_m: p.x_m.get(),
            initial_y_m: p.y_m.get(),
            initial_theta_rad: p.theta_rad.get(),
            initial_sigma_x_m: p.sigma_x_m.get(),
            initial_sigma_y_m: p.sigma_y_m.get(),
            initial_sigma_theta_rad: p.sigma_theta_rad.get(),
            sigma_u: s.sigma_u.get(),
            sigma_v: s.sigma_v.get(),
            sigma_wander_m: s.sigma_wander_m.get(),
            wander_length_m: s.wander_length_m.get(),
            initial_loss_db: s.initial_loss_db.get(),
            initial_sigma_loss_db: s.initial_sigma_loss_db.get(),
            gate_probability,
            gate_chi2,
            association: s.association,
            confirm_after: crate::values::as_i64(s.confirm_after.get()),
            retire_after_misses: crate::values::as_i64(s.retire_after_misses.get()),
            retire_unseen_after_s: s.retire_unseen_after_s.get(),
            retire_unrepeatable_below: s.retire_unrepeatable_below.get(),
            repeatability_min_rotations: crate::values::as_i64(s.repeatability_min_rotations.get()),
            max_features: crate::values::as_i64(s.max_features.get()),
            use_power_in_observation: s.use_power_in_observation,
            first_estimate_jacobians: s.first_estimate_jacobians,
            repeat_look_decorrelation: s.repeat_look_decorrelation,
            repeat_look_max_factor: s.repeat_look_max_factor,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::wrap_angle;
    use std::f64::consts::PI;

    #[test]
    fn angles_wrap_into_minus_pi_exclusive_to_pi_inclusive() {
        for (angle, wrapped) in [
            (0.0, 0.0),
            (PI, PI),
            (-PI, PI),
            (3.0 * PI, PI),
            (2.0 * PI, 0.0),
            (-0.5, -0.5),
            (7.0, 7.0 - 2.0 * PI),
        ] {
            assert!(
                (wrap_angle(angle) - wrapped).abs() < 1e-12,
                "{angle} -> {}",
                wrap_angle(angle)
            );
        }
    }
}
