//! What the filter reports: a feature's estimate, one beam's report, the running totals, a
//! rotation's repeatability score and a motion measurement's outcome. Plain values.

use nalgebra::Matrix2;

use crate::state::FeatureId;
use crate::update::UpdateOutcome;

/// A feature as reported: position, material shares (not the logits), uncertainty.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureEstimate {
    /// Stable id.
    pub id: FeatureId,
    /// World x (m).
    pub x_m: f64,
    /// World y (m).
    pub y_m: f64,
    /// Reflected share.
    pub rho: f64,
    /// Absorbed share.
    pub alpha: f64,
    /// Position covariance (m^2).
    pub position_cov: Matrix2<f64>,
    /// Observations used.
    pub hits: u64,
}

/// What processing one beam did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BeamReport {
    /// The beam's features (in range order) that were candidates.
    pub candidates: Vec<FeatureId>,
    /// `(target index, feature)` pairs used in the update.
    pub associated: Vec<(usize, FeatureId)>,
    /// The batched update's NIS and dof, if one ran.
    pub update: Option<UpdateOutcome>,
    /// Features initialised from confirmed tentatives.
    pub initialised: Vec<FeatureId>,
    /// Features retired for repeated misses.
    pub retired: Vec<FeatureId>,
    /// Targets that started a new tentative.
    pub new_tentatives: usize,
    /// Unpaired targets inside some feature's exclusion gate (neither used nor tentative).
    pub excluded_targets: usize,
    /// Whether JCBB ran, and whether it exhausted its budget.
    pub used_jcbb: bool,
    /// JCBB stopped at its node budget.
    pub jcbb_budget_exhausted: bool,
}

/// Running totals.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FilterStats {
    /// Batched updates applied.
    pub updates: u64,
    /// Sum of NIS over updates.
    pub nis_sum: f64,
    /// Sum of their degrees of freedom (mean NIS / mean dof ~ 1 when consistent).
    pub nis_dof_sum: u64,
    /// Features initialised.
    pub initialised: u64,
    /// Features retired.
    pub retired: u64,
    /// Beams where JCBB ran.
    pub jcbb_runs: u64,
    /// Odometry samples older than the state (held from the state's time instead).
    pub late_odometry: u64,
    /// Targets dropped because the tentative list (or the state) was full.
    pub dropped_targets: u64,
    /// Unpaired targets inside some feature's exclusion gate.
    pub excluded_targets: u64,
    /// Odometry gaps bridged by re-initialising the pose covariance.
    pub bridged_gaps: u64,
    /// Of the bridged gaps and clock resynchronisations, those met with no map to relocalise
    /// against (no feature mapped, or fewer than
    /// [`FilterSettings::relocalise_min_features`](crate::FilterSettings::relocalise_min_features),
    /// which were dropped): the map frame was re-anchored at the pose estimate and the pose
    /// covariance not grown.
    pub reanchored_gaps: u64,
    /// Relocalisations accepted after a gap (see
    /// [`FilterSettings::relocalise_after_gap`](crate::FilterSettings::relocalise_after_gap)).
    pub relocalisations: u64,
    /// Turns held and tried for a relocalisation (accepted or not).
    pub relocalisation_attempts: u64,
    /// Relocalisations given up after
    /// [`FilterSettings::relocalise_give_up_s`](crate::FilterSettings::relocalise_give_up_s).
    pub relocalisations_abandoned: u64,
    /// Beams not used because the target rate was a burst (see
    /// [`FilterSettings::burst_factor`](crate::FilterSettings::burst_factor)).
    pub burst_beams: u64,
    /// Measurements of the motion since a mark applied
    /// ([`Ekf::observe_motion_since_mark`](crate::Ekf::observe_motion_since_mark)).
    pub motion_updates: u64,
    /// Features retired for being re-observed too rarely
    /// ([`Ekf::score_rotation`](crate::Ekf::score_rotation); also counted in `retired`).
    pub retired_unrepeatable: u64,
}

/// What [`Ekf::score_rotation`](crate::Ekf::score_rotation) counted over one rotation.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RotationScore {
    /// Features mapped before the rotation and in view during it.
    pub in_view: u64,
    /// Of those, the ones a target was associated with.
    pub reobserved: u64,
    /// Features retired as unrepeatable.
    pub retired: Vec<FeatureId>,
}

/// What a measurement of the motion since a mark did
/// ([`Ekf::observe_motion_since_mark`](crate::Ekf::observe_motion_since_mark)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotionOutcome {
    /// Applied, with its normalised innovation squared (3 dof).
    Applied {
        /// Normalised innovation squared.
        nis: f64,
    },
    /// Refused by the gate; nothing changed.
    Gated {
        /// Normalised innovation squared.
        nis: f64,
    },
    /// No mark to measure from; nothing changed.
    NoMark,
}
