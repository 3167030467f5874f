//! The filter as the daemon uses it: odometry in, one beam at a time in, estimates out.
//!
//! Per beam: reject non-finite input (state untouched), predict to the beam's timestamp,
//! find the features inside the beam (sorted by range), predict their `(R, beta, P)`,
//! associate (gate, nearest neighbour or JCBB), apply one batched update, count misses and
//! retire features not seen where they should be, and pass unclaimed targets to the
//! tentative list, initialising the ones it confirms.
//!
//! This module holds [`Ekf`] and its construction; its jobs are in the submodules:
//!
//! - `steps`: the beam entry points ([`Ekf::process_beam`], [`Ekf::process_beam_offered`])
//!   in the paper's steps, and a beam with no targets;
//! - `beam_update`: a beam's observation prediction (eq. 13), association and batched update;
//! - `burst`: the guard against bursts of targets;
//! - `init`: unclaimed targets to tentatives, and confirmed ones into the state;
//! - `map`: hits, misses and retirement, the lazily added feature noise, submaps;
//! - `prediction`: odometry, the prediction to a time, gaps and clock changes;
//! - `motion`: the measured motion since a mark (stochastic cloning);
//! - `relocalise`: relocalisation against the map after a gap;
//! - `known`: features known beforehand (a saved map's) put into the state and taken out;
//! - `queries`: the estimates and counts a caller reads;
//! - `report`: the values those return.

mod beam_update;
mod burst;
mod init;
mod known;
mod map;
mod motion;
mod prediction;
mod queries;
mod relocalise;
mod report;
mod steps;

use nalgebra::Matrix3;
use radar_model::geometry::Pose2;

use crate::association::GateTable;
use crate::error::FilterError;
use crate::lifecycle::TentativeList;
use crate::observation::BeamObservationModel;
use crate::predict::{OdometrySample, ProcessModel};
use crate::settings::FilterSettings;
use crate::state::SlamState;
use burst::TargetRate;
use relocalise::Relocalisation;

pub use report::{BeamReport, FeatureEstimate, FilterStats, MotionOutcome, RotationScore};

/// The augmented-state EKF with its models.
#[derive(Debug, Clone)]
pub struct Ekf<M, O> {
    settings: FilterSettings,
    gates: GateTable,
    exclusion: GateTable,
    state: SlamState,
    motion: M,
    observer: O,
    odometry: Option<OdometrySample>,
    tentatives: TentativeList,
    stats: FilterStats,
    /// Set after a bridged gap until the pose is relocalised against the map.
    relocalising: Option<Relocalisation>,
    /// Targets per second, for the burst guard.
    target_rate: TargetRate,
    /// Time of the latest beam the filter mapped with (predicted to, or took as empty with
    /// odometry held; not refused, not held for a relocalisation): a rotation with none is
    /// not scored by [`Self::score_rotation`].
    last_mapped_beam_s: f64,
    /// Time of the latest beam judged part of a burst (see
    /// [`FilterSettings::burst_factor`]): no feature counts as unseen before it.
    last_burst_beam_s: f64,
}

impl<M: ProcessModel, O: BeamObservationModel> Ekf<M, O> {
    /// A filter at `pose` (covariance `pose_cov`) at `time_s`, with no features.
    pub fn new(
        settings: FilterSettings,
        pose: Pose2,
        pose_cov: Matrix3<f64>,
        time_s: f64,
        motion: M,
        observer: O,
    ) -> Result<Self, FilterError> {
        settings.validate()?;
        let mut state = SlamState::new(
            pose,
            pose_cov,
            settings.initial_loss_db,
            settings.initial_loss_std_db.powi(2),
            time_s,
        )?;
        state.set_odometry_bias_prior([
            settings.speed_scale_std.powi(2),
            settings.steer_bias_std_rad.powi(2),
        ]);
        Ok(Self {
            gates: GateTable::new(settings.gate_probability, 24),
            exclusion: GateTable::new(
                settings
                    .exclusion_probability
                    .max(settings.gate_probability),
                3,
            ),
            settings,
            state,
            motion,
            observer,
            odometry: None,
            tentatives: TentativeList::default(),
            stats: FilterStats::default(),
            relocalising: None,
            target_rate: TargetRate::default(),
            last_mapped_beam_s: f64::NEG_INFINITY,
            last_burst_beam_s: f64::NEG_INFINITY,
        })
    }
}
