//! A simulated Navtech radar that speaks the real Colossus protocol over TCP.
//!
//! The simulator renders a scene (point features with the paper's reflectivity `rho` and
//! absorption `alpha`, see [`scene`]) as seen by a rotating FMCW radar on a vehicle driven by
//! the paper's process model ([`trajectory`]), one power-range spectrum per azimuth from the
//! pose at that azimuth's own timestamp, through `radar-model`'s spectrum synthesis
//! ([`render`]). It serves those spectra to up to three clients exactly as a Navtech radar
//! does ([`server`]), serves the vehicle's odometry on a second port ([`odometry`]), writes
//! the ground truth ([`truth`]), replays recordings (Oxford/Boreas polar PNGs and raw
//! Colossus byte streams, [`replay`]) and injects faults on request ([`faults`]).
//!
//! IO: this crate does network and file IO (the server, the odometry port, the ground-truth
//! file, scene and recording files). Parsing, rendering and fault logic are plain functions
//! testable without IO.
//!
//! ```no_run
//! # async fn demo() -> Result<(), sim_sensor::SimError> {
//! use sim_sensor::{scene::shipped, SimOptions, SimServer};
//! let scene = shipped::load("penetration-wood")?;
//! let handle = SimServer::spawn(SimOptions::for_tests(scene)).await?;
//! println!("radar on {}, odometry on {:?}", handle.local_addr(), handle.odometry_addr());
//! handle.shutdown().await?;
//! # Ok(()) }
//! ```

pub mod error;
pub mod faults;
pub mod gyro;
pub mod index;
pub mod odometry;
pub mod radar;
pub mod realism;
pub mod render;
pub mod replay;
pub mod scene;
pub mod schedule;
pub mod server;
pub mod settings;
pub mod trajectory;
pub mod truth;
pub mod visits;

pub use error::{ClientError, ReplayError, SceneError, SimError};
pub use faults::{FaultScope, FaultSettings, NoiseBurst, Stall};
pub use server::{SimHandle, SimServer, SimStats, SimStatsSnapshot};
pub use settings::{OdometryNoise, Pacing, ShapingScope, SimOptions, SourceSpec};
