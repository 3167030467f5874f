//! The paper's power-range physics (Jose and Adams, augmented-state SLAM for multiple
//! line-of-sight features with millimetre-wave radar): beam geometry (eq. 3, 4), material
//! parameters as `softmax(u, v, 0)`, multi-target received power (eq. 13, paper and
//! textbook forms) with analytic Jacobians, the per-beam observation `[R, beta, P]` and its
//! dense Jacobian, receiver range compensation, the book chapter's noise models, and
//! whole-spectrum prediction, synthesis and comparison (figures 8-10).
//!
//! **No IO and no clock**: every function is pure, apart from random draws from a
//! caller-supplied (seedable) generator.
//!
//! Conventions (see `docs/contracts.md`): SI units, f64, angles wrapped to (-pi, pi];
//! bearing `beta = wrap(theta - atan2(dy, dx))` (clockwise); observed power `P_i` is
//! uncompensated (`eq. 13 in dB - L`); measured spectra carry the compensation.
//!
//! # Choices, in one place (each module documents its own)
//!
//! | what | choice |
//! |---|---|
//! | constants | `P_t` 15 dBm, `lambda` 3.89 mm, `G` 38.5 dBi, `A_I` 200 m^2 (`power`) |
//! | wire calibration | `rho = 1`, `L = 0` reads 80 dB; 1 m^2 reads 57 dB (`compensation`) |
//! | compensation | 40 dB/decade by default, 60 (paper) or a table; roll-off 200 m, order 4 |
//! | coincident targets | separations `sqrt(dR^2 + dr^2)`, `dr` 0.25 m; pairs closer than `dr` flagged |
//! | material | `softmax(u, v, 0)`, log-space, Jacobians within [-1, 1]; clamping only from user shares |
//! | floor | chapter's `power + 15 dB` on the wire: 0.2 dB at 10 m, Weibull (24.6 dB) beyond 45 m |
//! | peaks | Gaussian, FWHM = `dr`; phase-noise jitter 0.1 m (assumed); power noise 4.07 dB^2 |

pub mod compensation;
pub mod error;
pub mod geometry;
pub mod layout;
pub mod material;
pub mod motion;
pub mod noise;
pub mod observation;
pub mod power;
pub mod profile;
pub mod spectrum;

pub use compensation::{Compensation, GainCurve, GainTable, RollOff};
pub use error::ModelError;
pub use geometry::{
    features_in_beam, range_bearing, range_bearing_with_jacobian, wrap_angle, Beam, BeamHit, Pose2,
    RangeBearing, RangeBearingJacobian,
};
pub use material::{Material, Shares};
pub use motion::{ControlInput, MotionJacobian, MotionModel};
pub use noise::{seeded_rng, NoiseModel};
pub use observation::{observe_beam, BeamFeature, BeamObservation, Observation};
pub use power::{
    beam_powers_db, beam_powers_with_jacobian, BeamPowers, PowerModel, PowerTarget, RadarConstants,
    SpreadingForm,
};
pub use profile::{Announced, Choice, RadarProfile};
pub use spectrum::{SpectrumGeometry, SpectrumModel, SpectrumTarget};
