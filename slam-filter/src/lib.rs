//! The augmented-state EKF of Jose and Adams: vehicle pose, each feature's position and
//! material (reflected and absorbed shares, held as softmax logits u, v), and the radar's
//! loss L, estimated from odometry and from the range, bearing and power of every target
//! down each beam. No IO and no clock: time comes in with the data. No dependency on the
//! daemon's configuration, the radar driver or the simulator.
//!
//! The API a user needs is small: build an [`Ekf`] from [`FilterSettings`], an initial pose
//! and covariance, a process model ([`radar_model::motion::MotionModel`]) and a beam model
//! ([`RadarBeamModel`], or [`RangeBearingModel`] for plain range-bearing SLAM); feed it
//! [`OdometrySample`]s with [`Ekf::apply_odometry`] and every beam's targets as a
//! [`BeamObservation`] with [`Ekf::process_beam`] (which reads as the paper's steps); read
//! [`Ekf::pose`], [`Ekf::pose_covariance`] and [`Ekf::features`] (call
//! [`Ekf::settle_material_noise`] first when the material variances must be current). The
//! example `examples/drive_past_posts.rs` does exactly that. The modules below are public
//! for tests and for those who assemble a filter of their own.
//!
//! - [`state`]: storage, layout, augmenting and removing features with stable ids.
//! - [`predict`]: the process model (radar-model's eq. 2 or bicycle) to any time, O(n).
//! - [`observation`]: beam observations and the observation-model seam; rows and columns
//!   of a beam's Jacobian as [`radar_model::layout`] defines them.
//! - [`update`]: the batched, Cholesky-factorised, symmetric O(n^2 m) update.
//! - [`beam`]: which features a beam concerns, and their joint prediction.
//! - [`fej`]: first-estimates Jacobians.
//! - [`repeat_look`]: repeat-look decorrelation.
//! - [`association`]: chi-square gates, nearest neighbour, JCBB.
//! - [`lifecycle`]: tentative targets and their confirmation.
//! - [`health`]: NEES and covariance health.
//! - [`radar`]: radar-model's physics behind the filter's traits.
//! - [`ekf`]: [`Ekf`], the whole filter per beam.
//! - [`submap`]: local submaps of bounded size ([`Ekf::start_submap`]) and their frozen records.
//! - [`settings`]: [`FilterSettings`], plain validated values.
//!
//! Two departures from the textbook EKF, both measured on the simulator (60-seed ensemble,
//! `slam-node/README.md`) and both switchable:
//!
//! - **First-estimates Jacobians** (Huang, Mourikis and Roumeliotis): each feature's range,
//!   bearing and power Jacobians are evaluated at the position it entered the state with,
//!   and the propagation at the pose as last predicted, so every linearisation agrees that a
//!   rotation of the whole world is unobservable ([`fej`]).
//!   The standard EKF, linearising each feature at a moving estimate, gains information on
//!   the map's global heading that no measurement carries.
//! - **Repeat-look decorrelation**: while a feature stays within one range cell and one beam
//!   width of where a run of looks began (a parked or slow vehicle), its k-th look is used
//!   with k times its noise variance: the errors tied to the geometry (azimuth and bin
//!   quantisation, partial occlusion, speckle) repeat from rotation to rotation. Looks of
//!   one sweep (neighbouring azimuths) stay independent.

pub mod association;
pub mod beam;
pub mod drift;
pub mod ekf;
pub mod error;
pub mod fej;
pub mod health;
mod id;
pub mod lifecycle;
pub mod motion_tally;
pub mod observation;
pub mod predict;
pub mod process;
pub mod radar;
pub mod repeat_look;
pub mod settings;
pub mod state;
pub mod submap;
mod symmetric;
pub mod update;

pub use beam::BeamCandidate;
pub use ekf::{BeamReport, Ekf, FeatureEstimate, FilterStats, MotionOutcome, RotationScore};
pub use error::FilterError;
pub use health::CovarianceHealth;
pub use observation::{BeamObservation, BeamObservationModel, RangeBearingModel, Target};
pub use predict::{OdometrySample, ProcessModel};
pub use radar::RadarBeamModel;
pub use settings::{FilterSettings, SettingsError};
pub use state::{FeatureId, SlamState};
pub use submap::{FrozenSubmap, SubmapFeature, SubmapLimits};
pub use update::{batched_update, LinearisedObservation, UpdateOutcome};

/// The filter with radar-model's physics: its motion models and the multi-target beam
/// observation of eq. 13.
pub type RadarEkf = Ekf<radar_model::motion::MotionModel, RadarBeamModel>;
