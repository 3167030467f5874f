//! Is a map usable with this radar? The profile the map was made with against the one the
//! radar runs with now.

use std::fmt;

use radar_model::profile::RadarProfile;

use crate::model::{Map, MapProfile};

/// The map's radar and this radar differ.
///
/// When only the name differs ([`Self::geometry_differs`] is false: same azimuths, bins,
/// bin size and encoder) the looks are comparable and a caller may go on with a warning;
/// when the geometry differs, the features were placed with another range and bearing
/// quantisation and should not be matched.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct ProfileMismatch {
    /// The map's radar.
    pub map: MapProfile,
    /// This radar's.
    pub radar: MapProfile,
    /// Each difference, as `what: map's vs radar's`.
    pub differences: Vec<String>,
}

impl ProfileMismatch {
    /// The geometry differs, not only the name.
    pub fn geometry_differs(&self) -> bool {
        self.map.azimuths != self.radar.azimuths
            || self.map.range_bins != self.radar.range_bins
            || self.map.encoder_size != self.radar.encoder_size
            || !same_bin_size(self.map.bin_size_m, self.radar.bin_size_m)
    }
}

impl fmt::Display for ProfileMismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "the map was made with radar profile {:?}, this radar runs {:?}: {}",
            self.map.name,
            self.radar.name,
            self.differences.join(", ")
        )
    }
}

/// Bin sizes equal to a part in a million (they are written as decimal constants).
fn same_bin_size(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-6 * a.abs().max(b.abs())
}

impl Map {
    /// Whether the map was made with `profile`'s radar (name and geometry).
    pub fn check_profile(&self, profile: &RadarProfile) -> Result<(), ProfileMismatch> {
        self.check_against(&MapProfile::from(profile))
    }

    /// Whether the map was made with a radar of `radar`'s name and geometry.
    pub fn check_against(&self, radar: &MapProfile) -> Result<(), ProfileMismatch> {
        let m = &self.profile;
        let mut differences = Vec::new();
        if m.name != radar.name {
            differences.push(format!("name: {:?} vs {:?}", m.name, radar.name));
        }
        if m.azimuths != radar.azimuths {
            differences.push(format!("azimuths: {} vs {}", m.azimuths, radar.azimuths));
        }
        if m.range_bins != radar.range_bins {
            differences.push(format!(
                "range bins: {} vs {}",
                m.range_bins, radar.range_bins
            ));
        }
        if !same_bin_size(m.bin_size_m, radar.bin_size_m) {
            differences.push(format!(
                "bin size: {} m vs {} m",
                m.bin_size_m, radar.bin_size_m
            ));
        }
        if m.encoder_size != radar.encoder_size {
            differences.push(format!(
                "encoder size: {} vs {}",
                m.encoder_size, radar.encoder_size
            ));
        }
        if differences.is_empty() {
            Ok(())
        } else {
            Err(ProfileMismatch {
                map: m.clone(),
                radar: radar.clone(),
                differences,
            })
        }
    }
}
