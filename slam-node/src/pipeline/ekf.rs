//! The filter the daemon runs, named once for every stage that holds or reads it.

use slam_filter::RadarEkf;

/// The filter the daemon runs.
pub type DaemonEkf = RadarEkf;
