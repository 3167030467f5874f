//! The saved map: what a later run needs to localise in a place mapped before, and to
//! extend that map.
//!
//! A [`Map`] holds the radar profile it was made with, every submap's frame with its
//! covariance in the global graph, the submap's chain edge to the next, its features
//! (position, covariance, material logits with their covariance, id, observations), a
//! place-descriptor slot per submap, the loop closures, the time it was written and a free
//! `source` note. It is built from the global layer ([`Map::from_global`],
//! [`Map::from_parts`]) and gives back what the filter and the global layer use
//! ([`Map::frozen_submaps`], [`Map::pose_graph`]).
//!
//! The file ([`codec`]): a 24-byte header (magic, format version, CRC32 and length of the
//! payload), then the payload in postcard's format. Every length is checked against the
//! bytes present and a limit before memory is reserved; corruption, truncation, a future
//! version and a map of another radar ([`Map::check_profile`]) are typed errors naming the
//! file and the reason. `docs/map-format.md` in the repository documents the format field
//! by field.
//!
//! IO: [`Map::save`] (atomic: temporary file, fsync, rename) and [`Map::load`] read and write
//! one file; [`Map::read_from`] and [`Map::write_to`] work on any `Read` / `Write`. Nothing
//! else here does IO, and nothing reads the clock (the creation time is an argument).

pub mod codec;
pub mod convert;
pub mod error;
mod file;
pub mod format;
pub mod model;
pub mod profile;
pub mod validate;

pub use codec::{Limits, DEFAULT_MAX_PAYLOAD_BYTES, FORMAT_VERSION, HEADER_LEN, MAGIC};
pub use convert::{BuildReport, Drives, MapMeta};
pub use error::{FormatError, LoadError, SaveError, WriteError};
pub use format::{MAX_PATH_POINTS, MAX_SCAN_POINTS, PATH_SPACING_M};
pub use model::{
    LoopEdge, Map, MapFeature, MapPath, MapProfile, MapScan, MapSubmap, PlaceDescriptor, Pose,
};
pub use profile::ProfileMismatch;
