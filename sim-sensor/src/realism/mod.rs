//! The realistic renderer: what a Navtech radar's spectra look like on a real street, behind
//! a scene's `[realism]` table (a scene without it renders exactly as before, with
//! radar-model's point-target synthesis).
//!
//! What it adds, module by module:
//! - [`objects`]: extended and distributed targets (building fronts, walls, fences, hedges,
//!   parked and moving vehicles, trees, poles) expanded into many scatterers along their
//!   extent, each with a radar cross section, a surface normal (incidence-angle dependence
//!   of a flat surface: a diffuse `cos^n` term and a specular lobe), a Swerling fluctuation
//!   class, and the outline (segment or disk) that occludes or partly transmits what stands
//!   behind it;
//! - [`receiver`]: the receiver's side: the range kernel of the FMCW window (the window's
//!   power spectrum, with its sidelobes), the antenna's two-way azimuth pattern (an aperture
//!   with a tapered illumination, with its sidelobes), the fitted noise floor (a gamma
//!   distributed power per bin with a mean per range), and the unit's output quantisation
//!   (integer power, `dB = c 10 log10 k`, clipped);
//! - [`render`]: per rotation, the scatterers near the vehicle, their visibility through the
//!   occluders in front (a polar transmission buffer from the rotation's middle pose) and
//!   their multipath ghosts in strong flat reflectors; per azimuth, each candidate's range,
//!   antenna gain and speckle draw deposited into a range line, convolved with the range
//!   kernel, added to a floor draw and quantised;
//! - the scene's side (what the renderer is given: [`RealismSpec`], the objects, the
//!   `[street]` generator) lives in [`crate::scene`];
//! - [`stats`] and [`calibrate`]: statistics of polar scans (floor level and spread per
//!   range, two-sample Kolmogorov-Smirnov distance, fraction of bins above the floor, peak
//!   widths in range and azimuth) and the fit of the receiver to the real Oxford scans.
//!
//! Cost per azimuth grows with the scatterers near the beam, never with the scene: the
//! scatterers are held in the same grid index as point features, gathered once per
//! rotation near the vehicle and sorted by bearing. [`crate::render`] dispatches a scene with
//! a `[realism]` table here, and [`crate::render::render_scans`] renders whole scans of it.

pub mod calibrate;
pub mod objects;
pub mod picture;
pub mod receiver;
pub mod render;
pub mod stats;

pub use crate::scene::objects::{ObjectKind, ObjectSpec};
pub use crate::scene::realism_spec::{RangeWindow, RealismSpec};
pub use crate::scene::street::StreetSpec;

#[cfg(test)]
mod tests;
