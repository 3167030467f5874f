//! The daemon's pipeline: per azimuth, range compensation removed and every target
//! detected, grouped across azimuths, handed to the EKF at its own timestamp with the
//! odometry up to that time; whole-spectrum prediction compared with the measurement;
//! diagnostics and outputs per rotation. The processing ([`core`]) does no IO; [`run`] is the
//! thread that feeds it from the driver's channel and odometry and ships its outputs.

pub mod beams;
pub mod clock;
pub mod core;
pub mod counts;
pub mod derive;
pub mod ekf;
pub mod extend;
pub mod frontend;
pub mod gate;
pub mod gyro;
pub mod localise;
pub mod map_save;
pub mod odometry;
pub mod radar_odometry;
pub mod run;
pub mod saved_map;
#[cfg(feature = "sim")]
pub mod scene_truth;
pub mod scores;
pub mod settings;
pub mod spectrum;
pub mod stats;
pub mod submaps;
pub mod summary;
pub mod thinned;
pub mod truth;

pub use self::core::{Pipeline, PipelineError};
pub use derive::{Derived, SettingsRecipe, SourceFacts, Written};
pub use ekf::DaemonEkf;
pub use frontend::{FrontEnd, FrontEndSettings};
pub use run::{run_pipeline, PipelineInputs, RunControl, RunReport};
#[cfg(feature = "sim")]
pub use scene_truth::SceneTruth;
pub use settings::PipelineSettings;
pub use summary::PipelineSummary;
pub use truth::{TrueFeature, TruthObserver, TruthOracle};
