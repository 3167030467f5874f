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
