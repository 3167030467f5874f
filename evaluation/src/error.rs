//! The evaluation's errors: every failure of a measurement is a variant here.

use std::path::PathBuf;

use thiserror::Error;

/// Why an evaluation step could not be carried out.
#[derive(Debug, Error)]
pub enum EvalError {
    /// A shipped scene did not load.
    #[error("scene")]
    Scene(#[from] sim_sensor::SceneError),
    /// The simulator failed to render.
    #[error("simulator")]
    Sim(#[from] sim_sensor::SimError),
    /// radar-model rejected an input.
    #[error("radar model")]
    Model(#[from] radar_model::ModelError),
    /// The filter rejected its settings or its initial state.
    #[error("filter")]
    Filter(#[from] slam_filter::FilterError),
    /// A recorded scan could not be read.
    #[error("replay")]
    Replay(#[from] sim_sensor::ReplayError),
    /// Recorded ground truth could not be read.
    #[error("ground truth")]
    Truth(#[from] sim_sensor::replay::truth::TruthError),
    /// A data file held something unexpected.
    #[error("{path}: line {line}: {reason}")]
    Data {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What was wrong.
        reason: String,
    },
    /// Reading or writing a file failed.
    #[error("{path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Drawing a figure failed.
    #[error("figure {name}: {reason}")]
    Plot {
        /// The figure's file name.
        name: String,
        /// The drawing backend's message.
        reason: String,
    },
    /// A setting of the evaluation itself makes no sense.
    #[error("invalid evaluation setting: {0}")]
    Setting(String),
}
