//! The augmented-state EKF of Jose and Adams: vehicle pose, each feature's position and
//! material (reflected and absorbed shares, held as softmax logits u, v), and the radar's
//! loss L, estimated from odometry and from the range, bearing and power of every target
//! down each beam. No IO and no clock: time comes in with the data.
//!
//! - [`state`]: storage, layout, augmenting and removing features with stable ids.
//! - [`predict`]: the process model (radar-model's eq. 2 or bicycle) to any time, O(n).
//! - [`observation`]: beam observations and the observation-model seam.
//! - [`update`]: the batched, Cholesky-factorised, symmetric O(n^2 m) update.
//! - [`beam`]: which features a beam concerns, and their joint prediction.
//! - [`association`]: chi-square gates, nearest neighbour, JCBB.
//! - [`lifecycle`]: tentative targets and their confirmation.
//! - [`health`]: NEES and covariance health.
//! - [`radar`]: radar-model's physics behind the filter's traits.
//! - [`ekf`]: [`Ekf`], the whole filter per beam.
//! - [`settings`]: [`FilterSettings`], plain validated values.
//!
//! Two departures from the textbook EKF, both measured on the simulator (60-seed ensemble,
//! `slam-node/README.md`) and both switchable:
//!
//! - **First-estimates Jacobians** (Huang, Mourikis and Roumeliotis): each feature's range,
//!   bearing and power Jacobians are evaluated at the position it entered the state with,
//!   and the propagation at the pose as last predicted, so every linearisation agrees that a
//!   rotation of the whole world is unobservable ([`beam::relinearise_at_first_estimates`]).
//!   The standard EKF, linearising each feature at a moving estimate, gains information on
//!   the map's global heading that no measurement carries.
//! - **Repeat-look decorrelation**: while a feature stays within one range cell and one beam
//!   width of where a run of looks began (a parked or slow vehicle), its k-th look is used
//!   with k times its noise variance: the errors tied to the geometry (azimuth and bin
//!   quantisation, partial occlusion, speckle) repeat from rotation to rotation. Looks of
//!   one sweep (neighbouring azimuths) stay independent.

pub mod association;
pub mod beam;
pub mod ekf;
pub mod error;
pub mod health;
pub mod lifecycle;
pub mod observation;
pub mod predict;
pub mod radar;
pub mod settings;
pub mod state;
pub mod update;

pub use beam::BeamCandidate;
pub use ekf::{BeamReport, Ekf, FeatureEstimate, FilterStats};
pub use error::FilterError;
pub use health::CovarianceHealth;
pub use observation::{BeamObservation, BeamObservationModel, RangeBearingModel, Target};
pub use predict::{OdometrySample, ProcessModel};
pub use radar::RadarBeamModel;
pub use settings::{FilterSettings, SettingsError};
pub use state::{FeatureId, SlamState};
pub use update::{batched_update, LinearisedObservation, UpdateOutcome};
