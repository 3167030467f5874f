//! Replaying recordings over the protocol: polar PNG scans of the Oxford Radar RobotCar,
//! Boreas and RADIATE data sets ([`format`], [`scans`], [`png`], [`radiate`]) and raw
//! Colossus byte streams ([`raw`]), with the data sets' ground truth ([`truth`],
//! [`boreas`], [`radiate`]). Oxford and Boreas scans keep their recorded encoder values and
//! timestamps; RADIATE's are made from the azimuth column and the scan times. Every scan,
//! scan index and ground-truth file is read through [`files`]: regular files only (a FIFO
//! or a device is refused before it is opened), each kind with its byte limit.

pub mod boreas;
pub mod files;
pub mod format;
pub mod png;
pub mod radiate;
pub mod raw;
pub mod scans;
pub mod synthetic;
pub mod truth;

pub use format::ReplayFormat;
pub use scans::{ScanGeometry, ScanRecording, ScanSet};
