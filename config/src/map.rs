//! `[map]`: the saved map (slam-map's `.slmap` file: submaps, their frames in the global
//! graph, features, loop closures, the radar profile), for a later run to localise in.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::values::{NonNegativeF64, ValueError};

/// The shortest period between two saves during a run (s): a save writes the whole map.
pub const MIN_SAVE_EVERY_S: f64 = 1.0;

/// `[map]` as written in the file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawMap {
    /// Write the saved map at the end of the run. Default true.
    pub save: bool,
    /// The map file, relative to `output.directory`. Default `"map.slmap"`.
    pub path: PathBuf,
    /// Also write it every this many seconds of the run's clock, at least 1 (0: only at the
    /// end). Default 0.
    pub save_every_s: f64,
}

impl Default for RawMap {
    fn default() -> Self {
        Self {
            save: true,
            path: "map.slmap".into(),
            save_every_s: 0.0,
        }
    }
}

/// `[map]`, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct MapSettings {
    /// Write the saved map.
    pub save: bool,
    /// The file, inside the output directory.
    pub path: PathBuf,
    /// The period of saves during the run (s); `None`: only at the end.
    pub save_every_s: Option<f64>,
}

impl Default for MapSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let s = RawMap::default().check(&mut c);
        debug_assert!(c.is_clean(), "the [map] defaults must be valid");
        s
    }
}

fn period(s: f64) -> Result<Option<f64>, ValueError> {
    let s = NonNegativeF64::new(s)?.get();
    if s == 0.0 {
        Ok(None)
    } else if s < MIN_SAVE_EVERY_S {
        Err(ValueError::Rule(format!(
            "must be 0 (only at the end) or at least {MIN_SAVE_EVERY_S} s, got {s}"
        )))
    } else {
        Ok(Some(s))
    }
}

impl RawMap {
    /// Validates this section alone; errors name `map.<field>`.
    pub fn validate(&self) -> Result<MapSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c);
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker) -> MapSettings {
        MapSettings {
            save: self.save,
            path: c.check("map.path", crate::output::relative_file(&self.path)),
            save_every_s: c.check("map.save_every_s", period(self.save_every_s)),
        }
    }
}

impl From<&MapSettings> for RawMap {
    fn from(s: &MapSettings) -> Self {
        Self {
            save: s.save,
            path: s.path.clone(),
            save_every_s: s.save_every_s.unwrap_or(0.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_map_settings_are_named() {
        let raw = RawMap {
            save: true,
            path: "../elsewhere.slmap".into(),
            save_every_s: 0.5,
        };
        let errors = raw.validate().unwrap_err().to_string();
        for field in ["map.path", "map.save_every_s"] {
            assert!(errors.contains(field), "{field} missing from {errors}");
        }
        let raw = RawMap {
            save_every_s: f64::NAN,
            ..RawMap::default()
        };
        assert!(raw.validate().is_err());
    }

    #[test]
    fn defaults_round_trip() {
        let s = MapSettings::default();
        assert_eq!(RawMap::from(&s).validate().unwrap(), s);
        assert!(s.save);
        assert_eq!(s.save_every_s, None);
        let every = RawMap {
            save_every_s: 30.0,
            ..RawMap::default()
        }
        .validate()
        .unwrap();
        assert_eq!(every.save_every_s, Some(30.0));
        assert_eq!(RawMap::from(&every).validate().unwrap(), every);
    }
}
